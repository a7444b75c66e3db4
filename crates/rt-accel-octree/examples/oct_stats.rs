//! Builds the octree over an OBJ mesh and prints build time and `stats()` for several leaf
//! sizes; with `--trace`, also the single-thread speed of both walks on the mesh's standard
//! primary, shadow and diffuse rays (median of 5).
//!
//! `cargo run --release -p rt-accel-octree --features measure --example oct_stats -- path/to/mesh.obj [--trace [SIDE [parametric|recursive]]]`
use rt_accel_octree::{Octree, OctreeParams, OctreeTraversal};
use rt_geom::{Accel, Triangle, load_obj};
use rt_testkit::RaySets;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let Some(path) = args.get(1) else {
        eprintln!("usage: oct_stats MESH.obj [--trace [SIDE]]");
        std::process::exit(2);
    };
    let tris: Vec<Triangle> = match load_obj(path) {
        Ok(m) => m.triangles(),
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    if args.get(2).map(String::as_str) == Some("--trace") {
        let side = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(512);
        trace(path, &tris, side, args.get(4).map(String::as_str));
        return;
    }
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

/// `only`: "parametric" or "recursive" (default both); `OCT_REPS` repetitions (default 5).
fn trace(path: &str, tris: &[Triangle], side: usize, only: Option<&str>) {
    let reps: usize = std::env::var("OCT_REPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5);
    let scene = std::path::Path::new(path)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("");
    let start = Instant::now();
    let params = OctreeParams {
        max_prims: std::env::var("OCT_MAX_PRIMS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(OctreeParams::standard().max_prims),
        ..OctreeParams::standard()
    };
    let tree = Octree::build(tris, params).expect("mesh builds");
    println!(
        "build {:.1} ms  {}",
        start.elapsed().as_secs_f64() * 1e3,
        tree.stats()
    );
    let sets = RaySets::generate(scene, tris, &tree, side, side, 7);
    walks(&tree, &sets, only, reps);
}

/// Both walks (or `only` one) over the three ray sets; a function of its own so that
/// `valgrind --toggle-collect='*walks*'` counts the walks alone.
#[inline(never)]
fn walks(tree: &Octree<Triangle>, sets: &RaySets, only: Option<&str>, reps: usize) {
    let trees: Vec<Octree<Triangle>> = [OctreeTraversal::Parametric, OctreeTraversal::Recursive]
        .into_iter()
        .filter(|w| only.is_none_or(|o| format!("{w:?}").eq_ignore_ascii_case(o)))
        .map(|w| tree.clone().with_traversal(w))
        .collect();
    let accels: Vec<&dyn Accel> = trees.iter().map(|t| t as &dyn Accel).collect();
    let rates = sets.race(&accels, reps);
    for (name, rates) in RaySets::NAMES.iter().zip(&rates) {
        for (tree, rate) in trees.iter().zip(rates) {
            println!("{:?} {name:<8} {rate:7.2} Mrays/s", tree.params().traversal);
        }
        if let [a, b] = rates[..] {
            println!("parametric / recursive {name}: {:.2}x", a / b);
        }
    }
}
