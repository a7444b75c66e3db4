//! Grid parameters against speed: builds one grid per argument over an OBJ mesh, prints each
//! one's build time and `stats()`, then the single-thread speed of each on the mesh's standard
//! primary, shadow and diffuse rays (median of 5, the grids taking turns).
//!
//! `cargo run --release -p rt-accel-grid --example grid_params -- path/to/mesh.obj (or sphere:N, stadium:N)
//! uniform:DENSITY two-level:TOP_DENSITY:DENSITY adaptive:MAX_CELL_PRIMS:DENSITY ... [SIDE]`
//! (`SIDE`: camera resolution, default 512), e.g. `two-level:0.02:0.5 adaptive:24:0.125`.

use rt_accel_grid::{Grid, GridKind, GridParams};
use rt_geom::{Accel, Triangle};
use rt_testkit::RaySets;
use std::time::Instant;

fn parse_params(s: &str) -> Option<GridParams> {
    let mut parts = s.split(':');
    let kind = parts.next()?;
    let numbers: Vec<f32> = parts.map(|x| x.parse().ok()).collect::<Option<_>>()?;
    Some(match (kind, &numbers[..]) {
        ("uniform", &[density]) => GridParams {
            density,
            ..GridParams::uniform()
        },
        ("two-level", &[top_density, density]) => GridParams {
            kind: GridKind::TwoLevel { top_density },
            density,
            ..GridParams::two_level()
        },
        ("adaptive", &[max_cell_prims, density]) => GridParams {
            kind: GridKind::Adaptive {
                max_cell_prims: max_cell_prims as u32,
                max_levels: 4,
            },
            density,
            ..GridParams::adaptive()
        },
        _ => return None,
    })
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage =
        "usage: grid_params MESH.obj uniform:D | two-level:TOP:D | adaptive:MAX:D ... [SIDE]";
    let Some(path) = args.first() else {
        eprintln!("{usage}");
        std::process::exit(2);
    };
    let side = args
        .last()
        .and_then(|s| s.parse::<usize>().ok())
        .unwrap_or(512);
    let chosen: Vec<(&String, GridParams)> = args[1..]
        .iter()
        .filter_map(|s| Some((s, parse_params(s)?)))
        .collect();
    if chosen.is_empty() {
        eprintln!("{usage}");
        std::process::exit(2);
    }
    let tris: Vec<Triangle> = rt_testkit::scenes::mesh_or_sphere(path).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1);
    });
    let mut grids = Vec::new();
    for (label, params) in &chosen {
        let start = Instant::now();
        match Grid::build(&tris, *params) {
            Ok(grid) => {
                let ms = start.elapsed().as_secs_f64() * 1e3;
                println!("{label}: {ms:7.1} ms  {}", grid.stats());
                grids.push(grid);
            }
            Err(e) => {
                eprintln!("{label}: {e}");
                std::process::exit(1);
            }
        }
    }
    let scene = std::path::Path::new(path)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("");
    let sets = RaySets::generate(scene, &tris, &grids[0], side, side, 7);
    let accels: Vec<&dyn Accel> = grids.iter().map(|g| g as &dyn Accel).collect();
    let labels: Vec<String> = chosen.iter().map(|(l, _)| l.to_string()).collect();
    sets.print_race(&accels, &labels, 5);
}
