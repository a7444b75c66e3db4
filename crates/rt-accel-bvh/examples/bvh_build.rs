//! Builds a BVH2 with every builder over an OBJ mesh and prints the median build time and
//! `stats()` (nodes, depth, bytes, SAH cost): the build-time and SAH-quality table of the crate.
//!
//! `cargo run --release -p rt-accel-bvh --example bvh_build -- path/to/mesh.obj [REPS [BUILDER]]`, or
//! `-- sphere:N` for a tessellated sphere of about N triangles. `RAYON_NUM_THREADS` sets the
//! threads (all cores by default).

use rt_accel_bvh::{Bvh, BvhBuilder, BvhParams};
use rt_geom::Accel;
use std::time::Instant;

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(path) = args.next() else {
        eprintln!("usage: bvh_build MESH.obj|sphere:N [REPS [BUILDER]]");
        std::process::exit(2);
    };
    let reps: usize = args.next().and_then(|r| r.parse().ok()).unwrap_or(5).max(1);
    let only = args.next();
    let tris = rt_testkit::scenes::mesh_or_sphere(&path).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1);
    });
    println!(
        "{path}: {} triangles, {} threads, median of {reps}",
        tris.len(),
        rayon::current_num_threads()
    );
    let balanced = BvhParams::balanced();
    for (name, params) in [
        ("midpoint", balanced.with_builder(BvhBuilder::Midpoint)),
        ("median", balanced.with_builder(BvhBuilder::Median)),
        ("binned-8", BvhParams::fast()),
        ("binned-16", balanced),
        (
            "binned-32",
            balanced.with_builder(BvhBuilder::BinnedSah { bins: 32 }),
        ),
        ("sweep", BvhParams::quality()),
        ("binned-16+reinsertion", balanced.with_reinsertion(1.0)),
        ("spatial", BvhParams::spatial()),
    ] {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        let mut times = Vec::with_capacity(reps);
        let mut built = None;
        for _ in 0..reps {
            let start = Instant::now();
            let bvh = Bvh::build(&tris, params);
            times.push(start.elapsed().as_secs_f64() * 1e3);
            built = Some(bvh);
        }
        times.sort_by(f64::total_cmp);
        match built.expect("at least one repetition") {
            Ok(bvh) => println!("{name:>21}: {:8.1} ms  {}", times[reps / 2], bvh.stats()),
            Err(e) => println!("{name:>21}: {e}"),
        }
    }
}
