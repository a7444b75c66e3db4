//! Saved grids against rebuilding them: builds each kind over a mesh, saves, loads back
//! (checks included) and compares the times and the answers.
//!
//! `cargo run --release -p rt-accel-grid --features measure --example grid_save_load -- MESH.obj`

use rt_accel_grid::{Grid, GridParams};
use rt_testkit::{View, save_load_report};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .ok_or("usage: grid_save_load MESH.obj")?;
    let tris = rt_geom::load_obj(&path)?.triangles();
    let rays = View::front(&rt_geom::Aabb::around(&tris)).camera_rays(320, 320);
    for (name, params) in [
        ("grid", GridParams::uniform()),
        ("grid2", GridParams::two_level()),
        ("grid-adaptive", GridParams::adaptive()),
    ] {
        save_load_report(
            name,
            || Grid::build(&tris, params),
            Grid::to_bytes,
            |b| Grid::from_bytes(b, &tris),
            &rays,
        )?;
    }
    Ok(())
}
