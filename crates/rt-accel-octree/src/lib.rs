//! # rt-accel-octree: octrees
//!
//! | module | what it holds |
//! |---|---|
//! | [`node`] | [`OctNode`], 64 bytes: child and leaf masks, first inner child and first leaf, the octants' quantized content boxes; [`OctLeaf`], 8 bytes (layout there) |
//! | [`params`] | [`OctreeParams`], [`OctreeTraversal`] |
//! | `build` | split at the centre while a node holds more than `max_prims`; primitives clipped to each octant |
//! | `traverse` | the classic recursive nearest-first walk, and the parametric walk of Revelles et al. |
//! | `stats` | `stats()` and `validate()` |
//! | [`save`] | saved octrees over triangles: `to_bytes`, `from_bytes`, checked on load |
//!
//! ```
//! use rt_accel_octree::{Octree, OctreeParams};
//! use rt_geom::{Accel, Ray, Triangle, Vec3};
//!
//! let tris = [
//!     Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y),
//!     Triangle::new(Vec3::new(0.0, 0.0, -1.0), Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, 1.0, -1.0)),
//! ];
//! let tree = Octree::build(&tris, OctreeParams::standard()).expect("finite input");
//! let hit = tree.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z)).unwrap();
//! assert_eq!((hit.t, hit.prim), (1.0, 0));
//! tree.validate().unwrap();
//! ```

#![warn(missing_docs)]

mod build;
pub mod node;
mod octree;
pub mod params;
pub mod save;
mod stats;
mod traverse;

pub use node::{ChildRef, OctLeaf, OctNode};
pub use octree::Octree;
pub use params::{MAX_DEPTH, OctreeParams, OctreeTraversal};
