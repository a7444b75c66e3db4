//! Builds the octree over an OBJ mesh and prints build time and `stats()`.
//!
//! `cargo run --release -p rt-accel-octree --example oct_stats -- path/to/mesh.obj`
use rt_accel_octree::{Octree, OctreeParams};
use rt_geom::{Accel, load_obj};
use std::time::Instant;

fn main() {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: oct_stats MESH.obj");
        std::process::exit(2);
    };
    let tris = match load_obj(&path) {
        Ok(m) => m.triangles(),
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    for max_prims in [2, 4, 10, 20] {
        let params = OctreeParams {
            max_prims,
            ..OctreeParams::standard()
        };
        let start = Instant::now();
        match Octree::build(&tris, params) {
            Ok(t) => println!(
                "max_prims {max_prims:>2}: {:8.1} ms  {}",
                start.elapsed().as_secs_f64() * 1e3,
                t.stats()
            ),
            Err(e) => println!("{e}"),
        }
    }
}
