//! Grid parameters against speed: builds one grid per argument over an OBJ mesh, prints each
//! one's build time and `stats()`, then the single-thread speed of each on the mesh's standard
//! primary, shadow and diffuse rays (median of 5, the grids taking turns).
//!
//! `cargo run --release -p rt-accel-grid --features measure --example grid_params -- path/to/mesh.obj (or sphere:N, stadium:N)
//! uniform:DENSITY two-level:TOP_DENSITY:DENSITY adaptive:MAX_CELL_PRIMS:DENSITY ... [SIDE]`
//! (`SIDE`: camera resolution, default 512), e.g. `two-level:0.01:0.5 adaptive:24:0.125`; a
//! `+mailbox` suffix turns on per-ray mailboxes (`two-level:0.01:0.5+mailbox`), a `+noskip`
//! suffix (last) turns off empty-space skipping (`uniform:0.5+noskip`).

use rt_accel_grid::{Grid, GridKind, GridParams};
use rt_geom::Triangle;
use rt_testkit::RaySets;

fn parse_params(s: &str) -> Option<GridParams> {
    let (s, skip_empty) = match s.strip_suffix("+noskip") {
        Some(s) => (s, false),
        None => (s, true),
    };
    let (s, mailbox) = match s.strip_suffix("+mailbox") {
        Some(s) => (s, true),
        None => (s, false),
    };
    let mut parts = s.split(':');
    let kind = parts.next()?;
    let numbers: Vec<f32> = parts.map(|x| x.parse().ok()).collect::<Option<_>>()?;
    let params = match (kind, &numbers[..]) {
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
    };
    Some(params.with_mailbox(mailbox).with_skip_empty(skip_empty))
}

fn main() {
    RaySets::race_configs(
        "usage: grid_params MESH.obj uniform:D | two-level:TOP:D | adaptive:MAX:D[+mailbox][+noskip] ... [SIDE]",
        parse_params,
        |tris: &[Triangle], params| Grid::build(tris, *params),
    );
}
