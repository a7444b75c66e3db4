//! # rt-accel-kd: kd-trees and BSP trees
//!
//! | module | what it holds |
//! |---|---|
//! | [`node`] | [`KdNode`], the 8-byte flattened node (layout documented there) |
//! | [`params`] | [`KdParams`] with presets `sah()`, `midpoint()`, `centroid()`; [`KdBuilder`], [`KdTraversal`] |
//! | `build` | split-plane events, the O(N log N) SAH sweep (Wald & Havran 2006), naive planes, perfect splits, flattening |
//! | [`traverse`] | front-to-back traversal, iterative and recursive, closest- and any-hit ([`traverse::step`]) |
//! | `stats` | `stats()` and `validate()` |
//! | [`save`] | saved kd-trees over triangles: `to_bytes`, `from_bytes`, checked on load |
//! | [`bsp`] | [`BspTree`]: planes of any orientation (the primitives' own, and axis-aligned), same nodes and walk |
//!
//! ```
//! use rt_accel_kd::{KdParams, KdTree};
//! use rt_geom::{Accel, Ray, Triangle, Vec3};
//!
//! let tris = [
//!     Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y),
//!     Triangle::new(Vec3::new(0.0, 0.0, -1.0), Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, 1.0, -1.0)),
//! ];
//! let kd = KdTree::build(&tris, KdParams::sah()).expect("finite input");
//! let hit = kd.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z)).unwrap();
//! assert_eq!((hit.t, hit.prim), (1.0, 0));
//! kd.validate().unwrap();
//! ```

#![warn(missing_docs)]

pub mod bsp;
mod build;
pub mod node;
pub mod params;
pub mod save;
mod stats;
pub mod traverse;
mod tree;

pub use bsp::{BspParams, BspTree, SplitPlane};
pub use node::KdNode;
pub use params::{KdBuilder, KdParams, KdTraversal, MAX_DEPTH};
pub use tree::KdTree;
