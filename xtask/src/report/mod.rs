//! `cargo xtask bench --report DIR`: the bench and the scaling sweep in one run, written as a
//! self-contained report: `index.md` (the machine, the commit and the exact command; a verdict
//! per scene; the tables) and PNG plots (plotters).

//!
//! | file | what it holds |
//! |---|---|
//! | `mod.rs` | options, the run (bench, sweep, SPD renders) and writing the files |
//! | `markdown.rs` | `index.md`: verdicts, tables, slopes |
//! | `plots.rs` | the PNG plots and the font they are drawn with |
//! | `renders.rs` | the SPD scenes rendered with every structure that holds spheres and cones |

mod markdown;
mod plots;
mod renders;

use crate::bench::{self, BenchOptions, Record};
use crate::sweep::{self, SweepOptions, SweepRecord};
use markdown::index_md;
use plots::{plot_packets, plot_sweep, plot_throughput, plot_tradeoff, register_font};
use renders::{SpdRow, spd_renders};
use std::path::PathBuf;

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
        plot_errors.push("the embedded plot font could not be registered: plots skipped".into());
    }
    let index = dir.join("index.md");
    let text = index_md(opts, records, sweep, spd, threads, &plots, &plot_errors);
    std::fs::write(&index, text).map_err(|e| format!("{}: {e}", index.display()))?;
    Ok(index)
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
            ratio_vs_embree_fast: None,
            ray_count: 1000,
            hits: 500,
            prims: if scene == "big" { 100_000 } else { 1000 },
            sah_cost: Some(3.0),
            tests_per_ray: (accel == "counted").then_some((20.0, 3.5)),
        }
    }

    #[test]
    fn counted_records_get_test_columns() {
        let plain = crate::table::text(&[record("bvh8", "small", "primary", 8.0, 40.0)]);
        assert!(!plain.contains("prims/ray"), "{plain}");
        let counted = [record("counted", "small", "primary", 8.0, 40.0)];
        for table in [
            crate::table::text(&counted),
            crate::table::markdown(&counted),
        ] {
            assert!(
                table.contains("boxes/ray") && table.contains("prims/ray"),
                "{table}"
            );
            assert!(table.contains("20.0") && table.contains("3.5"), "{table}");
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
        // A quick report is a smoke test: tables and plots, no verdicts.
        let index = write(&opts, &records, &sweep, &spd, 2).unwrap();
        let text = std::fs::read_to_string(&index).unwrap();
        assert!(
            text.contains("a smoke test") && !text.contains("renders fastest"),
            "{text}"
        );
        assert!(!text.contains("Verdict per scene"), "{text}");
        let opts = ReportOptions {
            quick: false,
            command: "cargo xtask bench --report x".into(),
            ..opts
        };
        let index = write(&opts, &records, &sweep, &spd, 2).unwrap();
        let text = std::fs::read_to_string(&index).unwrap();
        assert!(
            text.contains("- command: `cargo xtask bench --report x`"),
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
        assert!(register_font(), "the embedded plot font registers");
        {
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
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
