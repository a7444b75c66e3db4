//! Ray packets: `N` rays in structure-of-arrays form (the layout the per-lane box test
//! vectorises over), an active mask, and packets cut from image tiles.

use rt_geom::Ray;
use rt_geom::aabb::PAD;
#[cfg(doc)]
use rt_geom::aabb::SlabRay;

/// The packet sizes: square tiles of 2x2 to 16x16 pixels.
pub const TILE_SIDES: [usize; 4] = [2, 4, 8, 16];

/// `N` rays, structure of arrays. Lanes past the rays given, and lanes with invalid rays, are
/// inactive from the start. `N` is a multiple of 4: the lane loops run over blocks of 8 lanes
/// (4 when `N` is not a multiple of 8), fixed-size arrays that the compiler turns into one SIMD
/// instruction per operation (SSE; AVX in the `-C target-cpu=native` build of `cargo xtask`),
/// with no `unsafe` and a portable fallback on any target.
#[derive(Clone, Debug)]
pub struct RayPacket<'a, const N: usize> {
    /// The rays themselves (the primitive kernels take them whole): lane `i` is `rays[i]`.
    pub rays: &'a [Ray],
    /// The lanes, on the heap: a packet is a pointer and a slice, cheap to return, and its
    /// lanes are reused by the next packet of the thread ([`RayPacket::recycle`]).
    lanes: Box<Lanes<N>>,
}

/// The lanes of a [`RayPacket`] (which dereferences to them).
#[derive(Clone, Debug)]
pub struct Lanes<const N: usize> {
    /// Origins per axis.
    pub origin: [[f32; N]; 3],
    /// Directions per axis.
    pub dir: [[f32; N]; 3],
    /// `1 / dir` per axis (`+-inf` for zero components, as `Ray::inv_dir`).
    pub inv_dir: [[f32; N]; 3],
    /// The slab test's reciprocals for a box's min and max plane, with the padding folded in
    /// as [`rt_geom::aabb::SlabRay`] folds it: `inv_dir` scaled by `1 - PAD` for the plane
    /// the lane enters by and `1 + PAD` for the one it leaves by; plain `inv_dir` for the
    /// lanes with `tmin < 0`, which set `pad_after`.
    pub inv_lo: [[f32; N]; 3],
    /// See `inv_lo`.
    pub inv_hi: [[f32; N]; 3],
    /// Some active lane has `tmin < 0`: box tests pad their intervals afterwards (lanes with
    /// folded reciprocals are then padded twice, which stays conservative).
    pub pad_after: bool,
    /// The watertight triangle test's shear rows per lane ([`Ray::watertight_rows`]): `x`, `y`,
    /// `z` of row 0, then of row 1.
    pub shear: [[f32; N]; 6],
    /// Start of each lane's interval.
    pub tmin: [f32; N],
    /// Shrinks to each lane's closest hit during traversal; `-inf` in inactive lanes (from
    /// the fill, and once an any-hit query is done with a lane), so that the largest `tmax`
    /// bounds how far the packet may still find hits.
    pub tmax: [f32; N],
    /// Lanes that carry a ray still being traced.
    pub active: [bool; N],
    /// Per lane, the primitive its ray leaves and skips (`u32::MAX`: none), read only when
    /// `skipping` ([`RayPacket::leaving`]).
    pub skip: [u32; N],
    /// Some lane skips a primitive.
    pub skipping: bool,
}

impl<const N: usize> std::ops::Deref for RayPacket<'_, N> {
    type Target = Lanes<N>;
    #[inline(always)]
    fn deref(&self) -> &Lanes<N> {
        &self.lanes
    }
}

impl<const N: usize> std::ops::DerefMut for RayPacket<'_, N> {
    #[inline(always)]
    fn deref_mut(&mut self) -> &mut Lanes<N> {
        &mut self.lanes
    }
}

thread_local! {
    /// Lanes of packets this thread traced, for its next ones (a few: one per packet size
    /// in use, more only while packets are nested).
    static SPARE_LANES: std::cell::RefCell<Vec<Box<dyn std::any::Any>>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

impl<'a, const N: usize> RayPacket<'a, N> {
    /// A packet of up to `N` rays (the first `rays.len()` lanes), its lanes from the ones this
    /// thread's last packet of `N` lanes gave back ([`Self::recycle`]), or new.
    pub fn new(rays: &'a [Ray]) -> Self {
        const { assert!(N > 0 && N % 4 == 0, "packets hold a multiple of 4 lanes") };
        assert!(
            rays.len() <= N,
            "{} rays do not fit a packet of {N}",
            rays.len()
        );
        let spare = SPARE_LANES.with(|spare| {
            let mut spare = spare.borrow_mut();
            let at = spare.iter().position(|l| l.is::<Lanes<N>>())?;
            spare.swap_remove(at).downcast::<Lanes<N>>().ok()
        });
        let lanes = spare.unwrap_or_else(|| {
            Box::new(Lanes {
                origin: [[0.0; N]; 3],
                dir: [[0.0; N]; 3],
                inv_dir: [[0.0; N]; 3],
                inv_lo: [[0.0; N]; 3],
                inv_hi: [[0.0; N]; 3],
                pad_after: false,
                shear: [[0.0; N]; 6],
                tmin: [0.0; N],
                tmax: [f32::NEG_INFINITY; N],
                active: [false; N],
                skip: [u32::MAX; N],
                skipping: false,
            })
        });
        let mut p = Self { rays, lanes };
        p.fill();
        p.skipping = false;
        p
    }

    /// A packet of rays that each leave a primitive, `leaving[i]` for ray `i` (`None`: it
    /// leaves none; an empty slice: no ray does), which its lane skips as
    /// [`rt_geom::SkipPrim`] makes a single ray's filtered query skip it: a ray leaving a
    /// planar primitive starts on it with no offset.
    pub fn leaving(rays: &'a [Ray], leaving: &[Option<u32>]) -> Self {
        let mut p = Self::new(rays);
        p.skipping = leaving.iter().any(Option::is_some);
        if p.skipping {
            assert_eq!(leaving.len(), rays.len(), "one primitive left per ray");
            for (lane, &prim) in p.lanes.skip.iter_mut().zip(leaving) {
                *lane = prim.unwrap_or(u32::MAX);
            }
            p.lanes.skip[leaving.len()..].fill(u32::MAX);
        }
        p
    }

    /// Gives the packet's lanes back for this thread's next packet of `N` lanes, which then
    /// needs no allocation and no zeroing (every lane is written again: the rays' lanes, and
    /// the lanes past them as inactive). Zeroing a new 256-lane packet's 26 KiB each time, and
    /// before that copying it once more on return, were a measurable part of a packet's time.
    pub fn recycle(self) {
        let lanes: Box<dyn std::any::Any> = self.lanes;
        SPARE_LANES.with(|spare| {
            let mut spare = spare.borrow_mut();
            if spare.len() < 8 {
                spare.push(lanes);
            }
        });
    }

    /// Writes every lane, in place: the rays' lanes and the lanes past them (inactive, an
    /// empty interval). The fields are written lane block by lane block: building them as
    /// arrays of their own and moving them into the packet would copy every byte once more.
    fn fill(&mut self) {
        // A block of lanes at a time: the rays' own numbers (origin, direction, interval; one
        // row of 8 per ray, transposed into lanes), then everything derived from them
        // (reciprocals, folded reciprocals, shear rows) in SIMD, with the operations of
        // `Ray::segment` and `SlabRay`, so the same bits. Copying the derived numbers from the
        // rays took 23 scalar loads and stores per ray, and filling a 16x16 packet was a third
        // of the teapot's packet time.
        let mut pad_after = false;
        for base in (0..N).step_by(crate::lanes::block_width(N)) {
            pad_after |= match crate::lanes::block_width(N) {
                8 => self.fill_block::<8>(base),
                _ => self.fill_block::<4>(base),
            };
        }
        self.pad_after = pad_after;
    }

    /// Fills the `W` lanes from `base` (a block of 8, or of 4 in packets of 4): the rays'
    /// origins, directions, intervals and validity, and what [`Ray::segment`] derives from
    /// them (`1 / dir`, the dominant axis and the watertight shear rows) and the folded
    /// reciprocals of [`SlabRay`], the same operations in the same order per lane. Lanes past
    /// the rays stay inactive; the derived fields of inactive lanes are zero. Returns whether
    /// an active lane has `tmin < 0` (see [`Self::pad_after`]).
    #[inline(always)]
    fn fill_block<const W: usize>(&mut self, base: usize) -> bool {
        use wide::{CmpGe, CmpLe, CmpLt, f32x8};
        let st = |v: &mut [f32; N], x: f32x8| {
            v[base..base + W].copy_from_slice(&x.to_array()[..W]);
        };
        // Lanes past the rays: an empty interval.
        let past = f32x8::new([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, f32::NEG_INFINITY]);
        // Validity as a lane mask (all ones or all zeros).
        let mut valid = [0.0; 8];
        let mut row = |l: usize, r: &Ray| {
            valid[l] = f32::from_bits(if r.is_valid() { u32::MAX } else { 0 });
            let (o, d) = (r.origin(), r.dir());
            f32x8::new([o.x, o.y, o.z, d.x, d.y, d.z, r.tmin, r.tmax])
        };
        // A whole block of rays (all but the last block of a packet) without a check per lane.
        let rows = match self.rays.get(base..base + W) {
            Some(rays) => std::array::from_fn(|l| if l < W { row(l, &rays[l]) } else { past }),
            None => std::array::from_fn(|l| match self.rays.get(base + l) {
                Some(r) if l < W => row(l, r),
                _ => past,
            }),
        };
        let [ox, oy, oz, dx, dy, dz, tmin, tmax] = f32x8::transpose(rows);
        let (d, zero, one) = ([dx, dy, dz], f32x8::ZERO, f32x8::ONE);
        for (a, o) in [ox, oy, oz].into_iter().enumerate() {
            st(&mut self.origin[a], o);
            st(&mut self.dir[a], d[a]);
        }
        let valid = f32x8::new(valid);
        let active = valid & tmin.cmp_le(tmax);
        st(&mut self.tmin, tmin);
        // Inactive lanes end at `-inf`: the largest `tmax` of a packet's lanes bounds how far
        // its active ones may still find a hit (`Beam::limit_to_lanes`).
        st(
            &mut self.tmax,
            active.blend(tmax, f32x8::splat(f32::NEG_INFINITY)),
        );
        let active_bits = active.move_mask() as u32;
        let lanes: [bool; 8] = spread_bits(active_bits).map(|b| b != 0);
        self.active[base..base + W].copy_from_slice(&lanes[..W]);
        // `SlabRay::fold_factors` and `SlabRay::new`.
        let folds = tmin.cmp_ge(zero);
        let near = folds.blend(f32x8::splat(1.0 - PAD), one);
        let far = folds.blend(f32x8::splat(1.0 + PAD), one);
        for (a, &da) in d.iter().enumerate() {
            let inv = one / da;
            let neg = inv.cmp_lt(zero);
            st(&mut self.inv_dir[a], valid.blend(inv, zero));
            st(
                &mut self.inv_lo[a],
                valid.blend(inv * neg.blend(far, near), zero),
            );
            st(
                &mut self.inv_hi[a],
                valid.blend(inv * neg.blend(near, far), zero),
            );
        }
        // `Ray::segment`'s axes: `kz` the dominant one (ties to the lower axis), `kx`, `ky`
        // the next ones, swapped when `dir[kz] < 0`.
        let abs = d.map(f32x8::abs);
        let kz0 = abs[0].cmp_ge(abs[1]) & abs[0].cmp_ge(abs[2]);
        let kz1 = !kz0 & abs[1].cmp_ge(abs[2]);
        let kz = [kz0, kz1, !kz0 & !kz1];
        let dkz = kz[0].blend(d[0], kz[1].blend(d[1], d[2]));
        let swap = dkz.cmp_lt(zero);
        let kx = [
            (kz[1] & swap) | (kz[2] & !swap),
            (kz[0] & !swap) | (kz[2] & swap),
            (kz[0] & swap) | (kz[1] & !swap),
        ];
        let ky = [
            (kz[1] & !swap) | (kz[2] & swap),
            (kz[0] & swap) | (kz[2] & !swap),
            (kz[0] & !swap) | (kz[1] & swap),
        ];
        let pick = |k: [f32x8; 3]| k[0].blend(d[0], k[1].blend(d[1], d[2]));
        let sx = valid.blend(pick(kx) / dkz, zero);
        let sy = valid.blend(pick(ky) / dkz, zero);
        // `Ray::segment`'s rows: one at `kx` (`ky`), `-Sx` (`-Sy`) at `kz`, zero elsewhere.
        // (Negated by a product: `wide`'s `-x` is `0 - x`, which loses the sign of a zero.)
        let unit = |k: f32x8| k.blend(one, zero);
        let (nsx, nsy) = (sx * f32x8::splat(-1.0), sy * f32x8::splat(-1.0));
        for a in 0..3 {
            st(&mut self.shear[a], kz[a].blend(nsx, unit(kx[a])));
            st(&mut self.shear[3 + a], kz[a].blend(nsy, unit(ky[a])));
        }
        (active & !folds).any()
    }

    /// Lane `i`'s ray with its interval ending at the lane's current closest hit.
    #[inline(always)]
    pub fn ray(&self, i: usize) -> Ray {
        self.rays[i].with_range(self.tmin[i], self.tmax[i])
    }

    /// Number of active lanes.
    pub fn active_count(&self) -> usize {
        self.active.iter().filter(|&&a| a).count()
    }
}

/// The low 8 bits of `bits` as 8 bytes, byte `l` one when bit `l` is set (a few integer
/// operations instead of a shift, mask and store per lane).
#[inline(always)]
fn spread_bits(bits: u32) -> [u8; 8] {
    const LOW7: u64 = 0x7f7f_7f7f_7f7f_7f7f;
    // Byte `l` keeps bit `l` of a copy of the 8 bits, then any non-zero byte becomes 1.
    let y = ((bits as u64 & 0xff) * 0x0101_0101_0101_0101) & 0x8040_2010_0804_0201;
    ((((y & LOW7) + LOW7) | y) >> 7 & 0x0101_0101_0101_0101).to_le_bytes()
}

/// Indices of a row-major `width x height` image's pixels grouped into `tw x th` tiles, tiles
/// in row-major order (edge tiles are smaller). Inside a tile the pixels go by blocks of 4x2,
/// the blocks in Morton order: each block of 8 lanes covers a compact patch of the image (and
/// 16 lanes 4x4 pixels), so a small box that some of the tile's rays enter is entered by few
/// blocks.
pub fn tiles(width: usize, height: usize, tw: usize, th: usize) -> Vec<Vec<usize>> {
    let (tw, th) = (tw.max(1), th.max(1));
    let mut out = Vec::with_capacity(width.div_ceil(tw) * height.div_ceil(th));
    for ty in (0..height).step_by(th) {
        for tx in (0..width).step_by(tw) {
            let mut t = Vec::with_capacity(tw * th);
            for y in ty..(ty + th).min(height) {
                for x in tx..(tx + tw).min(width) {
                    t.push(y * width + x);
                }
            }
            t.sort_by_cached_key(|&i| lane_order(i % width - tx, i / width - ty));
            out.push(t);
        }
    }
    out
}

/// The place of pixel `(x, y)` of a tile among the packet's lanes: blocks of 4x2 pixels (one
/// block of 8 SIMD lanes each) in Morton order, `y` first, pixels row-major inside a block:
/// lanes 0..8 are 4x2 pixels, 0..16 are 4x4, 0..32 are 8x4, 0..64 are 8x8.
fn lane_order(x: usize, y: usize) -> (usize, usize, usize) {
    let (bx, by) = (x / 4, y / 2);
    let mut morton = 0;
    for bit in 0..16 {
        morton |= (by >> bit & 1) << (2 * bit) | (bx >> bit & 1) << (2 * bit + 1);
    }
    (morton, y % 2, x % 4)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_geom::Vec3;

    #[test]
    fn spread_bits_gives_one_byte_per_bit() {
        for bits in 0..1024u32 {
            let want: [u8; 8] = std::array::from_fn(|l| (bits >> l & 1) as u8);
            assert_eq!(spread_bits(bits), want, "{bits:#b}");
        }
    }

    #[test]
    fn tiles_cover_every_pixel_once() {
        let t = tiles(10, 7, 4, 4);
        assert_eq!(t.len(), 3 * 2);
        assert_eq!(
            t[0],
            vec![0, 1, 2, 3, 10, 11, 12, 13, 20, 21, 22, 23, 30, 31, 32, 33]
        );
        assert_eq!(t[2].len(), 2 * 4);
        let mut all: Vec<usize> = t.concat();
        all.sort();
        assert_eq!(all, (0..70).collect::<Vec<_>>());
    }

    #[test]
    fn tile_lanes_go_by_blocks_of_4x2() {
        let t = tiles(16, 16, 8, 8);
        // The first block of 8 lanes is the tile's top-left 4x2 pixels, the second the 4x2
        // below it, then the two to their right (Morton order, y first).
        assert_eq!(t[0][..8], [0, 1, 2, 3, 16, 17, 18, 19]);
        assert_eq!(t[0][8..16], [32, 33, 34, 35, 48, 49, 50, 51]);
        assert_eq!(t[0][16..24], [4, 5, 6, 7, 20, 21, 22, 23]);
        assert_eq!(t[1][..4], [8, 9, 10, 11]);
    }

    /// Every lane equals its ray bit for bit: reciprocals, the slab test's folded
    /// reciprocals (`SlabRay`'s, by the direction's sign), the shear rows, validity.
    #[test]
    fn filled_lanes_equal_the_rays_bit_for_bit() {
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        // Components that exercise the dominant axis's ties, signed zeros and signs.
        let picks = [0.0, -0.0, 1.0, -1.0, 0.5, -0.5, 2.0, -2.0, 1e-30, -3.0e7];
        let mut comp = || {
            let r = next();
            if r % 3 == 0 {
                picks[(r >> 8) as usize % picks.len()]
            } else {
                ((r >> 11) as f64 / (1u64 << 53) as f64 * 4.0 - 2.0) as f32
            }
        };
        let mut rays = Vec::new();
        for k in 0..4000 {
            let o = Vec3::new(comp(), comp(), comp());
            let d = Vec3::new(comp(), comp(), comp());
            let (tmin, tmax) = match k % 5 {
                0 => (-1.0, 3.0),
                1 => (0.0, f32::INFINITY),
                2 => (2.0, 1.0),
                3 => (f32::NAN, 1.0),
                _ => (0.25, 8.0),
            };
            rays.push(Ray::segment(o, d, tmin, tmax));
        }
        rays.push(Ray::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X));
        rays.push(Ray::new(Vec3::ZERO, Vec3::new(f32::INFINITY, 1.0, 0.0)));
        fn check<const N: usize>(rays: &[Ray]) {
            let bits = |v: f32| v.to_bits();
            // `N - 1` rays per packet: the last block is partial.
            for chunk in rays.chunks(N - 1) {
                let p = RayPacket::<N>::new(chunk);
                let mut pad_after = false;
                for (i, r) in chunk.iter().enumerate() {
                    let active = r.is_valid() && r.tmin <= r.tmax;
                    assert_eq!(p.active[i], active, "{r:?}");
                    if !active {
                        assert_eq!(p.tmax[i], f32::NEG_INFINITY, "{r:?}");
                        continue;
                    }
                    let slab = rt_geom::aabb::SlabRay::new(r);
                    pad_after |= slab.pad_after;
                    let rows = r.watertight_rows();
                    let (o, d) = (r.origin(), r.dir());
                    assert_eq!((p.tmin[i], p.tmax[i]), (r.tmin, r.tmax));
                    for a in 0..3 {
                        assert_eq!((p.origin[a][i], p.dir[a][i]), (o[a], d[a]));
                        assert_eq!(bits(p.inv_dir[a][i]), bits(r.inv_dir()[a]), "{r:?}");
                        let (lo, hi) = match slab.neg[a] {
                            true => (slab.inv_far[a], slab.inv_near[a]),
                            false => (slab.inv_near[a], slab.inv_far[a]),
                        };
                        assert_eq!(bits(p.inv_lo[a][i]), bits(lo), "{r:?}");
                        assert_eq!(bits(p.inv_hi[a][i]), bits(hi), "{r:?}");
                        assert_eq!(bits(p.shear[a][i]), bits(rows[0][a]), "{r:?}");
                        assert_eq!(bits(p.shear[3 + a][i]), bits(rows[1][a]), "{r:?}");
                    }
                }
                assert_eq!(p.pad_after, pad_after);
                assert!(!p.active[chunk.len()..].iter().any(|&a| a));
                assert!(
                    p.tmax[chunk.len()..]
                        .iter()
                        .all(|&t| t == f32::NEG_INFINITY)
                );
            }
        }
        check::<4>(&rays);
        check::<16>(&rays);
        check::<256>(&rays);
    }

    #[test]
    fn partial_and_invalid_lanes_are_inactive() {
        let rays = [
            Ray::new(Vec3::ZERO, Vec3::X),
            Ray::new(Vec3::ZERO, Vec3::ZERO),
            Ray::segment(Vec3::ZERO, Vec3::Y, 2.0, 1.0),
        ];
        let p = RayPacket::<4>::new(&rays);
        assert_eq!(p.active, [true, false, false, false]);
        assert_eq!(p.inv_dir[0][0], 1.0);
        assert_eq!(p.inv_dir[1][0], f32::INFINITY);
    }
}
