//! Saved structures against rebuilding: builds `TriBvh8` (the fastest-tracing preset and the
//! spatial-split one) over a mesh, saves each, loads it back (checks included) and compares
//! the times and the answers.
//!
//! `cargo run --release -p rt-accel-bvh --example save_load -- MESH.obj [OUT_DIR]`

use rt_accel_bvh::{BvhParams, TriBvh8};
use rt_geom::{Accel, Ray, Vec3};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = args.next().ok_or("usage: save_load MESH.obj [OUT_DIR]")?;
    let out_dir = args.next();
    let tris = rt_geom::load_obj(&path)?.triangles();
    let b = rt_geom::Aabb::around(&tris);
    let rays: Vec<Ray> = (0..100_000u32)
        .map(|i| {
            let f = |k: u32| ((i.wrapping_mul(k) >> 8) & 0xffff) as f32 / 65535.0;
            let o =
                b.center() + b.extent() * Vec3::new(f(2654435761) - 0.5, f(2246822519) - 0.5, 1.5);
            let target = b.min + b.extent() * Vec3::new(f(3266489917), f(668265263), f(374761393));
            Ray::new(o, target - o)
        })
        .collect();
    for (name, params) in [
        ("fastest_trace", BvhParams::fastest_trace()),
        ("spatial", BvhParams::spatial().for_soa_leaves()),
    ] {
        let t = Instant::now();
        let built = TriBvh8::build(&tris, params)?;
        let build_s = t.elapsed().as_secs_f64();
        let bytes = built.to_bytes();
        if let Some(dir) = &out_dir {
            std::fs::write(format!("{dir}/{name}.rtbvh"), &bytes)?;
        }
        let t = Instant::now();
        let loaded = TriBvh8::from_bytes(&bytes, &tris)?;
        let load_s = t.elapsed().as_secs_f64();
        let same = rays.iter().all(|r| {
            loaded.intersect(r) == built.intersect(r) && loaded.occluded(r) == built.occluded(r)
        });
        println!(
            "{name}: {} triangles, build {build_s:.3} s, load {load_s:.3} s ({:.1}x faster), {:.1} MB, same answers on {} rays: {same}",
            tris.len(),
            build_s / load_s,
            bytes.len() as f64 / 1e6,
            rays.len()
        );
        if !same {
            return Err("a loaded structure answered otherwise".into());
        }
    }
    Ok(())
}
