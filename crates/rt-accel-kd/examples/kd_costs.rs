//! The SAH constants against speed: builds one SAH kd-tree per `KT/KI/BONUS` (traversal cost,
//! intersection cost, empty bonus) over an OBJ mesh, prints each one's build time and
//! `stats()`, then the single-thread speed of each on the mesh's standard primary, shadow and
//! diffuse rays (median of 5, the trees taking turns).
//!
//! `cargo run --release -p rt-accel-kd --example kd_costs -- path/to/mesh.obj (or sphere:N, stadium:N) 15/20/0.2 15/7/0.1 [SIDE]`
//! (`SIDE`: camera resolution, default 512).

use rt_accel_kd::{KdParams, KdTree};
use rt_geom::{Accel, Triangle};
use rt_testkit::RaySets;
use std::time::Instant;

fn parse_costs(s: &str) -> Option<KdParams> {
    let v: Vec<f32> = s
        .split('/')
        .map(|x| x.parse().ok())
        .collect::<Option<_>>()?;
    let [kt, ki, bonus] = v[..] else { return None };
    Some(KdParams {
        traversal_cost: kt,
        intersection_cost: ki,
        empty_bonus: bonus,
        ..KdParams::sah()
    })
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: kd_costs MESH.obj KT/KI/BONUS... [SIDE]";
    let Some(path) = args.first() else {
        eprintln!("{usage}");
        std::process::exit(2);
    };
    let side = args
        .last()
        .and_then(|s| s.parse::<usize>().ok())
        .unwrap_or(512);
    let params: Vec<KdParams> = args[1..].iter().filter_map(|s| parse_costs(s)).collect();
    if params.is_empty() {
        eprintln!("{usage}");
        std::process::exit(2);
    }
    let tris: Vec<Triangle> = rt_testkit::scenes::mesh_or_sphere(path).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1);
    });
    let mut trees = Vec::new();
    for p in &params {
        let start = Instant::now();
        match KdTree::build(&tris, *p) {
            Ok(kd) => {
                println!(
                    "{}/{}/{}: {:7.1} ms  {}",
                    p.traversal_cost,
                    p.intersection_cost,
                    p.empty_bonus,
                    start.elapsed().as_secs_f64() * 1e3,
                    kd.stats()
                );
                trees.push(kd);
            }
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        }
    }
    let scene = std::path::Path::new(path)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("");
    let sets = RaySets::generate(scene, &tris, &trees[0], side, side, 7);
    let accels: Vec<&dyn Accel> = trees.iter().map(|t| t as &dyn Accel).collect();
    let labels: Vec<String> = params
        .iter()
        .map(|p| {
            let (kt, ki, bonus) = (p.traversal_cost, p.intersection_cost, p.empty_bonus);
            format!("{kt}/{ki}/{bonus}")
        })
        .collect();
    sets.print_race(&accels, &labels, 5);
}
