//! # rt-packet: ray packets and packet traversal
//!
//! | module | what it holds |
//! |---|---|
//! | [`packet`] | [`RayPacket`]: `N` rays in structure-of-arrays form with an active mask; [`tiles`] of an image |
//! | [`bvh`] | [`PacketTraversal`] for rt's [`Bvh`](rt_accel_bvh::Bvh): first-active-ray descent (Wald, Boulos & Shirley 2007); [`PacketAccel`], the same behind a trait object |
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

pub mod bvh;
pub mod packet;

pub use bvh::{MAX_GROUP, PacketAccel, PacketTraversal};
pub use packet::{RayPacket, TILE_SIDES, tiles};
