//! The per-lane kernels, over blocks of `W` consecutive lanes (8, 4 for packets of 4, 16 for
//! the kd-tree's walks, as two halves): the slab test of one box against every lane, and
//! [`PacketPrimitive`], one primitive against every lane, on the level's eight-lane vectors
//! ([`F8`]; `wide::f64x4` for the refinement of accepted triangle hits). Each lane computes exactly what the single-ray
//! code computes for its ray (same operations in the same order, no fused multiply-add), so
//! the answers agree bit for bit.
//!
//! A block's lanes are a bit mask (`u32`, bit `l` = lane `base + l`).

use crate::RayPacket;
use crate::simd::F8;
use rt_geom::aabb::PAD;
#[cfg(doc)]
use rt_geom::aabb::{pad_down, pad_up};
use rt_geom::{Cone, Hit, PrimHit, Primitive, Shape, Sphere, Triangle, Vec3, keep_hit};
use wide::{CmpGe, CmpGt, CmpLe, f64x4};

/// The block width for packets of `N` lanes.
pub(crate) const fn block_width(n: usize) -> usize {
    if n % 8 == 0 { 8 } else { 4 }
}

/// Lanes `base..base + min(W, 8)` of `v` in one SIMD register (for `W` = 4 the upper four are
/// zero; the masks below keep only the block's own bits).
#[inline(always)]
pub(crate) fn load<V: F8, const N: usize, const W: usize>(v: &[f32; N], base: usize) -> V {
    if W >= 8 {
        return V::load(&v[base..]);
    }
    let mut a = [0.0; 8];
    a[..W].copy_from_slice(&v[base..base + W]);
    V::new(a)
}

/// The bits of the SIMD lanes of `m` (all ones or all zeros each) that belong to a block of
/// `W` lanes (the first 8 of them when `W` is larger).
#[inline(always)]
fn bits<V: F8, const W: usize>(m: V) -> u32 {
    m.bits() & ((1 << W.min(8)) - 1)
}

/// The slab test of 8 lanes from `base` (4 for `W` = 4) against the box `[min, max]`, each lane
/// over `[tmin, tmax]` of the packet: the entry and exit by the packet's folded reciprocals
/// (`inv_lo`, `inv_hi`), computed as [`rt_geom::aabb::SlabRay::entry`] computes them; unpadded
/// for the lanes that do not fold (see `RayPacket::pad_after`).
#[inline(always)]
fn slabs<V: F8, const N: usize, const W: usize>(
    min: &[f32; 3],
    max: &[f32; 3],
    p: &RayPacket<'_, N>,
    base: usize,
) -> (V, V) {
    let mut t0 = load::<V, N, W>(&p.tmin, base);
    let mut t1 = load::<V, N, W>(&p.tmax, base);
    for a in 0..3 {
        let o = load::<V, N, W>(&p.origin[a], base);
        let (inv_lo, inv_hi) = (
            load::<V, N, W>(&p.inv_lo[a], base),
            load::<V, N, W>(&p.inv_hi[a], base),
        );
        // Both planes, then the near one by the sign of the direction (`inv < 0` is
        // `is_sign_negative` for every active lane: an inverse of -0 or NaN belongs to an
        // invalid ray).
        let t_lo = (V::splat(min[a]) - o) * inv_lo;
        let t_hi = (V::splat(max[a]) - o) * inv_hi;
        let neg = inv_lo.lt(V::zero());
        let tn = neg.select(t_hi, t_lo);
        let tf = neg.select(t_lo, t_hi);
        // `if tn > t0 { tn } else { t0 }`: NaN keeps the interval as it is.
        t0 = tn.gt(t0).select(tn, t0);
        t1 = tf.lt(t1).select(tf, t1);
    }
    (t0, t1)
}

/// `t - |t| PAD` and `t + |t| PAD` on 8 lanes ([`pad_down`], [`pad_up`]).
#[inline(always)]
pub(crate) fn pad<V: F8>(t: V, up: bool) -> V {
    let m = t.abs() * V::splat(PAD);
    if up { t + m } else { t - m }
}

/// The lanes of the block at `base` that are active and enter the box `[min, max]` within
/// their `[tmin, tmax]`: the single-ray traversal's padded slab test
/// ([`rt_geom::aabb::SlabRay::entry`]) lane by lane.
#[inline(always)]
pub(crate) fn enter_mask<V: F8, const N: usize, const W: usize>(
    min: &[f32; 3],
    max: &[f32; 3],
    p: &RayPacket<'_, N>,
    base: usize,
) -> u32 {
    let mut mask = 0;
    for half in (0..W).step_by(8) {
        let (t0, t1) = slabs::<V, N, W>(min, max, p, base + half);
        let (t0, t1) = if p.pad_after {
            (pad(t0, false), pad(t1, true))
        } else {
            (t0, t1)
        };
        mask |= bits::<V, W>(t0.le(t1)) << half;
    }
    mask & active_mask::<N, W>(p, base)
}

/// A block's values per lane, eight lanes per register: blocks of 16 use both, blocks of 8
/// and 4 the first (lanes past the block hold what the function that made them says).
pub(crate) type BlockRegs<V> = [V; 2];

/// Registers of a block of `w` lanes.
pub(crate) const fn registers(w: usize) -> usize {
    w.div_ceil(8)
}

/// The lanes `l` of a block of `W` where `x[l] <= y[l]` (false when either is NaN).
#[inline(always)]
pub(crate) fn le_bits<V: F8, const W: usize>(x: &BlockRegs<V>, y: &BlockRegs<V>) -> u32 {
    let mut mask = 0;
    for h in 0..registers(W) {
        mask |= x[h].le(y[h]).bits() << (8 * h);
    }
    mask & (u32::MAX >> (32 - W))
}

/// `v` in the lanes of `bits`, `other` elsewhere (past the block too).
#[inline(always)]
pub(crate) fn select_lanes<V: F8>(bits: u32, v: &BlockRegs<V>, other: f32) -> BlockRegs<V> {
    let other = V::splat(other);
    [
        V::from_bits(bits).select(v[0], other),
        V::from_bits(bits >> 8).select(v[1], other),
    ]
}

/// The lanes of the block at `base` whose direction is negative (sign bit set, `-0`
/// included) along each axis, as the sign of `inv_dir`.
#[inline(always)]
pub(crate) fn negative_bits<V: F8, const N: usize, const W: usize>(
    p: &RayPacket<'_, N>,
    base: usize,
) -> [u32; 3] {
    std::array::from_fn(|a| {
        let mut mask = 0;
        for h in 0..registers(W) {
            mask |= load::<V, N, W>(&p.inv_dir[a], base + 8 * h).bits() << (8 * h);
        }
        mask & (u32::MAX >> (32 - W))
    })
}

/// [`rt_geom::aabb::SlabRay::entry`] of the block's lanes (with `pad_after`,
/// [`rt_geom::Aabb::clip_ray`]): the padded entry and exit of each lane, in registers, and the
/// mask of the active lanes that enter.
#[inline(always)]
pub(crate) fn clip_block<V: F8, const N: usize, const W: usize>(
    min: &[f32; 3],
    max: &[f32; 3],
    p: &RayPacket<'_, N>,
    base: usize,
) -> (BlockRegs<V>, BlockRegs<V>, u32) {
    let (mut near, mut far, mut mask) = ([V::zero(); 2], [V::zero(); 2], 0);
    for h in 0..registers(W) {
        let (t0, t1) = slabs::<V, N, W>(min, max, p, base + 8 * h);
        let (t0, t1) = if p.pad_after {
            let (t0, t1) = (pad(t0, false), pad(t1, true));
            // `t0.max(tmin)` of `clip_ray` (t0 is never NaN for a lane that enters).
            let tmin = load::<V, N, W>(&p.tmin, base + 8 * h);
            (tmin.gt(t0).select(tmin, t0), t1)
        } else {
            // Never below `tmin`: the slabs start from it and only raise it.
            (t0, t1)
        };
        mask |= bits::<V, W>(t0.le(t1)) << (8 * h);
        (near[h], far[h]) = (t0, t1);
    }
    (near, far, mask & active_mask::<N, W>(p, base))
}

/// The active lanes of the block at `base`.
#[inline(always)]
pub(crate) fn active_mask<const N: usize, const W: usize>(
    p: &RayPacket<'_, N>,
    base: usize,
) -> u32 {
    let mut mask = 0;
    for half in (0..W).step_by(8) {
        // The flags as bytes (0 or 1) of one word; the multiply gathers bit 0 of byte `l`
        // into bit `56 + l`.
        let mut bytes = [0u8; 8];
        let flags = &p.active[base + half..base + half + W.min(8)];
        for (byte, &on) in bytes.iter_mut().zip(flags) {
            *byte = on as u8;
        }
        let gathered = u64::from_le_bytes(bytes).wrapping_mul(0x0102_0408_1020_4080) >> 56;
        mask |= (gathered as u32) << half;
    }
    mask
}

/// A primitive tested against several lanes of a packet at once. The default tests the lanes
/// one by one with [`Primitive::intersect`]; triangles compute the watertight edge functions of
/// all lanes together.
pub trait PacketPrimitive: Primitive {
    /// The hits of the lanes in `mask` (bits relative to `base`) of the block at `base`, each
    /// lane over `[tmin, tmax]` of the packet: exactly `self.intersect(&p.ray(lane))`. Returns
    /// the lanes that hit, each one's hit in `out` (other lanes of `out` are left as they are).
    /// `V`: the vectors of the level the traversal runs at.
    #[inline(always)]
    fn intersect_block<V: F8, const N: usize, const W: usize>(
        &self,
        p: &RayPacket<'_, N>,
        base: usize,
        mask: u32,
        out: &mut [PrimHit; W],
    ) -> u32 {
        let mut hits = 0;
        for_each_lane(mask, |l| {
            if let Some(h) = self.intersect(&p.ray(base + l)) {
                out[l] = h;
                hits |= 1 << l;
            }
        });
        hits
    }
}

/// The lane version of [`rt_geom::test_primitives`]: every primitive (with its id) against the
/// lanes in `lanes` of the block at `base`, each lane over `[tmin, tmax]` with `tmax` its
/// closest hit so far. Closest hit: a hit replaces the lane's best by the tie rule
/// ([`replaces`]) and shrinks its `tmax`. With `ANY_HIT`, a lane that hits anything is done
/// (made inactive, its `tmax` `-inf`). Returns the lanes whose `tmax` changed (that hit
/// something).
#[inline(always)]
pub(crate) fn test_block<'a, V: F8, P, const N: usize, const W: usize, const ANY_HIT: bool>(
    prims: impl Iterator<Item = (&'a P, u32)>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
    base: usize,
    mut lanes: u32,
) -> u32
where
    P: PacketPrimitive + 'a,
{
    let mut changed = 0;
    let mut hits = [PrimHit::default(); W];
    for (prim, id) in prims {
        if lanes == 0 {
            break;
        }
        let tested = if p.skipping {
            lanes & !skipping_lanes::<N, W>(p, base, id)
        } else {
            lanes
        };
        let hit = prim.intersect_block::<V, N, W>(p, base, tested, &mut hits);
        for_each_lane(hit, |l| {
            let h = hits[l];
            let lane = base + l;
            if ANY_HIT {
                best[lane] = Some(Hit::new(h, id));
                p.active[lane] = false;
                p.tmax[lane] = f32::NEG_INFINITY;
                lanes &= !(1 << l);
            } else {
                keep_hit::<false>(h, id, &mut p.tmax[lane], &mut best[lane]);
            }
            changed |= 1 << l;
        });
    }
    changed
}

/// The lanes of the block at `base` that leave (skip) primitive `id`.
#[inline(always)]
fn skipping_lanes<const N: usize, const W: usize>(
    p: &RayPacket<'_, N>,
    base: usize,
    id: u32,
) -> u32 {
    let mut bits = 0;
    for (l, &skip) in p.skip[base..base + W].iter().enumerate() {
        bits |= ((skip == id) as u32) << l;
    }
    bits
}

/// Calls `f` with every set bit of `mask`, lowest first.
#[inline(always)]
pub(crate) fn for_each_lane(mut mask: u32, mut f: impl FnMut(usize)) {
    while mask != 0 {
        f(mask.trailing_zeros() as usize);
        mask &= mask - 1;
    }
}

impl PacketPrimitive for Triangle {
    /// The watertight test of every lane at once up to the edge functions `(U, V, W)`, as
    /// [`Triangle::intersect_watertight`] computes them (vertex minus origin, dot products with
    /// the shear rows, left to right); the lanes whose signs accept go on one by one through
    /// [`Triangle::finish_watertight`], and lanes with an edge function of exactly zero through
    /// the whole scalar kernel (its `f64` recomputation).
    #[inline(always)]
    fn intersect_block<V: F8, const N: usize, const W: usize>(
        &self,
        p: &RayPacket<'_, N>,
        base: usize,
        mask: u32,
        out: &mut [PrimHit; W],
    ) -> u32 {
        let mut hits = 0;
        for half in (0..W).step_by(8) {
            let (sub, mask) = (base + half, mask >> half & 0xff);
            if mask == 0 {
                continue;
            }
            // Spelled out, no closures bound to names: `array.map` compiles to a call that
            // copies the loaded lanes, and a closure that stays out of line runs at the
            // baseline level inside the AVX2 walks (`rt_geom::isa`).
            let o = [
                load::<V, N, W>(&p.origin[0], sub),
                load::<V, N, W>(&p.origin[1], sub),
                load::<V, N, W>(&p.origin[2], sub),
            ];
            let s = [
                load::<V, N, W>(&p.shear[0], sub),
                load::<V, N, W>(&p.shear[1], sub),
                load::<V, N, W>(&p.shear[2], sub),
                load::<V, N, W>(&p.shear[3], sub),
                load::<V, N, W>(&p.shear[4], sub),
                load::<V, N, W>(&p.shear[5], sub),
            ];
            let (ax, ay) = sheared(self.v[0], &o, &s);
            let (bx, by) = sheared(self.v[1], &o, &s);
            let (cx, cy) = sheared(self.v[2], &o, &s);
            let u = cx * by - cy * bx;
            let v = ax * cy - ay * cx;
            let w = bx * ay - by * ax;
            let z = V::zero();
            let neg = u.lt(z) | v.lt(z) | w.lt(z);
            let pos = u.gt(z) | v.gt(z) | w.gt(z);
            let mixed = bits::<V, W>(neg & pos);
            let zero = bits::<V, W>(u.eq(z) | v.eq(z) | w.eq(z));
            let (eu, ev, ew) = (u.to_array(), v.to_array(), w.to_array());
            for_each_lane(
                mask & zero,
                #[inline(always)]
                |l| keep(out, &mut hits, half + l, self.intersect(&p.ray(sub + l))),
            );
            let candidates = mask & !mixed & !zero;
            if candidates.count_ones() < 4 {
                for_each_lane(
                    candidates,
                    #[inline(always)]
                    |l| {
                        let edges = (eu[l], ev[l], ew[l]);
                        let h = self.finish_watertight_inline(&p.ray(sub + l), edges);
                        keep(out, &mut hits, half + l, h);
                    },
                );
            } else if !self.is_degenerate() {
                refine_lanes(
                    self,
                    p,
                    sub,
                    candidates,
                    (&eu, &ev, &ew),
                    #[inline(always)]
                    |l, h| keep(out, &mut hits, half + l, h),
                );
            }
        }
        hits
    }
}

/// Lane `lane`'s answer `h` into `out`, its bit into `hits` when it hits.
#[inline(always)]
fn keep<const W: usize>(out: &mut [PrimHit; W], hits: &mut u32, lane: usize, h: Option<PrimHit>) {
    if let Some(h) = h {
        out[lane] = h;
        *hits |= 1 << lane;
    }
}

/// A vertex in every lane's sheared frame: `(x, y)` from the lanes' origins `o` and shear
/// rows `s`, as the scalar kernel computes them.
#[inline(always)]
fn sheared<V: F8>(v: Vec3, o: &[V; 3], s: &[V; 6]) -> (V, V) {
    let (x, y, z) = (
        V::splat(v.x) - o[0],
        V::splat(v.y) - o[1],
        V::splat(v.z) - o[2],
    );
    (
        x * s[0] + y * s[1] + z * s[2],
        x * s[3] + y * s[4] + z * s[5],
    )
}

/// [`Triangle::finish_watertight`] of the lanes in `lanes` (bits relative to `base`), whose
/// edge functions `(U, V, W)` agree in sign and are not zero, four lanes at a time: the `f64`
/// refinement of [`Triangle::refine`] with the same operations in the same order on
/// `wide::f64x4` (each lane's shear from its own dominant axis), so every lane's answer is the
/// scalar one, bit for bit. A lane whose `f64` edge functions disagree (the ray passes a
/// rounding error outside the triangle), or whose depth lies outside the triangle's box,
/// goes through the scalar `refine` for its fallback,
/// and the last lanes, fewer than four, through the scalar path altogether (gathering them
/// costs more than it saves where a triangle meets one or two lanes). Each lane's answer goes to `keep(lane, answer)`
/// (lanes relative to `base`); a lane whose interval excludes the hit is not handed over.
#[inline(always)]
fn refine_lanes<const N: usize>(
    tri: &Triangle,
    p: &RayPacket<'_, N>,
    base: usize,
    mut lanes: u32,
    (eu, ev, ew): (&[f32; 8], &[f32; 8], &[f32; 8]),
    mut keep: impl FnMut(usize, Option<PrimHit>),
) {
    while lanes != 0 {
        if lanes.count_ones() < 4 {
            // Fewer than four lanes: the scalar refinement costs less than gathering them.
            for_each_lane(
                lanes,
                #[inline(always)]
                |l| {
                    keep(
                        l,
                        tri.finish_watertight_inline(&p.ray(base + l), (eu[l], ev[l], ew[l])),
                    );
                },
            );
            return;
        }
        // Up to four lanes; spare slots repeat the first (their results are not used).
        let mut pick = [0usize; 4];
        let mut n = 0;
        while lanes != 0 && n < 4 {
            pick[n] = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            n += 1;
        }
        for k in n..4 {
            pick[k] = pick[0];
        }
        // Per lane, by its axes (kx, ky, kz): direction, origin and the vertices' coordinates.
        let (mut d, mut o, mut v) = ([[0.0f64; 4]; 3], [[0.0f64; 4]; 3], [[[0.0f64; 4]; 3]; 3]);
        let verts = tri.v.map(
            #[inline(always)]
            |v| v.to_array(),
        );
        let axes = pick.map(
            #[inline(always)]
            |l| p.rays[base + l].watertight_axes(),
        );
        if axes.iter().all(|a| *a == axes[0]) {
            // One permutation for the four (rays of a tile share their dominant axis): the
            // vertices' coordinates once, the lanes' from the packet's rows.
            for (j, &axis) in axes[0].iter().enumerate() {
                for (k, &l) in pick.iter().enumerate() {
                    d[j][k] = p.dir[axis][base + l] as f64;
                    o[j][k] = p.origin[axis][base + l] as f64;
                }
                for (vi, vert) in v.iter_mut().zip(&verts) {
                    vi[j] = [vert[axis] as f64; 4];
                }
            }
        } else {
            for (k, (&l, lane_axes)) in pick.iter().zip(&axes).enumerate() {
                let ray = &p.rays[base + l];
                // Arrays indexed by the lane's axes (a `Vec3` indexed at run time branches).
                let (dir, org) = (ray.dir().to_array(), ray.origin().to_array());
                for (j, &axis) in lane_axes.iter().enumerate() {
                    d[j][k] = dir[axis] as f64;
                    o[j][k] = org[axis] as f64;
                    for (i, vert) in verts.iter().enumerate() {
                        v[i][j][k] = vert[axis] as f64;
                    }
                }
            }
        }
        let orient = pick.map(
            #[inline(always)]
            |l| {
                if eu[l] + ev[l] + ew[l] < 0.0 {
                    -1.0
                } else {
                    1.0
                }
            },
        );
        let d = d.map(f64x4::new);
        let o = o.map(f64x4::new);
        // The offsets from the origin, and the shear scaled by the major component, as the
        // scalar refinement takes them. Functions, not closures: see `rt_geom::isa`.
        #[inline(always)]
        fn offsets(vert: [[f64; 4]; 3], o: [f64x4; 3]) -> [f64x4; 3] {
            [
                f64x4::new(vert[0]) - o[0],
                f64x4::new(vert[1]) - o[1],
                f64x4::new(vert[2]) - o[2],
            ]
        }
        #[inline(always)]
        fn shear([px, py, pz]: [f64x4; 3], d: [f64x4; 3]) -> [f64x4; 2] {
            [px * d[2] - d[0] * pz, py * d[2] - d[1] * pz]
        }
        let off = [offsets(v[0], o), offsets(v[1], o), offsets(v[2], o)];
        let [ax, ay] = shear(off[0], d);
        let [bx, by] = shear(off[1], d);
        let [cx, cy] = shear(off[2], d);
        let (az, bz, cz) = (off[0][2], off[1][2], off[2][2]);
        let orient = f64x4::new(orient);
        let e0 = (cx * by - cy * bx) * orient;
        let e1 = (ax * cy - ay * cx) * orient;
        let e2 = (bx * ay - by * ax) * orient;
        let sum = e0 + e1 + e2;
        let zero = f64x4::ZERO;
        let inside = e0.cmp_ge(zero) & e1.cmp_ge(zero) & e2.cmp_ge(zero) & sum.cmp_gt(zero);
        let t = ((e0 * az + e1 * bz + e2 * cz) / (sum * d[2])).to_array();
        let t = [t[0] as f32, t[1] as f32, t[2] as f32, t[3] as f32];
        // `Aabb::holds_hit` of the triangle's box at each lane's `t` (as the scalar
        // refinement asks it): the lanes whose depth lies outside take the scalar path.
        let step_t = f64x4::new([t[0] as f64, t[1] as f64, t[2] as f64, t[3] as f64]);
        let half_pad = f64x4::splat(rt_geom::aabb::PAD as f64 * 0.5);
        let mut held = inside;
        for j in 0..3 {
            let (a, b, c) = (off[0][j], off[1][j], off[2][j]);
            let step = d[j] * step_t;
            let slack = step.abs() * half_pad;
            let (below, above) = (step - slack, step + slack);
            held = held
                & (a.cmp_le(above) | b.cmp_le(above) | c.cmp_le(above))
                & (a.cmp_ge(below) | b.cmp_ge(below) | c.cmp_ge(below));
        }
        let held = held.move_mask();
        for (k, &l) in pick[..n].iter().enumerate() {
            let (u, v, w) = (eu[l], ev[l], ew[l]);
            if u + v + w == 0.0 {
                continue;
            }
            let lane = base + l;
            let t = t[k];
            // Grazing lanes, and depths outside the triangle's box (far vertices: see
            // `Aabb::holds_hit`), take the scalar refinement, which moves them into it.
            if held >> k & 1 == 0 {
                keep(l, tri.refine(&p.ray(lane), (u, v, w)));
                continue;
            }
            if t >= p.tmin[lane] && t <= p.tmax[lane] {
                let rcp = 1.0 / (u + v + w);
                keep(
                    l,
                    Some(PrimHit {
                        t,
                        u: v * rcp,
                        v: w * rcp,
                    }),
                );
            }
        }
    }
}

impl PacketPrimitive for Sphere {}
impl PacketPrimitive for Cone {}
impl PacketPrimitive for Shape {}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::{PacketKernel, run};
    use rt_geom::Isa;
    use rt_geom::Ray;
    use rt_geom::aabb::SlabRay;

    /// Every triangle of `tris` against every block of 8 of `rays`, on each level's vectors:
    /// every lane's answer must be the scalar kernel's, bit for bit.
    fn blocks_equal_the_scalar_kernel(tris: &[Triangle], rays: &[Ray]) {
        struct Blocks<'a>(&'a [Triangle], &'a [Ray]);
        impl PacketKernel for Blocks<'_> {
            type Output = ();
            #[inline(always)]
            fn run<V: F8>(self) {
                for chunk in self.1.chunks(8) {
                    let p = RayPacket::<8>::new(chunk);
                    for t in self.0 {
                        let mut got = [PrimHit::default(); 8];
                        let mask = active_mask::<8, 8>(&p, 0);
                        let hit = t.intersect_block::<V, 8, 8>(&p, 0, mask, &mut got);
                        for (l, r) in chunk.iter().enumerate() {
                            let got = (hit >> l & 1 == 1).then_some(got[l]);
                            assert_eq!(got, t.intersect(r), "{t:?} {r:?}");
                        }
                    }
                }
            }
        }
        for isa in Isa::available() {
            run(isa, Blocks(tris, rays));
        }
    }

    #[test]
    fn triangle_lanes_equal_the_scalar_kernel() {
        // Rays through vertices, along edges, grazing, parallel, and general ones: every lane's
        // answer must be the scalar kernel's, bit for bit.
        let tris = rt_testkit::scenes::random_soup(200, 4);
        let mut rays = Vec::new();
        let mut k = 0u32;
        for t in &tris[..40] {
            for target in [t.v[0], t.v[1], (t.v[0] + t.v[1]) * 0.5, t.centroid()] {
                k += 1;
                let o = Vec3::new((k % 7) as f32 * 0.3 - 1.0, (k % 5) as f32 * 0.4 - 1.0, 2.0);
                rays.push(Ray::new(o, target - o));
            }
        }
        rays.push(Ray::new(Vec3::ZERO, Vec3::X));
        blocks_equal_the_scalar_kernel(&tris, &rays);
    }

    #[test]
    fn lanes_refined_four_at_a_time_equal_the_scalar_kernel() {
        // Blocks whose 8 lanes mostly hit the same triangle (the four-lane f64 refinement),
        // with rays through its vertices and edges (the scalar fallback), from several sides
        // (each lane its own dominant axis), and intervals that end before, at and after the
        // hit.
        let tris = [
            Triangle::new(
                Vec3::new(-1.0, -1.0, 0.0),
                Vec3::new(1.0, -1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ),
            Triangle::new(
                Vec3::new(0.0, -2.0, -1.0),
                Vec3::new(0.3, 2.0, 1.0),
                Vec3::new(0.1, 0.0, 3.0),
            ),
            Triangle::new(
                Vec3::new(1e-3, 0.0, 0.0),
                Vec3::new(2.0, 1e-4, 0.0),
                Vec3::new(4.0, 2e-4, 1e-6),
            ),
        ];
        let origins = [
            Vec3::new(0.2, 0.1, 3.0),
            Vec3::new(-4.0, 0.3, 0.5),
            Vec3::new(0.5, 5.0, -2.0),
        ];
        for t in &tris {
            let mut rays = Vec::new();
            for (k, o) in origins.iter().enumerate() {
                for (j, target) in [
                    t.centroid(),
                    t.v[0],
                    (t.v[1] + t.v[2]) * 0.5,
                    t.v[0] * 0.7 + t.v[1] * 0.2 + t.v[2] * 0.1,
                    t.v[2],
                    t.v[0] * 0.1 + t.v[1] * 0.1 + t.v[2] * 0.8,
                    (t.v[0] + t.v[1]) * 0.5,
                    t.v[1] * 0.4 + t.v[2] * 0.6,
                ]
                .into_iter()
                .enumerate()
                {
                    let d = target - *o;
                    let tmax = [f32::INFINITY, 1.0, 0.999_999, 1.000_001][(j + k) % 4];
                    rays.push(Ray::segment(*o, d, 0.0, tmax));
                }
            }
            blocks_equal_the_scalar_kernel(std::slice::from_ref(t), &rays);
        }
    }

    #[test]
    fn active_mask_gathers_every_pattern() {
        let rays = [Ray::new(Vec3::ZERO, Vec3::X); 8];
        let mut p = RayPacket::<8>::new(&rays);
        for bits in 0..256u32 {
            for l in 0..8 {
                p.active[l] = bits >> l & 1 == 1;
            }
            assert_eq!(active_mask::<8, 8>(&p, 0), bits);
            assert_eq!(active_mask::<8, 4>(&p, 4), bits >> 4);
        }
    }

    #[test]
    fn block_clip_equals_single_ray_slab_tests() {
        // Entries as `SlabRay::entry` computes them (intervals from 0); with an interval
        // starting behind the origin, every lane unfolded and padded afterwards: exactly
        // `clip_ray`, entry and exit.
        let b = rt_geom::Aabb::new(Vec3::ZERO, Vec3::ONE);
        for tmin in [0.0, -0.5] {
            let rays: Vec<Ray> = (0..16)
                .map(|i| {
                    let f = i as f32 / 16.0;
                    let d = Vec3::new(1.0 - 2.0 * (i % 2) as f32, 0.0, f - 0.5);
                    let o = Vec3::new(0.5 - 1.5 * d.x, f * 1.5 - 0.2, 0.5);
                    Ray::segment(o, d, tmin, f32::INFINITY)
                })
                .collect();
            let p = RayPacket::<16>::new(&rays);
            assert_eq!(p.pad_after, tmin < 0.0);
            for base in [0, 8] {
                let (min, max) = (b.min.to_array(), b.max.to_array());
                let (t0, t1, m) = clip_block::<wide::f32x8, 16, 8>(&min, &max, &p, base);
                let (t0, t1) = (t0[0].to_array(), t1[0].to_array());
                for l in 0..8 {
                    let r = &rays[base + l];
                    if tmin < 0.0 {
                        let expect = b.clip_ray(r);
                        assert_eq!(m >> l & 1 == 1, expect.is_some(), "lane {}", base + l);
                        if let Some((a, b)) = expect {
                            assert_eq!((t0[l], t1[l]), (a, b), "lane {}", base + l);
                        }
                    } else {
                        let expect = SlabRay::new(r).entry(&min, &max, r.tmin, r.tmax);
                        assert_eq!(m >> l & 1 == 1, expect.is_some(), "lane {}", base + l);
                        if let Some(a) = expect {
                            assert_eq!(t0[l], a, "lane {}", base + l);
                        }
                    }
                }
                assert_eq!(enter_mask::<wide::f32x8, 16, 8>(&min, &max, &p, base), m);
            }
        }
    }
}
