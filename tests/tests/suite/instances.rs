//! Two-level ray tracing against the same scene flattened into world-space triangles: the
//! conformance suite's instanced mode. Objects get every kind of structure; instances get
//! rotations, non-uniform scales, mirrors, overlaps and counts in the thousands.

use rt_accel_bvh::{Bvh, BvhParams, Instance, InstanceBvh, Object, Refit, TopUpdate, TriBvh8};
use rt_accel_kd::{KdParams, KdTree};
use rt_geom::glam::{Affine3A, Quat};
use rt_geom::{Accel, BruteForce, BuildError, Ray, Triangle, Vec3};
use rt_testkit::conformance::{Report, Tolerance, check_scene};
use rt_testkit::rays::RayKind;
use rt_testkit::{Rng, Scene, scenes};

/// The objects of the transformed scenes, each with another structure.
fn objects() -> (Vec<Vec<Triangle>>, Vec<Object>) {
    let geometry = vec![
        scenes::tessellated_sphere(300, Vec3::ZERO, 1.0),
        scenes::torus(400, 1.0, 0.3),
        scenes::random_soup(60, 7),
        scenes::planar_grid(4),
    ];
    let objects = vec![
        Object::build(&geometry[0], TriBvh8::build_for_tracing)
            .unwrap()
            .shared(),
        Object::build(&geometry[1], |p| Bvh::build(p, BvhParams::balanced()))
            .unwrap()
            .shared(),
        Object::build(&geometry[2], |p| KdTree::build(p, KdParams::sah()))
            .unwrap()
            .shared(),
        Object::build(&geometry[3], BruteForce::build)
            .unwrap()
            .shared(),
    ];
    (geometry, objects)
}

/// A rotation about a random axis, a scale per axis in [0.3, 3] (negative on x for a mirror)
/// and a translation.
fn random_transform(rng: &mut Rng, mirror: bool, spread: f32) -> Affine3A {
    let axis = rng.unit_vector();
    let angle = rng.range(0.0, std::f32::consts::TAU);
    let mut scale = Vec3::new(
        rng.range(0.3, 3.0),
        rng.range(0.3, 3.0),
        rng.range(0.3, 3.0),
    );
    if mirror {
        scale.x = -scale.x;
    }
    let at = Vec3::new(
        rng.range(-1.0, 1.0),
        rng.range(-1.0, 1.0),
        rng.range(-1.0, 1.0),
    ) * spread;
    Affine3A::from_scale_rotation_translation(scale, Quat::from_axis_angle(axis, angle), at)
}

/// The scene flattened instance by instance: the world-space triangles in the order of the
/// global primitive ids.
fn flatten(geometry: &[Vec<Triangle>], instances: &[Instance]) -> Vec<Triangle> {
    instances
        .iter()
        .flat_map(|inst| {
            geometry[inst.object as usize]
                .iter()
                .map(move |t| Triangle {
                    v: t.v.map(|p| inst.transform.transform_point3(p)),
                })
        })
        .collect()
}

/// Holds the instanced scene to brute force on its flattened form with
/// [`Tolerance::TRANSFORMED`]: no mismatch, and at most 1% of the rays of the general families
/// excused for hits within the rounding band of an edge or an interval's end (the families
/// aimed at edges, vertices and hit distances are excused as often as they land there).
fn conforms_flattened(
    name: &str,
    objects: &[Object],
    geometry: &[Vec<Triangle>],
    instances: &[Instance],
) -> Report {
    let flat = Scene::new(name, flatten(geometry, instances));
    let report = check_scene(
        &flat,
        |_| InstanceBvh::build(objects.to_vec(), instances, BvhParams::balanced()),
        Tolerance::TRANSFORMED,
    )
    .unwrap();
    let lines: Vec<String> = report.mismatches.iter().map(|m| format!("  {m}")).collect();
    assert!(
        report.is_ok(),
        "{} of {} rays disagree:\n{}",
        report.mismatch_count,
        report.rays,
        lines.join("\n")
    );
    assert_general_rays_agree(&report);
    assert!(
        report.hits * 4 > report.rays,
        "only {} hits in {} rays",
        report.hits,
        report.rays
    );
    report
}

/// Holds a scene updated in place (moved instances, a refit object) to brute force on its
/// flattened form, with [`Tolerance::TRANSFORMED`]: no mismatch.
fn updated_scene_conforms<O: Accel>(
    name: &str,
    geometry: &[Vec<Triangle>],
    instances: &[Instance],
    scene: InstanceBvh<O>,
) -> Report {
    let flat = Scene::new(name, flatten(geometry, instances));
    let once = std::cell::RefCell::new(Some(scene));
    let report = check_scene(
        &flat,
        |_| Ok::<_, BuildError>(once.borrow_mut().take().unwrap()),
        Tolerance::TRANSFORMED,
    )
    .unwrap();
    let first = report.mismatches.first().map(ToString::to_string);
    assert!(report.is_ok(), "{name}: {first:?}");
    report
}

/// At most 1% of the random, inside and aimed rays are excused.
fn assert_general_rays_agree(report: &Report) {
    for kind in [RayKind::Random, RayKind::Inside, RayKind::Aimed] {
        let excused = report.tolerated_by_kind.get(&kind).copied().unwrap_or(0);
        assert!(
            excused <= 4,
            "{excused} of 400 {kind:?} rays excused on {}",
            report.scene
        );
    }
}

#[test]
fn rotated_scaled_and_mirrored_instances_agree_with_the_flattened_scene() {
    let (geometry, objects) = objects();
    let mut rng = Rng::new(11);
    let mut instances: Vec<Instance> = (0..40)
        .map(|i| Instance {
            object: (i % 4) as u32,
            transform: random_transform(&mut rng, i % 3 == 0, 8.0),
        })
        .collect();
    // A small sphere inside the torus's box, and a soup inside the sphere's.
    let torus_at = Affine3A::from_scale_rotation_translation(
        Vec3::splat(4.0),
        Quat::from_rotation_x(0.3),
        Vec3::new(20.0, 0.0, 0.0),
    );
    instances.push(Instance {
        object: 1,
        transform: torus_at,
    });
    instances.push(Instance {
        object: 0,
        transform: Affine3A::from_scale_rotation_translation(
            Vec3::new(0.5, 0.8, -0.6),
            Quat::IDENTITY,
            Vec3::new(20.0, 0.0, 0.0),
        ),
    });
    instances.push(Instance {
        object: 2,
        transform: Affine3A::from_translation(Vec3::new(20.0, 0.5, 0.2)),
    });
    let report = conforms_flattened("transformed", &objects, &geometry, &instances);
    eprintln!(
        "transformed: {} rays, {} hits, excused near edges {:?}, max |dt| {}",
        report.rays, report.hits, report.tolerated_by_kind, report.max_dt
    );
}

#[test]
fn thousands_of_instances_of_one_small_object() {
    let object = scenes::tessellated_sphere(24, Vec3::ZERO, 0.4);
    let objects = vec![
        Object::build(&object, TriBvh8::build_for_tracing)
            .unwrap()
            .shared(),
    ];
    let mut rng = Rng::new(3);
    let instances: Vec<Instance> = (0..3000)
        .map(|i| {
            let cell = Vec3::new((i % 15) as f32, (i / 15 % 15) as f32, (i / 225) as f32);
            let t = random_transform(&mut rng, i % 2 == 0, 0.0);
            Instance {
                object: 0,
                transform: Affine3A {
                    translation: (cell * 1.5).into(),
                    ..t
                },
            }
        })
        .collect();
    let report = conforms_flattened(
        "thousands",
        &objects,
        std::slice::from_ref(&object),
        &instances,
    );
    eprintln!(
        "thousands: {} rays, {} hits, excused {:?}, max |dt| {}",
        report.rays, report.hits, report.tolerated_by_kind, report.max_dt
    );
    // The object is stored once: the scene takes far less than 3000 copies of it.
    let scene = InstanceBvh::build(objects.clone(), &instances, BvhParams::balanced()).unwrap();
    let (one, all) = (objects[0].accel().stats().bytes, scene.stats().bytes);
    assert_eq!(scene.stats().primitives, 3000 * object.len());
    assert!(
        all < one + 3000 * 256,
        "{all} bytes for 3000 instances of a {one}-byte object"
    );
}

#[test]
fn untransformed_objects_answer_exactly_like_the_flat_scene() {
    // Every conformance scene cut into objects of 100 consecutive triangles, each placed by
    // the identity: a top level over per-object structures, bit for bit the flat answers
    // (the identity transform is exact, and global ids keep the flat order for ties).
    for scene in scenes::conformance_triangle_scenes() {
        let chunks: Vec<Vec<Triangle>> =
            scene.prims.chunks(100).map(<[Triangle]>::to_vec).collect();
        let objects: Vec<Object> = chunks
            .iter()
            .map(|c| {
                Object::build(c, TriBvh8::build_for_tracing)
                    .unwrap()
                    .shared()
            })
            .collect();
        let instances: Vec<Instance> = (0..objects.len() as u32)
            .map(|object| Instance {
                object,
                transform: Affine3A::IDENTITY,
            })
            .collect();
        rt_testkit::conformance::assert_conforms(&scene, |_| {
            InstanceBvh::build(objects.clone(), &instances, BvhParams::balanced())
        });
    }
}

#[test]
fn hits_name_the_instance_and_the_object_primitive() {
    let (geometry, objects) = objects();
    let mut rng = Rng::new(5);
    let instances: Vec<Instance> = (0..12)
        .map(|i| Instance {
            object: (i % 4) as u32,
            transform: random_transform(&mut rng, i % 2 == 1, 6.0),
        })
        .collect();
    let scene = InstanceBvh::build(objects, &instances, BvhParams::balanced()).unwrap();
    let mut hits = 0;
    for _ in 0..2000 {
        // From anywhere towards an instance's origin, give or take a unit.
        let origin = rng.point_in(Vec3::splat(-12.0), Vec3::splat(12.0));
        let aim = instances[rng.below(instances.len())].transform.translation;
        let ray = Ray::new(origin, Vec3::from(aim) + rng.unit_vector() - origin);
        let (Some(global), Some(local)) = (scene.intersect(&ray), scene.intersect_instance(&ray))
        else {
            assert!(scene.intersect_instance(&ray).is_none());
            continue;
        };
        hits += 1;
        let inst = instances[local.instance as usize];
        assert_eq!(
            scene.first_primitive(local.instance) + local.hit.prim,
            global.prim
        );
        assert_eq!(local.hit.t, global.t);
        // The object's primitive, moved by the instance's transform, is hit there.
        let tri = geometry[inst.object as usize][local.hit.prim as usize];
        let world = Triangle {
            v: tri.v.map(|p| inst.transform.transform_point3(p)),
        };
        let h = world
            .intersect_watertight(&ray)
            .expect("the named primitive is hit");
        assert!(
            (h.t - global.t).abs() <= 1e-4 * h.t.max(1.0),
            "{h:?} {global:?}"
        );
    }
    assert!(hits > 1000, "{hits}");
}

#[test]
fn moving_instances_refit_or_rebuild_the_top_level() {
    let (geometry, objects) = objects();
    let mut rng = Rng::new(8);
    let instances: Vec<Instance> = (0..30)
        .map(|i| Instance {
            object: (i % 4) as u32,
            transform: random_transform(&mut rng, false, 8.0),
        })
        .collect();
    for update in [TopUpdate::Refit, TopUpdate::Rebuild] {
        let mut scene =
            InstanceBvh::build(objects.clone(), &instances, BvhParams::balanced()).unwrap();
        let moved: Vec<Affine3A> = (0..30)
            .map(|i| random_transform(&mut rng, i % 3 == 0, 12.0))
            .collect();
        scene.set_transforms(&moved, update).unwrap();
        let now: Vec<Instance> = instances
            .iter()
            .zip(&moved)
            .map(|(i, &transform)| Instance { transform, ..*i })
            .collect();
        assert_eq!(scene.instances(), &now[..]);
        let report = updated_scene_conforms(&format!("moved {update:?}"), &geometry, &now, scene);
        assert_general_rays_agree(&report);
    }
}

#[test]
fn a_deforming_object_refits_its_structure_and_the_top_level() {
    let geometry = scenes::tessellated_sphere(500, Vec3::ZERO, 1.0);
    let objects = vec![Object::build(&geometry, TriBvh8::build_for_tracing).unwrap()];
    let instances: Vec<Instance> = (0..5)
        .map(|i| Instance {
            object: 0,
            transform: Affine3A::from_translation(Vec3::new(3.0 * i as f32, 0.0, 0.0)),
        })
        .collect();
    let mut scene: InstanceBvh<TriBvh8> =
        InstanceBvh::build(objects, &instances, BvhParams::balanced()).unwrap();
    // A ripple that also stretches the object to twice its height.
    let rippled: Vec<Triangle> = geometry
        .iter()
        .map(|t| Triangle {
            v: t.v
                .map(|p| Vec3::new(p.x, 2.0 * p.y + 0.2 * (5.0 * p.x).sin(), p.z)),
        })
        .collect();
    scene.refit_object(0, &rippled, TopUpdate::Refit).unwrap();
    scene.validate().unwrap();
    updated_scene_conforms("rippled", std::slice::from_ref(&rippled), &instances, scene);
    // Bad refits leave the scene unchanged.
    let mut scene: InstanceBvh<TriBvh8> = InstanceBvh::build(
        vec![Object::build(&geometry, TriBvh8::build_for_tracing).unwrap()],
        &instances,
        BvhParams::balanced(),
    )
    .unwrap();
    let probe = Ray::new(Vec3::new(0.1, 0.1, -5.0), Vec3::Z);
    let before = scene.intersect(&probe);
    assert!(before.is_some());
    let mut bad = rippled.clone();
    bad[7].v[2].z = f32::INFINITY;
    assert_eq!(
        scene.refit_object(0, &bad, TopUpdate::Refit),
        Err(BuildError::NonFinite { prim: 7 })
    );
    assert!(
        scene
            .refit_object(0, &rippled[1..], TopUpdate::Rebuild)
            .unwrap_err()
            .to_string()
            .contains("primitive count")
    );
    assert!(
        scene
            .refit_object(3, &rippled, TopUpdate::Refit)
            .unwrap_err()
            .to_string()
            .contains("object")
    );
    assert_eq!(scene.intersect(&probe), before);
    scene.validate().unwrap();
    // A structure that cannot be refit through the trait is a compile error, not a run-time one.
    fn refits<O: Refit<Triangle>>() {}
    refits::<TriBvh8>();
}

#[test]
fn bad_instances_get_clear_errors() {
    let (_, objects) = objects();
    let build = |t: Affine3A, object: u32| {
        InstanceBvh::build(
            objects.clone(),
            &[Instance {
                object,
                transform: t,
            }],
            BvhParams::balanced(),
        )
    };
    let singular = build(Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0)), 0).unwrap_err();
    assert!(singular.to_string().contains("invertible"), "{singular}");
    let mut nan = Affine3A::IDENTITY;
    nan.translation.y = f32::NAN;
    assert!(build(nan, 0).unwrap_err().to_string().contains("finite"));
    let inf = Affine3A::from_scale(Vec3::splat(f32::INFINITY));
    assert!(build(inf, 0).is_err());
    let missing = build(Affine3A::IDENTITY, 9).unwrap_err();
    assert!(missing.to_string().contains("object"), "{missing}");
    let far = build(Affine3A::from_translation(Vec3::splat(1e19)), 0).unwrap_err();
    assert!(matches!(far, BuildError::OutOfRange { .. }), "{far}");
    // Moving: a count mismatch or a singular transform leaves the scene as it was.
    let mut scene = build(Affine3A::IDENTITY, 0).unwrap();
    let probe = Ray::new(Vec3::new(0.1, 0.2, -5.0), Vec3::Z);
    let before = scene.intersect(&probe);
    assert!(before.is_some());
    assert!(scene.set_transforms(&[], TopUpdate::Refit).is_err());
    assert!(
        scene
            .set_transforms(&[Affine3A::from_scale(Vec3::ZERO)], TopUpdate::Rebuild)
            .is_err()
    );
    assert_eq!(scene.intersect(&probe), before);
    // No instances, and instances of an empty object: a scene that misses every ray.
    let empty = InstanceBvh::build(objects.clone(), &[], BvhParams::balanced()).unwrap();
    assert!(empty.intersect(&probe).is_none());
    let nothing = vec![
        Object::build(&[] as &[Triangle], TriBvh8::build_for_tracing)
            .unwrap()
            .shared(),
    ];
    let hollow = InstanceBvh::build(
        nothing,
        &[Instance {
            object: 0,
            transform: Affine3A::IDENTITY,
        }],
        BvhParams::balanced(),
    )
    .unwrap();
    assert!(hollow.intersect(&probe).is_none());
    hollow.validate().unwrap();
    // Objects whose structures have no filtered queries (a peer's): the scene's filtered
    // queries could not go through them, so the build refuses them; rt's structures say they
    // filter, behind `dyn Accel` too.
    let tris = scenes::random_soup(10, 1);
    let plain = BruteForce::build(&tris).unwrap();
    let peer = Object::new(&tris, rt_testkit::Unfiltered(&plain)).unwrap();
    let at = [Instance {
        object: 0,
        transform: Affine3A::IDENTITY,
    }];
    let refused = InstanceBvh::build(vec![peer], &at, BvhParams::balanced()).unwrap_err();
    assert!(
        refused.to_string().contains("filtered queries"),
        "{refused}"
    );
    let boxed: Box<dyn Accel> = Box::new(plain.clone());
    assert!(boxed.filtered().is_some());
    let own = Object::new(&tris, boxed).unwrap();
    let scene = InstanceBvh::build(vec![own], &at, BvhParams::balanced()).unwrap();
    assert!(scene.filtered().is_some());
}

/// Filtered queries and every hit through instances, against brute force asked the same
/// question instance by instance in each object's space (the ray carried there as the
/// scene carries it, so the answers are exact): the filter sees global ids.
#[test]
fn filters_and_all_hits_through_instances() {
    use rt_geom::{FilteredAccel, Hit, Keep, sorted_hits};
    use rt_testkit::conformance::FILTERS;
    let (geometry, objects) = objects();
    let mut rng = Rng::new(5);
    let instances: Vec<Instance> = (0..24)
        .map(|i| Instance {
            object: (i % 4) as u32,
            transform: random_transform(&mut rng, i % 3 == 0, 4.0),
        })
        .collect();
    let scene = InstanceBvh::build(objects, &instances, BvhParams::balanced()).unwrap();
    let brutes: Vec<BruteForce<Triangle>> = geometry
        .iter()
        .map(|g| BruteForce::build(g).unwrap())
        .collect();
    let mut first = Vec::new();
    let mut at = 0;
    for inst in &instances {
        first.push(at);
        at += geometry[inst.object as usize].len() as u32;
    }
    let n = at;
    // Every instance's object asked in its own space, each hit offered with its global id.
    let reference = |ray: &Ray, filter: &mut dyn rt_geom::HitFilter, any: bool| {
        let mut best: Option<Hit> = None;
        let mut all = Vec::new();
        for (i, inst) in instances.iter().enumerate() {
            if filter.skips_instance(i as u32) {
                continue;
            }
            let to_object = inst.transform.inverse();
            let tmax = if any {
                ray.tmax
            } else {
                best.map_or(ray.tmax, |b| b.t)
            };
            let local = Ray::segment(
                to_object.transform_point3(ray.origin()),
                to_object.transform_vector3(ray.dir()),
                ray.tmin,
                tmax,
            );
            let brute = &brutes[inst.object as usize];
            let mut global = |h: &Hit| {
                let g = Hit {
                    prim: first[i] + h.prim,
                    ..*h
                };
                all.push(g);
                filter.accepts(&g)
            };
            if let Some(h) = brute.intersect_filtered(&local, &mut global) {
                let h = Hit {
                    prim: first[i] + h.prim,
                    ..h
                };
                if any {
                    return (Some(h), all);
                }
                let mut t = tmax;
                let ph = rt_geom::PrimHit {
                    t: h.t,
                    u: h.u,
                    v: h.v,
                };
                best.record::<false>(ph, h.prim, &mut t);
            }
        }
        (best, all)
    };
    let mut checked = 0;
    for k in 0..600 {
        let o = Vec3::new(
            rng.range(-6.0, 6.0),
            rng.range(-6.0, 6.0),
            rng.range(-6.0, 6.0),
        );
        let target = if k % 2 == 0 {
            Vec3::new(
                rng.range(-3.0, 3.0),
                rng.range(-3.0, 3.0),
                rng.range(-3.0, 3.0),
            )
        } else {
            Vec3::ZERO
        };
        let ray = Ray::new(o, target - o);
        let closest = scene.intersect(&ray);
        assert_eq!(
            closest,
            reference(&ray, &mut |_: &Hit| true, false).0,
            "ray {ray:?}"
        );
        for (name, accept) in FILTERS {
            let mut filter = |h: &Hit| accept(h, closest, n);
            let (want, _) = reference(&ray, &mut filter, false);
            let got = scene.intersect_filtered(&ray, &mut filter);
            assert_eq!(got, want, "intersect_filtered ({name}), ray {ray:?}");
            let (want_any, _) = reference(&ray, &mut filter, true);
            let got_any = scene.occluded_filtered(&ray, &mut filter);
            assert_eq!(
                got_any,
                want_any.is_some(),
                "occluded_filtered ({name}), ray {ray:?}"
            );
        }
        // Instance masks: instance i has bit i % 3; the query's mask picks some.
        let instance_masks: Vec<u32> = (0..instances.len()).map(|i| 1 << (i % 3)).collect();
        for ray_mask in [0b001, 0b110, 0] {
            let mut masked = rt_geom::Masked {
                prims: &[],
                instances: &instance_masks,
                ray: ray_mask,
                inner: |_: &Hit| true,
            };
            let (want, _) = reference(&ray, &mut masked, false);
            assert_eq!(
                scene.intersect_filtered(&ray, &mut masked),
                want,
                "mask {ray_mask:#b}"
            );
            let (want_any, _) = reference(&ray, &mut masked, true);
            let got_any = scene.occluded_filtered(&ray, &mut masked);
            assert_eq!(got_any, want_any.is_some(), "occluded, mask {ray_mask:#b}");
        }
        let (_, all) = reference(&ray, &mut |_: &Hit| false, false);
        let mut got = Vec::new();
        scene.for_each_hit(&ray, &mut |h| {
            got.push(*h);
            std::ops::ControlFlow::Continue(())
        });
        assert_eq!(got, sorted_hits(all), "for_each_hit, ray {ray:?}");
        checked += got.len();
    }
    assert!(
        checked > 600,
        "{checked} hits: the rays must meet the instances"
    );
}
