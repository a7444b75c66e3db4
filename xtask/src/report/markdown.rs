//! `index.md`: the machine, the commit and the command; a verdict per scene (full runs only);
//! the tables; the sweep's slopes; the SPD renders.

use super::ReportOptions;
use super::renders::SpdRow;
use crate::bench::Record;
use crate::sweep::{SweepRecord, loglog_slope};
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// The machine: CPU model and logical cores.
pub(super) fn machine() -> String {
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
pub(super) fn commit() -> String {
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
pub(super) fn by_scene(
    records: &[Record],
    threads: usize,
) -> BTreeMap<(String, String), Vec<&Record>> {
    let mut map: BTreeMap<(String, String), Vec<&Record>> = BTreeMap::new();
    for r in records.iter().filter(|r| r.threads == threads) {
        map.entry((r.scene.clone(), r.rays.clone()))
            .or_default()
            .push(r);
    }
    map
}

pub(super) fn index_md(
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
    let _ = writeln!(s, "- build: {}", crate::native::build_description());
    let _ = writeln!(s, "- command: `{}`", opts.command);
    let _ = writeln!(
        s,
        "- throughput: median Mrays/s of {} timed runs, single rays; ratios against obvhs's \
         CwBvh with its own triangle test, measured in the same run. Verdicts use {threads} \
         thread(s).\n",
        if opts.quick { 3 } else { 5 }
    );
    let mut scenes: Vec<&str> = records.iter().map(|r| r.scene.as_str()).collect();
    scenes.dedup();
    let groups = by_scene(records, threads);
    if opts.quick {
        let _ = writeln!(
            s,
            "## Quick run: a smoke test\n\n`--quick` traces a 128x128 camera and checks that every \
             structure, packet path and plot runs; its figures are not comparable with a full run's \
             and no verdict is drawn from them. Run without `--quick` to compare structures.\n"
        );
    } else {
        let _ = writeln!(s, "## Verdict per scene\n");
        let _ = writeln!(
            s,
            "Packet lines: the fastest packet path and tile size on the same rays, against the \
             same structure's single rays.\n"
        );
    }
    for scene in scenes.iter().filter(|_| !opts.quick) {
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
    s.push_str(&crate::table::markdown(records));
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
        for scene in scenes.into_iter().filter(|_| !opts.quick) {
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

/// `(family, accel, slope of ns/ray, slope of build time)` per series, in first-seen order.
pub(super) fn slopes(sweep: &[SweepRecord]) -> Vec<(String, String, Option<f64>, Option<f64>)> {
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

/// The fastest packet record of `set` on `scene` (`primary-16x16`, ...), against the same
/// structure's single rays (for a packet path over another entry's structure, that entry's).
pub(super) fn packet_verdict(
    records: &[Record],
    scene: &str,
    set: &str,
    threads: usize,
) -> Option<String> {
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
