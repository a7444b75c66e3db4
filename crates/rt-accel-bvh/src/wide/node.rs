//! Node layout ([`WideNode<N>`], structure of arrays so that one lane is one child):
//!
//! ```text
//! min[axis][lane], max[axis][lane]   f32   child boxes; empty lanes have min = +inf, max = -inf
//! child[lane]                        u32   inner: node index; leaf: first primitive (leaf order)
//! count[lane]                        u32   0 for an inner child (or an empty lane), else the
//!                                          leaf's primitive count
//! ```
//!
//! 4-wide: 128 bytes, 8-wide: 256 bytes. The lane loops are written over fixed-size arrays so
//! that the compiler turns each into one SIMD instruction (SSE for 4 lanes; AVX for 8 lanes in
//! the `-C target-cpu=native` build of `cargo xtask bench`), with no `unsafe` and a portable
//! fallback on any target.

use rt_geom::Aabb;

/// A node of a `N`-wide BVH.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct WideNode<const N: usize> {
    /// Per axis and child, the minimum corner of the child box.
    pub min: [[f32; N]; 3],
    /// Per axis and child, the maximum corner of the child box.
    pub max: [[f32; N]; 3],
    /// Per child, the node index (inner) or the first primitive (leaf).
    pub child: [u32; N],
    /// Per child, the primitive count of a leaf; 0 for an inner child or an unused lane.
    pub count: [u32; N],
}

const _: () = assert!(std::mem::size_of::<WideNode<4>>() == 128);
const _: () = assert!(std::mem::size_of::<WideNode<8>>() == 256);

impl<const N: usize> WideNode<N> {
    pub(crate) const EMPTY: Self = Self {
        min: [[f32::INFINITY; N]; 3],
        max: [[f32::NEG_INFINITY; N]; 3],
        child: [u32::MAX; N],
        count: [0; N],
    };

    pub(crate) fn set_bounds(&mut self, lane: usize, b: Aabb) {
        for a in 0..3 {
            self.min[a][lane] = b.min[a];
            self.max[a][lane] = b.max[a];
        }
    }

    /// Child `lane`'s box.
    pub fn bounds(&self, lane: usize) -> Aabb {
        Aabb::new(
            rt_geom::Vec3::new(self.min[0][lane], self.min[1][lane], self.min[2][lane]),
            rt_geom::Vec3::new(self.max[0][lane], self.max[1][lane], self.max[2][lane]),
        )
    }

    /// Whether the lane holds a child (inner or leaf).
    pub fn is_used(&self, lane: usize) -> bool {
        self.child[lane] != u32::MAX
    }
}
