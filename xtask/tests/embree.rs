//! Intel Embree 3 as rt's peer answers what rt answers (feature `embree`, Debian's
//! `libembree-dev`).
#![cfg(feature = "embree")]

use rt_geom::Vec3;
use rt_geom::{Accel, Ray, Triangle};
use xtask::embree::{EmbreeMode, EmbreeScene};

#[test]
fn embree_hits_what_rt_hits() {
    let tris = rt_testkit::scenes::random_soup(500, 3);
    let scene = EmbreeScene::build(&tris, 1, EmbreeMode::Robust).unwrap();
    agrees_with_brute_force(&tris, &scene);
    for mode in [EmbreeMode::Default, EmbreeMode::Medium] {
        agrees_with_brute_force(&tris, &EmbreeScene::build(&tris, 1, mode).unwrap());
    }
    // Embree's 8-wide packets answer as its single rays.
    let rays: Vec<Ray> = (0..101)
        .map(|i| {
            Ray::new(
                Vec3::new(0.5, 0.5, -2.0),
                Vec3::new(
                    (i % 10) as f32 / 10.0 - 0.5,
                    (i / 10) as f32 / 10.0 - 0.5,
                    2.0,
                ),
            )
        })
        .chain([Ray::new(Vec3::ZERO, Vec3::ZERO)])
        .collect();
    let mut hits = vec![None; rays.len()];
    let mut blocked = vec![false; rays.len()];
    rt_packet::PacketAccel::intersect_packet_group(&scene, &rays, &mut hits);
    rt_packet::PacketAccel::occluded_packet_group(&scene, &rays, &mut blocked);
    for (k, r) in rays.iter().enumerate() {
        assert_eq!(hits[k], scene.intersect(r), "ray {k}");
        assert_eq!(blocked[k], scene.occluded(r), "ray {k}");
    }
    let empty = EmbreeScene::build(&[], 1, EmbreeMode::Robust).unwrap();
    assert!(empty.intersect(&Ray::new(Vec3::ZERO, Vec3::X)).is_none());
    let nan = [Triangle::new(Vec3::NAN, Vec3::X, Vec3::Y)];
    assert!(EmbreeScene::build(&nan, 1, EmbreeMode::Robust).is_err());
}

/// Camera-like rays through a random soup: Embree's closest `t` within 1e-4 relative of
/// brute force's on all but a couple of rays, and `occluded` equal to a hit.
fn agrees_with_brute_force(tris: &[Triangle], scene: &EmbreeScene) {
    let brute = rt_geom::BruteForce::build(tris).unwrap();
    let mut agree = 0;
    for i in 0..400 {
        let o = Vec3::new(0.5, 0.5, -2.0);
        let d = Vec3::new(
            (i % 20) as f32 / 20.0 - 0.5,
            (i / 20) as f32 / 20.0 - 0.5,
            2.0,
        );
        let ray = Ray::new(o, d);
        let (a, b) = (scene.intersect(&ray), brute.intersect(&ray));
        assert_eq!(a.is_some(), scene.occluded(&ray));
        match (a, b) {
            (Some(a), Some(b)) => {
                assert!((a.t - b.t).abs() <= 1e-4 * b.t, "{a:?} {b:?}");
                agree += 1;
            }
            (None, None) => agree += 1,
            _ => {}
        }
    }
    assert!(agree >= 398, "{agree} of 400 agree");
}
