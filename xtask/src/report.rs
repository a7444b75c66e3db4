//! `cargo xtask bench --report DIR`: the bench and the scaling sweep in one run, written as a
//! self-contained report: `index.md` (the machine, the commit and the exact command; a verdict
//! per scene; the tables) and PNG plots (plotters).

use crate::bench::{self, BenchOptions, Record};
use crate::sweep::{self, SweepOptions, SweepRecord, loglog_slope};
use plotters::prelude::*;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The sweep's structures: one of each kind, brute force where affordable, obvhs.
pub const SWEEP_ACCELS: &str = "brute,bvh,bvh8,kd,kd-midpoint,bsp,grid,grid-dda,grid2,octree,obvhs";

/// The SPD renders' structures (those that hold spheres and cones).
pub const SPD_ACCELS: &str = "bvh8,kd,bsp,grid,grid2,octree";

#[derive(Clone, Debug)]
pub struct ReportOptions {
    pub dir: PathBuf,
    pub quick: bool,
    pub accels: Option<String>,
    pub scenes: Option<String>,
    pub threads: Vec<usize>,
    /// The command line, recorded in the report.
    pub command: String,
}

/// Runs the bench and the sweep and writes the report; returns the path of `index.md`.
pub fn report(opts: &ReportOptions) -> Result<PathBuf, String> {
    let dir = &opts.dir;
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let threads = *opts.threads.iter().max().unwrap_or(&1);
    // A quick report measures the largest thread count only (a run of under two minutes).
    let bench_threads = if opts.quick {
        vec![threads]
    } else {
        opts.threads.clone()
    };
    let records = bench::bench(&BenchOptions {
        quick: opts.quick,
        accels: opts.accels.clone(),
        scenes: opts.scenes.clone(),
        json: Some(dir.join("bench.json")),
        threads: bench_threads,
    })?;
    let sweep = sweep::sweep(&SweepOptions {
        quick: opts.quick,
        accels: Some(SWEEP_ACCELS.into()),
        json: Some(dir.join("sweep.json")),
        threads,
    })?;
    let spd = spd_renders(opts.quick)?;
    write(opts, &records, &sweep, &spd, threads)
}

/// Writes `index.md` and the plots from measured records.
fn write(
    opts: &ReportOptions,
    records: &[Record],
    sweep: &[SweepRecord],
    spd: &[SpdRow],
    threads: usize,
) -> Result<PathBuf, String> {
    let dir = &opts.dir;
    let fonts = register_font();
    let mut plots = Vec::new();
    let mut plot_errors = Vec::new();
    if fonts {
        let mut attempt = |name: &str, r: Result<(), String>| match r {
            Ok(()) => plots.push(name.to_string()),
            Err(e) => plot_errors.push(format!("{name}: {e}")),
        };
        attempt(
            "throughput.png",
            plot_throughput(&dir.join("throughput.png"), records, threads),
        );
        attempt(
            "tradeoff.png",
            plot_tradeoff(&dir.join("tradeoff.png"), records, threads),
        );
        if records
            .iter()
            .any(|r| r.threads == threads && r.rays.contains('-'))
        {
            attempt(
                "packets.png",
                plot_packets(&dir.join("packets.png"), records, threads),
            );
        }
        for family in sweep::FAMILIES {
            let name = format!("sweep-{family}.png");
            attempt(&name, plot_sweep(&dir.join(&name), sweep, family));
        }
    } else {
        plot_errors
            .push("no TrueType font found (DejaVu Sans or Liberation Sans): plots skipped".into());
    }
    let index = dir.join("index.md");
    let text = index_md(opts, records, sweep, spd, threads, &plots, &plot_errors);
    std::fs::write(&index, text).map_err(|e| format!("{}: {e}", index.display()))?;
    Ok(index)
}

/// Fonts plotters can draw with: the first TrueType sans font found on the system.
fn register_font() -> bool {
    const CANDIDATES: [&str; 3] = [
        "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
        "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
        "/usr/share/fonts/TTF/DejaVuSans.ttf",
    ];
    for path in CANDIDATES {
        if let Ok(bytes) = std::fs::read(path) {
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                return true;
            }
        }
    }
    false
}

/// The machine: CPU model and logical cores.
fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{cpu}, {cores} logical cores, {}", std::env::consts::OS)
}

/// `git describe`-like: the commit, and `-dirty` with uncommitted changes.
fn commit() -> String {
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    match git(&["rev-parse", "--short=12", "HEAD"]) {
        Some(hash) => {
            let dirty = git(&["status", "--porcelain", "--untracked-files=no"])
                .is_some_and(|s| !s.is_empty());
            if dirty { format!("{hash}-dirty") } else { hash }
        }
        None => "unknown (not a git checkout)".into(),
    }
}

/// The records of one thread count, grouped by scene then ray set.
fn by_scene(records: &[Record], threads: usize) -> BTreeMap<(String, String), Vec<&Record>> {
    let mut map: BTreeMap<(String, String), Vec<&Record>> = BTreeMap::new();
    for r in records.iter().filter(|r| r.threads == threads) {
        map.entry((r.scene.clone(), r.rays.clone()))
            .or_default()
            .push(r);
    }
    map
}

fn index_md(
    opts: &ReportOptions,
    records: &[Record],
    sweep: &[SweepRecord],
    spd: &[SpdRow],
    threads: usize,
    plots: &[String],
    plot_errors: &[String],
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# rt bench report\n");
    let _ = writeln!(s, "- machine: {}", machine());
    let _ = writeln!(s, "- commit: `{}`", commit());
    let _ = writeln!(s, "- command: `{}`", opts.command);
    let _ = writeln!(
        s,
        "- throughput: median Mrays/s of {} timed runs, single rays; ratios against the faster \
         obvhs preset measured in the same run. Verdicts use {threads} thread(s).\n",
        if opts.quick { 3 } else { 5 }
    );
    let _ = writeln!(s, "## Verdict per scene\n");
    let _ = writeln!(
        s,
        "Packet lines: the fastest packet path and tile size on the same rays, against the same \
         structure's single rays.\n"
    );
    let mut scenes: Vec<&str> = records.iter().map(|r| r.scene.as_str()).collect();
    scenes.dedup();
    let groups = by_scene(records, threads);
    for scene in &scenes {
        let prims = records
            .iter()
            .find(|r| r.scene == *scene)
            .map_or(0, |r| r.prims);
        let _ = writeln!(s, "### {scene} ({prims} triangles)\n");
        for set in ["primary", "shadow", "diffuse"] {
            let Some(rs) = groups.get(&(scene.to_string(), set.to_string())) else {
                continue;
            };
            let mut sorted: Vec<&&Record> = rs.iter().collect();
            sorted.sort_by(|a, b| b.mrays_s.total_cmp(&a.mrays_s));
            let Some(best) = sorted.first() else { continue };
            let margin = sorted.get(1).map_or(String::new(), |second| {
                format!(
                    ", {:.2}x the next ({})",
                    best.mrays_s / second.mrays_s.max(1e-9),
                    second.accel
                )
            });
            let _ = writeln!(
                s,
                "- **{set}**: `{}` at {:.2} Mrays/s{margin}; build {:.0} ms, {:.1} MiB{}",
                best.accel,
                best.mrays_s,
                best.build_ms,
                best.bytes as f64 / (1 << 20) as f64,
                best.ratio_vs_obvhs
                    .map_or(String::new(), |x| format!(", {x:.2}x obvhs")),
            );
            if let Some(line) = packet_verdict(records, scene, set, threads) {
                let _ = writeln!(s, "{line}");
            }
        }
        let _ = writeln!(s);
    }
    for p in plots.iter().filter(|p| !p.starts_with("sweep")) {
        let _ = writeln!(s, "![{p}]({p})\n");
    }
    let _ = writeln!(s, "## Tables\n");
    // With the `embree` feature, a last column: the ratio to Embree.
    let embree = records.iter().any(|r| r.ratio_vs_embree.is_some());
    let _ = writeln!(
        s,
        "| structure | scene | rays | threads | build ms | Mrays/s | vs obvhs | MiB | SAH |{}",
        if embree { " vs embree |" } else { "" }
    );
    let _ = writeln!(
        s,
        "|---|---|---|---:|---:|---:|---:|---:|---:|{}",
        if embree { "---:|" } else { "" }
    );
    for r in records {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.1} | {:.2} | {} | {:.1} | {} |{}",
            r.accel,
            r.scene,
            r.rays,
            r.threads,
            r.build_ms,
            r.mrays_s,
            r.ratio_vs_obvhs.map_or("-".into(), |x| format!("{x:.2}x")),
            r.bytes as f64 / (1 << 20) as f64,
            r.sah_cost.map_or("-".into(), |x| format!("{x:.1}")),
            match (embree, r.ratio_vs_embree) {
                (false, _) => String::new(),
                (true, x) => format!(" {} |", x.map_or("-".into(), |x| format!("{x:.2}x"))),
            },
        );
    }
    let _ = writeln!(s, "\n## Scaling sweep\n");
    let _ = writeln!(
        s,
        "Tessellated spheres, random soups and a teapot in a stadium from {} to {} triangles, {threads} thread(s), \
         128x128 camera rays. Slopes are least-squares fits of log(time) against log(N): \
         1 is linear (brute force), 1/3 the uniform grid's N^(1/3), ~0.1-0.3 logarithmic.\n",
        sweep.iter().map(|r| r.n).min().unwrap_or(0),
        sweep.iter().map(|r| r.n).max().unwrap_or(0)
    );
    let _ = writeln!(s, "| family | structure | time per ray ~ N^ | build ~ N^ |");
    let _ = writeln!(s, "|---|---|---:|---:|");
    for (family, accel, ray_slope, build_slope) in slopes(sweep) {
        let f = |x: Option<f64>| x.map_or("-".into(), |x| format!("{x:.2}"));
        let _ = writeln!(
            s,
            "| {family} | {accel} | {} | {} |",
            f(ray_slope),
            f(build_slope)
        );
    }
    let _ = writeln!(s);
    for p in plots.iter().filter(|p| p.starts_with("sweep")) {
        let _ = writeln!(s, "![{p}]({p})\n");
    }
    let _ = writeln!(s, "## SPD scenes rendered (Whitted, depth 5)\n");
    if spd.is_empty() {
        let _ = writeln!(
            s,
            "No SPD scenes found (`../shared/scenes/spd` or `$RT_SPD`).\n"
        );
    } else {
        let _ = writeln!(
            s,
            "Haines' Standard Procedural Databases with analytic spheres and cones, rendered by \
             `cargo xtask render` at {0}x{0}; Mrays/s counts every ray cast (eye, shadow, \
             reflected, refracted).\n",
            spd[0].size
        );
        let _ = writeln!(
            s,
            "| scene | primitives | structure | build ms | render s | rays | Mrays/s |"
        );
        let _ = writeln!(s, "|---|---:|---|---:|---:|---:|---:|");
        for r in spd {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.1} | {:.3} | {} | {:.2} |",
                r.scene,
                r.prims,
                r.accel,
                r.build_ms,
                r.seconds,
                r.rays,
                r.rays as f64 / r.seconds.max(1e-9) / 1e6
            );
        }
        let _ = writeln!(s);
        let mut scenes: Vec<&str> = spd.iter().map(|r| r.scene.as_str()).collect();
        scenes.dedup();
        for scene in scenes {
            let mut rows: Vec<&SpdRow> = spd.iter().filter(|r| r.scene == scene).collect();
            rows.sort_by(|a, b| a.seconds.total_cmp(&b.seconds));
            if let [best, next, ..] = rows[..] {
                let _ = writeln!(
                    s,
                    "- **{scene}**: `{}` renders fastest, {:.2}x `{}`",
                    best.accel,
                    next.seconds / best.seconds.max(1e-9),
                    next.accel
                );
            }
        }
        let _ = writeln!(s);
    }
    if !plot_errors.is_empty() {
        let _ = writeln!(s, "## Plot problems\n");
        for e in plot_errors {
            let _ = writeln!(s, "- {e}");
        }
    }
    let _ = writeln!(
        s,
        "\nRaw records: [bench.json](bench.json), [sweep.json](sweep.json)."
    );
    s
}

/// One SPD scene rendered with one structure.
struct SpdRow {
    scene: String,
    prims: usize,
    accel: String,
    size: u32,
    build_ms: f64,
    seconds: f64,
    rays: u64,
}

/// Renders every SPD scene present with each of [`SPD_ACCELS`] (on all cores).
fn spd_renders(quick: bool) -> Result<Vec<SpdRow>, String> {
    // The full report adds the larger sizes of balls, tetra and mount: the same scenes at 9x,
    // 16x-64x and 16x the primitives, a scaling series on real scenes.
    let names: Vec<&str> = if quick {
        vec!["balls", "gears", "tree"]
    } else {
        let mut v = rt_testkit::models::SPD_NAMES.to_vec();
        v.extend([
            "balls-size5",
            "balls-size6",
            "tetra-size8",
            "tetra-size9",
            "mount-size8",
        ]);
        v
    };
    let size = if quick { 96 } else { 256 };
    let accels = crate::registry::select(Some(SPD_ACCELS))?;
    let found: Vec<_> = names
        .iter()
        .filter_map(|n| rt_testkit::models::spd_path(n).map(|p| (*n, p)))
        .collect();
    let pb = crate::run::bar((found.len() * accels.len()) as u64, "SPD renders");
    let mut rows = Vec::new();
    for (name, path) in found {
        let scene = rt_shade::load_nff(&path).map_err(|e| e.to_string())?;
        let options = rt_shade::RenderOptions {
            width: size,
            height: size,
            ..Default::default()
        };
        for entry in &accels {
            pb.set_message(format!("{name} {}", entry.name));
            let start = std::time::Instant::now();
            let accel = entry.build_any(&scene.shapes)?;
            let build_ms = start.elapsed().as_secs_f64() * 1e3;
            let out = rt_shade::render(&scene, accel.as_ref(), &options, &|_| {})
                .map_err(|e| e.to_string())?;
            rows.push(SpdRow {
                scene: name.to_string(),
                prims: scene.shapes.len(),
                accel: entry.name.to_string(),
                size,
                build_ms,
                seconds: out.seconds,
                rays: out.stats.total(),
            });
            pb.inc(1);
        }
    }
    pb.finish_and_clear();
    Ok(rows)
}

/// `(family, accel, slope of ns/ray, slope of build time)` per series, in first-seen order.
fn slopes(sweep: &[SweepRecord]) -> Vec<(String, String, Option<f64>, Option<f64>)> {
    let mut keys: Vec<(String, String)> = Vec::new();
    for r in sweep {
        let k = (r.family.clone(), r.accel.clone());
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    keys.into_iter()
        .map(|(family, accel)| {
            let series: Vec<&SweepRecord> = sweep
                .iter()
                .filter(|r| r.family == family && r.accel == accel)
                .collect();
            let ray = loglog_slope(
                &series
                    .iter()
                    .map(|r| (r.n as f64, r.ns_per_ray))
                    .collect::<Vec<_>>(),
            );
            let build = loglog_slope(
                &series
                    .iter()
                    .map(|r| (r.n as f64, r.build_ms))
                    .collect::<Vec<_>>(),
            );
            (family, accel, ray, build)
        })
        .collect()
}

const SIZE: (u32, u32) = (1000, 600);

/// A tick label: 1k, 250k, 1M; 0.5, 12, 300.
fn short(v: f64) -> String {
    if v >= 1e6 {
        format!("{}M", trim(v / 1e6))
    } else if v >= 1e3 {
        format!("{}k", trim(v / 1e3))
    } else {
        trim(v)
    }
}

fn trim(v: f64) -> String {
    let s = format!("{v:.2}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Draws into an RGB buffer with plotters and writes it as PNG with `image`.
fn png(
    path: &Path,
    draw: impl FnOnce(DrawingArea<BitMapBackend, plotters::coord::Shift>) -> Result<(), String>,
) -> Result<(), String> {
    let mut buf = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        draw(root.clone())?;
        root.present().map_err(|e| e.to_string())?;
    }
    image::RgbImage::from_raw(SIZE.0, SIZE.1, buf)
        .ok_or("plot buffer size")?
        .save_with_format(path, image::ImageFormat::Png)
        .map_err(|e| format!("{}: {e}", path.display()))
}

fn colour(i: usize) -> RGBColor {
    const P: [RGBColor; 12] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
        RGBColor(0, 0, 0),
        RGBColor(110, 70, 0),
    ];
    P[i % P.len()]
}

fn names<'a>(it: impl Iterator<Item = &'a str>) -> Vec<&'a str> {
    let mut v: Vec<&str> = Vec::new();
    for n in it {
        if !v.contains(&n) {
            v.push(n);
        }
    }
    v
}

/// Family colour of a structure name (bvh, bvlist, kd, bsp, grid, octree, obvhs, brute).
fn family_colour(name: &str) -> RGBColor {
    const FAMILIES: [&str; 8] = [
        "bvlist", "bvh", "kd", "bsp", "grid", "octree", "obvhs", "brute",
    ];
    colour(
        FAMILIES
            .iter()
            .position(|f| name.starts_with(f))
            .unwrap_or(9),
    )
}

/// One panel per scene: primary-ray Mrays/s per structure, fastest on top, bars coloured by
/// family and labelled with the structure's name.
fn plot_throughput(path: &Path, records: &[Record], threads: usize) -> Result<(), String> {
    let rs: Vec<&Record> = records
        .iter()
        .filter(|r| r.threads == threads && r.rays == "primary")
        .collect();
    let scenes = names(rs.iter().map(|r| r.scene.as_str()));
    png(path, |root| {
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        let root = root
            .titled(
                &format!("primary rays, {threads} thread(s): Mrays/s"),
                ("sans-serif", 22),
            )
            .map_err(e)?;
        let panels = root.split_evenly((1, scenes.len().max(1)));
        for (panel, scene) in panels.iter().zip(&scenes) {
            let mut bars: Vec<&&Record> = rs.iter().filter(|r| r.scene == *scene).collect();
            bars.sort_by(|a, b| b.mrays_s.total_cmp(&a.mrays_s));
            let top = bars.first().map_or(1.0, |r| r.mrays_s).max(0.1) * 1.15;
            let n = bars.len().max(1);
            let mut chart = ChartBuilder::on(panel)
                .caption(*scene, ("sans-serif", 18))
                .margin(8)
                .x_label_area_size(25)
                .y_label_area_size(5)
                .build_cartesian_2d(0.0..top, 0.0..n as f64)
                .map_err(e)?;
            chart
                .configure_mesh()
                .disable_y_mesh()
                .y_labels(0)
                .x_label_formatter(&|x| short(*x))
                .draw()
                .map_err(e)?;
            for (k, r) in bars.iter().enumerate() {
                let y = (n - 1 - k) as f64;
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(0.0, y + 0.12), (r.mrays_s, y + 0.88)],
                        family_colour(&r.accel).mix(0.75).filled(),
                    )))
                    .map_err(e)?;
                chart
                    .draw_series(std::iter::once(Text::new(
                        format!("{} {:.2}", r.accel, r.mrays_s),
                        (top * 0.01, y + 0.78),
                        ("sans-serif", 11),
                    )))
                    .map_err(e)?;
            }
        }
        Ok(())
    })
}

/// Build time against primary-ray throughput on the largest scene, one labelled point per
/// structure.
fn plot_tradeoff(path: &Path, records: &[Record], threads: usize) -> Result<(), String> {
    let largest = records
        .iter()
        .max_by_key(|r| r.prims)
        .map(|r| r.scene.clone())
        .unwrap_or_default();
    let rs: Vec<&Record> = records
        .iter()
        .filter(|r| r.threads == threads && r.rays == "primary" && r.scene == largest)
        .collect();
    let max_x = rs.iter().map(|r| r.build_ms).fold(1.0, f64::max) * 2.0;
    let min_x = rs
        .iter()
        .map(|r| r.build_ms)
        .fold(f64::INFINITY, f64::min)
        .clamp(0.01, max_x)
        / 1.5;
    let max_y = rs.iter().map(|r| r.mrays_s).fold(0.1, f64::max) * 1.1;
    png(path, |root| {
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!(
                    "{largest}: build time against primary-ray throughput (up and left is better)"
                ),
                ("sans-serif", 20),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d((min_x..max_x).log_scale(), 0.0..max_y)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("build ms (log)")
            .y_desc("Mrays/s")
            .x_label_formatter(&|x| short(*x))
            .draw()
            .map_err(e)?;
        for r in &rs {
            let p = (r.build_ms.max(min_x), r.mrays_s);
            let c = family_colour(&r.accel);
            chart
                .draw_series(std::iter::once(Circle::new(p, 5, c.filled())))
                .map_err(e)?;
            chart
                .draw_series(std::iter::once(Text::new(
                    r.accel.clone(),
                    p,
                    ("sans-serif", 11),
                )))
                .map_err(e)?;
        }
        Ok(())
    })
}

/// Packets against single rays: one panel per scene and ray set (primary, shadow), the speed-up
/// over the same structure's single rays against the tile size, a line per packet path.
fn plot_packets(path: &Path, records: &[Record], threads: usize) -> Result<(), String> {
    const SETS: [&str; 2] = ["primary", "shadow"];
    let sides = rt_packet::TILE_SIDES;
    let points = |scene: &str, set: &str, accel: &str| -> Vec<(f64, f64)> {
        sides
            .iter()
            .enumerate()
            .filter_map(|(k, side)| {
                let rays = format!("{set}-{side}x{side}");
                let r = records.iter().find(|r| {
                    r.threads == threads && r.scene == scene && r.accel == accel && r.rays == rays
                })?;
                Some((k as f64, crate::bench::packet_speedup(records, r)?))
            })
            .collect()
    };
    let packet_records = || {
        records
            .iter()
            .filter(|r| r.threads == threads && r.rays.contains('-'))
    };
    let scenes = names(packet_records().map(|r| r.scene.as_str()));
    let accels = names(packet_records().map(|r| r.accel.as_str()));
    let top = packet_records()
        .filter_map(|r| crate::bench::packet_speedup(records, r))
        .fold(1.0, f64::max)
        * 1.15;
    png(path, |root| {
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        let root = root
            .titled(
                &format!("packets, {threads} thread(s): x the same structure's single rays"),
                ("sans-serif", 22),
            )
            .map_err(e)?;
        let panels = root.split_evenly((SETS.len(), scenes.len().max(1)));
        for (k, panel) in panels.iter().enumerate() {
            let (set, scene) = (
                SETS[k / scenes.len().max(1)],
                scenes[k % scenes.len().max(1)],
            );
            let mut chart = ChartBuilder::on(panel)
                .caption(format!("{scene}, {set}"), ("sans-serif", 16))
                .margin(8)
                .x_label_area_size(22)
                .y_label_area_size(32)
                .build_cartesian_2d(-0.2..sides.len() as f64 - 0.8, 0.0..top)
                .map_err(e)?;
            chart
                .configure_mesh()
                .x_labels(sides.len())
                .x_label_formatter(&|x| {
                    let s = sides[(x.round().max(0.0) as usize).min(sides.len() - 1)];
                    format!("{s}x{s}")
                })
                .draw()
                .map_err(e)?;
            // No gain below this line.
            chart
                .draw_series(LineSeries::new(
                    [(-0.2, 1.0), (sides.len() as f64 - 0.8, 1.0)],
                    BLACK.mix(0.4),
                ))
                .map_err(e)?;
            for (i, accel) in accels.iter().enumerate() {
                let line = points(scene, set, accel);
                if line.is_empty() {
                    continue;
                }
                let c = colour(i);
                chart
                    .draw_series(LineSeries::new(line.clone(), c.stroke_width(2)))
                    .map_err(e)?
                    .label(*accel)
                    .legend(move |(x, y)| {
                        PathElement::new([(x, y), (x + 16, y)], c.stroke_width(2))
                    });
                chart
                    .draw_series(line.iter().map(|p| Circle::new(*p, 3, c.filled())))
                    .map_err(e)?;
            }
            if k > 0 {
                // One legend, in the first panel.
                continue;
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK.mix(0.3))
                .label_font(("sans-serif", 11))
                .draw()
                .map_err(e)?;
        }
        Ok(())
    })
}

/// Log-log: time per ray and build time against N, with reference slopes.
fn plot_sweep(path: &Path, sweep: &[SweepRecord], family: &str) -> Result<(), String> {
    let rs: Vec<&SweepRecord> = sweep.iter().filter(|r| r.family == family).collect();
    if rs.is_empty() {
        return Err(format!("no {family} records"));
    }
    let accels = names(rs.iter().map(|r| r.accel.as_str()));
    let (n0, n1) = (
        rs.iter().map(|r| r.n).min().unwrap_or(1) as f64,
        rs.iter().map(|r| r.n).max().unwrap_or(2) as f64,
    );
    png(path, |root| {
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        let (left, right) = root.split_horizontally(SIZE.0 / 2);
        for (area, what) in [(left, "ns per ray"), (right, "build ms")] {
            let value = |r: &SweepRecord| {
                if what == "build ms" {
                    r.build_ms
                } else {
                    r.ns_per_ray
                }
            };
            let vals: Vec<f64> = rs.iter().map(|r| value(r)).filter(|v| *v > 0.0).collect();
            let lo = vals.iter().copied().fold(f64::INFINITY, f64::min).max(1e-3) / 2.0;
            let hi = vals.iter().copied().fold(0.0, f64::max).max(lo * 4.0) * 2.0;
            let mut chart = ChartBuilder::on(&area)
                .caption(format!("{family}: {what} against N"), ("sans-serif", 20))
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(55)
                .build_cartesian_2d((n0 / 1.2..n1 * 1.2).log_scale(), (lo..hi).log_scale())
                .map_err(e)?;
            chart
                .configure_mesh()
                .x_desc("N triangles")
                .y_desc(what)
                .x_label_formatter(&|x| short(*x))
                .y_label_formatter(&|y| short(*y))
                .draw()
                .map_err(e)?;
            for (ai, accel) in accels.iter().enumerate() {
                let pts: Vec<(f64, f64)> = rs
                    .iter()
                    .filter(|r| r.accel == *accel && value(r) > 0.0)
                    .map(|r| (r.n as f64, value(r)))
                    .collect();
                chart
                    .draw_series(LineSeries::new(pts.clone(), colour(ai).stroke_width(2)))
                    .map_err(e)?
                    .label(*accel)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 16, y)], colour(ai).stroke_width(2))
                    });
                chart
                    .draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour(ai).filled())))
                    .map_err(e)?;
            }
            // Reference slopes from the geometric mean of the values at the smallest N.
            let first: Vec<f64> = rs
                .iter()
                .filter(|r| r.n as f64 == n0)
                .map(|r| value(r))
                .filter(|v| *v > 0.0)
                .collect();
            let mid = (first.iter().map(|v| v.ln()).sum::<f64>() / first.len().max(1) as f64).exp();
            for (label, f) in [
                ("~ N", Box::new(|n: f64| n / n0) as Box<dyn Fn(f64) -> f64>),
                ("~ N^(1/3)", Box::new(|n: f64| (n / n0).cbrt())),
                ("~ log N", Box::new(|n: f64| n.ln() / n0.ln())),
            ] {
                let pts: Vec<(f64, f64)> = (0..=20)
                    .map(|i| n0 * (n1 / n0).powf(i as f64 / 20.0))
                    .map(|n| (n, mid * f(n)))
                    .collect();
                chart
                    .draw_series(LineSeries::new(pts, BLACK.mix(0.35).stroke_width(1)))
                    .map_err(e)?
                    .label(label)
                    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], BLACK.mix(0.35)));
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .label_font(("sans-serif", 12))
                .draw()
                .map_err(e)?;
        }
        Ok(())
    })
}

/// The fastest packet record of `set` on `scene` (`primary-16x16`, ...), against the same
/// structure's single rays (for a packet path over another entry's structure, that entry's).
fn packet_verdict(records: &[Record], scene: &str, set: &str, threads: usize) -> Option<String> {
    let prefix = format!("{set}-");
    let best = records
        .iter()
        .filter(|r| r.scene == scene && r.threads == threads && r.rays.starts_with(&prefix))
        .max_by(|a, b| a.mrays_s.total_cmp(&b.mrays_s))?;
    let single = crate::bench::packet_speedup(records, best)
        .map_or(String::new(), |x| format!(", {x:.2}x its single rays"));
    Some(format!(
        "- **{set} packets**: `{}` {} at {:.2} Mrays/s{single}{}",
        best.accel,
        &best.rays[prefix.len()..],
        best.mrays_s,
        best.ratio_vs_obvhs
            .map_or(String::new(), |x| format!(", {x:.2}x obvhs")),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(accel: &str, scene: &str, rays: &str, mrays_s: f64, build_ms: f64) -> Record {
        Record {
            accel: accel.into(),
            scene: scene.into(),
            rays: rays.into(),
            threads: 2,
            build_ms,
            mrays_s,
            bytes: 1 << 20,
            ratio_vs_obvhs: Some(mrays_s / 2.0),
            ratio_vs_embree: None,
            ray_count: 1000,
            hits: 500,
            prims: if scene == "big" { 100_000 } else { 1000 },
            sah_cost: Some(3.0),
        }
    }

    #[test]
    fn report_from_records_has_verdicts_tables_and_plots() {
        let mut records = Vec::new();
        for scene in ["small", "big"] {
            for set in ["primary", "shadow", "diffuse"] {
                records.push(record("bvh8", scene, set, 8.0, 40.0));
                records.push(record("kd", scene, set, 6.0, 300.0));
                records.push(record("obvhs", scene, set, 2.0, 500.0));
            }
            // Packet paths: a structure's own, and one over kd's single rays.
            records.push(record("bvh", scene, "primary", 4.0, 10.0));
            records.push(record("bvh", scene, "primary-16x16", 10.0, 10.0));
            records.push(record("kd-mlrta", scene, "primary-16x16", 9.0, 300.0));
            records.push(record("kd-mlrta", scene, "shadow-8x8", 12.0, 300.0));
        }
        let mut sweep = Vec::new();
        for family in sweep::FAMILIES {
            for (accel, k) in [("brute", 1.0), ("grid", 0.33), ("bvh", 0.1)] {
                for n in [1_000usize, 10_000, 100_000] {
                    sweep.push(SweepRecord {
                        family: family.into(),
                        accel: accel.into(),
                        n,
                        threads: 2,
                        build_ms: n as f64 * 1e-3,
                        build_ns_per_nlogn: 1.0,
                        ns_per_ray: 100.0 * (n as f64).powf(k),
                        hits: 10,
                        bytes: n * 64,
                    });
                }
            }
        }
        let spd = vec![
            SpdRow {
                scene: "balls".into(),
                prims: 7383,
                accel: "bvh8".into(),
                size: 64,
                build_ms: 5.0,
                seconds: 0.1,
                rays: 100_000,
            },
            SpdRow {
                scene: "balls".into(),
                prims: 7383,
                accel: "kd".into(),
                size: 64,
                build_ms: 40.0,
                seconds: 0.2,
                rays: 100_000,
            },
        ];
        let dir = std::env::temp_dir().join(format!("rt-report-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let opts = ReportOptions {
            dir: dir.clone(),
            quick: true,
            accels: None,
            scenes: None,
            threads: vec![2],
            command: "cargo xtask bench --report x --quick".into(),
        };
        let index = write(&opts, &records, &sweep, &spd, 2).unwrap();
        let text = std::fs::read_to_string(&index).unwrap();
        assert!(
            text.contains("- command: `cargo xtask bench --report x --quick`"),
            "{text}"
        );
        assert!(
            text.contains("- machine: ") && text.contains("- commit: `"),
            "{text}"
        );
        assert!(
            text.contains("- **primary**: `bvh8` at 8.00 Mrays/s, 1.33x the next (kd)"),
            "{text}"
        );
        assert!(
            text.contains(
                "- **primary packets**: `bvh` 16x16 at 10.00 Mrays/s, 2.50x its single rays"
            ),
            "{text}"
        );
        assert!(
            text.contains(
                "- **shadow packets**: `kd-mlrta` 8x8 at 12.00 Mrays/s, 2.00x its single rays"
            ),
            "{text}"
        );
        assert!(!text.contains("**diffuse packets**"), "{text}");
        assert!(text.contains("| soup | grid | 0.33 | 1.00 |"), "{text}");
        assert!(
            text.contains("- **balls**: `bvh8` renders fastest, 2.00x `kd`"),
            "{text}"
        );
        if register_font() {
            for png in [
                "throughput.png",
                "tradeoff.png",
                "packets.png",
                "sweep-sphere.png",
                "sweep-soup.png",
            ] {
                let bytes = std::fs::read(dir.join(png)).unwrap_or_else(|e| panic!("{png}: {e}"));
                assert!(bytes.starts_with(b"\x89PNG"), "{png}");
                assert!(
                    text.contains(&format!("![{png}]({png})")),
                    "{png} not linked"
                );
            }
        } else {
            assert!(text.contains("plots skipped"), "{text}");
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
