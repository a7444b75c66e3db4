//! Wide BVHs (4 and 8 children per node), collapsed from a [`Bvh`](crate::Bvh): one data-parallel slab
//! test for all children of a node, children visited nearest first.
//!
//!
//! | file | what it holds |
//! |---|---|
//! | `node.rs` | [`WideNode`], the node layout |
//! | `build.rs` | [`WideTree::collapse`]: wide nodes written from a collapse plan |
//! | `traverse.rs` | the stack walk over any wide node layout, the lanes' slab test, the leaf test |
//! | `stats.rs` | [`WideTree::stats`] and [`WideTree::check`] |
//! | `refit.rs` | [`WideTree::refit`]: child boxes recomputed after primitives move |
//! | `bvh.rs` | [`WideBvh`] ([`Bvh4`], [`Bvh8`]): a topology and the primitives its leaves hold |

mod build;
mod bvh;
mod node;
mod refit;
mod stats;
mod traverse;

pub use bvh::{Bvh4, Bvh8, WideBvh};
pub use node::WideNode;
pub(crate) use traverse::{WideLanes, lane_entries, test_leaf, traverse_nodes};

use crate::BvhParams;
use rt_geom::{Aabb, AccelStats, Hit, Ray};

/// Every leaf's `(first, count)` of a wide topology (any node layout), in node order.
pub(crate) fn leaves_of<Node: WideLanes<N>, const N: usize>(
    nodes: &[Node],
    root_leaf: Option<(u32, u32)>,
) -> Vec<(u32, u32)> {
    let lanes = nodes.iter().flat_map(|n| {
        (0..N)
            .filter(|&l| n.child(l) != u32::MAX && n.count(l) > 0)
            .map(|l| (n.child(l), n.count(l)))
    });
    root_leaf.into_iter().chain(lanes).collect()
}

/// The topology of a wide BVH: nodes, root box, depth. Leaves are ranges of a leaf-ordered
/// primitive array kept by the owner ([`WideBvh`], or `TriBvh` with SIMD triangle leaves), which
/// supplies the leaf test to [`WideTree::traverse`].
#[derive(Clone, Debug)]
pub struct WideTree<const N: usize> {
    pub(crate) nodes: Vec<WideNode<N>>,
    pub(crate) root_bounds: Aabb,
    /// The root is a single leaf (`first`, `count`) when the whole scene fits one leaf.
    pub(crate) root_leaf: Option<(u32, u32)>,
    pub(crate) depth: usize,
}

/// What the owner of a wide topology's leaves ([`TriBvh`](crate::TriBvh)) needs of it:
/// [`WideTree`] and [`CompressedTree`](crate::CompressedTree) implement it.
pub trait WideTopology: Send + Sync {
    /// The stack traversal; `leaf(first, count, ray, best)` tests a leaf (see
    /// [`WideTree::traverse`]).
    fn traverse<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        leaf: impl FnMut(u32, u32, &mut Ray, &mut Option<Hit>) -> bool,
    ) -> Option<Hit>;
    /// Checks the topology; `leaf(first, count, bounds)` checks each leaf.
    fn check(&self, leaf: impl FnMut(u32, u32, &Aabb) -> Result<(), String>) -> Result<(), String>;
    /// Every leaf's `(first, count)`.
    fn leaves(&self) -> Vec<(u32, u32)>;
    /// Recomputes every box from `leaf_bounds(first, count)` (see [`WideTree::refit`]) and
    /// returns the statistics of the refitted topology over `prims` primitives (node bytes
    /// only).
    fn refit_boxes(
        &mut self,
        leaf_bounds: &dyn Fn(u32, u32) -> Aabb,
        prims: usize,
        params: &BvhParams,
    ) -> AccelStats;
}

impl<const N: usize> WideTopology for WideTree<N> {
    #[inline(always)]
    fn traverse<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        leaf: impl FnMut(u32, u32, &mut Ray, &mut Option<Hit>) -> bool,
    ) -> Option<Hit> {
        WideTree::traverse::<ANY_HIT>(self, ray, leaf)
    }

    fn check(&self, leaf: impl FnMut(u32, u32, &Aabb) -> Result<(), String>) -> Result<(), String> {
        WideTree::check(self, leaf)
    }

    fn leaves(&self) -> Vec<(u32, u32)> {
        WideTree::leaves(self)
    }

    fn refit_boxes(
        &mut self,
        leaf_bounds: &dyn Fn(u32, u32) -> Aabb,
        prims: usize,
        params: &BvhParams,
    ) -> AccelStats {
        self.refit(leaf_bounds);
        self.stats(prims, params)
    }
}

impl<const N: usize> WideTree<N> {
    /// The wide nodes, root first.
    pub fn nodes(&self) -> &[WideNode<N>] {
        &self.nodes
    }

    /// The box of the whole tree (rays that miss it miss everything).
    pub fn root_bounds(&self) -> Aabb {
        self.root_bounds
    }

    /// `Some((first, count))` when the whole tree is one leaf (and `nodes()` is empty).
    pub fn root_leaf(&self) -> Option<(u32, u32)> {
        self.root_leaf
    }

    /// The depth of the deepest leaf (the root is 0).
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Every leaf's `(first, count)`, in node order.
    pub fn leaves(&self) -> Vec<(u32, u32)> {
        leaves_of(&self.nodes, self.root_leaf)
    }

    /// Stack traversal; all children of a node are tested at once and pushed far to near.
    /// `leaf(first, count, ray, best)` tests a leaf, shrinking `ray.tmax` and updating `best`
    /// `(hit, caller's id)`; it returns true to stop (any-hit queries).
    #[inline(always)]
    pub fn traverse<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        leaf: impl FnMut(u32, u32, &mut Ray, &mut Option<Hit>) -> bool,
    ) -> Option<Hit> {
        traverse_nodes::<_, N, ANY_HIT>(
            &self.nodes,
            &self.root_bounds,
            self.root_leaf,
            self.depth,
            ray,
            leaf,
        )
    }
}
