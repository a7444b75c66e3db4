//! Renders a scene by Whitted ray tracing through the 8-wide triangle BVH and writes a PNG:
//! the built-in chess board, or an OBJ (with its MTL) or NFF file.
//!
//! ```sh
//! cargo run --release -p rt-shade --example render_png -- [chess|SCENE.obj|SCENE.nff] [OUT.png]
//! ```
//!
//! Scenes with analytic spheres or cones (most NFF files) need a structure that holds mixed
//! shapes; this one builds a binary BVH over the shapes for those.

use rt_accel_bvh::{Bvh, BvhParams, TriBvh8};
use rt_geom::Accel;
use rt_shade::{RenderOptions, Scene, chess, load_nff, load_obj_scene, render};
use std::path::{Path, PathBuf};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let which = args.next().unwrap_or_else(|| "chess".into());
    let out = PathBuf::from(args.next().unwrap_or_else(|| "chess.png".into()));

    let scene: Scene = match which.as_str() {
        "chess" => chess(),
        p if p.ends_with(".nff") => load_nff(Path::new(p))?,
        p => load_obj_scene(Path::new(p))?,
    };
    // Triangle-only scenes take the fastest structure; mixed shapes a BVH over shapes.
    let accel: Box<dyn Accel> = match scene.triangles() {
        Some(tris) => Box::new(TriBvh8::build_for_tracing(&tris)?),
        None => Box::new(Bvh::build(&scene.shapes, BvhParams::balanced())?),
    };
    let (width, height) = if which == "chess" {
        (800, 600)
    } else {
        (512, 512)
    };
    let options = RenderOptions {
        width,
        height,
        ..RenderOptions::default()
    };
    let rendered = render(&scene, accel.as_ref(), &options, &|_| {})?;
    rendered.image.save_png(&out)?;
    let s = rendered.stats;
    println!(
        "{}: {width}x{height}, {} eye rays, {} shadow rays -> {}",
        scene.name,
        s.eye_rays,
        s.shadow,
        out.display()
    );
    Ok(())
}
