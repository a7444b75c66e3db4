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

/// Objects of several geometries placed by instances: the hit names the instance, the
/// geometry of its object and the primitive in it, with the normal in world space, and masks
/// per geometry and per instance hold; objects built with BVHs and kd-trees answer what
/// objects answered by brute force answer, and the names agree with a table of the
/// flattened scene.
#[test]
fn instanced_geometries_name_instance_geometry_and_primitive() {
    use rt_accel_bvh::{Instance, InstanceBvh, Object};
    use rt_geom::glam::{Affine3A, Quat};
    let mut objects = vec![Geometries::new(), Geometries::new()];
    let soup = |n, seed| scenes::random_soup(n, seed).into_iter().map(Shape::from);
    let spheres = |n, seed| scenes::random_spheres(n, seed).into_iter().map(Shape::from);
    objects[0].add(soup(80, 21), 0b001);
    objects[0].add(spheres(30, 22), 0b010);
    objects[1].add(spheres(20, 23), 0b100);
    objects[1].add(soup(50, 24), 0b011);
    let mut rng = Rng::new(5);
    let instances: Vec<Instance> = (0..5)
        .map(|i| {
            let axis = rng.unit_vector();
            let rotation = Quat::from_axis_angle(axis, rng.range(0.0, 6.0));
            let scale = Vec3::new(rng.range(0.5, 2.0), rng.range(0.5, 2.0), 1.0);
            let at = rng.point_in(Vec3::splat(-2.0), Vec3::splat(2.0));
            Instance {
                object: i % 2,
                transform: Affine3A::from_scale_rotation_translation(scale, rotation, at),
            }
        })
        .collect();
    let instance_masks = [u32::MAX, 0b001, u32::MAX, 0b110];
    let scene = |exact: bool| {
        let built: Vec<Object> = objects
            .iter()
            .enumerate()
            .map(|(o, g)| {
                let p = g.primitives();
                let object = match (exact, o) {
                    (true, _) => Object::build(p, BruteForce::build).map(Object::shared),
                    (false, 0) => Object::build(p, |p| Bvh8::build(p, BvhParams::balanced()))
                        .map(Object::shared),
                    (false, _) => {
                        Object::build(p, |p| KdTree::build(p, KdParams::sah())).map(Object::shared)
                    }
                };
                object.unwrap()
            })
            .collect();
        InstanceBvh::build(built, &instances, BvhParams::balanced()).unwrap()
    };
    let (exact, subject) = (scene(true), scene(false));
    let want_of = exact.with_geometries(&objects, &instance_masks).unwrap();
    let got_of = subject.with_geometries(&objects, &instance_masks).unwrap();
    // The flattened scene's table: per global id, (instance, geometry, primitive, its mask).
    let mut table = Vec::new();
    for (i, inst) in instances.iter().enumerate() {
        let g = &objects[inst.object as usize];
        for p in 0..g.primitives().len() as u32 {
            let (geometry, prim) = g.locate(p);
            table.push((i as u32, geometry, prim, g.prim_mask(p)));
        }
    }
    let mut named = 0;
    for _ in 0..3000 {
        let o = rng.point_in(Vec3::splat(-4.0), Vec3::splat(4.0));
        let ray = Ray::new(o, rng.point_in(Vec3::splat(-1.0), Vec3::splat(1.0)) - o);
        for mask in [u32::MAX, 0b001, 0b110, 0b100, 0] {
            let want = want_of.intersect(&ray, mask);
            assert_eq!(
                got_of.intersect(&ray, mask),
                want,
                "mask {mask:#b}, {ray:?}"
            );
            assert_eq!(got_of.occluded(&ray, mask), want.is_some());
            // The same hit through a filter reading the table.
            let seen = |h: &rt_geom::Hit| {
                let (i, _, _, m) = table[h.prim as usize];
                m & mask != 0
                    && instance_masks
                        .get(i as usize)
                        .is_none_or(|im| im & mask != 0)
            };
            let plain = exact.intersect_filtered(&ray, &mut { seen });
            assert_eq!(plain.map(|h| h.t), want.map(|h| h.hit.t));
            let (Some(h), Some(p)) = (want, plain) else {
                continue;
            };
            let (instance, geometry, prim, _) = table[p.prim as usize];
            assert_eq!(
                (h.instance, h.hit.geometry, h.hit.prim),
                (instance, geometry, prim)
            );
            let n = h.hit.normal.expect("shapes have normals");
            assert!((n.length() - 1.0).abs() < 1e-4, "normal {n}");
            // A triangle's normal is its world-space triangle's, up to orientation.
            let inst = &instances[instance as usize];
            let first = table.iter().position(|t| t.0 == instance).unwrap();
            let local = objects[inst.object as usize].primitives()[p.prim as usize - first];
            if let Shape::Triangle(t) = local {
                let world = rt_geom::Triangle {
                    v: t.v.map(|v| inst.transform.transform_point3(v)),
                };
                assert!(
                    world.normal().dot(n).abs() > 0.999,
                    "{n} vs {}",
                    world.normal()
                );
                named += 1;
            }
        }
    }
    assert!(named > 100, "{named} triangle hits checked");
}
