//! The conformance suite over every registered structure, and per structure with its options.

use rt_geom::{BruteForce, Sphere, Triangle};
use rt_testkit::scenes;
use xtask::registry::REGISTRY;

/// Every structure in the registry (so every structure `verify`, `bench` and `trace` know) on
/// `scene`, held to its registered tolerance against brute force with its triangle kernel;
/// peers that answer otherwise by design on these scenes (`conformance: false`: not
/// watertight) are checked on the meshes by `verify`.
fn every_registered_structure_conforms(scene: &str) {
    let scene = scenes::triangle_scene(scene);
    let mut failures = Vec::new();
    for entry in REGISTRY.iter().filter(|e| e.conformance) {
        match entry.check_triangle_scene(&scene) {
            Ok(r) if r.is_ok() => {}
            Ok(r) => failures.push(format!(
                "{} on {}: {} mismatches, first: {}",
                entry.name, scene.name, r.mismatch_count, r.mismatches[0]
            )),
            Err(e) => failures.push(format!("{} on {}: {e}", entry.name, scene.name)),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// One test per conformance scene (the harness runs them in parallel), and a check that the
/// list is the suite's.
macro_rules! per_scene {
    ($($scene:ident),* $(,)?) => {
        mod every_registered_structure {
            use super::*;
            $(
                #[test]
                fn $scene() {
                    every_registered_structure_conforms(stringify!($scene));
                }
            )*

            #[test]
            fn covers_every_conformance_scene() {
                let names: Vec<String> =
                    scenes::conformance_triangle_scenes().into_iter().map(|s| s.name).collect();
                assert_eq!(names, [$(stringify!($scene)),*]);
            }
        }
    };
}

per_scene!(
    soup,
    sphere_mesh,
    torus,
    planar_grid,
    coplanar,
    axis_slivers,
    duplicates,
    teapot_in_stadium,
    overlapping_fan,
    long_slivers,
    huge_coords,
    tiny_coords,
    one_triangle,
    empty,
    far_soup,
    far_sphere,
    far_stadium,
    far_dense,
    far_slivers,
);

mod brute {
    use super::*;
    rt_testkit::conformance_tests!(
        triangles: |p: &[Triangle]| BruteForce::build(p),
        spheres: |p: &[Sphere]| BruteForce::build(p),
        shapes: |p: &[rt_geom::Shape]| BruteForce::build(p),
    );
}

mod obvhs_bvh2 {
    use super::*;
    use xtask::obvhs_accel::ObvhsBvh2;
    rt_testkit::conformance_tests!(
        tolerance: xtask::registry::OBVHS_TOLERANCE,
        triangles: |p: &[Triangle]| ObvhsBvh2::build(p),
    );
}

mod obvhs_cwbvh {
    use super::*;
    use xtask::obvhs_accel::ObvhsCwBvhRtKernel;
    rt_testkit::conformance_tests!(
        tolerance: xtask::registry::find("obvhs-cwbvh-rt-kernel").unwrap().tolerance,
        triangles: |p: &[Triangle]| ObvhsCwBvhRtKernel::build(p),
    );
}
