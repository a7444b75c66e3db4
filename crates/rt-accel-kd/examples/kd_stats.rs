//! Builds every kd-tree and BSP preset over an OBJ mesh and prints build time and `stats()`.
//!
//! `cargo run --release -p rt-accel-kd --example kd_stats -- path/to/mesh.obj`, or
//! `-- sphere:N` for a tessellated sphere of about N triangles.

use rt_accel_kd::{BspParams, BspTree, KdParams, KdTree};
use rt_geom::Accel;
use std::time::Instant;

fn main() {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: kd_stats MESH.obj");
        std::process::exit(2);
    };
    let tris = rt_testkit::scenes::mesh_or_sphere(&path).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1);
    });
    println!("{path}: {} triangles", tris.len());
    for (name, params) in [
        ("sah", KdParams::sah()),
        ("midpoint", KdParams::midpoint()),
        ("centroid", KdParams::centroid()),
    ] {
        let start = Instant::now();
        match KdTree::build(&tris, params) {
            Ok(kd) => println!(
                "{name:>9}: {:8.1} ms  {}",
                start.elapsed().as_secs_f64() * 1e3,
                kd.stats()
            ),
            Err(e) => println!("{name:>9}: {e}"),
        }
    }
    for (name, params) in [
        ("bsp", BspParams::standard()),
        ("bsp-auto", BspParams::autopartition()),
    ] {
        let start = Instant::now();
        match BspTree::build(&tris, params) {
            Ok(t) => println!(
                "{name:>9}: {:8.1} ms  {}",
                start.elapsed().as_secs_f64() * 1e3,
                t.stats()
            ),
            Err(e) => println!("{name:>9}: {e}"),
        }
    }
}
