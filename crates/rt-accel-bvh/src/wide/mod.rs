//! Wide BVHs (4 and 8 children per node), collapsed from a [`Bvh`](crate::Bvh): one data-parallel slab
//! test for all children of a node, children visited nearest first. One tree type,
//! [`WideTree`], serves every node layout ([`NodeLayout`]: exact boxes in [`WideNode`],
//! quantized ones in [`CompressedNode`](crate::CompressedNode)).
//!
//! | file | what it holds |
//! |---|---|
//! | `node.rs` | [`WideNode`], the node layout, and [`NodeLayout`], what the tree needs of a layout |
//! | `build.rs` | [`WideTree::collapse`]: wide nodes written from a collapse plan |
//! | `traverse.rs` | the stack walk over any node layout, the lanes' slab test, the leaf test |
//! | `stats.rs` | [`WideTree::stats`] and [`WideTree::check`] |
//! | `refit.rs` | [`WideTree::refit`]: child boxes recomputed after primitives move |
//! | `bvh.rs` | [`WideBvh`] ([`Bvh4`], [`Bvh8`], [`CompressedBvh8`](crate::CompressedBvh8)): a topology and the primitives its leaves hold |

mod build;
mod bvh;
mod node;
mod refit;
mod stats;
mod traverse;

pub use bvh::{Bvh4, Bvh8, WideBvh};
pub use node::{NodeLayout, WideNode};
pub(crate) use traverse::{lane_entries, near_far, test_leaf};

use rt_geom::pages::Pages;
use rt_geom::{Aabb, Hit, Isa, Keep, Level, Ray};

/// The topology of a wide BVH over a node layout (`N` lanes of [`WideNode<N>`] by default):
/// nodes, root box, depth. Leaves are ranges of a leaf-ordered primitive array kept by the
/// owner ([`WideBvh`], or [`TriBvh`](crate::TriBvh) with SIMD triangle leaves), which
/// supplies the leaf test to [`WideTree::traverse`].
#[derive(Clone, Debug)]
pub struct WideTree<const N: usize, Node = WideNode<N>> {
    pub(crate) nodes: Pages<Node>,
    pub(crate) root_bounds: Aabb,
    /// The root is a single leaf (`first`, `count`) when the whole scene fits one leaf.
    pub(crate) root_leaf: Option<(u32, u32)>,
    pub(crate) depth: usize,
    /// The instruction set the owner's queries run the walk compiled for ([`Isa::selected`]
    /// when collapsed).
    pub(crate) isa: Isa,
}

impl<const N: usize, Node: NodeLayout<N>> WideTree<N, Node> {
    /// The wide nodes, root first.
    pub fn nodes(&self) -> &[Node] {
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

    /// The instruction set the owner's queries run the walk compiled for.
    pub fn isa(&self) -> Isa {
        self.isa
    }

    /// The same tree, its owner's queries run compiled for `isa` (or, where this CPU lacks
    /// it, for the best level it has): for tests and measurements of each level.
    pub fn with_isa(mut self, isa: Isa) -> Self {
        self.isa = isa.or_best();
        self
    }

    /// Every leaf's `(first, count)`, in node order.
    pub fn leaves(&self) -> Vec<(u32, u32)> {
        let lanes = self.nodes.iter().flat_map(|n| {
            (0..N)
                .filter(|&l| n.is_used(l) && n.count(l) > 0)
                .map(|l| (n.child(l), n.count(l)))
        });
        self.root_leaf.into_iter().chain(lanes).collect()
    }

    /// Stack traversal; all children of a node are tested at once and pushed far to near.
    /// `leaf(first, count, ray, best)` tests a leaf, offering its hits (with the caller's
    /// ids) to `best` ([`Keep`]), which shrinks `ray.tmax` to a kept one; it returns true to
    /// stop (any-hit queries). Returns the hit `best` kept.
    /// The node tests run on `level`'s vectors ([`Level`]: inside a walk [`rt_geom::isa::run`]
    /// runs, the level it runs at; else [`rt_geom::BaseLevel`]).
    #[inline(always)]
    pub fn traverse<const ANY_HIT: bool, V: Level, K: Keep>(
        &self,
        level: V,
        ray: &Ray,
        best: impl FnOnce() -> K,
        leaf: impl FnMut(u32, u32, &mut Ray, &mut K) -> bool,
    ) -> Option<Hit> {
        self.traverse_prefetching::<ANY_HIT, V, K>(
            level,
            ray,
            best,
            leaf,
            None::<fn(u32) -> *const u8>,
        )
    }

    /// [`Self::traverse`], with `prefetch`: every child a node's test enters asked for early,
    /// an inner node by its index and a leaf at the address `prefetch` gives for its first
    /// primitive (where the owner keeps the leaf's data).
    #[inline(always)]
    pub(crate) fn traverse_prefetching<const ANY_HIT: bool, V: Level, K: Keep>(
        &self,
        level: V,
        ray: &Ray,
        best: impl FnOnce() -> K,
        leaf: impl FnMut(u32, u32, &mut Ray, &mut K) -> bool,
        prefetch: Option<impl Fn(u32) -> *const u8>,
    ) -> Option<Hit> {
        traverse::traverse_nodes::<_, N, ANY_HIT, V, K>(
            level,
            &self.nodes,
            &self.root_bounds,
            self.root_leaf,
            self.depth,
            ray,
            best,
            leaf,
            prefetch,
        )
    }
}
