//! The flattened octree: inner nodes of 64 bytes (one cache line) and leaves of 8 bytes, in
//! two arrays.
//!
//! ```text
//! OctNode (inner node, 64 bytes, 64-byte aligned)
//! offset  size  field
//!      0     4  inner_base  index in `nodes` of the node's first inner child
//!      4     4  leaf_base   index in `leaves` of its first leaf child
//!      8     1  mask        bit i: octant i is non-empty (stored)
//!      9     1  leaf_mask   bit i: octant i is a leaf (a subset of `mask`)
//!     10     6  (padding)
//!     16    24  lo          [axis][octant]: the octant's content box, min corner, 0..=255
//!     40    24  hi          [axis][octant]: its max corner (see `content_box`)
//!
//! OctLeaf (8 bytes): first entry in the index array, number of primitives
//! ```
//!
//! Octant `i` of a node is the half of its box above the centre along x when bit 0 of `i` is
//! set, along y for bit 1, along z for bit 2. Only non-empty octants are stored: the inner
//! ones contiguously in `nodes` and the leaves contiguously in `leaves`, each in octant
//! order, so that inner octant `i` is node `inner_base + popcount(inner mask below i)` and
//! leaf octant `i` is leaf `leaf_base + popcount(leaf_mask below i)`.
//!
//! The content box of an octant is the union of its primitives clipped to its cell: a ray
//! that enters the cell but misses the content box cannot hit anything there, and the walks
//! skip it (the "min/max information" of the classic octree). The parent holds its eight octants'
//! boxes, quantized to 1/254 of the octant's side (one step for all eight) and rounded
//! outward (6 bytes each, stored by axis so that one SIMD pass reads all eight), so that a
//! walk decides which octants to enter from the one cache line of the parent and loads a
//! child only when it goes there.
//! `content_box` is the one formula both the build (to round outward) and the walks use.

use rt_geom::{Aabb, Vec3};

/// An inner node: one cache line (layout in the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(64))]
pub struct OctNode {
    inner_base: u32,
    leaf_base: u32,
    mask: u8,
    leaf_mask: u8,
    _pad: [u8; 6],
    /// Content box codes of octant `i`, axis `a`: `lo[a][i]..=hi[a][i]`.
    pub lo: [[u8; 8]; 3],
    /// Upper content box codes of octant `i`, axis `a`.
    pub hi: [[u8; 8]; 3],
}

const _: () = assert!(std::mem::size_of::<OctNode>() == 64);

/// A leaf: the primitives `indices[first..first + count]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OctLeaf {
    /// First index of the leaf's primitives.
    pub first: u32,
    /// Number of primitives.
    pub count: u32,
}

const _: () = assert!(std::mem::size_of::<OctLeaf>() == 8);

impl OctLeaf {
    /// The leaf's range in the index array.
    #[inline]
    pub fn prims(&self) -> std::ops::Range<usize> {
        self.first as usize..self.first as usize + self.count as usize
    }
}

/// A reference to a node: an inner node's index in `nodes`, or a leaf's in `leaves` with
/// [`ChildRef::LEAF`] set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChildRef(pub u32);

impl ChildRef {
    /// The tag bit of a leaf reference.
    pub const LEAF: u32 = 1 << 31;

    /// A reference to inner node `i`.
    pub fn inner(i: usize) -> Self {
        Self(i as u32)
    }

    /// A reference to leaf `i`.
    pub fn leaf(i: usize) -> Self {
        Self(i as u32 | Self::LEAF)
    }

    /// Whether this names a leaf.
    #[inline]
    pub fn is_leaf(self) -> bool {
        self.0 & Self::LEAF != 0
    }

    /// The index in `nodes` or in `leaves`.
    #[inline]
    pub fn index(self) -> usize {
        (self.0 & !Self::LEAF) as usize
    }
}

/// Largest number of inner nodes or leaves (the top bit of a [`ChildRef`] is its kind).
pub const MAX_NODES: usize = ChildRef::LEAF as usize;

impl OctNode {
    /// An inner node with no octants yet (see [`OctNode::set_octant`]).
    pub fn new(inner_base: u32, leaf_base: u32) -> Self {
        Self {
            inner_base,
            leaf_base,
            mask: 0,
            leaf_mask: 0,
            _pad: [0; 6],
            lo: [[0; 8]; 3],
            hi: [[0; 8]; 3],
        }
    }

    /// The node with these fields (a saved tree's node, checked by the loader).
    pub(crate) fn from_parts(
        (inner_base, leaf_base): (u32, u32),
        (mask, leaf_mask): (u8, u8),
        lo: [[u8; 8]; 3],
        hi: [[u8; 8]; 3],
    ) -> Self {
        Self {
            inner_base,
            leaf_base,
            mask,
            leaf_mask,
            _pad: [0; 6],
            lo,
            hi,
        }
    }

    /// Marks octant `i` non-empty (a leaf when `leaf`) with quantized content `q` (from
    /// [`quantize_content`]). Octants must be set in increasing order of `i`.
    pub fn set_octant(&mut self, i: usize, leaf: bool, q: [u8; 6]) {
        self.mask |= 1 << i;
        self.leaf_mask |= (leaf as u8) << i;
        for a in 0..3 {
            self.lo[a][i] = q[a];
            self.hi[a][i] = q[a + 3];
        }
    }

    /// Non-empty octants.
    #[inline]
    pub fn mask(&self) -> u8 {
        self.mask
    }

    /// Octants that are leaves.
    #[inline]
    pub fn leaf_mask(&self) -> u8 {
        self.leaf_mask
    }

    /// The node of octant `i`, if it is non-empty.
    #[inline]
    pub fn child(&self, i: usize) -> Option<ChildRef> {
        let below = (1u32 << i) - 1;
        let (mask, leaves) = (self.mask as u32, self.leaf_mask as u32);
        if mask >> i & 1 == 0 {
            None
        } else if leaves >> i & 1 == 1 {
            let k = (leaves & below).count_ones();
            Some(ChildRef::leaf((self.leaf_base + k) as usize))
        } else {
            let k = (mask & !leaves & below).count_ones();
            Some(ChildRef::inner((self.inner_base + k) as usize))
        }
    }

    /// The quantized content box of octant `i` (meaningful when it is non-empty).
    #[inline]
    pub fn content(&self, i: usize) -> [u8; 6] {
        [
            self.lo[0][i],
            self.lo[1][i],
            self.lo[2][i],
            self.hi[0][i],
            self.hi[1][i],
            self.hi[2][i],
        ]
    }

    /// The box holding everything octant `i` holds, given this node's cell.
    #[inline]
    pub fn content_box(&self, cell: &Aabb, i: usize) -> Aabb {
        content_box(&octant(cell, i), content_step(cell), &self.content(i))
    }

    /// Index in `nodes` of the first inner child.
    pub fn inner_base(&self) -> usize {
        self.inner_base as usize
    }

    /// Index in `leaves` of the first leaf child.
    pub fn leaf_base(&self) -> usize {
        self.leaf_base as usize
    }
}

/// Quantized content covering a node's whole cell.
pub const FULL_CELL: [u8; 6] = [0, 0, 0, 255, 255, 255];

/// Quantization step of the content boxes of a node's octants, from the node's cell: 1/254 of
/// an octant's side (half the cell's), the same for all eight octants, so that code 255 lies
/// beyond an octant's far face (whatever the rounding) and code 0 is exactly its near face.
/// One step for the eight lets the parametric walk take it as one number per axis.
#[inline]
pub fn content_step(parent: &Aabb) -> Vec3 {
    (parent.max - parent.min) * (1.0 / 508.0)
}

/// The box of quantized `content` in the octant `cell` whose parent gives `step`
/// ([`content_step`]): `min + q * step` per coordinate.
#[inline]
pub fn content_box(cell: &Aabb, step: Vec3, q: &[u8; 6]) -> Aabb {
    let at = |i: usize| Vec3::new(q[i] as f32, q[i + 1] as f32, q[i + 2] as f32);
    Aabb::new(cell.min + at(0) * step, cell.min + at(3) * step)
}

/// The smallest codes whose [`content_box`] holds `content` clipped to the octant `cell` (the
/// whole cell when that is empty: nothing is ever culled by a box too small); `step` from its
/// parent ([`content_step`]).
pub fn quantize_content(cell: &Aabb, step: Vec3, content: &Aabb) -> [u8; 6] {
    let c = content.intersection(*cell);
    if c.is_empty() {
        return FULL_CELL;
    }
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
    octant_at(b, b.center(), i)
}

/// Octant `i` of `b`, given its centre `c` (= `b.center()`).
#[inline(always)]
pub fn octant_at(b: &Aabb, c: Vec3, i: usize) -> Aabb {
    let upper = rt_geom::glam::BVec3::new(i & 1 != 0, i & 2 != 0, i & 4 != 0);
    Aabb::new(Vec3::select(upper, c, b.min), Vec3::select(upper, b.max, c))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_and_octants() {
        let mut n = OctNode::new(10, 20);
        for (i, leaf) in [(1, false), (2, true), (5, false), (7, true)] {
            n.set_octant(i, leaf, [i as u8, 1, 2, 3, 4, 5]);
        }
        assert_eq!(n.mask(), 0b1010_0110);
        assert_eq!(n.leaf_mask(), 0b1000_0100);
        assert_eq!(n.child(0), None);
        assert_eq!(n.child(1), Some(ChildRef::inner(10)));
        assert_eq!(n.child(2), Some(ChildRef::leaf(20)));
        assert_eq!(n.child(5), Some(ChildRef::inner(11)));
        assert_eq!(n.child(7), Some(ChildRef::leaf(21)));
        assert_eq!(n.content(5), [5, 1, 2, 3, 4, 5]);
        let r = ChildRef::leaf(21);
        assert!(r.is_leaf() && r.index() == 21 && !ChildRef::inner(21).is_leaf());
        assert_eq!(OctLeaf { first: 5, count: 3 }.prims(), 5..8);
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
            let corner = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5) * scale * 100.0;
            // An octant of a parent twice its size, as the build quantizes it.
            let parent = Aabb::new(corner, corner + Vec3::splat(2.0 * scale));
            let cell = octant(&parent, k % 8);
            let step = content_step(&parent);
            let min = cell.min;
            let (a, b) = (
                Vec3::new(rnd(), rnd(), rnd()),
                Vec3::new(rnd(), rnd(), rnd()),
            );
            let mut content = Aabb::new(min + a.min(b) * scale, min + a.max(b) * scale);
            if k % 7 == 0 {
                content = cell;
            }
            let q = quantize_content(&cell, step, &content);
            let got = content_box(&cell, step, &q);
            let want = content.intersection(cell);
            assert!(
                got.min.cmple(want.min).all() && got.max.cmpge(want.max).all(),
                "{cell:?} {content:?} -> {q:?} {got:?}"
            );
            // Tight: within two steps of the content.
            assert!(
                (want.min - got.min).cmple(step * 2.0).all(),
                "{want:?} {got:?}"
            );
            // Inside the cell, but for code 255 one step beyond its far face: the
            // parametric walk takes an octant's planes from this box alone.
            assert!(
                got.min.cmpge(cell.min).all() && got.max.cmple(cell.max + step * 1.01).all(),
                "{cell:?} {got:?}"
            );
        }
        // An empty content keeps the whole cell.
        let parent = Aabb::new(Vec3::ZERO, Vec3::splat(2.0));
        let (cell, step) = (octant(&parent, 0), content_step(&parent));
        assert_eq!(quantize_content(&cell, step, &Aabb::EMPTY), FULL_CELL);
        let full = content_box(&cell, step, &FULL_CELL);
        assert!(full.max.cmpge(Vec3::ONE).all());
    }
}
