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

/// Whether `RT_LONG_TESTS=1`: the suites sized for a quick `cargo test` (the filtered
/// queries on every eighth conformance ray, one flipped bit per byte of a saved structure,
/// the pathological scenes at half of `cargo xtask stress`'s size) run at full size, as CI
/// runs them.
pub fn long_tests() -> bool {
    std::env::var("RT_LONG_TESTS").is_ok_and(|v| v == "1")
}

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

/// A saved structure against a rebuild, for the `save_load` and `kd_save_load` examples:
/// builds with `build`, saves with `save`, loads back with `load` (its checks included), and
/// prints the times, the size and whether the loaded structure answers `rays` as the built
/// one, bit for bit (an error if not).
pub fn save_load_report<A: rt_geom::Accel, E: std::error::Error + 'static>(
    name: &str,
    build: impl FnOnce() -> Result<A, rt_geom::BuildError>,
    save: impl Fn(&A) -> Vec<u8>,
    load: impl FnOnce(&[u8]) -> Result<A, E>,
    rays: &[rt_geom::Ray],
) -> Result<Vec<u8>, Box<dyn std::error::Error>> {
    let t = std::time::Instant::now();
    let built = build()?;
    let build_s = t.elapsed().as_secs_f64();
    let bytes = save(&built);
    let t = std::time::Instant::now();
    let loaded = load(&bytes)?;
    let load_s = t.elapsed().as_secs_f64();
    let same = rays.iter().all(|r| {
        loaded.intersect(r) == built.intersect(r) && loaded.occluded(r) == built.occluded(r)
    });
    println!(
        "{name}: {} primitives, build {build_s:.3} s, load {load_s:.3} s ({:.1}x faster), {:.1} MB, same answers on {} rays: {same}",
        built.stats().primitives,
        build_s / load_s,
        bytes.len() as f64 / 1e6,
        rays.len()
    );
    if !same {
        return Err(format!("{name}: the loaded structure answered otherwise").into());
    }
    Ok(bytes)
}

/// For saved-structure tests: `built` loads back from its bytes (`save`, `load`) answering
/// every ray of `rays` as it does, and saves to the same bytes again.
pub fn assert_round_trip<A: rt_geom::Accel, E: std::fmt::Debug>(
    built: &A,
    save: impl Fn(&A) -> Vec<u8>,
    load: impl Fn(&[u8]) -> Result<A, E>,
    rays: &[rt_geom::Ray],
) {
    let bytes = save(built);
    let loaded = load(&bytes).expect("a saved structure loads");
    for r in rays {
        assert_eq!(loaded.intersect(r), built.intersect(r), "{r:?}");
        assert_eq!(loaded.occluded(r), built.occluded(r), "{r:?}");
    }
    assert_eq!(save(&loaded), bytes, "saved again, other bytes");
}

/// For saved-structure tests: every conformance scene (triangles), built by `build`, loads
/// back from its bytes (`save`, `load`): the loader's checks refuse nothing the build makes.
pub fn assert_conformance_scenes_load<A, E: std::fmt::Debug>(
    build: impl Fn(&[rt_geom::Triangle]) -> A,
    save: impl Fn(&A) -> Vec<u8>,
    load: impl Fn(&[u8], &[rt_geom::Triangle]) -> Result<A, E>,
) {
    for scene in scenes::conformance_triangle_scenes() {
        let loaded = load(&save(&build(&scene.prims)), &scene.prims);
        assert!(loaded.is_ok(), "{}: {:?}", scene.name, loaded.err());
    }
}

/// For saved-structure tests: every prefix of `bytes` is refused by `load`, and with each
/// byte changed (every eighth unless [`long_tests`]) `load` refuses them or loads a
/// structure that answers every ray of `rays` as `brute` does.
pub fn assert_damage_refused<A: rt_geom::Accel, E>(
    bytes: &[u8],
    load: impl Fn(&[u8]) -> Result<A, E>,
    brute: &dyn rt_geom::Accel,
    rays: &[rt_geom::Ray],
) {
    for len in 0..bytes.len() {
        assert!(load(&bytes[..len]).is_err(), "{len} bytes loaded");
    }
    let stride = if long_tests() { 1 } else { 8 };
    for at in (0..bytes.len()).step_by(stride) {
        let mut damaged = bytes.to_vec();
        damaged[at] ^= 0x5a;
        if let Ok(loaded) = load(&damaged) {
            for r in rays {
                assert_eq!(loaded.intersect(r), brute.intersect(r), "byte {at}");
                assert_eq!(loaded.occluded(r), brute.occluded(r), "byte {at}");
            }
        }
    }
}

/// The bytes of a fuzz target's saved finding, `fuzz/regressions/<target>/<file>`, for the
/// tests that hold each finding refused for its fault.
pub fn fuzz_regression(target: &str, file: &str) -> Vec<u8> {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fuzz/regressions");
    let path = format!("{dir}/{target}/{file}");
    std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}
