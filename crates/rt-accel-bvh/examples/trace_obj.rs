//! Loads an OBJ mesh, builds the 8-wide triangle BVH with the preset that traces fastest, shoots
//! a pinhole camera's rays at it and prints what they hit.
//!
//! ```sh
//! cargo run --release -p rt-accel-bvh --example trace_obj -- [MESH.obj] [SIDE]
//! ```
//!
//! Without arguments it traces the octahedron in `assets/` at 512x512.

use rt_accel_bvh::TriBvh8;
use rt_geom::{Accel, Ray, Vec3};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = args.next().unwrap_or_else(|| {
        concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/octahedron.obj").to_string()
    });
    let side: u32 = args.next().map(|s| s.parse()).transpose()?.unwrap_or(512);
    if side == 0 || side > 16384 {
        return Err(format!("SIDE must be 1..=16384, not {side}").into());
    }

    let mesh = rt_geom::load_obj(&path)?;
    let tris = mesh.triangles();
    let start = Instant::now();
    let bvh = TriBvh8::build_for_tracing(&tris)?;
    let build = start.elapsed();

    // A pinhole on the +z side of the mesh's box, looking down -z, its view just holding the box.
    let bounds = mesh.bounds();
    let (center, radius) = (bounds.center(), bounds.extent().length() * 0.5);
    let eye = center + Vec3::new(0.0, 0.0, 2.5 * radius);
    let half = 0.5 / side as f32;
    let rays: Vec<Ray> = (0..side * side)
        .map(|i| {
            let (x, y) = (
                (i % side) as f32 / side as f32 + half,
                (i / side) as f32 / side as f32 + half,
            );
            let target =
                center + Vec3::new((2.0 * x - 1.0) * radius, (1.0 - 2.0 * y) * radius, 0.0);
            Ray::new(eye, target - eye)
        })
        .collect();

    let start = Instant::now();
    let hits: Vec<_> = rays.iter().map(|r| bvh.intersect(r)).collect();
    let trace = start.elapsed();
    let hit_count = hits.iter().flatten().count();
    let nearest = hits.iter().flatten().min_by(|a, b| a.t.total_cmp(&b.t));

    println!(
        "{path}: {} triangles, built in {:.1} ms ({:.1} bytes per triangle)",
        tris.len(),
        build.as_secs_f64() * 1e3,
        bvh.stats().bytes as f64 / tris.len().max(1) as f64
    );
    println!(
        "{} rays, {hit_count} hit, {:.2} Mrays/s on one thread",
        rays.len(),
        rays.len() as f64 / trace.as_secs_f64() / 1e6
    );
    if let Some(h) = nearest {
        println!("nearest hit: triangle {} at t = {}", h.prim, h.t);
    }
    Ok(())
}
