//! What a renderer asks of its queries, in one small scene: several geometries with ray
//! masks (a lamp's bulb seen by the camera but casting no shadow), a filter (an alpha
//! cut-out: a leaf with holes), hits naming geometry, primitive and normal, and every hit
//! along a ray.
//!
//! `cargo run -p rt-accel-bvh --example filters_masks_ids`

use rt_accel_bvh::TriBvh8;
use rt_geom::{FilteredAccel, Geometries, GeometryHit, Hit, Ray, Triangle, Vec3};
use std::ops::ControlFlow;

const CAMERA: u32 = 1;
const SHADOW: u32 = 2;

/// A square of side `2 * half` at height `z`, as two triangles.
fn square(half: f32, z: f32) -> [Triangle; 2] {
    let p = |x: f32, y: f32| Vec3::new(x * half, y * half, z);
    [
        Triangle::new(p(-1.0, -1.0), p(1.0, -1.0), p(1.0, 1.0)),
        Triangle::new(p(-1.0, -1.0), p(1.0, 1.0), p(-1.0, 1.0)),
    ]
}

fn main() {
    let mut scene = Geometries::new();
    let floor = scene.add(square(10.0, 0.0), CAMERA | SHADOW);
    let leaf = scene.add(square(2.0, 1.0), CAMERA | SHADOW);
    let bulb = scene.add(square(0.2, 3.0), CAMERA);
    let bvh = TriBvh8::build_for_tracing(scene.primitives()).expect("finite triangles");

    // The leaf's alpha: holes where the barycentric u of the hit is below 0.3.
    let mut alpha = |h: &GeometryHit| h.geometry != leaf || h.u >= 0.3;

    let down = |x: f32, y: f32| Ray::new(Vec3::new(x, y, 5.0), -Vec3::Z);
    for (x, y) in [(0.0, 0.0), (1.5, -1.5), (-1.5, 1.9), (5.0, 5.0)] {
        let ray = down(x, y);
        let seen = scene.intersect_filtered(&bvh, &ray, CAMERA, &mut alpha);
        let name = |h: &GeometryHit| ["floor", "leaf", "bulb"][h.geometry as usize];
        match seen {
            Some(h) => println!(
                "camera ray at ({x}, {y}): {} (triangle {}) at t = {}, normal {:?}",
                name(&h),
                h.prim,
                h.t,
                h.normal.unwrap_or_default()
            ),
            None => println!("camera ray at ({x}, {y}): nothing"),
        }
        // A shadow ray from the floor up to the light above the bulb: the bulb casts none,
        // and light passes the leaf's holes.
        let shadow = Ray::segment(Vec3::new(x, y, 0.0), Vec3::Z, 1e-3, 4.0);
        let lit = !scene.occluded_filtered(&bvh, &shadow, SHADOW, &mut alpha);
        println!(
            "  the floor below is {}",
            if lit { "lit" } else { "in shadow" }
        );
    }
    let _ = (floor, bulb);

    // Every hit along one ray, nearest first (transparency, volumes).
    let mut along = Vec::new();
    bvh.for_each_hit(&down(0.05, 0.0), &mut |h: &Hit| {
        along.push((scene.locate(h.prim), h.t));
        ControlFlow::Continue(())
    });
    println!("every hit along the ray at (0.05, 0): {along:?}");
}
