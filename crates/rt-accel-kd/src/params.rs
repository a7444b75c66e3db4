//! Build parameters with presets.

use rt_geom::BuildError;

/// How a [`KdTree`](crate::KdTree) chooses its split planes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KdBuilder {
    /// Surface area heuristic over every candidate plane (the faces of the primitives' boxes,
    /// clipped to the node: perfect splits), swept in O(N log N) (Wald & Havran 2006).
    Sah,
    /// Naive: the largest extent of the node split at its middle.
    Midpoint,
    /// Naive: the largest extent split at the centre of gravity of the node's geometry (the
    /// mean centre of the primitives' clipped boxes).
    Centroid,
}

/// Which traversal [`KdTree::intersect`](rt_geom::Accel::intersect) runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KdTraversal {
    /// Explicit stack, near child first (pbrt, Havran's TA_B^rec made iterative).
    Iterative,
    /// The classic recursive front-to-back descent.
    Recursive,
}

/// Parameters of [`KdTree::build`](crate::KdTree::build).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KdParams {
    /// How split planes are chosen.
    pub builder: KdBuilder,
    /// SAH cost of traversing an inner node (Wald & Havran use 15 against 20 for a test).
    pub traversal_cost: f32,
    /// SAH cost of one primitive test.
    pub intersection_cost: f32,
    /// Fraction of the cost taken off a split that cuts off empty space (Wald & Havran: 0.2,
    /// i.e. the split costs 80%). Not granted to flat empty children.
    pub empty_bonus: f32,
    /// Depth cap. `None`: `8 + 1.3 log2 N` (Havran), at most [`MAX_DEPTH`].
    pub max_depth: Option<u32>,
    /// Naive builders: stop splitting at this many primitives. The SAH builder stops by cost.
    pub max_leaf_size: u32,
    /// The tree holds at most `reference_budget * N` primitive references (each split
    /// duplicates the primitives it cuts); a split that would exceed its node's share is not
    /// made. This is the memory bound on pathological input: at most `reference_budget * N`
    /// indices and as many copies of the primitives for the leaf test (36 bytes each for a
    /// triangle, [`rt_geom::LeafPrims`]), and `2 * max_depth` nodes per reference.
    pub reference_budget: f32,
    /// Subtrees with more primitives than this are built in parallel (rayon).
    pub parallel_threshold: usize,
    /// Iterative or recursive walk.
    pub traversal: KdTraversal,
}

/// No leaf lies deeper than this; it also sizes the traversal stack.
pub const MAX_DEPTH: u32 = 64;

impl KdParams {
    /// The SAH kd-tree with constants measured for rt's traversal: a traversal step costs
    /// about five primitive tests (15 against 3), since leaves test their triangles four at a
    /// time from a copy laid out for it ([`rt_geom::LeafPrims`]), and empty space is cut off
    /// at 90% of the cost: leaves of about 9 triangles (measured with the `kd_costs` example:
    /// `docs/notes/kd-constants.md`).
    pub const fn sah() -> Self {
        Self {
            traversal_cost: 15.0,
            intersection_cost: 3.0,
            empty_bonus: 0.1,
            ..Self::wald_havran()
        }
    }

    /// The SAH kd-tree with Wald & Havran's constants (traversal 15, test 20, empty bonus
    /// 0.2): leaves of 2-3 triangles. The packet paths of `rt-packet` build with these: a
    /// packet tests a leaf one triangle per block of 8 lanes, so larger leaves cost it more
    /// than they save.
    pub const fn wald_havran() -> Self {
        Self {
            builder: KdBuilder::Sah,
            traversal_cost: 15.0,
            intersection_cost: 20.0,
            empty_bonus: 0.2,
            max_depth: None,
            max_leaf_size: 8,
            reference_budget: 8.0,
            parallel_threshold: 4096,
            traversal: KdTraversal::Iterative,
        }
    }

    /// Naive midpoint splits of the largest extent, leaves of up to 8.
    pub const fn midpoint() -> Self {
        Self {
            builder: KdBuilder::Midpoint,
            ..Self::sah()
        }
    }

    /// Naive splits at the centre of gravity, leaves of up to 8.
    pub const fn centroid() -> Self {
        Self {
            builder: KdBuilder::Centroid,
            ..Self::sah()
        }
    }

    /// The same parameters with another walk.
    pub const fn with_traversal(mut self, traversal: KdTraversal) -> Self {
        self.traversal = traversal;
        self
    }

    /// The depth cap for `n` primitives.
    pub fn depth_cap(&self, n: usize) -> u32 {
        match self.max_depth {
            Some(d) => d.min(MAX_DEPTH),
            None => (8.0 + 1.3 * (n.max(1) as f64).log2())
                .round()
                .min(MAX_DEPTH as f64) as u32,
        }
    }

    /// Checks every field; the error names the first one out of range.
    pub fn validate(&self) -> Result<(), BuildError> {
        let (kt, ki, bonus) = (
            self.traversal_cost,
            self.intersection_cost,
            self.empty_bonus,
        );
        rt_geom::check_sah_costs(kt, ki)?;
        BuildError::require(
            (0.0..1.0).contains(&bonus),
            "empty_bonus",
            bonus,
            "0 <= b < 1",
        )?;
        if let Some(d) = self.max_depth {
            BuildError::require(d <= MAX_DEPTH, "max_depth", d, "0..=64")?;
        }
        let leaf = self.max_leaf_size;
        BuildError::require(
            (1..=1 << 20).contains(&leaf),
            "max_leaf_size",
            leaf,
            "1..=1048576",
        )?;
        BuildError::require_reference_budget(self.reference_budget)?;
        Ok(())
    }
}

impl Default for KdParams {
    fn default() -> Self {
        Self::sah()
    }
}
