//! [`BspParams`]: how a BSP tree is built and walked.

use crate::KdParams;
use crate::params::KdTraversal;
use rt_geom::BuildError;

/// Parameters of [`BspTree::build`](super::BspTree::build).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BspParams {
    /// SAH cost of traversing an inner node.
    pub traversal_cost: f32,
    /// SAH cost of one primitive test.
    pub intersection_cost: f32,
    /// Planes of the node's own primitives tried per node (spread evenly over them).
    pub candidates: u32,
    /// Also try the three axis-aligned planes through the median centroid.
    pub axis_planes: bool,
    /// Nodes of at most this many primitives become leaves.
    pub max_leaf_size: u32,
    /// Depth cap. `None`: `8 + 1.3 log2 N`, at most [`MAX_DEPTH`](crate::MAX_DEPTH).
    pub max_depth: Option<u32>,
    /// At most `reference_budget * N` references in all (as [`KdParams::reference_budget`]).
    pub reference_budget: f32,
    /// Subtrees with more primitives than this are built in parallel.
    pub parallel_threshold: usize,
    /// Iterative or recursive walk.
    pub traversal: KdTraversal,
}

impl BspParams {
    /// 16 primitive planes and 3 axis-aligned planes per node, the kd-tree's SAH constants.
    pub const fn standard() -> Self {
        let kd = KdParams::sah();
        Self {
            traversal_cost: kd.traversal_cost,
            intersection_cost: kd.intersection_cost,
            candidates: 16,
            axis_planes: true,
            max_leaf_size: 1,
            max_depth: None,
            reference_budget: kd.reference_budget,
            parallel_threshold: kd.parallel_threshold,
            traversal: KdTraversal::Iterative,
        }
    }

    /// Autopartition only: planes of the primitives, no axis-aligned ones.
    pub const fn autopartition() -> Self {
        Self {
            axis_planes: false,
            ..Self::standard()
        }
    }

    /// Checks every field; the error names the first one out of range.
    pub fn validate(&self) -> Result<(), BuildError> {
        // The fields shared with the kd-tree are checked by its rules.
        KdParams {
            traversal_cost: self.traversal_cost,
            intersection_cost: self.intersection_cost,
            max_depth: self.max_depth,
            max_leaf_size: self.max_leaf_size,
            reference_budget: self.reference_budget,
            ..KdParams::sah()
        }
        .validate()?;
        let c = self.candidates;
        let ok = c <= 1024 && (c > 0 || self.axis_planes);
        BuildError::require(ok, "candidates", c, "0..=1024, and > 0 without axis planes")?;
        Ok(())
    }
}

impl Default for BspParams {
    fn default() -> Self {
        Self::standard()
    }
}
