//! A saved SAH kd-tree against rebuilding it: builds over a mesh, saves, loads back (checks
//! included) and compares the times and the answers.
//!
//! `cargo run --release -p rt-accel-kd --example kd_save_load -- MESH.obj`

use rt_accel_kd::{KdParams, KdTree};
use rt_testkit::{View, save_load_report};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args().nth(1).ok_or("usage: save_load MESH.obj")?;
    let tris = rt_geom::load_obj(&path)?.triangles();
    let rays = View::front(&rt_geom::Aabb::around(&tris)).camera_rays(320, 320);
    save_load_report(
        "kd sah",
        || KdTree::build(&tris, KdParams::sah()),
        KdTree::to_bytes,
        |b| KdTree::from_bytes(b, &tris),
        &rays,
    )?;
    Ok(())
}
