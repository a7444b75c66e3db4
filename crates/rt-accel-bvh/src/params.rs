//! Build parameters with presets.

use rt_geom::BuildError;

/// How a [`Bvh`](crate::Bvh) chooses its splits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BvhBuilder {
    /// Split the largest centroid extent at its middle (naive, fast to build).
    Midpoint,
    /// Split at the median primitive along the largest centroid extent (naive, balanced).
    Median,
    /// Surface area heuristic over `bins` centroid bins per axis (Wald 2007).
    BinnedSah {
        /// Bins per axis.
        bins: u32,
    },
    /// Surface area heuristic over every split between sorted centroids (full sweep).
    SweepSah,
}

/// How a wide BVH ([`WideTree`](crate::WideTree)) is collapsed from the binary one (see the
/// `collapse` module for the measurements).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WideCollapse {
    /// Each wide node opens the inner child of largest surface area until it has `N` lanes
    /// (Embree's collapse).
    LargestArea,
    /// The collapse of least SAH cost over the whole tree (Ylitie, Karras & Laine 2017):
    /// fewer, fuller nodes.
    Sah,
    /// [`Self::LargestArea`] for the wide nodes whose box has at least `above` times the
    /// root's surface area, [`Self::Sah`] below them: near the root, where most rays start
    /// inside the boxes, the SAH's rays from outside are a poor model.
    LargestAreaThenSah {
        /// Nodes of at least this fraction of the root's area take the greedy rule.
        above: f32,
    },
}

impl WideCollapse {
    /// The default: the greedy rule for nodes of a tenth of the root's area or more.
    pub const DEFAULT: Self = Self::LargestAreaThenSah { above: 0.1 };
}

/// Parameters of [`Bvh::build`](crate::Bvh::build).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhParams {
    /// How split planes are chosen.
    pub builder: BvhBuilder,
    /// Leaves hold at most this many primitives (1..=255), except at the depth cap.
    pub max_leaf_size: u32,
    /// SAH cost of traversing an inner node, relative to one primitive test.
    pub traversal_cost: f32,
    /// SAH cost of one primitive test.
    pub intersection_cost: f32,
    /// Subtrees with more primitives than this are built in parallel (rayon).
    pub parallel_threshold: usize,
    /// Spatial splits (SBVH, with the binned builder only): tried where the two sides of the
    /// best object split overlap by more than this fraction of the root's surface area
    /// (Stich et al. use 1e-5). `None`: object splits only.
    pub spatial_alpha: Option<f32>,
    /// Spatial splits stop once they have added this many references per primitive.
    pub spatial_budget: f32,
    /// Primitives the leaf kernel tests together (1, 2, 4, 8 or 16): the SAH counts a leaf's
    /// tests in blocks of this many, `ceil(n / leaf_block)` (Embree's `logBlockSize`), so a
    /// leaf of 3 triangles costs what one of 4 does when four are tested at once.
    pub leaf_block: u32,
    /// How wide BVHs built with these parameters collapse the binary tree (the binary
    /// [`Bvh`](crate::Bvh) ignores it).
    pub collapse: WideCollapse,
    /// Reinsertion after the build (Bittner, Hapala & Havran 2013; Meister & Bittner 2018):
    /// subtrees move to wherever they lower the SAH cost. The fraction of nodes, largest
    /// first, reconsidered in the first of 16 passes (later passes take fewer); 0 turns it
    /// off (every preset but [`BvhParams::fastest_trace`], which takes 0.25), 1 reconsiders
    /// every node. Top-down builders place large overlapping triangles poorly; reinsertion
    /// repairs that at a fraction of the build time.
    pub reinsertion: f32,
}

/// No leaf lies deeper than this; a leaf at the cap may exceed `max_leaf_size`.
pub const MAX_DEPTH: usize = 64;

impl BvhParams {
    /// Binned SAH with 8 bins, leaves of up to 8.
    pub const fn fast() -> Self {
        Self {
            builder: BvhBuilder::BinnedSah { bins: 8 },
            max_leaf_size: 8,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
            parallel_threshold: 4096,
            spatial_alpha: None,
            spatial_budget: 1.0,
            leaf_block: 1,
            collapse: WideCollapse::DEFAULT,
            reinsertion: 0.0,
        }
    }

    /// Binned SAH with 16 bins, leaves of up to 4.
    pub const fn balanced() -> Self {
        Self {
            builder: BvhBuilder::BinnedSah { bins: 16 },
            max_leaf_size: 4,
            ..Self::fast()
        }
    }

    /// Full sweep SAH, leaves of up to 4.
    pub const fn quality() -> Self {
        Self {
            builder: BvhBuilder::SweepSah,
            max_leaf_size: 4,
            ..Self::fast()
        }
    }

    /// Binned SAH with 16 bins and spatial splits (SBVH), leaves of up to 4.
    pub const fn spatial() -> Self {
        Self {
            spatial_alpha: Some(1e-5),
            ..Self::balanced()
        }
    }

    /// The preset that traces fastest over SoA-leaf triangle BVHs ([`TriBvh8`](crate::TriBvh8),
    /// [`TriBvh4`](crate::TriBvh4)): binned SAH with leaf costs in blocks of four
    /// ([`Self::for_soa_leaves`]), then reinsertion over the largest quarter of the nodes,
    /// which repairs what top-down splits place poorly at little build cost.
    pub const fn fastest_trace() -> Self {
        Self::balanced().for_soa_leaves().with_reinsertion(0.25)
    }

    /// [`Self::fastest_trace`]'s counterpart with spatial splits (SBVH): per-triangle leaf
    /// costs ([`Self::for_soa_leaves`]), reinsertion over the largest quarter of the nodes,
    /// and the SAH-optimal collapse from the root down ([`WideCollapse::Sah`]). The split
    /// references leave the top of the tree with fewer large overlapping boxes, so the greedy
    /// rule that serves [`Self::fastest_trace`] near the root only costs lanes here.
    pub const fn fastest_trace_spatial() -> Self {
        Self::spatial()
            .for_soa_leaves()
            .with_collapse(WideCollapse::Sah)
            .with_reinsertion(0.25)
    }

    /// Whether the tree may reference a primitive from several leaves.
    pub const fn splits_primitives(&self) -> bool {
        self.spatial_alpha.is_some() && matches!(self.builder, BvhBuilder::BinnedSah { .. })
    }

    /// The preset for trees whose leaves test four triangles at once ([`TriBvh4`],
    /// [`TriBvh8`], [`CompressedTriBvh8`](crate::CompressedTriBvh8)).
    ///
    /// Object splits: the SAH counts leaf tests in blocks of four ([`Self::leaf_block`] = 4,
    /// as Embree does for its four-triangle leaves), a traversal step weighs two such tests,
    /// and leaves hold up to 8 triangles (two tests): a leaf of four costs what a leaf of one
    /// does, so trees get fewer, fuller leaves. Where one leaf's box spans a scene that rays
    /// start inside, the blocks cost more than the SAH says.
    ///
    /// Spatial splits keep per-triangle costs (a step weighs 1.5 tests, leaves of up to 4):
    /// with blocks, leaves of up to eight gather the split parts of large triangles, which
    /// rays that start inside a scene enter before their hit.
    /// Measurements: `docs/notes/leaf-costs.md`.
    ///
    /// [`TriBvh4`]: crate::TriBvh4
    /// [`TriBvh8`]: crate::TriBvh8
    pub const fn for_soa_leaves(mut self) -> Self {
        if self.spatial_alpha.is_some() {
            self.traversal_cost = 1.5;
        } else {
            self.traversal_cost = 2.0;
            self.leaf_block = 4;
            if self.max_leaf_size < 8 {
                self.max_leaf_size = 8;
            }
        }
        self
    }

    /// The SAH's count of primitive tests for `n` primitives: blocks of [`Self::leaf_block`].
    #[inline(always)]
    pub(crate) fn tests(&self, n: usize) -> f32 {
        let shift = self.leaf_block.trailing_zeros();
        ((n + (1 << shift) - 1) >> shift) as f32
    }

    /// The SAH cost of a leaf of `n` primitives (relative to a traversal step's
    /// `traversal_cost`).
    #[inline(always)]
    pub(crate) fn leaf_cost(&self, n: usize) -> f32 {
        self.intersection_cost * self.tests(n)
    }

    /// The same parameters with another builder.
    pub const fn with_builder(mut self, builder: BvhBuilder) -> Self {
        self.builder = builder;
        self
    }

    /// The same parameters with another binary-to-wide collapse rule.
    pub const fn with_collapse(mut self, collapse: WideCollapse) -> Self {
        self.collapse = collapse;
        self
    }

    /// The same parameters with reinsertion over the largest `fraction` of the nodes (0: none).
    pub const fn with_reinsertion(mut self, fraction: f32) -> Self {
        self.reinsertion = fraction;
        self
    }

    /// Checks every field; the error names the first one out of range.
    pub fn validate(&self) -> Result<(), BuildError> {
        if let BvhBuilder::BinnedSah { bins } = self.builder {
            BuildError::require((2..=256).contains(&bins), "bins", bins, "2..=256")?;
        }
        let (leaf, kt, ki) = (
            self.max_leaf_size,
            self.traversal_cost,
            self.intersection_cost,
        );
        BuildError::require((1..=255).contains(&leaf), "max_leaf_size", leaf, "1..=255")?;
        rt_geom::check_sah_costs(kt, ki)?;
        if let Some(alpha) = self.spatial_alpha {
            BuildError::require(
                (0.0..=1.0).contains(&alpha),
                "spatial_alpha",
                alpha,
                "0..=1",
            )?;
        }
        BuildError::require(
            self.leaf_block.is_power_of_two() && self.leaf_block <= 16,
            "leaf_block",
            self.leaf_block,
            "1, 2, 4, 8 or 16",
        )?;
        if let WideCollapse::LargestAreaThenSah { above } = self.collapse {
            BuildError::require(above >= 0.0, "collapse above", above, ">= 0")?;
        }
        let r = self.reinsertion;
        BuildError::require((0.0..=1.0).contains(&r), "reinsertion", r, "0..=1")?;
        let budget = self.spatial_budget;
        BuildError::require(
            (0.0..=16.0).contains(&budget),
            "spatial_budget",
            budget,
            "0..=16",
        )?;
        Ok(())
    }
}

impl Default for BvhParams {
    fn default() -> Self {
        Self::balanced()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leaf_tests_count_blocks() {
        let per_prim = BvhParams::balanced();
        assert_eq!(per_prim.tests(3), 3.0);
        let soa = BvhParams::balanced().for_soa_leaves();
        assert_eq!((soa.leaf_block, soa.max_leaf_size), (4, 8));
        let counts: Vec<f32> = [0, 1, 4, 5, 8, 9].map(|n| soa.tests(n)).to_vec();
        assert_eq!(counts, [0.0, 1.0, 1.0, 2.0, 2.0, 3.0]);
        // Spatial splits keep per-primitive costs.
        let spatial = BvhParams::spatial().for_soa_leaves();
        assert_eq!((spatial.leaf_block, spatial.max_leaf_size), (1, 4));
        assert_eq!(spatial.traversal_cost, 1.5);
        let traced = BvhParams::fastest_trace_spatial();
        assert!(traced.splits_primitives() && traced.validate().is_ok());
        assert_eq!((traced.leaf_block, traced.max_leaf_size), (1, 4));
        assert_eq!(
            (traced.collapse, traced.reinsertion),
            (WideCollapse::Sah, 0.25)
        );
    }
}
