//! Build parameters with presets.

use rt_geom::BuildError;

/// Which grid [`Grid::build`](crate::Grid::build) makes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GridKind {
    /// One level: about `density * N` cells.
    Uniform,
    /// Two levels (Kalojanov, Billeter & Slusallek 2011): a coarse top grid of
    /// `top_density * N` cells; every non-empty top cell gets its own grid of
    /// `density * n_cell` cells over the box of its content.
    TwoLevel {
        /// Top-level cells per primitive.
        top_density: f32,
    },
    /// Adaptive (Jevans & Wyvill 1989, Klimaszewski & Sederberg 1997): a cell holding more
    /// than `max_cell_prims` primitives is subdivided into a grid of `density * n_cell`
    /// cells over the box of its content, recursively, to at most `max_levels` levels.
    Adaptive {
        /// Cells holding more primitives are refined.
        max_cell_prims: u32,
        /// Levels at most, the top one included.
        max_levels: u32,
    },
}

/// Parameters of [`Grid::build`](crate::Grid::build).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridParams {
    /// Uniform, two-level or adaptive.
    pub kind: GridKind,
    /// Cells per primitive (λ): a grid over `n` primitives gets about `density * n` cells,
    /// shaped like the box it covers. Cleary & Wyvill's and Wald's rule of thumb is 1 to 5.
    pub density: f32,
    /// At most this many cells per level (4 bytes each).
    pub max_cells: u32,
    /// The whole grid (all levels) holds at most `max_refs_per_prim * N` references: a level
    /// whose cells would hold more (large triangles in fine cells) is made coarser, and
    /// sub-grids share what their parent leaves. With `max_cells`, the memory bound (each
    /// reference: a 4-byte index and a copy of its primitive for the cell test,
    /// [`rt_geom::LeafPrims`]).
    pub max_refs_per_prim: f32,
    /// Skip a primitive already tested by this ray (a small per-ray cache of the last ids),
    /// instead of testing it again in every cell it spans. Off in every preset: with
    /// triangles tested four at a time a repeat costs less than the lookup.
    pub mailbox: bool,
    /// Cross empty space a whole empty cube at a time ([`crate::skip`]); off, the walk steps
    /// through every cell (the classic 3D-DDA, whose cost per ray grows as the cube root of
    /// the cell count). On in every preset.
    pub skip_empty: bool,
}

impl GridParams {
    /// A uniform grid of one cell per two primitives, no mailboxes. Cells test their
    /// triangles four or eight at a time from copies laid out for it
    /// ([`rt_geom::LeafPrims`]), so coarser cells than the classic 2-5 per primitive pay
    /// (measured with the `grid_params` example: `docs/notes/grid-presets.md`).
    pub const fn uniform() -> Self {
        Self {
            kind: GridKind::Uniform,
            density: 0.5,
            max_cells: 1 << 25,
            max_refs_per_prim: 32.0,
            mailbox: false,
            skip_empty: true,
        }
    }

    /// Two levels: a top grid of one cell per 100 primitives, each non-empty cell's content
    /// refined at one cell per 2 primitives.
    pub const fn two_level() -> Self {
        Self {
            kind: GridKind::TwoLevel { top_density: 0.01 },
            density: 0.5,
            ..Self::uniform()
        }
    }

    /// Adaptive: a uniform grid of one cell per 8 primitives; cells of more than 24
    /// primitives refined the same way over their content, to at most 4 levels.
    pub const fn adaptive() -> Self {
        Self {
            kind: GridKind::Adaptive {
                max_cell_prims: 24,
                max_levels: 4,
            },
            density: 0.125,
            ..Self::uniform()
        }
    }

    /// The same parameters with per-ray mailboxes on or off.
    pub const fn with_mailbox(mut self, mailbox: bool) -> Self {
        self.mailbox = mailbox;
        self
    }

    /// The same parameters with empty-space skipping on or off.
    pub const fn with_skip_empty(mut self, skip_empty: bool) -> Self {
        self.skip_empty = skip_empty;
        self
    }

    /// Checks every field; the error names the first one out of range. Densities must be
    /// positive and finite, at most 64 cells per primitive (a huge λ would ask for more cells
    /// than the memory cap anyway).
    pub fn validate(&self) -> Result<(), BuildError> {
        let density_ok = |d: f32| d.is_finite() && d > 0.0 && d <= 64.0;
        let d = self.density;
        BuildError::require(density_ok(d), "density", d, "0 < density <= 64")?;
        match self.kind {
            GridKind::Uniform => {}
            GridKind::TwoLevel { top_density: t } => {
                BuildError::require(density_ok(t), "top_density", t, "0 < density <= 64")?;
            }
            GridKind::Adaptive {
                max_cell_prims,
                max_levels,
            } => {
                BuildError::require(
                    max_cell_prims >= 1,
                    "max_cell_prims",
                    max_cell_prims,
                    ">= 1",
                )?;
                let levels_ok = (1..=8).contains(&max_levels);
                BuildError::require(levels_ok, "max_levels", max_levels, "1..=8")?;
            }
        }
        let cells = self.max_cells;
        BuildError::require(
            (1..=1 << 28).contains(&cells),
            "max_cells",
            cells,
            "1..=2^28",
        )?;
        let refs = self.max_refs_per_prim;
        BuildError::require(
            refs.is_finite() && refs >= 1.0,
            "max_refs_per_prim",
            refs,
            ">= 1, finite",
        )?;
        Ok(())
    }
}

impl Default for GridParams {
    fn default() -> Self {
        Self::uniform()
    }
}
