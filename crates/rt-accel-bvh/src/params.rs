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
    BinnedSah { bins: u32 },
    /// Surface area heuristic over every split between sorted centroids (full sweep).
    SweepSah,
}

/// Parameters of [`Bvh::build`](crate::Bvh::build).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhParams {
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

    /// Whether the tree may reference a primitive from several leaves.
    pub const fn splits_primitives(&self) -> bool {
        self.spatial_alpha.is_some() && matches!(self.builder, BvhBuilder::BinnedSah { .. })
    }

    /// The preset for trees whose leaves test four triangles at once ([`TriBvh4`],
    /// [`TriBvh8`], [`CompressedTriBvh8`](crate::CompressedTriBvh8)): a traversal step weighs
    /// two primitive tests (1.5 with spatial splits), so leaves hold about 2.8 triangles
    /// instead of 1.9. Bench (`cargo xtask bench --threads 2`), `bvh8-tri` primary / shadow /
    /// diffuse: bunny +11% / +8% / +7%, dragon +4% / +1% / +8%, sponza -3% / -4% / -4%
    /// (within this machine's noise), 20-25% fewer bytes; the BVHs with one-primitive leaf
    /// tests do not gain (`bvh8` 2-10% slower).
    ///
    /// [`TriBvh4`]: crate::TriBvh4
    /// [`TriBvh8`]: crate::TriBvh8
    pub const fn for_soa_leaves(mut self) -> Self {
        self.traversal_cost = if self.spatial_alpha.is_some() {
            1.5
        } else {
            2.0
        };
        self
    }

    pub const fn with_builder(mut self, builder: BvhBuilder) -> Self {
        self.builder = builder;
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
