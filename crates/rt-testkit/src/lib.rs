//! # rt-testkit (unpublished): what every rt structure is tested and measured with
//!
//! | module | what it holds |
//! |---|---|
//! | [`rng`] | [`Rng`], a seeded generator: every scene and ray set is reproducible |
//! | [`scenes`] | procedural and adversarial scenes ([`Scene`]): soups, tessellated spheres and tori, planar and sliver scenes, duplicates, teapot in a stadium, huge and tiny coordinates, spheres, one primitive, nothing |
//! | [`rays`] | conformance ray families ([`RayKind`]), the standard camera ([`View`]) and the primary / shadow / diffuse sets ([`RaySets`]) |
//! | [`disc`] | [`Disc`], user geometry with only the two required methods of `Primitive`, and its scenes |
//! | [`conformance`] | the one generic check against brute force, and [`conformance_tests!`] |
//! | [`rayfile`] | `.rays` and `.hits` files, read and written (exchanging rays and answers with other engines) |
//! | `props` | the generated-property suites' case count and lattice coordinates (feature `proptest`) |
//! | [`models`] | where `../shared/models` is, and loading its meshes (tests skip with a message when it is absent) |
//!
//! ```
//! use rt_geom::{BruteForce, Triangle};
//! use rt_testkit::{conformance, scenes};
//!
//! // Any structure: a builder closure from primitives to `Result<impl Accel, BuildError>`.
//! let scene = scenes::triangle_scene("coplanar");
//! conformance::assert_conforms(&scene, |p: &[Triangle]| BruteForce::build(p));
//! ```

pub mod conformance;
pub mod disc;
pub mod models;
#[cfg(feature = "proptest")]
pub mod props;
pub mod rayfile;
pub mod rays;
pub mod rng;
pub mod scenes;

pub use conformance::{Report, Tolerance};
pub use disc::Disc;
pub use rays::{RayKind, RaySets, TestRay, View};
pub use rng::Rng;
/// For the macros (`$crate::rt_geom::Triangle`).
#[doc(hidden)]
pub use rt_geom;
pub use scenes::NoGeometry;
pub use scenes::Scene;

/// A structure's plain queries only ([`rt_geom::Accel::filtered`] is `None`), as a peer's
/// structure answers: what a renderer does without filtered queries can be compared with what
/// it does with them.
pub struct Unfiltered<'a>(pub &'a dyn rt_geom::Accel);

impl rt_geom::Accel for Unfiltered<'_> {
    fn intersect(&self, ray: &rt_geom::Ray) -> Option<rt_geom::Hit> {
        self.0.intersect(ray)
    }

    fn occluded(&self, ray: &rt_geom::Ray) -> bool {
        self.0.occluded(ray)
    }

    fn stats(&self) -> rt_geom::AccelStats {
        self.0.stats()
    }

    fn validate(&self) -> Result<(), String> {
        self.0.validate()
    }
}
