//! A saved octree against rebuilding it: builds over a mesh, saves, loads back (checks
//! included) and compares the times and the answers.
//!
//! `cargo run --release -p rt-accel-octree --features measure --example oct_save_load -- MESH.obj`

use rt_accel_octree::{Octree, OctreeParams};
use rt_testkit::{View, save_load_report};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .ok_or("usage: oct_save_load MESH.obj")?;
    let tris = rt_geom::load_obj(&path)?.triangles();
    let rays = View::front(&rt_geom::Aabb::around(&tris)).camera_rays(320, 320);
    save_load_report(
        "octree",
        || Octree::build(&tris, OctreeParams::standard()),
        Octree::to_bytes,
        |b| Octree::from_bytes(b, &tris),
        &rays,
    )?;
    Ok(())
}
