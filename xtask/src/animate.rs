//! `cargo xtask render --scene chess --frames N`: the moving chess scene (a knight's jump, a
//! toppling pawn, a rippling cloth), frame by frame, with each way of updating the structure
//! timed, and the trace time after it: rebuild everything, refit everything, or move the
//! instances and refit the deforming object under a rebuilt top level.

use crate::render::{Differences, RenderArgs, instances};
use crate::run::{bar, pool};
use rt_accel_bvh::{BvhParams, InstanceBvh, Object, Refit, TopUpdate, TriBvh8};
use rt_geom::{Accel, BuildError, Shape, Triangle};
use std::path::PathBuf;
use std::time::Instant;

/// How a frame's structure was brought up to date.
const STRATEGIES: [&str; 3] = ["rebuild all", "refit all", "top level"];

/// One frame: per strategy, the update and trace seconds.
#[derive(Clone, Debug)]
pub struct FrameTimes {
    pub frame: u32,
    pub update: [f64; 3],
    pub trace: [f64; 3],
    /// How the instanced render differs from the flat one (rounding of the transforms on
    /// silhouettes and shadow edges).
    pub instanced_differ: Differences,
}

fn triangles(shapes: &[Shape]) -> Vec<Triangle> {
    shapes
        .iter()
        .filter_map(|s| s.as_triangle().copied())
        .collect()
}

fn timed<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let start = Instant::now();
    let out = f();
    (out, start.elapsed().as_secs_f64())
}

/// Renders `frames` frames to `DIR/frame-NNN.png` (default `target/render/chess-frames`) with
/// `bvh8-tri` (the fastest layout, refit in place) and returns the per-frame times.
pub fn animate(args: &RenderArgs, frames: u32) -> Result<Vec<FrameTimes>, String> {
    if args.scene != "chess" {
        return Err(format!(
            "--frames animates the chess scene (--scene chess), not {}",
            args.scene
        ));
    }
    if !(1..=10_000).contains(&frames) {
        return Err(format!("--frames {frames}: expected 1 to 10000"));
    }
    let dir = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("target/render/chess-frames"));
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let pool = pool(args.threads)?;
    let options = args.options((400, 300))?;
    let at = |f: u32| {
        if frames == 1 {
            0.0
        } else {
            f as f32 / (frames - 1) as f32
        }
    };
    let err = |e: BuildError| e.to_string();

    // Frame 0 builds what the refit and top-level strategies then update.
    let (scene, objects) = rt_shade::chess_moving(at(0));
    let mut refitted = pool
        .install(|| TriBvh8::build_for_tracing(&triangles(&scene.shapes)))
        .map_err(err)?;
    let cloth = objects.objects.len() as u32 - 1;
    let built: Vec<Object<TriBvh8>> = objects
        .objects
        .iter()
        .map(|o| Object::build(&triangles(&o.shapes), TriBvh8::build_for_tracing))
        .collect::<Result<_, _>>()
        .map_err(err)?;
    let mut two_level =
        InstanceBvh::build(built, &instances(&objects), BvhParams::balanced()).map_err(err)?;

    let progress = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        bar(frames as u64, "frames".to_string())
    };
    let mut out = Vec::new();
    for f in 0..frames {
        let (scene, objects) = rt_shade::chess_moving(at(f));
        let tris = triangles(&scene.shapes);
        let (rebuilt, rebuild_s) = timed(|| pool.install(|| TriBvh8::build_for_tracing(&tris)));
        let rebuilt = rebuilt.map_err(err)?;
        let (refit, refit_s) = timed(|| pool.install(|| refitted.refit(&tris)));
        refit.map_err(err)?;
        let transforms: Vec<_> = objects.instances.iter().map(|i| i.transform).collect();
        let cloth_tris = triangles(&objects.objects[cloth as usize].shapes);
        let (moved, top_s) = timed(|| {
            pool.install(|| {
                // The cloth's boxes refit the old top level (cheap); the one rebuild follows.
                two_level.refit_object(cloth, &cloth_tris, TopUpdate::Refit)?;
                two_level.set_transforms(&transforms, TopUpdate::Rebuild)
            })
        });
        moved.map_err(err)?;
        let render = |accel: &dyn Accel| -> Result<(rt_shade::Image, f64), String> {
            let r = pool
                .install(|| rt_shade::render(&scene, accel, &options, &|_| {}))
                .map_err(|e| e.to_string())?;
            Ok((r.image, r.seconds))
        };
        let (flat_image, rebuild_t) = render(&rebuilt)?;
        let (refit_image, refit_t) = render(&refitted)?;
        let (image, top_t) = render(&two_level)?;
        if refit_image.pixels != flat_image.pixels {
            return Err(format!(
                "frame {f}: the refit structure rendered another image than the rebuilt one"
            ));
        }
        let differ = Differences::between(&flat_image, &image);
        image.save_png(&dir.join(format!("frame-{f:03}.png")))?;
        out.push(FrameTimes {
            frame: f,
            update: [rebuild_s, refit_s, top_s],
            trace: [rebuild_t, refit_t, top_t],
            instanced_differ: differ,
        });
        progress.inc(1);
    }
    progress.finish_and_clear();
    Ok(out)
}

/// The per-frame table: update and trace milliseconds of each strategy.
pub fn table(times: &[FrameTimes]) -> String {
    let mut s = format!(
        "{:>5} | {:>31} | {:>31} | instanced vs flat\n{:>5} | {:>8} {:>9} {:>9} | {:>8} {:>9} {:>9} | pixels differing visibly (max)\n",
        "",
        "update ms",
        "trace ms",
        "frame",
        STRATEGIES[0],
        STRATEGIES[1],
        STRATEGIES[2],
        STRATEGIES[0],
        STRATEGIES[1],
        STRATEGIES[2]
    );
    for t in times {
        let ms = |x: f64| x * 1e3;
        s += &format!(
            "{:>5} | {:>11.2} {:>9.2} {:>9.2} | {:>11.1} {:>9.1} {:>9.1} | {} ({:.4})\n",
            t.frame,
            ms(t.update[0]),
            ms(t.update[1]),
            ms(t.update[2]),
            ms(t.trace[0]),
            ms(t.trace[1]),
            ms(t.trace[2]),
            t.instanced_differ.pixels,
            t.instanced_differ.max
        );
    }
    if let (Some(first), Some(last)) = (times.first(), times.last()) {
        let total = |k: usize| times.iter().map(|t| t.update[k] + t.trace[k]).sum::<f64>();
        s += &format!(
            "refit's trace time went from {:.1} ms to {:.1} ms (rebuilt: {:.1} ms); update + trace over all frames: rebuild all {:.0} ms, refit all {:.0} ms, top level {:.0} ms\n",
            first.trace[1] * 1e3,
            last.trace[1] * 1e3,
            last.trace[0] * 1e3,
            total(0) * 1e3,
            total(1) * 1e3,
            total(2) * 1e3
        );
    }
    s
}
