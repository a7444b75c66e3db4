//! Several geometries in one structure: masks per geometry and query, hits naming the
//! geometry, the primitive in it and the normal, through structures of every family, against
//! brute force asked the same.

use rt_accel_bvh::{Bvh8, BvhParams};
use rt_accel_kd::{KdParams, KdTree};
use rt_geom::{BruteForce, FilteredAccel, Geometries, Ray, Shape, Vec3};
use rt_testkit::{Rng, scenes};

/// Four geometries of shapes (triangle soups, spheres, cones), masks of one bit each but the
/// last, which has two.
fn scene() -> Geometries<Shape> {
    let mut g = Geometries::new();
    g.add(
        scenes::random_soup(120, 3).into_iter().map(Shape::from),
        0b0001,
    );
    g.add(
        scenes::random_spheres(60, 4).into_iter().map(Shape::from),
        0b0010,
    );
    g.add(scenes::mixed_shapes(80, 5), 0b0100);
    g.add(
        scenes::random_soup(90, 6).into_iter().map(Shape::from),
        0b1001,
    );
    g
}

#[test]
fn masks_ids_and_normals_agree_with_brute_force() {
    let mut g = scene();
    let structures: Vec<(&str, Box<dyn FilteredAccel>)> = vec![
        (
            "bvh8",
            Box::new(Bvh8::build(g.primitives(), BvhParams::balanced()).unwrap()),
        ),
        (
            "kd",
            Box::new(KdTree::build(g.primitives(), KdParams::sah()).unwrap()),
        ),
        (
            "grid",
            Box::new(
                rt_accel_grid::Grid::build(g.primitives(), rt_accel_grid::GridParams::default())
                    .unwrap(),
            ),
        ),
    ];
    let brute = BruteForce::build(g.primitives()).unwrap();
    let mut rng = Rng::new(9);
    let mut hits = [0usize; 4];
    for k in 0..1500 {
        if k == 750 {
            // Masks change without a rebuild.
            g.set_mask(2, 0b1000);
        }
        let o = rng.point_in(Vec3::splat(-0.5), Vec3::splat(1.5));
        let ray = Ray::new(o, rng.point_in(Vec3::ZERO, Vec3::ONE) - o);
        for mask in [u32::MAX, 0b0001, 0b0110, 0b1000, 0] {
            let want = g.intersect(&brute, &ray, mask);
            if let Some(h) = want {
                hits[h.geometry as usize] += 1;
                assert!(g.mask(h.geometry) & mask != 0);
                let n = h.normal.expect("shapes have normals");
                assert!((n.length() - 1.0).abs() < 1e-4, "normal {n}");
            }
            for (name, accel) in &structures {
                let got = g.intersect(accel.as_ref(), &ray, mask);
                assert_eq!(got, want, "{name}, mask {mask:#b}, ray {ray:?}");
                assert_eq!(
                    g.occluded(accel.as_ref(), &ray, mask),
                    want.is_some(),
                    "{name}"
                );
            }
        }
    }
    assert!(hits.iter().all(|&n| n > 20), "hits per geometry: {hits:?}");
    // Located ids name the primitive in its geometry.
    let prims = g.primitives();
    let mut at = 0;
    for geometry in 0..g.len() as u32 {
        let mut n = 0;
        while at < prims.len() && g.locate(at as u32).0 == geometry {
            assert_eq!(g.locate(at as u32), (geometry, n));
            (at, n) = (at + 1, n + 1);
        }
        assert!(n > 0);
    }
}

/// A filter on geometry hits: the hit it rejects lets the ray go on.
#[test]
fn a_filter_sees_geometry_hits() {
    let g = scene();
    let accel = Bvh8::build(g.primitives(), BvhParams::balanced()).unwrap();
    let brute = BruteForce::build(g.primitives()).unwrap();
    let mut rng = Rng::new(2);
    let mut went_on = 0;
    for _ in 0..2000 {
        let o = rng.point_in(Vec3::splat(-0.5), Vec3::splat(1.5));
        let ray = Ray::new(o, rng.point_in(Vec3::ZERO, Vec3::ONE) - o);
        let mut no_spheres = |h: &rt_geom::GeometryHit| h.geometry != 1;
        let want = g.intersect_filtered(&brute, &ray, u32::MAX, &mut no_spheres);
        let got = g.intersect_filtered(&accel, &ray, u32::MAX, &mut no_spheres);
        assert_eq!(got, want, "ray {ray:?}");
        let want = g.occluded_filtered(&brute, &ray, 0b0111, &mut no_spheres);
        assert_eq!(
            g.occluded_filtered(&accel, &ray, 0b0111, &mut no_spheres),
            want
        );
        let plain = g.intersect(&accel, &ray, u32::MAX);
        if plain.is_some_and(|h| h.geometry == 1) && got.is_some() {
            went_on += 1;
        }
    }
    assert!(
        went_on > 10,
        "{went_on} rays went on past a rejected sphere"
    );
}
