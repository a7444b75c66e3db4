//! Node layout ([`WideNode<N>`], structure of arrays so that one lane is one child):
//!
//! ```text
//! min[axis][lane]   f32   child boxes' minimum corners; empty lanes have min = +inf
//! child[lane]       u32   inner: node index; leaf: first primitive (leaf order)
//! max[axis][lane]   f32   child boxes' maximum corners; empty lanes have max = -inf
//! count[lane]       u32   0 for an inner child (or an empty lane), else the leaf's primitive count
//! ```
//!
//! 4-wide: 128 bytes, 8-wide: 256 bytes, in this order: every cache line of a node holds
//! planes of the slab test, so the test's loads ask for all of the node's lines at once (a
//! line of children and counts alone would be asked for only by the read of the child hit,
//! after the test). The lane loops are written over fixed-size arrays so that the compiler
//! turns each into one SIMD instruction (SSE for 4 lanes; AVX for 8 lanes in the `-C
//! target-cpu=native` build of `cargo xtask bench`), with no `unsafe` and a portable fallback
//! on any target.

use super::traverse::lane_entries;
use rt_geom::aabb::SlabRay;
use rt_geom::{Aabb, Level};

/// A wide node layout as build, walk, check, stats and refit see it: one entry distance per
/// lane, each lane's child, its box. [`WideNode`] stores boxes exactly;
/// [`CompressedNode`](crate::CompressedNode) quantizes them.
pub trait NodeLayout<const N: usize>: Copy + Send + Sync + std::fmt::Debug {
    /// Whether the stored boxes are the children's exact boxes (a child's box then lies in
    /// its parent's); quantized layouts round outward and only promise to hold their child.
    const EXACT: bool;
    /// The node holding `node`'s children, its boxes rounded outward if the layout must.
    fn from_exact(node: &WideNode<N>) -> Self;
    /// The lanes the ray enters within `[tmin, tmax]` (bit `lane`), and the entry distance
    /// per lane (meaningful for those).
    /// on `level`'s vectors.
    fn entries<V: Level>(&self, level: V, ray: &SlabRay, tmin: f32, tmax: f32) -> (u32, [f32; N]);
    /// Per lane, [`Self::child`].
    fn children(&self) -> &[u32; N];
    /// Per lane, [`Self::count`].
    fn counts(&self) -> &[u32; N];
    /// Inner child: node index; leaf: first primitive; `u32::MAX` for an empty lane.
    #[inline(always)]
    fn child(&self, lane: usize) -> u32 {
        self.children()[lane]
    }
    /// 0 for an inner child, else the leaf's primitive count.
    #[inline(always)]
    fn count(&self, lane: usize) -> u32 {
        self.counts()[lane]
    }
    /// The box of `lane` as the walk sees it.
    fn bounds(&self, lane: usize) -> Aabb;
    /// Bit `lane` set for the lanes the walk must mask (those that hold a child).
    fn used_mask(&self) -> u32;
    /// Whether the lane holds a child (inner or leaf).
    #[inline(always)]
    fn is_used(&self, lane: usize) -> bool {
        self.child(lane) != u32::MAX
    }
    /// Bit `lane` set for the lanes that hold a leaf (a count above 0): one compare of all
    /// lanes where the counts are an array.
    #[inline(always)]
    fn leaf_mask(&self) -> u32 {
        (0..N).fold(0, |m, l| m | ((self.count(l) > 0) as u32) << l)
    }
}

/// A node of a `N`-wide BVH, aligned to a cache line: a node of 8 reads four lines, where a
/// 32-byte alignment let it straddle five.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct WideNode<const N: usize> {
    /// Per axis and child, the minimum corner of the child box.
    pub min: [[f32; N]; 3],
    /// Per child, the node index (inner) or the first primitive (leaf).
    pub child: [u32; N],
    /// Per axis and child, the maximum corner of the child box.
    pub max: [[f32; N]; 3],
    /// Per child, the primitive count of a leaf; 0 for an inner child or an unused lane.
    pub count: [u32; N],
}

const _: () = assert!(std::mem::size_of::<WideNode<4>>() == 128);
const _: () = assert!(std::mem::size_of::<WideNode<8>>() == 256);
const _: () = assert!(std::mem::align_of::<WideNode<4>>() == 64);
// Planes in every cache line: the max planes start the second half of the node, and the
// children share a line with the min planes, the counts one with the max planes.
const _: () = assert!(std::mem::offset_of!(WideNode<8>, max) == 128);
const _: () = assert!(std::mem::offset_of!(WideNode<4>, max) == 64);

impl<const N: usize> WideNode<N> {
    pub(crate) const EMPTY: Self = Self {
        min: [[f32::INFINITY; N]; 3],
        max: [[f32::NEG_INFINITY; N]; 3],
        child: [u32::MAX; N],
        count: [0; N],
    };

    /// Row `r & 7` of the node read as `N` floats: rows 0-2 are the min planes, 4-6 the max
    /// planes (3 and 7 the children and counts).
    #[inline(always)]
    fn row(&self, r: usize) -> &[f32; N] {
        const {
            assert!(std::mem::size_of::<Self>() == 8 * N * 4);
            assert!(std::mem::offset_of!(Self, max) == 4 * N * 4);
        };
        // SAFETY: `Self` is `repr(C)`, eight rows of `N` four-byte values without padding
        // (checked above), each row aligned as `f32` is; row `r & 7` lies inside `self`, and
        // every bit pattern is an `f32`.
        // Measured reason: picking the address by row offset instead of selecting between
        // the min and max rows per axis.
        unsafe { &*(self as *const Self).cast::<[f32; N]>().add(r & 7) }
    }

    pub(crate) fn set_bounds(&mut self, lane: usize, b: Aabb) {
        for a in 0..3 {
            self.min[a][lane] = b.min[a];
            self.max[a][lane] = b.max[a];
        }
    }
}

impl<const N: usize> NodeLayout<N> for WideNode<N> {
    const EXACT: bool = true;

    #[inline(always)]
    fn from_exact(node: &WideNode<N>) -> Self {
        *node
    }

    #[inline(always)]
    fn entries<V: Level>(&self, level: V, ray: &SlabRay, tmin: f32, tmax: f32) -> (u32, [f32; N]) {
        // Each plane's row by its offset from the node (`axis + 4 * sign`: the max planes
        // start at row 4), not by a select of two addresses per axis.
        let planes = std::array::from_fn(|a| {
            let near = a + 4 * ray.neg[a] as usize;
            (self.row(near), self.row(near ^ 4))
        });
        lane_entries(level, planes, ray, tmin, tmax)
    }

    #[inline(always)]
    fn children(&self) -> &[u32; N] {
        &self.child
    }

    #[inline(always)]
    fn counts(&self) -> &[u32; N] {
        &self.count
    }

    fn bounds(&self, lane: usize) -> Aabb {
        Aabb::new(
            rt_geom::Vec3::new(self.min[0][lane], self.min[1][lane], self.min[2][lane]),
            rt_geom::Vec3::new(self.max[0][lane], self.max[1][lane], self.max[2][lane]),
        )
    }

    /// Every lane: an empty lane's box (min = +inf, max = -inf) gives NaN for every valid ray
    /// (a near plane at +-inf puts the entry at +inf, the far one puts the exit at -inf).
    #[inline(always)]
    fn used_mask(&self) -> u32 {
        u32::MAX
    }
}
