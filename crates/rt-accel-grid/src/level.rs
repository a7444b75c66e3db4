//! One grid level: its box, resolution and cell planes, and the layout of its cells in the
//! grid's arrays.
//!
//! ```text
//! Grid.levels[l]     the level's box, resolution, cell size (level 0 is the root grid)
//! Grid.offsets       per level, cells + 1 entries from `first`: cell c holds
//!                    refs[offsets[first + c] .. offsets[first + c + 1]]
//! Grid.children      per level that has sub-grids, one entry per cell from `first_child`:
//!                    the level refining that cell, or NO_CHILD
//! Grid.refs          primitive indices (u32), cell after cell
//! Grid.planes        per level and axis, from `plane_first[a]`: the `res[a] + 1` values of
//!                    `Level::plane(a, 0..=res[a])` (the walk reads them instead of
//!                    computing them)
//! ```
//!
//! Cells are numbered `x + res_x * (y + res_y * z)`. Plane `i` along an axis is
//! `min + i * size` (the last one exactly `max`); build and traversal both use [`Level::plane`],
//! so a primitive is in exactly the cells whose boxes the walk computes.

use rt_geom::{Aabb, Vec3};

/// `children` entry of a cell that has no sub-grid.
pub const NO_CHILD: u32 = u32::MAX;

/// Largest resolution along one axis.
pub const MAX_RES: u32 = 1 << 20;

/// One grid: its box, resolution and cell size.
#[derive(Clone, Debug, PartialEq)]
pub struct Level {
    /// The box the cells tile.
    pub bounds: Aabb,
    /// Cells per axis.
    pub res: [u32; 3],
    /// Cell size per axis.
    pub cell: [f32; 3],
    /// Reciprocal cell size per axis.
    pub inv_cell: [f32; 3],
    /// Index in `Grid.offsets` of this level's first cell.
    pub first: u32,
    /// Index in `Grid.children` of this level's first cell, or [`NO_CHILD`].
    pub first_child: u32,
    /// Per axis, index in `Grid.planes` of this level's plane 0.
    pub plane_first: [u32; 3],
}

impl Level {
    /// A level over `bounds` with about `cells` cells shaped like the box (cubes where the
    /// box allows), at most `max_cells`. Flat axes get one cell.
    pub fn new(bounds: Aabb, cells: f64, max_cells: u32) -> Self {
        let e = bounds.extent();
        let axes: Vec<usize> = (0..3).filter(|&a| e[a] > 0.0).collect();
        let mut res = [1u32; 3];
        if !axes.is_empty() {
            // Side `s` of a cube cell: prod(e_a / s) = cells over the non-flat axes.
            let d = axes.len() as f64;
            let log_measure: f64 = axes.iter().map(|&a| (e[a] as f64).ln()).sum();
            let mut target = cells.clamp(1.0, max_cells as f64);
            loop {
                let side = ((log_measure - target.ln()) / d).exp();
                for &a in &axes {
                    res[a] = ((e[a] as f64 / side).round()).clamp(1.0, MAX_RES as f64) as u32;
                }
                let total: u64 = res.iter().map(|&r| r as u64).product();
                if total <= max_cells as u64 || target <= 1.0 {
                    break;
                }
                target *= 0.8 * max_cells as f64 / total as f64;
            }
            if res.iter().map(|&r| r as u64).product::<u64>() > max_cells as u64 {
                res = [1; 3];
            }
        }
        Self::tiling(bounds, res)
    }

    /// The level tiling `bounds` with `res` cells per axis (its layout fields unset): what
    /// [`Self::new`] makes once it has chosen `res`, and a saved grid's levels are rebuilt by.
    pub fn tiling(bounds: Aabb, res: [u32; 3]) -> Self {
        let e = bounds.extent();
        let cell: [f32; 3] = std::array::from_fn(|a| e[a] / res[a] as f32);
        let inv_cell = cell.map(|c| if c > 0.0 { 1.0 / c } else { 0.0 });
        Self {
            bounds,
            res,
            cell,
            inv_cell,
            first: 0,
            first_child: NO_CHILD,
            plane_first: [0; 3],
        }
    }

    /// `b` widened on every side by the level's band: 2^-20 of its largest coordinate (16
    /// ulps). A primitive is listed in every cell whose widened box it touches, so a ray
    /// whose walk rounds two walls' crossings into one (stepping diagonally past a cell it
    /// grazes within rounding of their corner) still meets it in a cell it visits.
    pub fn widened(&self, b: &Aabb) -> Aabb {
        if b.is_empty() {
            return *b;
        }
        let scale = self
            .bounds
            .min
            .abs()
            .max(self.bounds.max.abs())
            .max_element();
        let band = Vec3::splat(scale * (1.0 / (1u32 << 20) as f32));
        Aabb::new(b.min - band, b.max + band)
    }

    /// Number of cells.
    pub fn cell_count(&self) -> usize {
        self.res.iter().map(|&r| r as usize).product()
    }

    /// Plane `i` (0..=res) along axis `a`.
    #[inline(always)]
    pub fn plane(&self, a: usize, i: u32) -> f32 {
        if i >= self.res[a] {
            self.bounds.max[a]
        } else {
            (self.bounds.min[a] + i as f32 * self.cell[a]).min(self.bounds.max[a])
        }
    }

    /// The cell along axis `a` whose slab `[plane(i), plane(i + 1))` holds `x` (clamped to
    /// the grid), exact with respect to [`Self::plane`].
    #[inline(always)]
    pub fn index_of(&self, a: usize, x: f32) -> u32 {
        self.index_by(a, x, |i| self.plane(a, i))
    }

    /// [`Self::index_of`] with the level's planes along `a` given by `plane` (a table of
    /// [`Self::plane`]'s values).
    #[inline(always)]
    pub fn index_by(&self, a: usize, x: f32, plane: impl Fn(u32) -> f32) -> u32 {
        let last = self.res[a] - 1;
        let guess = ((x - self.bounds.min[a]) * self.inv_cell[a]).floor();
        let mut i = if guess >= 0.0 {
            (guess as u32).min(last)
        } else {
            0
        };
        while i > 0 && x < plane(i) {
            i -= 1;
        }
        while i < last && x >= plane(i + 1) {
            i += 1;
        }
        i
    }

    /// The linear index of the cell at `idx` (x fastest).
    #[inline(always)]
    pub fn linear(&self, idx: [u32; 3]) -> usize {
        idx[0] as usize
            + self.res[0] as usize * (idx[1] as usize + self.res[1] as usize * idx[2] as usize)
    }

    /// The cell's box.
    pub fn cell_box(&self, idx: [u32; 3]) -> Aabb {
        Aabb::new(
            Vec3::from_array(std::array::from_fn(|a| self.plane(a, idx[a]))),
            Vec3::from_array(std::array::from_fn(|a| self.plane(a, idx[a] + 1))),
        )
    }

    /// The cell coordinates of linear index `c`.
    pub fn coords(&self, c: usize) -> [u32; 3] {
        let (rx, ry) = (self.res[0] as usize, self.res[1] as usize);
        [
            (c % rx) as u32,
            ((c / rx) % ry) as u32,
            (c / (rx * ry)) as u32,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolution_follows_the_box() {
        let l = Level::new(
            Aabb::new(Vec3::ZERO, Vec3::new(4.0, 2.0, 1.0)),
            8000.0,
            1 << 20,
        );
        assert_eq!(l.res, [40, 20, 10]);
        // Flat box: cells over the two non-flat axes only.
        let f = Level::new(
            Aabb::new(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0)),
            100.0,
            1 << 20,
        );
        assert_eq!(f.res, [10, 10, 1]);
        // A point: one cell.
        let p = Level::new(Aabb::new(Vec3::ONE, Vec3::ONE), 100.0, 1 << 20);
        assert_eq!(p.res, [1, 1, 1]);
        // The cap holds.
        let c = Level::new(Aabb::new(Vec3::ZERO, Vec3::ONE), 1e12, 1000);
        assert!(
            c.cell_count() <= 1000 && c.cell_count() > 100,
            "{:?}",
            c.res
        );
    }

    #[test]
    fn index_of_agrees_with_the_planes() {
        let l = Level::new(
            Aabb::new(Vec3::splat(-1.0), Vec3::splat(2.0)),
            27_000.0,
            1 << 20,
        );
        for a in 0..3 {
            for i in 0..l.res[a] {
                let p = l.plane(a, i);
                assert_eq!(l.index_of(a, p), i);
                if i > 0 && p != 0.0 {
                    // The float just below the plane.
                    let below = if p > 0.0 {
                        f32::from_bits(p.to_bits() - 1)
                    } else {
                        f32::from_bits(p.to_bits() + 1)
                    };
                    assert_eq!(l.index_of(a, below), i - 1);
                }
            }
            assert_eq!(l.plane(a, l.res[a]), 2.0);
            assert_eq!(l.index_of(a, 5.0), l.res[a] - 1);
            assert_eq!(l.index_of(a, -5.0), 0);
        }
        let c = l.linear([3, 4, 5]);
        assert_eq!(l.coords(c), [3, 4, 5]);
    }
}
