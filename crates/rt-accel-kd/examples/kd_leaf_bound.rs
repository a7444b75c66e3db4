//! How fast the SAH kd-tree's single rays could be if its traversal cost nothing: each ray's
//! walk is recorded once (`KdTree::leaves_tested`: the leaves it tests, in order, until its
//! answer), then the leaf tests alone are replayed (`KdTree::test_leaf`) and timed against
//! the whole query (`Accel::intersect` / `occluded`), one thread, median of 5 interleaved
//! passes, on the mesh's standard primary, shadow and diffuse rays. The ratio bounds what
//! any faster walk of the same tree could gain.
//!
//! `cargo run --release -p rt-accel-kd --features measure --example kd_leaf_bound -- MESH.obj [SIDE]` (`SIDE`: the
//! camera's resolution, default 512; `sphere:N` for a tessellated sphere).

use rt_accel_kd::{KdParams, KdTree};
use rt_geom::{Accel, Hit, Ray, Triangle};
use rt_testkit::RaySets;
use std::hint::black_box;
use std::time::Instant;

const ROUNDS: usize = 5;

/// The recorded leaves of one ray tested again, in order, until the answer.
fn replay<const ANY_HIT: bool>(tree: &KdTree<Triangle>, ray: &Ray, leaves: &[u32]) -> Option<Hit> {
    let mut r = *ray;
    let mut best = None;
    for &l in leaves {
        if tree.test_leaf::<ANY_HIT>(l as usize, &mut r, &mut best) {
            break;
        }
    }
    best
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Times the whole queries and the leaf replay of one ray set: both rates (Mrays/s), and the
/// leaves (empty ones too) and primitives tested per ray.
fn race<const ANY_HIT: bool>(
    tree: &KdTree<Triangle>,
    rays: &[Ray],
) -> Result<(f64, f64, f64, f64), String> {
    let mut recorded = Vec::with_capacity(rays.len());
    let (mut tests, mut prims) = (0usize, 0usize);
    for (k, ray) in rays.iter().enumerate() {
        let (tested, answer) = tree.leaves_tested::<ANY_HIT>(ray);
        // The replay must give the walk's answer.
        if replay::<ANY_HIT>(tree, ray, &tested) != answer {
            return Err(format!("ray {k}: the leaves alone answer otherwise"));
        }
        tests += tested.len();
        prims += tested
            .iter()
            .map(|&l| tree.nodes()[l as usize].count())
            .sum::<usize>();
        recorded.push(tested);
    }
    let (mut whole, mut replayed) = (Vec::new(), Vec::new());
    for _ in 0..ROUNDS {
        let t = Instant::now();
        for ray in rays {
            if ANY_HIT {
                black_box(tree.occluded(ray));
            } else {
                black_box(tree.intersect(ray));
            }
        }
        whole.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        for (ray, tested) in rays.iter().zip(&recorded) {
            black_box(replay::<ANY_HIT>(tree, ray, tested));
        }
        replayed.push(t.elapsed().as_secs_f64());
    }
    let rate = |s: f64| rays.len() as f64 / s / 1e6;
    let per_ray = |n: usize| n as f64 / rays.len().max(1) as f64;
    Ok((
        rate(median(whole)),
        rate(median(replayed)),
        per_ray(tests),
        per_ray(prims),
    ))
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first() else {
        return Err("usage: kd_leaf_bound MESH.obj|sphere:N [SIDE]".into());
    };
    let side: usize = match args.get(1) {
        Some(s) => s
            .parse()
            .map_err(|_| format!("SIDE must be a number, not {s:?}"))?,
        None => 512,
    };
    if side == 0 {
        return Err("SIDE must be positive".into());
    }
    let tris = rt_testkit::scenes::mesh_or_sphere(path)?;
    let tree = KdTree::build(&tris, KdParams::sah()).map_err(|e| e.to_string())?;
    let sets = RaySets::generate(path, &tris, &tree, side, side, 7);
    println!(
        "{path}: {} triangles, {side}x{side} camera, 1 thread, median of {ROUNDS}",
        tris.len()
    );
    println!("rays      whole Mrays/s  leaf tests alone  bound  leaves per ray  triangles per ray");
    for (name, rays, any) in [
        ("primary", &sets.primary, false),
        ("shadow", &sets.shadow, true),
        ("diffuse", &sets.diffuse, false),
    ] {
        let (whole, alone, per_ray, tris_per_ray) = if any {
            race::<true>(&tree, rays)?
        } else {
            race::<false>(&tree, rays)?
        };
        println!(
            "{name:<9} {whole:13.2}  {alone:16.2}  {:5.2}x  {per_ray:14.1}  {tris_per_ray:17.1}",
            alone / whole
        );
    }
    Ok(())
}
