//! Generated packets against single rays: for every packet traversal (BVH2, BVH4, BVH8, the
//! kd-tree, multi-level ray tracing), on generated scenes and packets whose lanes are switched
//! off by an arbitrary mask, every active lane answers exactly as its single ray does and
//! every inactive lane stays inactive and misses. A failure shrinks to a minimal case.
//! Cases per property: 128, or `PROPTEST_CASES`. (A unit-test module rather than an
//! integration test: it shares the packet walks the other tests compile.)

use crate::{MlrtaKdTree, PacketTraversal, RayPacket};
use proptest::prelude::*;
use rt_accel_bvh::{Bvh, Bvh4, Bvh8, BvhParams};
use rt_accel_kd::{KdParams, KdTree};
use rt_geom::{Accel, Ray, Triangle, Vec3};
use rt_testkit::props::config;

fn point() -> impl Strategy<Value = Vec3> {
    rt_testkit::props::point(6, 4.0)
}

/// Up to 40 triangles with shared lattice vertices, degenerate and duplicate ones among them.
fn scene() -> impl Strategy<Value = Vec<Triangle>> {
    prop::collection::vec(
        prop_oneof![
            6 => (point(), point(), point()).prop_map(|(a, b, c)| Triangle::new(a, b, c)),
            1 => point().prop_map(|a| Triangle::new(a, a, a)),
            1 => (point(), point()).prop_map(|(a, b)| Triangle::new(a, b, (a + b) * 0.5)),
        ],
        1..40,
    )
    .prop_map(|mut tris| {
        // A duplicate of the first triangle: coincident hits, ties broken by id.
        tris.push(tris[0]);
        tris
    })
}

/// 16 rays: from one origin (coherent, as a camera's) or from anywhere, some with intervals.
fn rays() -> impl Strategy<Value = Vec<Ray>> {
    (
        point(),
        any::<bool>(),
        prop::collection::vec((point(), point(), 0u8..4), 16),
    )
        .prop_map(|(eye, coherent, lanes)| {
            lanes
                .into_iter()
                .map(|(o, aim, interval)| {
                    let origin = if coherent {
                        eye + Vec3::new(0.0, 0.0, -8.0)
                    } else {
                        o * 2.0
                    };
                    let ray = Ray::new(origin, aim - origin);
                    match interval {
                        1 => ray.with_range(0.5, 1.0),
                        2 => ray.with_range(-1.0, 0.9),
                        3 => ray.with_range(1.0, 0.5),
                        _ => ray,
                    }
                })
                .collect()
        })
}

/// Runs both packet queries with the lanes off in `mask` switched off, and checks every lane.
fn check<A: PacketTraversal + Accel>(
    name: &str,
    accel: &A,
    rays: &[Ray],
    mask: u16,
) -> Result<(), TestCaseError> {
    let off = |i: usize| mask & (1 << i) != 0;
    // A packet of the rays with the lanes of `mask` switched off, as a fill leaves them.
    let masked = || {
        let mut packet = RayPacket::<16>::new(rays);
        for i in (0..16).filter(|&i| off(i)) {
            packet.active[i] = false;
            packet.tmax[i] = f32::NEG_INFINITY;
        }
        packet
    };
    let mut packet = masked();
    let hits = accel.intersect_packet(&mut packet);
    for (i, ray) in rays.iter().enumerate() {
        if off(i) {
            prop_assert!(
                hits[i].is_none() && !packet.active[i],
                "{name}: inactive lane {i} touched"
            );
        } else {
            prop_assert_eq!(
                hits[i],
                accel.intersect(ray),
                "{}: lane {} intersect",
                name,
                i
            );
        }
    }
    let mut packet = masked();
    let blocked = accel.occluded_packet(&mut packet);
    for (i, ray) in rays.iter().enumerate() {
        if off(i) {
            prop_assert!(
                !blocked[i] && !packet.active[i],
                "{name}: inactive lane {i} touched"
            );
        } else {
            prop_assert_eq!(
                blocked[i],
                accel.occluded(ray),
                "{}: lane {} occluded",
                name,
                i
            );
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(config(128))]

    #[test]
    fn active_lanes_answer_as_single_rays(tris in scene(), rays in rays(), mask in any::<u16>()) {
        check("bvh", &Bvh::build(&tris, BvhParams::balanced()).unwrap(), &rays, mask)?;
        check("bvh-fast", &Bvh::build(&tris, BvhParams::fast()).unwrap(), &rays, mask)?;
        check("bvh4", &Bvh4::build(&tris, BvhParams::balanced()).unwrap(), &rays, mask)?;
        check("bvh8", &Bvh8::build(&tris, BvhParams::spatial()).unwrap(), &rays, mask)?;
        let kd = KdTree::build(&tris, KdParams::wald_havran()).unwrap();
        check("kd", &kd, &rays, mask)?;
        check("kd-mlrta", &MlrtaKdTree::new(kd), &rays, mask)?;
    }
}
