//! The flattened node of [`Octree`](crate::Octree): 8 bytes.
//!
//! ```text
//! offset  size  field
//!      0     4  data   inner: index of the first child; leaf: first entry in the index array
//!      4     4  meta   bit 31: leaf;
//!                      inner: bits 0..=7 the child mask (bit i: octant i is non-empty);
//!                      leaf: bits 0..=30 the number of primitives
//! ```
//!
//! Octant `i` of a node is the half of its box above the centre along x when bit 0 of `i` is
//! set, along y for bit 1, along z for bit 2. Only non-empty octants are stored, contiguously
//! and in octant order: octant `i` is node `data + popcount(mask & ((1 << i) - 1))`.

use rt_geom::{Aabb, Vec3};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(8))]
pub struct OctNode {
    data: u32,
    meta: u32,
}

const _: () = assert!(std::mem::size_of::<OctNode>() == 8);

const LEAF: u32 = 1 << 31;

/// Largest primitive count of a leaf.
pub const MAX_LEAF_COUNT: u32 = LEAF - 1;

impl OctNode {
    pub fn inner(first_child: u32, mask: u8) -> Self {
        Self {
            data: first_child,
            meta: mask as u32,
        }
    }

    pub fn leaf(first: u32, count: u32) -> Self {
        debug_assert!(count <= MAX_LEAF_COUNT);
        Self {
            data: first,
            meta: LEAF | count,
        }
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
        let n = OctNode::inner(10, 0b1010_0110);
        assert!(!n.is_leaf());
        assert_eq!(n.child(0), None);
        assert_eq!(n.child(1), Some(10));
        assert_eq!(n.child(2), Some(11));
        assert_eq!(n.child(5), Some(12));
        assert_eq!(n.child(7), Some(13));
        let l = OctNode::leaf(5, 3);
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
}
