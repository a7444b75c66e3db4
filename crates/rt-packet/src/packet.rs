//! Ray packets: `N` rays in structure-of-arrays form (the layout the per-lane box test
//! vectorises over), an active mask, and packets cut from image tiles.

use rt_geom::Ray;
use rt_geom::aabb::SlabRay;

/// The packet sizes of the seeds: square tiles of 2x2 to 16x16 pixels.
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
    pub origin: [[f32; N]; 3],
    pub dir: [[f32; N]; 3],
    /// `1 / dir` per axis (`+-inf` for zero components, as `Ray::inv_dir`).
    pub inv_dir: [[f32; N]; 3],
    /// The slab test's reciprocals for a box's min and max plane, with the padding folded in
    /// as [`rt_geom::aabb::SlabRay`] folds it: `inv_dir` scaled by `1 - PAD` for the plane
    /// the lane enters by and `1 + PAD` for the one it leaves by; plain `inv_dir` for the
    /// lanes with `tmin < 0`, which set `pad_after`.
    pub inv_lo: [[f32; N]; 3],
    pub inv_hi: [[f32; N]; 3],
    /// Some active lane has `tmin < 0`: box tests pad their intervals afterwards (lanes with
    /// folded reciprocals are then padded twice, which stays conservative).
    pub pad_after: bool,
    /// The watertight triangle test's shear rows per lane ([`Ray::watertight_rows`]): `x`, `y`,
    /// `z` of row 0, then of row 1.
    pub shear: [[f32; N]; 6],
    pub tmin: [f32; N],
    /// Shrinks to each lane's closest hit during traversal.
    pub tmax: [f32; N],
    pub active: [bool; N],
}

impl<'a, const N: usize> RayPacket<'a, N> {
    /// A packet of up to `N` rays (the first `rays.len()` lanes).
    pub fn new(rays: &'a [Ray]) -> Self {
        const { assert!(N > 0 && N % 4 == 0, "packets hold a multiple of 4 lanes") };
        assert!(
            rays.len() <= N,
            "{} rays do not fit a packet of {N}",
            rays.len()
        );
        // Every field starts as the lanes past the rays read (inactive, an empty interval),
        // then one pass over the rays writes each lane in place: building the fields as
        // arrays of their own and moving them into the packet copied every byte once more
        // (64 `memcpy` calls per 16x16 packet, an eighth of the packet walk's instructions,
        // callgrind).
        let mut p = Self {
            rays,
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
        };
        for (i, r) in (0..N).zip(rays) {
            let (o, d, inv) = (r.origin(), r.dir(), r.inv_dir());
            let rows = r.watertight_rows();
            // The factors of the min and the max plane: 1 -+ PAD by the direction's sign, or
            // 1 and 1 for an interval starting behind the origin.
            let (near, far) = SlabRay::fold_factors(r.tmin);
            for a in 0..3 {
                p.origin[a][i] = o[a];
                p.dir[a][i] = d[a];
                p.inv_dir[a][i] = inv[a];
                let neg = inv[a] < 0.0;
                p.inv_lo[a][i] = inv[a] * if neg { far } else { near };
                p.inv_hi[a][i] = inv[a] * if neg { near } else { far };
                p.shear[a][i] = rows[0][a];
                p.shear[3 + a][i] = rows[1][a];
            }
            let active = r.is_valid() && r.tmin <= r.tmax;
            p.tmin[i] = r.tmin;
            p.tmax[i] = r.tmax;
            p.active[i] = active;
            p.pad_after |= active & !(r.tmin >= 0.0);
        }
        p
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
