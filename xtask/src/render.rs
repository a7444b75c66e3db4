//! `cargo xtask render`: a scene (the built-in chess board, an OBJ or an NFF file) rendered by
//! Whitted ray tracing or path tracing with any registered structure, to a PNG, with ray
//! statistics.

use crate::registry;
use crate::run::{bar, pool, spinner};
use rt_accel_bvh::{BvhParams, Instance, InstanceBvh, Object};
use rt_geom::{Accel, Hit, Ray, Triangle};
use rt_packet::PacketAccel;
use rt_shade::{
    Camera, Integrator, Packets, PathOptions, Projection, Queries, RayStats, RenderOptions, Scene,
    SceneObjects, ShadeOptions, SingleRays,
};
use serde::Serialize;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// What `cargo xtask render` was asked for (its command-line options).
#[derive(Clone, Debug, clap::Args)]
pub struct RenderArgs {
    /// `chess` or `chess-lamp` (built in: the board, or with a lamp whose bulb casts no
    /// shadow), or an .obj or .nff file.
    #[arg(long, default_value = "chess")]
    pub scene: String,
    /// Structure name (`cargo xtask accels`); with `--objects pieces|instanced`, the structure
    /// of each object.
    #[arg(long, default_value = "bvh8")]
    pub accel: String,
    /// The chess scene as one structure over all triangles (`flat`), or two-level: the board
    /// and each piece an object with its own structure under a top-level BVH (`pieces`), or
    /// one object per piece shape placed by 32 instances (`instanced`).
    #[arg(long, value_enum, default_value_t = Objects::Flat)]
    pub objects: Objects,
    /// Image size WxH (default: the scene's own; chess 800x600, NFF 512x512).
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Deepest ray, 1 to 32; the eye ray is depth 1.
    #[arg(long, default_value_t = 5)]
    pub depth: u32,
    /// Supersampling: N x N eye rays per pixel.
    #[arg(long, default_value_t = 1)]
    pub samples: u32,
    /// `whitted` (shadow, mirror and refracted rays) or `path` (path tracing: diffuse light
    /// bounced too, `--spp` paths per pixel).
    #[arg(long, value_enum, default_value_t = IntegratorArg::Whitted)]
    pub integrator: IntegratorArg,
    /// Paths per pixel with `--integrator path`.
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// The seed of the path tracer's random numbers (an image repeats for a seed).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Skip secondary rays whose weight is below this in every channel (0: cast all).
    #[arg(long, default_value_t = 0.0)]
    pub min_weight: f32,
    /// Fresnel weighting of reflection and refraction on transmitting surfaces.
    #[arg(long)]
    pub fresnel: bool,
    /// Orthographic camera instead of the scene's perspective one (same view height at the
    /// look-at point).
    #[arg(long)]
    pub orthographic: bool,
    /// Thin-lens aperture radius for depth of field (focus on the look-at point); 0 = pinhole.
    #[arg(long, default_value_t = 0.0)]
    pub aperture: f32,
    /// Threads (0 = all cores; at most 1024).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Trace every ray one by one even when the structure has a packet path (by default each
    /// 16x16 tile's eye rays, its shadow rays to each light and its reflected and refracted
    /// rays go through it as groups, packets where coherent; the image is the same).
    #[arg(long)]
    pub no_packets: bool,
    /// PNG to write (default target/render/SCENE.png; missing folders are created).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write ray statistics as JSON.
    #[arg(long)]
    pub stats: Option<PathBuf>,
    /// Animate the chess scene over N frames (a knight's jump, a toppling pawn, a rippling
    /// cloth) into the folder `--out` (default target/render/chess-frames), timing each way
    /// of updating the structure and the trace after it.
    #[arg(long)]
    pub frames: Option<u32>,
    /// Count bounding-volume and primitive tests per ray (runs a build with the `counters`
    /// feature; eye rays then go one by one, so every test is counted).
    #[arg(long)]
    pub count: bool,
    /// Instead of shading, the tests of each pixel's eye ray as a false-colour map with a
    /// legend: `boxes` (bounding-volume: node, cell) or `prims` (runs the counting build).
    #[arg(long, value_enum)]
    pub heatmap: Option<crate::heatmap::Heatmap>,
    /// No progress bars (tests).
    #[arg(skip)]
    pub quiet: bool,
}

impl RenderArgs {
    /// The render options asked for: `--size` or else `size`, samples, depth, weight, Fresnel;
    /// checked.
    pub fn options(&self, size: (u32, u32)) -> Result<RenderOptions, String> {
        let (width, height) = self.size.unwrap_or(size);
        let options = RenderOptions {
            width,
            height,
            samples_per_axis: self.samples,
            shade: ShadeOptions {
                max_depth: self.depth,
                min_weight: self.min_weight,
                fresnel: self.fresnel,
                ..ShadeOptions::default()
            },
            integrator: match self.integrator {
                IntegratorArg::Whitted => Integrator::Whitted,
                IntegratorArg::Path => Integrator::Path(PathOptions {
                    samples: self.spp,
                    seed: self.seed,
                    ..PathOptions::default()
                }),
            },
        };
        options.check()?;
        Ok(options)
    }
}

impl Default for RenderArgs {
    /// The command line's defaults.
    fn default() -> Self {
        #[derive(clap::Parser)]
        struct Defaults {
            #[command(flatten)]
            args: RenderArgs,
        }
        <Defaults as clap::Parser>::parse_from(["render"]).args
    }
}

/// `--integrator`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum IntegratorArg {
    /// The Whitted rules.
    Whitted,
    /// Path tracing.
    Path,
}

/// `--objects`: how the scene's geometry is organised.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Objects {
    /// One structure over every primitive.
    Flat,
    /// Each chess piece and the board an object with its own structure, under a top level.
    Pieces,
    /// One object per chess piece shape, placed by instances under a top level.
    Instanced,
}

/// The `--stats` file.
#[derive(Clone, Debug, Serialize)]
pub struct RenderStats {
    /// The rays cast, by kind.
    #[serde(flatten)]
    pub rays: RayStats,
    /// Tracing time (build excluded).
    pub seconds: f64,
    pub scene: String,
    pub accel: String,
    pub width: u32,
    pub height: u32,
    pub primitives: usize,
    pub build_seconds: f64,
    /// Whether the rays went through the structure's packet path (a tile's groups of rays).
    pub packets: bool,
    /// `--objects`.
    pub objects: Objects,
    /// Bounding-volume (node, cell) tests while tracing, with `--count`.
    pub node_tests: Option<u64>,
    /// Primitive tests while tracing, with `--count`.
    pub prim_tests: Option<u64>,
    /// What the image maps, with `--heatmap` (then only eye rays are cast).
    pub heatmap: Option<crate::heatmap::Heatmap>,
}

/// A finished render: where the PNG went, and the statistics.
pub struct RenderSummary {
    pub out: PathBuf,
    pub stats: RenderStats,
    pub image: rt_shade::Image,
    pub warnings: Vec<String>,
}

impl RenderSummary {
    /// One line for the terminal.
    pub fn line(&self) -> String {
        let s = &self.stats;
        let rays = s.rays.total();
        let counted = match (s.node_tests, s.prim_tests) {
            (Some(n), Some(p)) => format!(
                "; per ray {:.1} box tests, {:.1} primitive tests",
                n as f64 / rays.max(1) as f64,
                p as f64 / rays.max(1) as f64
            ),
            _ => String::new(),
        };
        let what = match s.heatmap {
            Some(crate::heatmap::Heatmap::Boxes) => ", a heatmap of box tests",
            Some(crate::heatmap::Heatmap::Prims) => ", a heatmap of primitive tests",
            None => "",
        };
        format!(
            "{} {}x{} with {}{}{}{what}: {} eye rays ({} hit), {}{} reflected, {} refracted, {} shadow; \
             build {:.3} s, trace {:.3} s ({:.2} Mrays/s){} -> {}",
            s.scene,
            s.width,
            s.height,
            s.accel,
            match s.objects {
                Objects::Flat => "",
                Objects::Pieces => " per piece under a top level",
                Objects::Instanced => " per piece shape, 33 instances under a top level",
            },
            if s.packets { ", tiles as packets" } else { "" },
            s.rays.eye_rays,
            s.rays.eye_hits,
            match s.rays.diffuse {
                0 => String::new(),
                n => format!("{n} diffuse, "),
            },
            s.rays.reflected,
            s.rays.refracted,
            s.rays.shadow,
            s.build_seconds,
            s.seconds,
            rays as f64 / s.seconds.max(1e-9) / 1e6,
            counted,
            self.out.display()
        )
    }
}

/// How two renders of one scene differ: an instanced scene against its flattened form, where
/// rays carried into each object's space round differently than the flattened vertices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Differences {
    /// Pixels that differ by more than [`Differences::VISIBLE`] in a channel.
    pub pixels: usize,
    /// The largest difference in any channel.
    pub max: f32,
    /// Pixels compared.
    pub of: usize,
}

impl Differences {
    /// A difference that shows: two steps of an 8-bit channel.
    pub const VISIBLE: f32 = 2.0 / 255.0;

    /// `a` against `b` (the same size).
    pub fn between(a: &rt_shade::Image, b: &rt_shade::Image) -> Self {
        let d: Vec<f32> = a
            .pixels
            .iter()
            .zip(&b.pixels)
            .map(|(p, q)| (*p - *q).abs().max_element())
            .collect();
        Differences {
            pixels: d.iter().filter(|&&x| x > Self::VISIBLE).count(),
            max: d.iter().copied().fold(0.0, f32::max),
            of: d.len(),
        }
    }

    /// What instancing is held to: at most 1% of the pixels differ visibly (silhouettes and
    /// shadow edges, where the rounding of a transform moves a ray across an edge; how far a
    /// single pixel may move depends on what it then sees, so no bound on `max`).
    pub fn within_instancing_tolerance(&self) -> bool {
        self.pixels * 100 <= self.of
    }
}

/// Parses `WxH`.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("size '{s}' is not WIDTHxHEIGHT (e.g. 640x480)");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    Ok((
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    ))
}

/// Loads, builds, renders and writes the PNG (and the statistics file): the phases below.
pub fn render(args: &RenderArgs) -> Result<RenderSummary, String> {
    let entry = registry::find(&args.accel).ok_or_else(|| registry::unknown(&args.accel))?;
    let out = output_path(args)?;
    let (scene, objects) = load(args)?;
    let options = args.options(scene.resolution.unwrap_or((640, 480)))?;
    let pool = pool(args.threads)?;
    let built = pool.install(|| build(entry, &scene, objects.as_ref(), args))?;
    let (rendered, counts) = match args.heatmap {
        Some(kind) => {
            pool.install(|| crate::heatmap::heatmap(&scene, built.single.as_ref(), &options, kind))?
        }
        None => trace(&scene, &built, &options, &pool, args.quiet)?,
    };
    report(args, entry, scene, &built, rendered, counts, out)
}

/// Report: the PNG, the statistics (and their `--stats` file), the scene's warnings.
fn report(
    args: &RenderArgs,
    entry: &registry::AccelEntry,
    scene: Scene,
    built: &Built,
    rendered: rt_shade::Rendered,
    counts: rt_geom::counters::Counts,
    out: Option<PathBuf>,
) -> Result<RenderSummary, String> {
    let out =
        out.unwrap_or_else(|| PathBuf::from("target/render").join(format!("{}.png", scene.name)));
    rendered.image.save_png(&out)?;
    let stats = RenderStats {
        rays: rendered.stats,
        seconds: rendered.seconds,
        scene: scene.name.clone(),
        accel: entry.name.to_string(),
        width: rendered.image.width,
        height: rendered.image.height,
        primitives: scene.shapes.len(),
        build_seconds: built.seconds,
        packets: built.packets.is_some(),
        objects: args.objects,
        node_tests: built.counting.then_some(counts.nodes),
        prim_tests: built.counting.then_some(counts.prims),
        heatmap: args.heatmap,
    };
    if let Some(path) = &args.stats {
        let json = serde_json::to_string_pretty(&stats).map_err(|e| e.to_string())?;
        std::fs::write(path, json + "\n").map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(RenderSummary {
        out,
        stats,
        image: rendered.image,
        warnings: scene.render_warnings(),
    })
}

/// `--out`, checked before any work: a PNG path, or `None` for the default.
fn output_path(args: &RenderArgs) -> Result<Option<PathBuf>, String> {
    match &args.out {
        Some(out)
            if out
                .extension()
                .is_none_or(|e| !e.eq_ignore_ascii_case("png")) =>
        {
            Err(format!(
                "{}: the image is written as PNG; name it *.png (missing folders are created)",
                out.display()
            ))
        }
        out => Ok(out.clone()),
    }
}

/// Load: the scene (with `--orthographic` and `--aperture` applied), and its objects and
/// instances when `--objects` asks for two levels.
pub(crate) fn load(args: &RenderArgs) -> Result<(Scene, Option<SceneObjects>), String> {
    let spinner = (!args.quiet).then(|| spinner(format!("loading {}", args.scene)));
    let (mut scene, objects) = match (args.objects, args.scene.as_str()) {
        (Objects::Flat, _) => (
            rt_shade::load_scene(&args.scene).map_err(|e| e.to_string())?,
            None,
        ),
        (form, "chess") => {
            let form = match form {
                Objects::Instanced => rt_shade::ChessForm::Instanced,
                _ => rt_shade::ChessForm::Pieces,
            };
            let (scene, objects) = rt_shade::chess_objects(form);
            (scene, Some(objects))
        }
        (_, other) => {
            return Err(format!(
                "--objects pieces and instanced are forms of the chess scene (--scene chess), \
                 not of {other}"
            ));
        }
    };
    if let Some(pb) = spinner {
        pb.finish_and_clear();
    }
    adjust_camera(&mut scene, args)?;
    Ok((scene, objects))
}

/// What the build phase made: the structure single rays go through, the packet path when
/// the tiles go through one, and how long it took.
pub(crate) struct Built {
    pub(crate) single: Box<dyn Accel>,
    packets: Option<Arc<dyn PacketAccel>>,
    seconds: f64,
    /// Whether tests are counted (`--count` in a counting build).
    counting: bool,
}

/// Build: a two-level structure (`--objects`), or the entry's packet path over a triangle
/// scene (its single rays the packet structure's own unless they belong to another entry),
/// or the entry over the scene's shapes.
pub(crate) fn build(
    entry: &registry::AccelEntry,
    scene: &Scene,
    objects: Option<&SceneObjects>,
    args: &RenderArgs,
) -> Result<Built, String> {
    let spinner = (!args.quiet).then(|| {
        spinner(format!(
            "building {} over {} primitives",
            entry.name,
            scene.shapes.len()
        ))
    });
    let start = Instant::now();
    let counting = (args.count || args.heatmap.is_some()) && rt_geom::counters::ENABLED;
    let packet_path = entry
        .packets
        .filter(|_| objects.is_none() && !args.no_packets && !counting);
    let triangles: Option<Vec<Triangle>> = packet_path.and_then(|_| {
        scene
            .shapes
            .iter()
            .map(|s| s.as_triangle().copied())
            .collect()
    });
    let (single, packets) = match (objects, packet_path.zip(triangles)) {
        (Some(objects), _) => (build_two_level(entry, objects)?, None),
        (None, Some((build, tris))) => {
            let packets: Arc<dyn PacketAccel> = build(&tris)
                .map_err(|e| format!("{}: {e}", entry.name))?
                .into();
            let single = match entry.packet_only {
                Some(_) => entry.build_any(&scene.shapes)?,
                None => Box::new(packets.clone()),
            };
            (single, Some(packets))
        }
        (None, None) => (entry.build_any(&scene.shapes)?, None),
    };
    if let Some(pb) = spinner {
        pb.finish_and_clear();
    }
    Ok(Built {
        single,
        packets,
        seconds: start.elapsed().as_secs_f64(),
        counting,
    })
}

/// Trace: the image tile by tile on the pool, a tile's rays through the packet path when
/// there is one; the tests counted per thread when the build counts them.
pub(crate) fn trace(
    scene: &Scene,
    built: &Built,
    options: &RenderOptions,
    pool: &rayon::ThreadPool,
    quiet: bool,
) -> Result<(rt_shade::Rendered, rt_geom::counters::Counts), String> {
    let progress = if quiet {
        indicatif::ProgressBar::hidden()
    } else {
        bar(options.tiles(), format!("render {}", scene.name))
    };
    pool.broadcast(|_| rt_geom::counters::take());
    let single = built.single.as_ref();
    let render = |packets: Option<Packets<'_>>| {
        rt_shade::render_with_packets(scene, single, packets, options, &|n| progress.inc(n))
    };
    let rendered = pool
        .install(|| match built.packets.as_deref() {
            Some(p) => with_packets(single, p, |packets| render(Some(packets))),
            None => render(None),
        })
        .map_err(|e| e.to_string())?;
    progress.finish_and_clear();
    let mut counts = rt_geom::counters::Counts::default();
    for c in pool.broadcast(|_| rt_geom::counters::take()) {
        counts += c;
    }
    Ok((rendered, counts))
}

/// Calls `f` with `packets` as the renderer takes a packet path: a group's rays through
/// `packets`, each skipping the primitive it leaves where the path can skip one, else ray by
/// ray through `single`'s filtered queries (a ray leaves a primitive only through a structure
/// with them).
pub fn with_packets<R>(
    single: &dyn Accel,
    packets: &dyn PacketAccel,
    f: impl FnOnce(Packets<'_>) -> R,
) -> R {
    let single = SingleRays(single);
    let leaving_path = packets.leaving();
    let intersect =
        |rays: &[Ray], leaving: &[Option<u32>], out: &mut [Option<Hit>]| match leaving_path {
            _ if leaving.is_empty() => packets.intersect_group(rays, out),
            Some(l) => l.intersect_group_leaving(rays, leaving, out),
            None => single.intersect(rays, leaving, out),
        };
    let occluded = |rays: &[Ray], leaving: &[Option<u32>], out: &mut [bool]| match leaving_path {
        _ if leaving.is_empty() => packets.occluded_group(rays, out),
        Some(l) => l.occluded_group_leaving(rays, leaving, out),
        None => single.occluded(rays, leaving, out),
    };
    f(Packets {
        intersect: &intersect,
        occluded: &occluded,
    })
}

/// The scene's instances as the two-level structure takes them.
pub fn instances(objects: &SceneObjects) -> Vec<Instance> {
    let to = |i: &rt_shade::SceneInstance| Instance {
        object: i.object,
        transform: i.transform,
    };
    objects.instances.iter().map(to).collect()
}

/// A two-level structure: each object built with `entry`, a top-level BVH over the instances.
pub fn build_two_level(
    entry: &registry::AccelEntry,
    objects: &SceneObjects,
) -> Result<Box<dyn Accel>, String> {
    let built: Vec<Object<Box<dyn Accel>>> = objects
        .objects
        .iter()
        .map(|o| {
            let accel = entry.build_any(&o.shapes)?;
            Object::new(&o.shapes, accel).map_err(|e| e.to_string())
        })
        .collect::<Result<_, String>>()?;
    let top = InstanceBvh::build(built, &instances(objects), BvhParams::balanced())
        .map_err(|e| format!("top level: {e}"))?;
    Ok(Box::new(top))
}

/// Applies `--orthographic` and `--aperture` to the scene's camera.
fn adjust_camera(scene: &mut Scene, args: &RenderArgs) -> Result<(), String> {
    let cam: Camera = scene.camera;
    let distance = (cam.look_at - cam.eye).length();
    if args.orthographic {
        let Projection::Perspective { vfov_deg } = cam.projection else {
            return Ok(());
        };
        let height = 2.0 * distance * (vfov_deg.to_radians() * 0.5).tan();
        scene.camera = Camera::orthographic(cam.eye, cam.look_at, cam.up, height);
    }
    if args.aperture != 0.0 {
        if args.orthographic {
            return Err("--aperture needs the perspective camera".into());
        }
        scene.camera = cam.with_thin_lens(args.aperture, distance);
    }
    scene.camera.check()
}
