//! The per-lane kernels, over blocks of `W` consecutive lanes (8, or 4 for packets of 4):
//! the slab test of one box against every lane, and [`PacketPrimitive`], one primitive against
//! every lane. Each lane computes exactly what the single-ray code computes for its ray (same
//! operations in the same order, no fused multiply-add), so the answers agree bit for bit.
//!
//! A block's lanes are a bit mask (`u32`, bit `l` = lane `base + l`).

use crate::RayPacket;
use rt_geom::aabb::{pad_down, pad_up};
use rt_geom::{Cone, Hit, PrimHit, Primitive, Shape, Sphere, Triangle, Vec3, replaces};

/// The block width for packets of `N` lanes.
pub(crate) const fn block_width(n: usize) -> usize {
    if n % 8 == 0 { 8 } else { 4 }
}

/// Lanes `base..base + W` as fixed-size arrays.
#[inline(always)]
pub(crate) fn block<const N: usize, const W: usize>(v: &[f32; N], base: usize) -> &[f32; W] {
    v[base..base + W]
        .try_into()
        .expect("block inside the packet")
}

/// The slab test of the block's lanes against the box `[min, max]`, each lane over `[tmin,
/// tmax]` of the packet: the unpadded entry and exit, computed as
/// [`rt_geom::Aabb::clip_ray`] computes them.
#[inline(always)]
fn slabs<const N: usize, const W: usize>(
    min: &[f32; 3],
    max: &[f32; 3],
    p: &RayPacket<'_, N>,
    base: usize,
) -> ([f32; W], [f32; W]) {
    let mut t0: [f32; W] = *block(&p.tmin, base);
    let mut t1: [f32; W] = *block(&p.tmax, base);
    for a in 0..3 {
        let o = block::<N, W>(&p.origin[a], base);
        let inv = block::<N, W>(&p.inv_dir[a], base);
        let (lo, hi) = (min[a], max[a]);
        for l in 0..W {
            // Both planes, then the near one by the sign of the direction: the same values
            // as the single-ray test's, in a form that vectorises.
            let t_lo = (lo - o[l]) * inv[l];
            let t_hi = (hi - o[l]) * inv[l];
            let neg = inv[l].is_sign_negative();
            let tn = if neg { t_hi } else { t_lo };
            let tf = if neg { t_lo } else { t_hi };
            t0[l] = if tn > t0[l] { tn } else { t0[l] };
            t1[l] = if tf < t1[l] { tf } else { t1[l] };
        }
    }
    (t0, t1)
}

/// The lanes of the block at `base` that are active and enter the box `[min, max]` within
/// their `[tmin, tmax]`: the single-ray traversal's padded slab test
/// ([`rt_geom::Aabb::clip_ray`]) lane by lane.
#[inline(always)]
pub(crate) fn enter_mask<const N: usize, const W: usize>(
    min: &[f32; 3],
    max: &[f32; 3],
    p: &RayPacket<'_, N>,
    base: usize,
) -> u32 {
    let (t0, t1) = slabs::<N, W>(min, max, p, base);
    let active: &[bool; W] = p.active[base..base + W].try_into().expect("block");
    let mut mask = 0;
    for l in 0..W {
        let enters = (pad_down(t0[l]) <= pad_up(t1[l])) & active[l];
        mask |= (enters as u32) << l;
    }
    mask
}

/// [`rt_geom::Aabb::clip_ray`] of the block's lanes: the padded entry and exit of each lane,
/// and the mask of the active lanes that enter.
#[inline(always)]
pub(crate) fn clip_block<const N: usize, const W: usize>(
    min: &[f32; 3],
    max: &[f32; 3],
    p: &RayPacket<'_, N>,
    base: usize,
) -> ([f32; W], [f32; W], u32) {
    let (mut t0, mut t1) = slabs::<N, W>(min, max, p, base);
    let tmin: &[f32; W] = block(&p.tmin, base);
    let active: &[bool; W] = p.active[base..base + W].try_into().expect("block");
    let mut mask = 0;
    for l in 0..W {
        t0[l] = pad_down(t0[l]);
        t1[l] = pad_up(t1[l]);
        let enters = (t0[l] <= t1[l]) & active[l];
        mask |= (enters as u32) << l;
        // `t0.max(tmin)` of `clip_ray` (t0 is never NaN here).
        t0[l] = if tmin[l] > t0[l] { tmin[l] } else { t0[l] };
    }
    (t0, t1, mask)
}

/// The active lanes of the block at `base`.
#[inline(always)]
pub(crate) fn active_mask<const N: usize, const W: usize>(
    p: &RayPacket<'_, N>,
    base: usize,
) -> u32 {
    (0..W).fold(0, |m, l| m | ((p.active[base + l] as u32) << l))
}

/// A primitive tested against several lanes of a packet at once. The default tests the lanes
/// one by one with [`Primitive::intersect`]; triangles compute the watertight edge functions of
/// all lanes together.
pub trait PacketPrimitive: Primitive {
    /// The hits of the lanes in `mask` (bits relative to `base`) of the block at `base`, each
    /// lane over `[tmin, tmax]` of the packet: exactly `self.intersect(&p.ray(lane))`.
    #[inline(always)]
    fn intersect_block<const N: usize, const W: usize>(
        &self,
        p: &RayPacket<'_, N>,
        base: usize,
        mask: u32,
    ) -> [Option<PrimHit>; W] {
        let mut out = [None; W];
        for_each_lane(mask, |l| out[l] = self.intersect(&p.ray(base + l)));
        out
    }
}

/// The lane version of [`rt_geom::test_primitives`]: every primitive (with its id) against the
/// lanes in `lanes` of the block at `base`, each lane over `[tmin, tmax]` with `tmax` its
/// closest hit so far. Closest hit: a hit replaces the lane's best by the tie rule
/// ([`replaces`]) and shrinks its `tmax`. With `ANY_HIT`, a lane that hits anything is done
/// (made inactive).
#[inline(always)]
pub(crate) fn test_block<'a, P, const N: usize, const W: usize, const ANY_HIT: bool>(
    prims: impl Iterator<Item = (&'a P, u32)>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
    base: usize,
    mut lanes: u32,
) where
    P: PacketPrimitive + 'a,
{
    for (prim, id) in prims {
        if lanes == 0 {
            break;
        }
        let hits = prim.intersect_block::<N, W>(p, base, lanes);
        for_each_lane(lanes, |l| {
            let Some(h) = hits[l] else { return };
            let lane = base + l;
            if ANY_HIT {
                best[lane] = Some(Hit::new(h, id));
                p.active[lane] = false;
                lanes &= !(1 << l);
            } else if replaces(h.t, id, best[lane].as_ref().map(Hit::key)) {
                best[lane] = Some(Hit::new(h, id));
                p.tmax[lane] = h.t;
            }
        });
    }
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
    fn intersect_block<const N: usize, const W: usize>(
        &self,
        p: &RayPacket<'_, N>,
        base: usize,
        mask: u32,
    ) -> [Option<PrimHit>; W] {
        let o = [0, 1, 2].map(|a| block::<N, W>(&p.origin[a], base));
        let s = [0, 1, 2, 3, 4, 5].map(|k| block::<N, W>(&p.shear[k], base));
        let sheared = |v: Vec3, l: usize| {
            let (x, y, z) = (v.x - o[0][l], v.y - o[1][l], v.z - o[2][l]);
            (
                x * s[0][l] + y * s[1][l] + z * s[2][l],
                x * s[3][l] + y * s[4][l] + z * s[5][l],
            )
        };
        let (mut eu, mut ev, mut ew) = ([0.0f32; W], [0.0f32; W], [0.0f32; W]);
        for l in 0..W {
            let (ax, ay) = sheared(self.v[0], l);
            let (bx, by) = sheared(self.v[1], l);
            let (cx, cy) = sheared(self.v[2], l);
            eu[l] = cx * by - cy * bx;
            ev[l] = ax * cy - ay * cx;
            ew[l] = bx * ay - by * ax;
        }
        let (mut accept, mut zero) = (0u32, 0u32);
        for l in 0..W {
            let (u, v, w) = (eu[l], ev[l], ew[l]);
            let mixed = (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0);
            accept |= (!mixed as u32) << l;
            zero |= ((u == 0.0 || v == 0.0 || w == 0.0) as u32) << l;
        }
        let mut out = [None; W];
        for_each_lane(mask & zero, |l| out[l] = self.intersect(&p.ray(base + l)));
        for_each_lane(mask & accept & !zero, |l| {
            out[l] = self.finish_watertight(&p.ray(base + l), (eu[l], ev[l], ew[l]));
        });
        out
    }
}

impl PacketPrimitive for Sphere {}
impl PacketPrimitive for Cone {}
impl PacketPrimitive for Shape {}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_geom::Ray;

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
        for chunk in rays.chunks(8) {
            let p = RayPacket::<8>::new(chunk);
            for t in &tris {
                let got = t.intersect_block::<8, 8>(&p, 0, active_mask::<8, 8>(&p, 0));
                for (l, r) in chunk.iter().enumerate() {
                    assert_eq!(got[l], t.intersect(r), "{t:?} {r:?}");
                }
            }
        }
    }

    #[test]
    fn block_clip_equals_clip_ray() {
        let b = rt_geom::Aabb::new(Vec3::ZERO, Vec3::ONE);
        let rays: Vec<Ray> = (0..16)
            .map(|i| {
                let f = i as f32 / 16.0;
                Ray::new(
                    Vec3::new(-1.0, f * 1.5 - 0.2, 0.5),
                    Vec3::new(1.0, 0.0, f - 0.5),
                )
            })
            .collect();
        let p = RayPacket::<16>::new(&rays);
        for base in [0, 8] {
            let (t0, t1, m) = clip_block::<16, 8>(&b.min.to_array(), &b.max.to_array(), &p, base);
            for l in 0..8 {
                let expect = b.clip_ray(&rays[base + l]);
                assert_eq!(m >> l & 1 == 1, expect.is_some(), "lane {}", base + l);
                if let Some((a, b)) = expect {
                    assert_eq!((t0[l], t1[l]), (a, b), "lane {}", base + l);
                }
            }
        }
    }
}
