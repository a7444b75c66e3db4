//! Build parameters.

use rt_geom::BuildError;

/// Which walk [`Octree::intersect`](rt_geom::Accel::intersect) runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OctreeTraversal {
    /// The classic recursive walk: the octants the ray's box test enters, nearest first.
    Recursive,
    /// Revelles, Ureña & Lastra (WSCG 2000): entry and exit parameters per axis, the first
    /// octant from the entry plane, the next from the exit plane, negative directions by an
    /// XOR mask on octant indices.
    Parametric,
}

/// Parameters of [`Octree::build`](crate::Octree::build).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OctreeParams {
    /// A node holding more primitives than this is split into eight (the classic figure is about 10;
    /// [`OctreeParams::standard`]: 24).
    pub max_prims: u32,
    /// No leaf deeper than this (at most [`MAX_DEPTH`]).
    pub max_depth: u32,
    /// At most `reference_budget * N` references in all: a split that would exceed its
    /// node's share (shared down in proportion to the children's counts) is not made. With
    /// the depth cap, the memory bound on pathological input (each reference: a 4-byte index
    /// and a copy of its primitive for the leaf test, [`rt_geom::LeafPrims`]).
    pub reference_budget: f32,
    /// Nodes with more primitives than this build their octants in parallel.
    pub parallel_threshold: usize,
    /// Parametric or recursive walk.
    pub traversal: OctreeTraversal,
    /// Each ray remembers the last 8 primitives it tested and skips them in later leaves (a
    /// primitive is listed in every leaf it overlaps). Off by default: with triangles tested
    /// four at a time, testing a repeat again costs less than looking it up.
    pub mailbox: bool,
}

/// Depth limit (a box halves 24 times before `f32` runs out of room for its centre).
pub const MAX_DEPTH: u32 = 24;

impl OctreeParams {
    /// Leaves of up to 24 primitives, depth up to 16, parametric traversal. The classic 10
    /// suits one triangle test at a time; leaves test four at once, and with 24 the walk
    /// takes fewer steps and each triangle is listed in fewer leaves (measured with the
    /// `oct_stats` example: `docs/notes/octree-walk.md`).
    pub const fn standard() -> Self {
        Self {
            max_prims: 24,
            max_depth: 16,
            reference_budget: 8.0,
            parallel_threshold: 4096,
            traversal: OctreeTraversal::Parametric,
            mailbox: false,
        }
    }

    /// The same parameters with another walk.
    pub const fn with_traversal(mut self, traversal: OctreeTraversal) -> Self {
        self.traversal = traversal;
        self
    }

    /// The same parameters with per-ray mailboxes on or off.
    pub const fn with_mailbox(mut self, mailbox: bool) -> Self {
        self.mailbox = mailbox;
        self
    }

    /// Checks every field; the error names the first one out of range.
    pub fn validate(&self) -> Result<(), BuildError> {
        BuildError::require(self.max_prims >= 1, "max_prims", self.max_prims, ">= 1")?;
        let depth = self.max_depth;
        BuildError::require(depth <= MAX_DEPTH, "max_depth", depth, "0..=24")?;
        BuildError::require_reference_budget(self.reference_budget)?;
        Ok(())
    }
}

impl Default for OctreeParams {
    fn default() -> Self {
        Self::standard()
    }
}
