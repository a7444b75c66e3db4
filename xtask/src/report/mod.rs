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
pub use plots::register_font;
use plots::{plot_packets, plot_sweep, plot_throughput, plot_tradeoff};
pub use renders::SpdRow;
use renders::spd_renders;
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
pub fn write(
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
