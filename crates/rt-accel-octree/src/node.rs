//! The flattened node of [`Octree`](crate::Octree): 16 bytes.
//!
//! ```text
//! offset  size  field
//!      0     4  data     inner: index of the first child; leaf: first entry in the index array
//!      4     4  meta     bit 31: leaf;
//!                        inner: bits 0..=7 the child mask (bit i: octant i is non-empty);
//!                        leaf: bits 0..=30 the number of primitives
//!      8     6  content  the min/max box of what the node holds, quantized in its own cell:
//!                        min x, y, z then max x, y, z, each 0..=255 (see `content_box`)
//!     14     2  (padding)
//! ```
//!
//! The content box is the union of the node's primitives clipped to its cell: a ray that
//! enters the cell but misses the content box cannot hit anything there, and the walks skip
//! the node (the "min/max information" of the seeds). Quantized to 1/254 of the cell side,
//! rounded outward, it costs 6 bytes; `content_box` is the one formula both the build
//! (to round outward) and the walks use.
//!
//! Octant `i` of a node is the half of its box above the centre along x when bit 0 of `i` is
//! set, along y for bit 1, along z for bit 2. Only non-empty octants are stored, contiguously
//! and in octant order: octant `i` is node `data + popcount(mask & ((1 << i) - 1))`.

use rt_geom::{Aabb, Vec3};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(16))]
pub struct OctNode {
    data: u32,
    meta: u32,
    content: [u8; 6],
}

const _: () = assert!(std::mem::size_of::<OctNode>() == 16);

const LEAF: u32 = 1 << 31;

/// Largest primitive count of a leaf.
pub const MAX_LEAF_COUNT: u32 = LEAF - 1;

impl OctNode {
    /// An inner node; `content` from [`quantize_content`] (the whole cell: [`FULL_CELL`]).
    pub fn inner(first_child: u32, mask: u8, content: [u8; 6]) -> Self {
        Self {
            data: first_child,
            meta: mask as u32,
            content,
        }
    }

    pub fn leaf(first: u32, count: u32, content: [u8; 6]) -> Self {
        debug_assert!(count <= MAX_LEAF_COUNT);
        Self {
            data: first,
            meta: LEAF | count,
            content,
        }
    }

    /// The box holding everything the node holds, given the node's cell.
    #[inline]
    pub fn content_box(&self, cell: &Aabb) -> Aabb {
        content_box(cell, &self.content)
    }

    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.meta & LEAF != 0
    }

    /// Non-empty octants of an inner node.
    #[inline]
    pub fn mask(&self) -> u8 {
        self.meta as u8
    }

    /// The node of octant `i`, if it is non-empty.
    #[inline]
    pub fn child(&self, i: usize) -> Option<usize> {
        let m = self.mask() as u32;
        (m >> i & 1 == 1).then(|| self.data as usize + (m & ((1 << i) - 1)).count_ones() as usize)
    }

    /// A leaf's range in the index array.
    #[inline]
    pub fn prims(&self) -> std::ops::Range<usize> {
        let first = self.data as usize;
        first..first + (self.meta & !LEAF) as usize
    }

    pub fn first_child(&self) -> usize {
        self.data as usize
    }
}

/// Quantized content covering a node's whole cell.
pub const FULL_CELL: [u8; 6] = [0, 0, 0, 255, 255, 255];

/// Quantization step of a content box: 1/254 of the cell side, so that code 255 lies beyond
/// the cell's far face (whatever the rounding) and code 0 is exactly its near face.
#[inline]
fn content_step(cell: &Aabb) -> Vec3 {
    (cell.max - cell.min) * (1.0 / 254.0)
}

/// The box of quantized `content` in `cell`: `min + q * step` per coordinate.
#[inline]
pub fn content_box(cell: &Aabb, q: &[u8; 6]) -> Aabb {
    let step = content_step(cell);
    let at = |i: usize| Vec3::new(q[i] as f32, q[i + 1] as f32, q[i + 2] as f32);
    Aabb::new(cell.min + at(0) * step, cell.min + at(3) * step)
}

/// The smallest codes whose [`content_box`] holds `content` clipped to `cell` (the whole
/// cell when that is empty: nothing is ever culled by a box too small).
pub fn quantize_content(cell: &Aabb, content: &Aabb) -> [u8; 6] {
    let c = content.intersection(*cell);
    if c.is_empty() {
        return FULL_CELL;
    }
    let step = content_step(cell);
    let mut q = [0u8; 6];
    for a in 0..3 {
        let at = |k: u8| cell.min[a] + k as f32 * step[a];
        let code = |x: f32| {
            let r = (x - cell.min[a]) / step[a];
            if r.is_finite() {
                r.clamp(0.0, 255.0)
            } else {
                0.0
            }
        };
        // Round outward, then correct for the rounding of `at` (it is the one formula).
        let mut lo = code(c.min[a]).floor() as u8;
        while lo > 0 && at(lo) > c.min[a] {
            lo -= 1;
        }
        let mut hi = (code(c.max[a]).ceil() as u8).max(lo);
        while hi < 255 && at(hi) < c.max[a] {
            hi += 1;
        }
        q[a] = lo;
        q[a + 3] = hi;
    }
    q
}

/// Octant `i` of `b` (split at its centre).
#[inline]
pub fn octant(b: &Aabb, i: usize) -> Aabb {
    let c = b.center();
    let pick =
        |bit: usize, lo: f32, mid: f32, hi: f32| if i & bit != 0 { (mid, hi) } else { (lo, mid) };
    let (x0, x1) = pick(1, b.min.x, c.x, b.max.x);
    let (y0, y1) = pick(2, b.min.y, c.y, b.max.y);
    let (z0, z1) = pick(4, b.min.z, c.z, b.max.z);
    Aabb::new(Vec3::new(x0, y0, z0), Vec3::new(x1, y1, z1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_and_octants() {
        let n = OctNode::inner(10, 0b1010_0110, FULL_CELL);
        assert!(!n.is_leaf());
        assert_eq!(n.child(0), None);
        assert_eq!(n.child(1), Some(10));
        assert_eq!(n.child(2), Some(11));
        assert_eq!(n.child(5), Some(12));
        assert_eq!(n.child(7), Some(13));
        let l = OctNode::leaf(5, 3, FULL_CELL);
        assert!(l.is_leaf());
        assert_eq!(l.prims(), 5..8);
        let b = Aabb::new(Vec3::ZERO, Vec3::splat(2.0));
        assert_eq!(octant(&b, 0), Aabb::new(Vec3::ZERO, Vec3::ONE));
        assert_eq!(octant(&b, 7), Aabb::new(Vec3::ONE, Vec3::splat(2.0)));
        assert_eq!(
            octant(&b, 1),
            Aabb::new(Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 1.0, 1.0))
        );
    }

    #[test]
    fn quantized_content_holds_the_content() {
        // Cells and contents of every scale and position, contents touching the faces.
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        for k in 0..20000 {
            let scale = [1e-3f32, 1.0, 37.5, 1e4][k % 4];
            let min = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5) * scale * 100.0;
            let cell = Aabb::new(min, min + Vec3::splat(scale));
            let (a, b) = (
                Vec3::new(rnd(), rnd(), rnd()),
                Vec3::new(rnd(), rnd(), rnd()),
            );
            let mut content = Aabb::new(min + a.min(b) * scale, min + a.max(b) * scale);
            if k % 7 == 0 {
                content = cell;
            }
            let q = quantize_content(&cell, &content);
            let got = content_box(&cell, &q);
            let want = content.intersection(cell);
            assert!(
                got.min.cmple(want.min).all() && got.max.cmpge(want.max).all(),
                "{cell:?} {content:?} -> {q:?} {got:?}"
            );
            // Tight: within two steps of the content.
            let step = (cell.max - cell.min) / 254.0;
            assert!(
                (want.min - got.min).cmple(step * 2.0).all(),
                "{want:?} {got:?}"
            );
        }
        // An empty content keeps the whole cell.
        let cell = Aabb::new(Vec3::ZERO, Vec3::ONE);
        assert_eq!(quantize_content(&cell, &Aabb::EMPTY), FULL_CELL);
        assert!(content_box(&cell, &FULL_CELL).max.cmpge(Vec3::ONE).all());
    }
}
