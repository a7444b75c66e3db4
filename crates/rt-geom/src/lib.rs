//! # rt-geom: the geometry every rt crate shares
//!
//! Rays, boxes, triangles, spheres, bounding volumes, watertight ray/primitive kernels, meshes
//! from OBJ, the one [`Accel`] trait and [`BruteForce`], the baseline every structure is checked
//! against.
//!
//! | module | what it holds |
//! |---|---|
//! | [`ray`] | [`Ray`] (one 64-byte cache line, with the watertight shear cached), [`Hit`], [`PrimHit`] |
//! | [`aabb`] | [`Aabb`] and its robust slab test ([`Aabb::clip_ray`], Ize 2013) |
//! | [`triangle`] | [`Triangle`]: watertight test (Woop, Benthin & Wald 2013), Möller–Trumbore, clipping; the lane kernel and its error bounds |
//! | [`sphere`] | [`Sphere`], solved in the stable form of Ray Tracing Gems ch. 7 |
//! | [`cone`] | [`Cone`]: open cones and cylinders (NFF's `c`), solved in `f64` |
//! | [`shape`] | [`Shape`]: a triangle, sphere or cone, for scenes that mix them |
//! | [`geometries`] | [`Geometries`]: several meshes and shape sets in one structure, each with a ray mask; hits name the geometry, the primitive in it and the normal |
//! | [`frame`] | [`Frame`]: coordinates relative to a structure's own box, for cell walks far from the origin |
//! | [`volume`] | [`BoundingVolume`]: [`BoundingSphere`], [`Aabb`], [`Kdop7`] (Kay & Kajiya 1986) |
//! | [`primitive`] | [`Primitive`]: what structures need of their elements |
//! | [`accel`] | [`Accel`], [`AccelStats`], [`BuildError`] |
//! | [`brute`] | [`BruteForce`] |
//! | [`filter`] | [`FilteredAccel`]: queries with a filter on each candidate hit, and every hit along a ray; [`Keep`], what a walk keeps of its hits |
//! | [`isa`] | [`Isa`] and [`Walk`]: walks and leaf tests compiled for AVX2 too, chosen at run time |
//! | [`leaf_prims`] | [`TriangleSoa`] (triangles leaf by leaf as structure of arrays, tested four at a time) and [`LeafPrims`] (the listed primitives of kd-trees, octrees and grids, laid out for the leaf test) |
//! | [`mesh`] | [`Mesh`], [`load_obj`] (through tobj), [`MeshError`] |
//! | [`pages`] | the structures' large arrays asked for on 2 MiB pages (Linux) |
//!
//! ```
//! use rt_geom::{Accel, BruteForce, Ray, Triangle, Vec3};
//!
//! let tris = [Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)];
//! let scene = BruteForce::build(&tris).expect("finite input");
//! let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), Vec3::new(0.0, 0.0, -1.0));
//! let hit = scene.intersect(&ray).expect("the ray hits the triangle");
//! assert_eq!((hit.t, hit.prim), (1.0, 0));
//! assert!(scene.occluded(&ray));
//! ```

#![warn(missing_docs)]

pub mod aabb;
pub mod accel;
pub mod brute;
pub mod cone;
pub mod counters;
pub mod filter;
pub mod frame;
pub mod geometries;
pub mod isa;
pub mod leaf_prims;
pub mod mesh;
pub mod pages;
pub mod primitive;
pub mod ray;
pub mod saved;
pub mod shape;
pub mod sphere;
pub mod triangle;
pub mod volume;

pub use aabb::Aabb;
pub use accel::{
    Accel, AccelStats, BuildError, MAX_COORDINATE, Mailbox, StatsSum, all_referenced,
    check_primitives, check_sah_costs, touches_cell,
};
pub use brute::BruteForce;
pub use cone::Cone;
pub use filter::{
    Filtered, FilteredAccel, HitFilter, Keep, Masked, Occlusion, SkipPrim, Skipping, sorted_hits,
};
pub use frame::Frame;
pub use geometries::{Geometries, GeometryHit};
pub use glam::{self, DVec3, Vec3};
pub use isa::{Avx2Level, BaseLevel, Isa, Kernel, Level, SortedLanes, Walk};
pub use leaf_prims::{LeafPrims, TriangleSoa};
pub use mesh::{Mesh, MeshError, MeshGroup, load_obj, parse_obj};
pub use primitive::Primitive;
pub use ray::{Hit, MIN_DIRECTION, PrimHit, Ray, keep_hit, replaces, test_primitives};
pub use shape::Shape;
pub use sphere::Sphere;
pub use triangle::{Triangle, TriangleKernel};
pub use volume::{BoundingSphere, BoundingVolume, KDOP7_NORMALS, Kdop7, LocalRay, SlabProjections};

/// Test input: a xorshift32 sequence from `seed` (non-zero), uniform in `[0, 1]`.
#[cfg(test)]
pub(crate) fn test_uniform(mut state: u32) -> impl FnMut() -> f32 {
    move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state as f32 / u32::MAX as f32
    }
}
