//! # rt-packet: ray packets and packet traversal
//!
//! | module | what it holds |
//! |---|---|
//! | [`packet`] | [`RayPacket`]: `N` rays in structure-of-arrays form with an active mask (its [`Lanes`], reused by the thread's next packet); [`tiles`] of an image |
//! | [`api`] | [`PacketTraversal`] (`intersect_packet`, `occluded_packet`) and [`PacketAccel`], the same behind a trait object for groups of up to [`MAX_GROUP`] rays ([`LeavingGroups`]: rays that each skip the primitive they leave); [`WithSingleRays`], a packet path with its own single-ray structure |
//! | [`lanes`] | the kernels over blocks of 8 lanes: the slab test, and [`PacketPrimitive`] (watertight triangle test of 8 lanes at once) |
//! | [`simd`] | [`F8`](simd::F8): the eight-lane vectors those kernels run on, per instruction set (one AVX register where the CPU has AVX2, chosen at run time as rt-geom's [`Isa`](rt_geom::Isa)) |
//! | [`beam`] | [`Beam`]: a packet bounded by interval arithmetic, for culling and entry points |
//! | [`bvh`] | packets through rt's [`Bvh`](rt_accel_bvh::Bvh): first-active-ray descent, beam culling (Wald, Boulos & Shirley 2007) |
//! | [`wide`] | packets through the wide BVHs ([`Bvh4`](rt_accel_bvh::Bvh4), [`Bvh8`](rt_accel_bvh::Bvh8)): the same descent over all children of a node |
//! | [`kd`] | packets through [`KdTree`](rt_accel_kd::KdTree) split by direction octant (Wald, Slusallek, Benthin & Wagner 2001) |
//! | [`mlrta`] | [`MlrtaKdTree`]: multi-level ray tracing (Reshetov, Soupikov & Hurley 2005), packets started at the entry point of their beam |
//!
//! Every lane's answer equals the single-ray answer of its ray, bit for bit (same box test,
//! same kernel, same tie rule).
//!
//! ```
//! use rt_accel_bvh::{Bvh, BvhParams};
//! use rt_geom::{Accel, Ray, Triangle, Vec3};
//! use rt_packet::{PacketTraversal, RayPacket};
//!
//! let tris = [Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)];
//! let bvh = Bvh::build(&tris, BvhParams::balanced()).unwrap();
//! let rays: Vec<Ray> = (0..4)
//!     .map(|i| Ray::new(Vec3::new(0.1 + 0.1 * i as f32, 0.2, 1.0), -Vec3::Z))
//!     .collect();
//! let hits = bvh.intersect_packet(&mut RayPacket::<4>::new(&rays));
//! for (hit, ray) in hits.iter().zip(&rays) {
//!     assert_eq!(*hit, bvh.intersect(ray));
//! }
//! ```

#![warn(missing_docs)]

/// Runs `$body` with `$w` a `const` of the block width for packets of `$n` lanes (8, or 4 for
/// packets that are not a multiple of 8), so that one generic traversal serves both.
macro_rules! by_block_width {
    ($n:expr, $w:ident => $body:expr) => {
        if crate::lanes::block_width($n) == 8 {
            const $w: usize = 8;
            $body
        } else {
            const $w: usize = 4;
            $body
        }
    };
}

pub mod api;
pub mod beam;
pub mod bvh;
#[cfg(test)]
mod check;
pub mod kd;
pub mod lanes;
pub mod mlrta;
pub mod packet;
#[cfg(test)]
mod properties;
pub mod simd;
pub mod wide;

pub use api::{
    COHERENT_COS, LeavingGroups, MAX_GROUP, PacketAccel, PacketTraversal, WithSingleRays,
    is_coherent,
};
pub use beam::Beam;
pub use lanes::PacketPrimitive;
pub use mlrta::{EntryPoint, MlrtaKdTree};
pub use packet::{Lanes, RayPacket, TILE_SIDES, tiles};
