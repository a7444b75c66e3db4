//! # rt-accel-bvh: bounding volume hierarchies
//!
//! The fastest single-ray structure is [`TriBvh8`] built by [`TriBvh8::build_for_tracing`]
//! (the [`BvhParams::fastest_trace`] preset); [`Bvh`] and the wide [`Bvh8`] hold any
//! [`Primitive`](rt_geom::Primitive) (spheres and cones too).
//!
//! | module | what it holds |
//! |---|---|
//! | [`bvlist`] | [`BvList`]: flat lists of bounding volumes (sphere, box, k-DOP), optionally two levels |
//! | `binary` | [`Bvh`], the binary BVH: build, flatten, reinsert, query |
//! | [`node`] | [`BvhNode`], the 32-byte flattened node (layout documented there) |
//! | [`params`] | [`BvhParams`] with presets `fast()`, `balanced()`, `quality()`, `spatial()`, `fastest_trace()`; [`BvhBuilder`] |
//! | `build` | top-down builders: midpoint, median, binned SAH (Wald 2007), sweep SAH, spatial splits; flattening; reinsertion |
//! | `traverse` | closest-hit and any-hit traversal, one generic function |
//! | `stats` | `stats()` and `validate()` |
//! | `refit` | [`Refit`]: new vertex positions, same topology, for every BVH layout |
//! | `collapse` | binary → wide: the greedy largest-area rule and the SAH-optimal plan ([`WideCollapse`]) |
//! | [`wide`] | [`Bvh4`], [`Bvh8`]: collapsed wide BVHs, all children tested at once ([`WideTree`]); node, build, traverse and stats in files of those names |
//! | [`compressed`] | [`CompressedNode`]: child boxes quantized to 8 bits per plane, 128-byte nodes; [`CompressedBvh8`] and [`CompressedTree`] are the wide BVH and its topology over that layout |
//! | [`instance`] | [`InstanceBvh`]: two-level ray tracing, a top-level BVH over [`Instance`]s (affine transforms) of [`Object`]s with their own structures; moving instances and refit objects; objects of several geometries ([`InstancedGeometries`]) |
//! | [`save`] | saved structures: a built [`TriBvh`] as versioned bytes and back, checked on load ([`LoadError`]) |
//! | [`tri`] | [`TriBvh4`], [`TriBvh8`], [`CompressedTriBvh8`]: wide BVHs over triangles stored leaf by leaf as SoA ([`TriangleSoa`], from rt-geom), four tested at once |
//!
//! ```
//! use rt_accel_bvh::{Bvh, BvhParams, TriBvh8};
//! use rt_geom::{Accel, Ray, Triangle, Vec3};
//!
//! let tris = [
//!     Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y),
//!     Triangle::new(Vec3::new(0.0, 0.0, -1.0), Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, 1.0, -1.0)),
//! ];
//! let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z);
//! let fastest = TriBvh8::build_for_tracing(&tris).expect("finite input");
//! let bvh = Bvh::build(&tris, BvhParams::balanced()).expect("finite input");
//! for accel in [&fastest as &dyn Accel, &bvh] {
//!     let hit = accel.intersect(&ray).unwrap();
//!     assert_eq!((hit.t, hit.prim), (1.0, 0));
//!     accel.validate().unwrap();
//! }
//! ```

#![warn(missing_docs)]

mod binary;
mod build;
pub mod bvlist;
mod collapse;
pub mod compressed;
pub mod instance;
pub mod node;
pub mod params;
mod refit;
pub mod save;
mod stats;
mod traverse;
pub mod tri;
pub mod wide;

pub use binary::Bvh;
pub use bvlist::{BvList, BvListParams, Grouping};
pub use compressed::{CompressedBvh8, CompressedNode, CompressedTree};
pub use instance::{
    Instance, InstanceBvh, InstanceGeometryHit, InstanceHit, InstancedGeometries, Object, TopUpdate,
};
pub use node::BvhNode;
pub use params::{BvhBuilder, BvhParams, MAX_DEPTH, WideCollapse};
pub use refit::Refit;
pub use rt_geom::TriangleSoa;
pub use save::LoadError;
pub use tri::{CompressedTriBvh8, TriBvh, TriBvh4, TriBvh8};
pub use wide::{Bvh4, Bvh8, NodeLayout, WideBvh, WideNode, WideTree};
