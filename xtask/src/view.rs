//! `cargo xtask view`: a scene ray traced frame after frame through any structure (its packet
//! path where it has one, the tiles spread over the cores), in a window or headless.
//!
//! The window (the `window` feature: minifb, a CPU frame buffer, no GPU API) takes keys: `W`
//! `A` `S` `D` move, `Q` `E` down and up, the arrows (or a drag with the left button) turn;
//! `Tab` switches the structure (rebuilt on another thread while the old one keeps
//! rendering), `M` the shading (in the counting build, `--counting`, also the heatmaps of each
//! eye ray's tests), `F` the frame size; `Esc` closes. The title names the structure and the
//! shading and gives the frame time and the rays per second. While the camera rests the picture refines: Whitted and
//! eye-ray shading take 2x2, then 3x3, then 4x4 eye rays per pixel; path tracing adds a
//! path per pixel each frame. Headless (`--frames N`), the camera orbits the scene's look-at
//! point in `N` steps and the frame rate is printed: what the window would show, measured.

use crate::registry;
use crate::render::{Built, RenderArgs, build, load, parse_size, trace};
use crate::run::pool;
use rt_shade::{Camera, Integrator, PathOptions, RenderOptions, Scene, ShadeOptions};
use std::time::Instant;

/// `cargo xtask view`'s arguments.
#[derive(clap::Args, Clone, Debug)]
pub struct ViewArgs {
    /// `chess`, `chess-lamp`, or an .obj or .nff file.
    #[arg(long, default_value = "chess")]
    pub scene: String,
    /// The structure to start with (`cargo xtask accels`); `Tab` switches to the next of
    /// [`SWITCH`].
    #[arg(long, default_value = "bvh8-tri")]
    pub accel: String,
    /// Frame size WxH.
    #[arg(long, value_parser = parse_size, default_value = "640x480")]
    pub size: (u32, u32),
    /// The shading to start with.
    #[arg(long, value_enum, default_value_t = Shading::Whitted)]
    pub shading: Shading,
    /// Headless: render this many frames along an orbit around the scene and print the
    /// frame rate; no window.
    #[arg(long)]
    pub frames: Option<u32>,
    /// Threads (0 = all cores; at most 1024).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// No refinement while the camera rests (every frame one eye ray or path per pixel).
    #[arg(long)]
    pub no_refine: bool,
    /// Count each eye ray's tests, so that `M` also shows them as heatmaps (box tests,
    /// primitive tests): runs the counting build (`target/view-counting`), whose frames are
    /// slower.
    #[arg(long)]
    pub counting: bool,
}

/// How the window shades.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shading {
    /// Whitted's rules: shadow, mirror and refracted rays, up to depth 5.
    Whitted,
    /// Eye rays alone: the lights' direct light without shadow rays, no mirror or refracted
    /// rays.
    Eye,
    /// Path tracing, one path per pixel per frame, accumulated while the camera rests.
    Path,
    /// Each eye ray's bounding-volume tests as a heatmap (the counting build: `--counting`).
    Boxes,
    /// Each eye ray's primitive tests as a heatmap (the counting build: `--counting`).
    Prims,
}

impl Shading {
    /// The name the window's title gives.
    pub fn name(self) -> &'static str {
        match self {
            Shading::Whitted => "whitted",
            Shading::Eye => "eye rays",
            Shading::Path => "path",
            Shading::Boxes => "box tests",
            Shading::Prims => "primitive tests",
        }
    }

    /// The shading `M` switches to: the heatmaps only in the counting build.
    pub fn next(self) -> Self {
        let counting = rt_geom::counters::ENABLED;
        match self {
            Shading::Whitted => Shading::Eye,
            Shading::Eye => Shading::Path,
            Shading::Path if counting => Shading::Boxes,
            Shading::Boxes => Shading::Prims,
            Shading::Path | Shading::Prims => Shading::Whitted,
        }
    }

    /// The heatmap this shading draws, if it is one.
    fn heatmap(self) -> Option<crate::heatmap::Heatmap> {
        match self {
            Shading::Boxes => Some(crate::heatmap::Heatmap::Boxes),
            Shading::Prims => Some(crate::heatmap::Heatmap::Prims),
            _ => None,
        }
    }

    /// The render options of refinement step `step` (0: the first frame after a move).
    pub fn options(self, (width, height): (u32, u32), step: u32) -> RenderOptions {
        let (samples_per_axis, max_depth, integrator) = match self {
            Shading::Whitted => (1 + step.min(3), 5, Integrator::Whitted),
            Shading::Eye | Shading::Boxes | Shading::Prims => {
                (1 + step.min(3), 1, Integrator::Whitted)
            }
            Shading::Path => (
                1,
                5,
                Integrator::Path(PathOptions {
                    samples: 1,
                    seed: step as u64,
                    ..PathOptions::default()
                }),
            ),
        };
        RenderOptions {
            width,
            height,
            samples_per_axis,
            shade: ShadeOptions {
                max_depth,
                shadows: self != Shading::Eye,
                ..ShadeOptions::default()
            },
            integrator,
        }
    }
}

/// The structures `Tab` goes through, in order.
pub const SWITCH: [&str; 7] = ["bvh8-tri", "bvh8", "bvh", "kd", "grid2", "octree", "bsp"];

/// The structure after `name` in [`SWITCH`] (the first one after any other).
pub fn next_structure(name: &str) -> &'static str {
    let at = SWITCH.iter().position(|&s| s == name);
    SWITCH[at.map_or(0, |i| (i + 1) % SWITCH.len())]
}

/// One frame: the picture as `0RGB` words, row-major from the top left, and what it cost.
pub struct Frame {
    /// The pixels, 8 bits per channel as `render`'s PNGs hold them.
    pub pixels: Vec<u32>,
    /// Linear colours, for accumulation.
    pub linear: Vec<rt_geom::Vec3>,
    /// Rays traced.
    pub rays: u64,
    /// Seconds of tracing.
    pub seconds: f64,
    /// Box and primitive tests per eye ray (heatmaps).
    pub tests: Option<(f64, f64)>,
}

/// The scene and a structure built over it, ready to render frames.
pub struct Viewer {
    /// The scene; its camera is the one frames are rendered from.
    pub scene: Scene,
    built: Built,
    /// The structure's name.
    pub accel: String,
    pool: rayon::ThreadPool,
}

impl Viewer {
    /// Loads the scene and builds `accel` over it on `threads` threads.
    pub fn new(scene: &str, accel: &str, threads: usize) -> Result<Self, String> {
        let args = render_args(scene, accel);
        let (scene, _) = load(&args)?;
        let pool = pool(threads)?;
        let built = build_on(&pool, &scene, accel)?;
        Ok(Self {
            scene,
            built,
            accel: accel.to_string(),
            pool,
        })
    }

    /// Renders one frame of `shading` with `options` from the scene's camera.
    pub fn frame(&self, shading: Shading, options: &RenderOptions) -> Result<Frame, String> {
        options.check()?;
        let (mut rendered, counts) = match shading.heatmap() {
            Some(_) if !rt_geom::counters::ENABLED => {
                return Err("the heatmaps need the counting build (`view --counting`)".into());
            }
            Some(kind) => self.pool.install(|| {
                let accel = self.built.single.as_ref();
                crate::heatmap::heatmap(&self.scene, accel, options, kind)
            })?,
            None => trace(&self.scene, &self.built, options, &self.pool, true)?,
        };
        // A heatmap's legend strip below the picture is left out: the title gives the means.
        let pixels = (options.width * options.height) as usize;
        rendered.image.pixels.truncate(pixels);
        rendered.image.height = options.height;
        let per_ray = |n: u64| n as f64 / rendered.stats.eye_rays.max(1) as f64;
        let tests = (rt_geom::counters::ENABLED && shading.heatmap().is_some())
            .then(|| (per_ray(counts.nodes), per_ray(counts.prims)));
        Ok(Frame {
            pixels: words(&rendered.image),
            linear: rendered.image.pixels,
            rays: rendered.stats.total(),
            seconds: rendered.seconds,
            tests,
        })
    }
}

/// `image` as `0RGB` words, 8 bits per channel as [`rt_shade::Image::to_rgb8`] gives them.
fn words(image: &rt_shade::Image) -> Vec<u32> {
    let rgb = image.to_rgb8();
    rgb.chunks_exact(3)
        .map(|p| (p[0] as u32) << 16 | (p[1] as u32) << 8 | p[2] as u32)
        .collect()
}

fn render_args(scene: &str, accel: &str) -> RenderArgs {
    RenderArgs {
        scene: scene.to_string(),
        accel: accel.to_string(),
        quiet: true,
        ..RenderArgs::default()
    }
}

/// Builds `accel` over `scene` on `pool`, as `render` builds it (its packet path included).
fn build_on(pool: &rayon::ThreadPool, scene: &Scene, accel: &str) -> Result<Built, String> {
    let entry = registry::find(accel).ok_or_else(|| registry::unknown(accel))?;
    pool.install(|| build(entry, scene, None, &render_args(&scene.name, accel)))
}

/// `camera` turned by `angle` radians about its up axis through the look-at point.
pub fn orbit(camera: &Camera, angle: f32) -> Camera {
    let rotation = rt_geom::glam::Quat::from_axis_angle(camera.up.normalize(), angle);
    Camera {
        eye: camera.look_at + rotation * (camera.eye - camera.look_at),
        ..*camera
    }
}

/// Headless: `frames` frames of `args.shading` (no refinement) along a full orbit; returns
/// the report line.
pub fn headless(args: &ViewArgs, frames: u32) -> Result<String, String> {
    if frames == 0 {
        return Err("--frames must be at least 1".into());
    }
    let mut viewer = Viewer::new(&args.scene, &args.accel, args.threads)?;
    let base = viewer.scene.camera;
    let options = args.shading.options(args.size, 0);
    let mut seconds = Vec::with_capacity(frames as usize);
    let (mut rays, start) = (0u64, Instant::now());
    for i in 0..frames {
        let angle = std::f32::consts::TAU * i as f32 / frames as f32;
        viewer.scene.camera = orbit(&base, angle);
        let frame = viewer.frame(args.shading, &options)?;
        seconds.push(frame.seconds);
        rays += frame.rays;
    }
    let wall = start.elapsed().as_secs_f64();
    seconds.sort_by(f64::total_cmp);
    let median = seconds[seconds.len() / 2];
    Ok(format!(
        "{frames} frames of {}x{}, {} shading, {} on {} threads: {:.1} frames/s ({:.1} ms median frame), {:.1} Mrays/s",
        args.size.0,
        args.size.1,
        args.shading.name(),
        viewer.accel,
        viewer.pool.current_num_threads(),
        frames as f64 / wall,
        median * 1e3,
        rays as f64 / wall / 1e6,
    ))
}

/// The window title: structure, shading, the last frame's time and rays per second (and
/// tests per ray for heatmaps; nothing before the first frame), refinement, and the structure
/// being built with its seconds so far.
pub fn title(
    accel: &str,
    shading: Shading,
    last: Option<&Frame>,
    step: u32,
    building: Option<(&str, f64)>,
) -> String {
    let mut t = format!("rt view: {accel} | {}", shading.name());
    if let Some(f) = last {
        t += &format!(
            " | {:.0} ms | {:.1} Mrays/s",
            f.seconds * 1e3,
            f.rays as f64 / f.seconds.max(1e-9) / 1e6
        );
        if let Some((boxes, prims)) = f.tests {
            t += &format!(" | {boxes:.1} boxes, {prims:.1} prims per ray");
        }
    }
    if step > 0 {
        t += &format!(" | refined x{}", step + 1);
    }
    if let Some((b, seconds)) = building {
        t += &format!(" | building {b}: {seconds:.1} s");
    }
    t
}

#[cfg(feature = "window")]
pub use window::run_window;

/// Without the `window` feature there is no window to open (`cargo xtask view` runs the build
/// with it; `--frames` works in either).
#[cfg(not(feature = "window"))]
pub fn run_window(_: &ViewArgs) -> Result<(), String> {
    Err(
        "this build has no window (feature `window`): `cargo xtask view` runs the build \
         with it; --frames N renders without one"
            .into(),
    )
}

#[cfg(feature = "window")]
mod window {
    use super::*;
    use minifb::{Key, KeyRepeat, MouseButton, MouseMode, Window, WindowOptions};
    use std::sync::mpsc;

    /// Opens the window and renders until it closes (see the module documentation).
    pub fn run_window(args: &ViewArgs) -> Result<(), String> {
        let mut viewer = Viewer::new(&args.scene, &args.accel, args.threads)?;
        let mut size = args.size;
        let mut shading = args.shading;
        let mut window = open(size)?;
        let mut step = 0u32;
        let mut accumulated: Vec<rt_geom::Vec3> = Vec::new();
        // A structure being built on another thread: its name and where it arrives.
        let mut pending: Option<(String, Instant, mpsc::Receiver<Result<Built, String>>)> = None;
        let mut last: Option<Frame> = None;
        // Where the pointer was while the left button was down (dragging turns the camera).
        let mut drag: Option<(f32, f32)> = None;
        // Whether the next frame starts over (the first one, and after any change).
        let mut restart = true;
        while window.is_open() && !window.is_key_down(Key::Escape) {
            let mut moved = std::mem::take(&mut restart);
            // Moves repeat while a key is held; switches act once per press.
            for key in window.get_keys_pressed(KeyRepeat::Yes) {
                moved |= steer(&mut viewer.scene.camera, key);
            }
            let pointer = window.get_mouse_pos(MouseMode::Discard);
            match (pointer, window.get_mouse_down(MouseButton::Left)) {
                (Some((x, y)), true) => {
                    if let Some((px, py)) = drag.filter(|&p| p != (x, y)) {
                        turn(&mut viewer.scene.camera, (px - x) * 0.005, (py - y) * 0.005);
                        moved = true;
                    }
                    drag = Some((x, y));
                }
                _ => drag = None,
            }
            for key in window.get_keys_pressed(KeyRepeat::No) {
                match key {
                    Key::Tab if pending.is_none() => {
                        let name = next_structure(&viewer.accel).to_string();
                        let (tx, rx) = mpsc::channel();
                        let (scene, n) = (viewer.scene.clone(), name.clone());
                        std::thread::spawn(move || {
                            let built = pool(1).and_then(|p| build_on(&p, &scene, &n));
                            let _ = tx.send(built);
                        });
                        pending = Some((name, Instant::now(), rx));
                    }
                    Key::M => {
                        shading = shading.next();
                        moved = true;
                    }
                    Key::F => {
                        size = if size == args.size {
                            (size.0 / 2, size.1 / 2)
                        } else {
                            args.size
                        };
                        window = open(size)?;
                        moved = true;
                    }
                    _ => {}
                }
            }
            if let Some((name, _, rx)) = &pending {
                match rx.try_recv() {
                    Ok(Ok(built)) => {
                        viewer.built = built;
                        viewer.accel = name.clone();
                        pending = None;
                        moved = true;
                    }
                    Ok(Err(e)) => return Err(format!("building {name}: {e}")),
                    Err(_) => {}
                }
            }
            if moved {
                step = 0;
            } else if !args.no_refine && (step < 3 || shading == Shading::Path) {
                step += 1;
            } else {
                // At rest and refined: nothing new to show but the build's progress.
                if let Some((name, since, _)) = &pending {
                    let building = Some((name.as_str(), since.elapsed().as_secs_f64()));
                    let last = last.as_ref();
                    window.set_title(&title(&viewer.accel, shading, last, step, building));
                }
                window.update();
                std::thread::sleep(std::time::Duration::from_millis(10));
                continue;
            }
            let mut frame = viewer.frame(shading, &shading.options(size, step))?;
            if shading == Shading::Path {
                accumulate(&mut accumulated, &mut frame, step, size);
            }
            let building = pending
                .as_ref()
                .map(|(n, since, _)| (n.as_str(), since.elapsed().as_secs_f64()));
            window.set_title(&title(&viewer.accel, shading, Some(&frame), step, building));
            window
                .update_with_buffer(&frame.pixels, size.0 as usize, size.1 as usize)
                .map_err(|e| e.to_string())?;
            last = Some(frame);
        }
        Ok(())
    }

    fn open((w, h): (u32, u32)) -> Result<Window, String> {
        let mut window = Window::new("rt view", w as usize, h as usize, WindowOptions::default())
            .map_err(|e| format!("opening a window: {e}"))?;
        window.set_target_fps(0);
        Ok(window)
    }

    /// Moves or turns the camera for `key`; whether it did.
    fn steer(camera: &mut Camera, key: Key) -> bool {
        let forward = camera.look_at - camera.eye;
        let distance = forward.length();
        let (dir, up) = (forward / distance, camera.up.normalize());
        let right = dir.cross(up).normalize();
        let step = 0.05 * distance;
        let shift = match key {
            Key::W => dir * step,
            Key::S => -dir * step,
            Key::D => right * step,
            Key::A => -right * step,
            Key::E => up * step,
            Key::Q => -up * step,
            _ => rt_geom::Vec3::ZERO,
        };
        if shift != rt_geom::Vec3::ZERO {
            camera.eye += shift;
            camera.look_at += shift;
            return true;
        }
        let (yaw, pitch) = match key {
            Key::Left => (0.05, 0.0),
            Key::Right => (-0.05, 0.0),
            Key::Up => (0.0, 0.05),
            Key::Down => (0.0, -0.05),
            _ => return false,
        };
        turn(camera, yaw, pitch);
        true
    }

    /// Turns the camera about its eye: `yaw` radians about its up axis, `pitch` about its
    /// right axis.
    fn turn(camera: &mut Camera, yaw: f32, pitch: f32) {
        use rt_geom::glam::Quat;
        let forward = camera.look_at - camera.eye;
        let up = camera.up.normalize();
        let right = forward.cross(up).normalize_or_zero();
        let rotation = Quat::from_axis_angle(up, yaw) * Quat::from_axis_angle(right, pitch);
        camera.look_at = camera.eye + rotation * forward;
    }

    /// Path tracing at rest: the frame's linear colours averaged with the `step` before it,
    /// and its pixels encoded from the average.
    fn accumulate(
        sum: &mut Vec<rt_geom::Vec3>,
        frame: &mut Frame,
        step: u32,
        (width, height): (u32, u32),
    ) {
        if step == 0 || sum.len() != frame.linear.len() {
            *sum = frame.linear.clone();
        } else {
            let n = step as f32;
            for (s, c) in sum.iter_mut().zip(&frame.linear) {
                *s = (*s * n + *c) / (n + 1.0);
            }
        }
        let pixels = sum.clone();
        frame.pixels = words(&rt_shade::Image {
            width,
            height,
            pixels,
        });
    }
}
