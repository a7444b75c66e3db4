//! Saved structures against rebuilding: builds `TriBvh8` (the fastest-tracing preset and the
//! spatial-split one) over a mesh, saves each, loads it back (checks included) and compares
//! the times and the answers.
//!
//! `cargo run --release -p rt-accel-bvh --example save_load -- MESH.obj [OUT_DIR]`

use rt_accel_bvh::{BvhParams, TriBvh8};
use rt_testkit::{View, save_load_report};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = args.next().ok_or("usage: save_load MESH.obj [OUT_DIR]")?;
    let out_dir = args.next();
    let tris = rt_geom::load_obj(&path)?.triangles();
    let rays = View::front(&rt_geom::Aabb::around(&tris)).camera_rays(320, 320);
    for (name, params) in [
        ("fastest_trace", BvhParams::fastest_trace()),
        ("spatial", BvhParams::spatial().for_soa_leaves()),
    ] {
        let bytes = save_load_report(
            name,
            || TriBvh8::build(&tris, params),
            TriBvh8::to_bytes,
            |b| TriBvh8::from_bytes(b, &tris),
            &rays,
        )?;
        if let Some(dir) = &out_dir {
            std::fs::write(format!("{dir}/{name}.rtbvh"), &bytes)?;
        }
    }
    Ok(())
}
