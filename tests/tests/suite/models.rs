//! The shared meshes load as their README says, and obvhs agrees with brute force on them.
//! Every test here skips, saying so, when `../shared/models` is absent.

use rt_geom::{Accel, BruteForce};
use rt_testkit::{RaySets, TestRay, conformance, models};
use xtask::obvhs_accel::ObvhsBvh2;

#[test]
fn meshes_have_the_documented_triangle_counts() {
    for (name, count) in [("teapot", 6_320), ("bunny", 69_451), ("sponza", 66_454)] {
        let Some(mesh) = models::load_model(name).unwrap() else {
            return;
        };
        assert_eq!(mesh.indices.len(), count, "{name}");
        assert!(mesh.bounds().is_finite());
        assert!(!mesh.groups.is_empty());
    }
}

#[test]
fn obvhs_matches_brute_force_on_the_teapot() {
    let Some(mesh) = models::load_model("teapot").unwrap() else {
        return;
    };
    let tris = mesh.triangles();
    let brute = BruteForce::build(&tris).unwrap();
    let sets = RaySets::generate("teapot", &tris, &brute, 48, 48, 1);
    assert!(!sets.shadow.is_empty() && !sets.diffuse.is_empty());
    let rays: Vec<TestRay> = sets.tagged();
    let obvhs = ObvhsBvh2::build(&tris).unwrap();
    obvhs.validate().unwrap();
    let report = conformance::compare(
        "teapot",
        &tris,
        &rays,
        &brute,
        &obvhs,
        conformance::Tolerance::EXACT,
    );
    assert!(
        report.is_ok(),
        "{:?}",
        report.mismatches.first().map(|m| m.to_string())
    );
    assert!(report.hits > 300, "{}", report.hits);
}
