//! # rt-accel-grid: uniform and hierarchical grids
//!
//! | module | what it holds |
//! |---|---|
//! | [`params`] | [`GridParams`] with presets `uniform()`, `two_level()`, `adaptive()`; [`GridKind`] |
//! | [`level`] | [`Level`]: one grid's box, resolution and cell planes; the array layout |
//! | `build` | primitives into the cells they overlap (clipped, not just boxed), counting sort, sub-grids, flattening |
//! | [`skip`] | per cell, the distance to the nearest occupied cell, to cross empty space in one step |
//! | `traverse` | the 3D-DDA (Amanatides & Woo 1987) through every level, optional mailboxes |
//! | `stats` | `stats()` and `validate()` |
//! | [`save`] | saved grids over triangles: `to_bytes`, `from_bytes`, checked on load |
//!
//! ```
//! use rt_accel_grid::{Grid, GridParams};
//! use rt_geom::{Accel, Ray, Triangle, Vec3};
//!
//! let tris = [
//!     Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y),
//!     Triangle::new(Vec3::new(0.0, 0.0, -1.0), Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, 1.0, -1.0)),
//! ];
//! let grid = Grid::build(&tris, GridParams::uniform()).expect("finite input");
//! let hit = grid.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z)).unwrap();
//! assert_eq!((hit.t, hit.prim), (1.0, 0));
//! grid.validate().unwrap();
//! ```

#![warn(missing_docs)]

mod build;
mod grid;
pub mod level;
pub mod params;
pub mod save;
pub mod skip;
mod stats;
mod traverse;

pub use grid::Grid;
pub use level::Level;
pub use params::{GridKind, GridParams};
