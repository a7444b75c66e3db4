//! The flattened node of [`KdTree`](crate::KdTree): 8 bytes, depth-first (the layout of pbrt's
//! `KdAccelNode`).
//!
//! ```text
//! offset  size  field
//!      0     4  data   inner: the split position (f32 bits; a BSP tree: its plane's index);
//!                      leaf with one primitive: its index;
//!                      leaf with more: index of its first entry in the tree's index array
//!      4     4  meta   bits 0..=1: split axis (0 = x, 1 = y, 2 = z), or 3 for a leaf;
//!                      bits 2..=31: inner: index of the child above the split (the child
//!                      below is the next node, index + 1); leaf: number of primitives
//! ```
//!
//! Walking it: start at node 0 with the ray clipped to the tree's bounds. At an inner node,
//! the child on the side of the origin is visited first, over the part of the ray's interval
//! before the split plane; the other child over the part after it. At a leaf, test its
//! primitives.

/// One node: an inner node (axis-aligned split plane) or a leaf.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(8))]
pub struct KdNode {
    data: u32,
    meta: u32,
}

const _: () = assert!(std::mem::size_of::<KdNode>() == 8);

const LEAF: u32 = 3;

/// The largest primitive count a leaf, and the largest node index an inner node, can hold.
pub const MAX_NODE_FIELD: u32 = (1 << 30) - 1;

impl KdNode {
    /// An inner node splitting at `split` along `axis`; the child above is node `above`.
    pub fn inner(axis: usize, split: f32, above: u32) -> Self {
        debug_assert!(axis < 3 && above <= MAX_NODE_FIELD);
        Self {
            data: split.to_bits(),
            meta: (above << 2) | axis as u32,
        }
    }

    /// An inner node of a [`BspTree`](crate::BspTree): `data` is the index of its plane.
    pub fn inner_plane(plane: u32, above: u32) -> Self {
        debug_assert!(above <= MAX_NODE_FIELD);
        Self {
            data: plane,
            meta: above << 2,
        }
    }

    /// A leaf of `count` primitives: `data` is the primitive itself when `count == 1`, else
    /// the offset of the first entry in the index array.
    pub fn leaf(count: u32, data: u32) -> Self {
        debug_assert!(count <= MAX_NODE_FIELD);
        Self {
            data,
            meta: (count << 2) | LEAF,
        }
    }

    /// Whether the node is a leaf.
    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.meta & 3 == LEAF
    }

    /// Split axis of an inner node.
    #[inline]
    pub fn axis(&self) -> usize {
        (self.meta & 3) as usize
    }

    /// Split position of an inner node.
    #[inline]
    pub fn split(&self) -> f32 {
        f32::from_bits(self.data)
    }

    /// Index of the child above the split (inner nodes).
    #[inline]
    pub fn above(&self) -> usize {
        (self.meta >> 2) as usize
    }

    /// Primitives in a leaf.
    #[inline]
    pub fn count(&self) -> usize {
        (self.meta >> 2) as usize
    }

    /// A leaf's primitives as a slice of indices: the node's own `data` for one primitive,
    /// else `count` entries of `indices` from `data`.
    #[inline]
    pub fn leaf_prims<'a>(&'a self, indices: &'a [u32]) -> &'a [u32] {
        match self.count() {
            0 => &[],
            1 => std::slice::from_ref(&self.data),
            n => &indices[self.data as usize..self.data as usize + n],
        }
    }

    /// A leaf of several primitives: its range `(first, count)` of the index array.
    #[inline]
    pub fn list(&self) -> Option<(u32, u32)> {
        (self.is_leaf() && self.count() > 1).then(|| (self.data, self.count() as u32))
    }

    /// Raw data word (split bits, primitive or offset).
    #[inline]
    pub fn data(&self) -> u32 {
        self.data
    }

    /// The two words as stored (`data`, `meta`): what a saved tree holds.
    pub(crate) fn words(&self) -> (u32, u32) {
        (self.data, self.meta)
    }

    /// A node of two stored words (see [`Self::words`]); any words make a node, which a
    /// loaded tree checks before its walks index anything by it.
    pub(crate) fn from_words(data: u32, meta: u32) -> Self {
        Self { data, meta }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_round_trip() {
        let n = KdNode::inner(2, -1.5, 12345);
        assert!(!n.is_leaf());
        assert_eq!((n.axis(), n.split(), n.above()), (2, -1.5, 12345));
        let l = KdNode::leaf(1, 77);
        assert!(l.is_leaf());
        assert_eq!(l.leaf_prims(&[]), &[77]);
        let l = KdNode::leaf(3, 1);
        assert_eq!(l.leaf_prims(&[9, 4, 5, 6]), &[4, 5, 6]);
        assert_eq!(KdNode::leaf(0, 0).leaf_prims(&[]), &[] as &[u32]);
        let big = KdNode::leaf(MAX_NODE_FIELD, 0);
        assert_eq!(big.count(), MAX_NODE_FIELD as usize);
    }
}
