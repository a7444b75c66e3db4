//! The flattened node of [`Bvh`](crate::Bvh): 32 bytes, depth-first.
//!
//! ```text
//! offset  size  field
//!      0    12  bounds.min  (f32 x 3)
//!     12     4  offset      inner: index of the second child (the first child is the next
//!                           node, index + 1); leaf: index of the first primitive in leaf order
//!     16    12  bounds.max  (f32 x 3)
//!     28     4  meta        bits 0..=29: primitive count (0 for an inner node);
//!                           bits 30..=31: split axis of an inner node (0 = x)
//! ```
//!
//! Walking it: start at node 0. At an inner node, the children are `i + 1` and `offset`; visit
//! first the child on the side the ray comes from (`axis` and the sign of `dir[axis]`). At a
//! leaf, primitives `offset .. offset + count` of the leaf-ordered primitive array.

use rt_geom::{Aabb, Vec3};

/// A binary BVH node (layout in the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct BvhNode {
    /// Minimum corner of the node box.
    pub min: [f32; 3],
    /// Second child (inner node) or first primitive (leaf).
    pub offset: u32,
    /// Maximum corner of the node box.
    pub max: [f32; 3],
    /// Primitive count (0 for inner nodes) in the low 30 bits, split axis in the top 2.
    pub meta: u32,
}

const _: () = assert!(std::mem::size_of::<BvhNode>() == 32);

/// Largest primitive count a leaf can hold (30 bits).
pub const MAX_LEAF_COUNT: u32 = (1 << 30) - 1;

impl BvhNode {
    /// A leaf over `count` primitives from `first`.
    pub fn leaf(bounds: Aabb, first: u32, count: u32) -> Self {
        debug_assert!(count > 0 && count <= MAX_LEAF_COUNT);
        Self {
            min: bounds.min.to_array(),
            offset: first,
            max: bounds.max.to_array(),
            meta: count,
        }
    }

    /// An inner node; its first child follows it, its second is `second_child`.
    pub fn inner(bounds: Aabb, second_child: u32, axis: usize) -> Self {
        Self {
            min: bounds.min.to_array(),
            offset: second_child,
            max: bounds.max.to_array(),
            meta: (axis as u32) << 30,
        }
    }

    /// Whether the node is a leaf.
    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.count() > 0
    }

    /// Primitives in a leaf (0 for an inner node).
    #[inline]
    pub fn count(&self) -> u32 {
        self.meta & MAX_LEAF_COUNT
    }

    /// Split axis of an inner node.
    #[inline]
    pub fn axis(&self) -> usize {
        (self.meta >> 30) as usize
    }

    /// The node box.
    #[inline]
    pub fn bounds(&self) -> Aabb {
        Aabb::new(Vec3::from_array(self.min), Vec3::from_array(self.max))
    }
}
