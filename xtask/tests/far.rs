//! `cargo xtask far` on a small mesh: the cell structures, the BSP tree and the BVH and
//! kd-tree answer as brute force does with the mesh at 5e6 (where `f32` steps by 0.5) and
//! at the origin, and the table names each.

use rt_geom::Vec3;
use xtask::far::{FarOptions, markdown, run};
use xtask::registry;

#[test]
fn every_kind_of_structure_answers_exactly_far_from_the_origin() {
    let mesh = rt_testkit::scenes::tessellated_sphere(4000, Vec3::ZERO, 1.0);
    let names = "grid,grid2,grid-adaptive,octree,bsp,kd,bvh8-tri";
    let entries = registry::select(Some(names)).unwrap();
    let options = FarOptions {
        sizes: vec![1.5, 30.0],
        offsets: vec![5.0e6],
        side: 32,
        threads: 2,
        repeat: 1,
    };
    let rows = run(&mesh, &entries, &options, &|_| {}).unwrap();
    assert_eq!(rows.len(), entries.len() * 2);
    for r in &rows {
        assert!(r.origin.error.is_none() && r.far.error.is_none(), "{r:?}");
        assert_eq!(
            (r.origin.differ, r.far.differ),
            (0, 0),
            "{} at size {}: rays differing from brute force at the origin and far away",
            r.accel,
            r.size
        );
    }
    let table = markdown(&rows);
    assert!(
        names
            .split(',')
            .all(|n| table.contains(&format!("| {n} |")))
    );
}

#[test]
fn placements_beyond_the_coordinate_range_are_an_error() {
    let mesh = rt_testkit::scenes::tessellated_sphere(100, Vec3::ZERO, 1.0);
    let entries = registry::select(Some("grid")).unwrap();
    let options = FarOptions {
        sizes: vec![1.0],
        offsets: vec![2.0e18],
        side: 4,
        threads: 1,
        repeat: 1,
    };
    let err = run(&mesh, &entries, &options, &|_| {}).unwrap_err();
    assert!(err.contains("placed mesh"), "{err}");
}
