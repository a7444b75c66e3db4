use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;
use xtask::{bench, native, registry, render, report, sweep, trace, verify, view};

/// rt's command line: list, verify, measure and run the acceleration structures.
#[derive(Parser)]
#[command(name = "cargo xtask", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the registered structure names, one per line.
    Accels {
        /// Also print what each one is.
        #[arg(long)]
        long: bool,
        /// Only the structures that have a packet path (`trace --packet`).
        #[arg(long)]
        packet: bool,
        /// Every structure as a Markdown table (the README's list).
        #[arg(long)]
        markdown: bool,
    },
    /// Every rt structure on pathological scenes (copies of one triangle, a point, coordinates
    /// near 1e38 and 1e-38, needles beside a huge triangle, a teapot in a stadium, flat boxes):
    /// build time, peak memory, size, answers against brute force.
    Stress {
        /// The full sizes (200k copies, 1M needles, 1M-triangle stadium) instead of the test
        /// suite's.
        #[arg(long)]
        full: bool,
        /// Comma-separated structure names (default: rt's own).
        #[arg(long)]
        accels: Option<String>,
        /// Write the table as Markdown to this file too.
        #[arg(long)]
        markdown: Option<PathBuf>,
    },
    /// Runs the fuzz targets of fuzz/ (cargo-fuzz, nightly toolchain) for a given time each and
    /// prints executions and failing inputs per target.
    Fuzz {
        /// Seconds per target.
        #[arg(long, default_value_t = 60)]
        seconds: u64,
        /// Comma-separated targets (default: all): obj, obj_scene, nff, rays, build_trace.
        #[arg(long)]
        targets: Option<String>,
    },
    /// Every structure against brute force (conformance scenes) and obvhs (shared meshes).
    Verify {
        /// Fewer rays, small meshes only (CI).
        #[arg(long)]
        quick: bool,
        /// Comma-separated structure names (default: all).
        #[arg(long)]
        accels: Option<String>,
    },
    /// Throughput, build time and memory per structure, scene, ray set and thread count.
    Bench {
        /// A run of under a minute.
        #[arg(long)]
        quick: bool,
        /// Comma-separated structure names (default: all).
        #[arg(long)]
        accels: Option<String>,
        /// Comma-separated scenes: teapot, bunny, sponza, dragon, soup-100k, sphere-200k,
        /// stadium-100k.
        #[arg(long)]
        scenes: Option<String>,
        /// Write the records as a JSON array.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Comma-separated thread counts.
        #[arg(long, value_delimiter = ',', default_value = "1,2")]
        threads: Vec<usize>,
        /// Box and primitive tests per ray in two more columns (a counting build: its speeds
        /// are not comparable with a plain run's).
        #[arg(long)]
        count: bool,
        /// Measure a `-C target-cpu=native` build (rt's release profile) beside the plain
        /// release build a dependent crate gets: runs of each in alternation, one table of
        /// both.
        #[arg(long, conflicts_with_all = ["json", "count", "sweep", "report"])]
        native: bool,
        /// The scaling sweep instead: build time and time per ray against N (1k to 1M
        /// triangles; --quick: to 100k) on spheres, soups and a teapot in a stadium, with log-log slopes. Uses the
        /// first thread count; default structures: brute,bvh,bvh8,kd,kd-midpoint,bsp,obvhs.
        #[arg(long, conflicts_with = "scenes")]
        sweep: bool,
        /// Run the bench and the sweep and write a report to DIR: index.md (machine, commit,
        /// command, a verdict per scene, tables) and PNG plots.
        #[arg(long, value_name = "DIR", conflicts_with_all = ["sweep", "json"])]
        report: Option<PathBuf>,
    },
    /// Whitted ray tracing of a scene to a PNG with any structure, with ray statistics.
    Render(render::RenderArgs),
    /// A window ray tracing the scene every frame: keys move the camera (W A S D Q E, arrows)
    /// and switch the structure (Tab), the shading (M) and the frame size (F); with --frames,
    /// no window: the frame rate along an orbit (runs the release build with the window,
    /// target/view).
    View(view::ViewArgs),
    /// One figure: the tests of each pixel's eye ray as a heatmap, for bvh8-tri, kd, grid2,
    /// octree, per-piece boxes and brute force, on the chess scene and sponza (runs the
    /// counting build).
    Heatmaps {
        /// Size of each panel, WxH.
        #[arg(long, value_parser = render::parse_size, default_value = "200x150")]
        size: (u32, u32),
        /// PNG to write.
        #[arg(long, default_value = "target/render/heatmaps.png")]
        out: PathBuf,
    },
    /// Trace a ray file through a mesh; write a hit file; print one timing line.
    Trace {
        #[arg(long)]
        mesh: PathBuf,
        #[arg(long)]
        rays: PathBuf,
        #[arg(long)]
        accel: String,
        /// Shadow-ray queries: an occluded ray is written as t = 0, prim = 0.
        #[arg(long)]
        occluded: bool,
        /// Threads (0 = all cores; at most 1024).
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Trace this many times (1 to 1000) and report the median.
        #[arg(long, default_value_t = 1)]
        repeat: usize,
        /// Trace WxH tiles of the image as packets (needs --width; the structure's packet path);
        /// rays after the last whole image row go in file order.
        #[arg(long, value_name = "WxH", value_parser = render::parse_size, requires = "width")]
        packet: Option<(u32, u32)>,
        /// Width in pixels of the row-major image the ray file holds (for --packet).
        #[arg(long)]
        width: Option<usize>,
        /// Measure a `-C target-cpu=native` build rather than the plain release build.
        #[arg(long)]
        native: bool,
        /// Also time each ray queried twice in a row and report the second query's rate
        /// (`warm_mrays_s`: its nodes and leaves cached, its branches just seen), beside the
        /// cold one (single rays only).
        #[arg(long, conflicts_with = "packet")]
        warm: bool,
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Every structure on a mesh placed at the origin and far from it (as GIS and CAD scenes
    /// come), at several sizes: build and trace time against the origin's, and the rays whose
    /// answers differ from brute force's.
    Far {
        /// The mesh: a `bench` scene name.
        #[arg(long, default_value = "bunny")]
        mesh: String,
        /// Comma-separated largest extents to scale the mesh to.
        #[arg(long, default_value = "1.5,30")]
        sizes: String,
        /// Comma-separated offsets of its centre along every axis, each against the same
        /// placed mesh moved back to the origin.
        #[arg(long, default_value = "3e5,5e6")]
        offsets: String,
        /// Camera resolution (side x side primary rays, and a diffuse ray per hit).
        #[arg(long, default_value_t = 128)]
        side: usize,
        /// Comma-separated structure names (default: rt's own but brute force, the
        /// reference).
        #[arg(long)]
        accels: Option<String>,
        /// Threads (0 = all cores).
        #[arg(long, default_value_t = 2)]
        threads: usize,
        /// Write the table as Markdown to this file too.
        #[arg(long)]
        markdown: Option<PathBuf>,
    },
    /// Write a standard ray set of a mesh (camera, shadow, diffuse) as a ray file.
    Rays {
        #[arg(long)]
        mesh: PathBuf,
        /// primary, shadow, diffuse or all.
        #[arg(long, default_value = "primary")]
        set: String,
        /// Camera resolution (size x size).
        #[arg(long, default_value_t = 256)]
        size: usize,
        #[arg(long)]
        out: PathBuf,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let (count, measuring) = match &cli.command {
        Command::Render(args) => (args.count || args.heatmap.is_some(), None),
        Command::Heatmaps { .. } => (true, None),
        Command::Bench { count, native, .. } => (*count, Some(*native)),
        Command::Trace { native, .. } => (false, Some(*native)),
        _ => (false, None),
    };
    let rerun = match (&cli.command, count, measuring) {
        (Command::View(args), _, _) => native::rerun_view(args.counting),
        (_, true, _) => native::rerun_counting(),
        (Command::Bench { native: true, .. }, false, _) => native::bench_plain_and_native(),
        (_, false, Some(native)) => native::rerun_for_measuring(native),
        (_, false, None) => None,
    };
    if let Some(code) = rerun {
        return code;
    }
    match run(cli.command) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(command: Command) -> Result<ExitCode, String> {
    match command {
        Command::Accels { markdown: true, .. } => print!("{}", registry::markdown_table()),
        Command::Accels { long, packet, .. } => {
            for e in registry::REGISTRY
                .iter()
                .filter(|e| !packet || e.packets.is_some())
            {
                if long {
                    println!("{:<18} {}", e.name, e.about);
                } else {
                    println!("{}", e.name);
                }
            }
        }
        Command::Stress {
            full,
            accels,
            markdown,
        } => {
            let entries = match accels {
                Some(list) => registry::select(Some(&list))?,
                None => xtask::stress::default_entries(),
            };
            let scenes = xtask::stress::stress_scenes(match full {
                true => xtask::stress::StressSize::Full,
                false => xtask::stress::StressSize::Tests,
            });
            let spinner = xtask::run::spinner("stress".to_string());
            let rows =
                xtask::stress::run(&scenes, &entries, &|m| spinner.set_message(m.to_string()));
            spinner.finish_and_clear();
            let table = xtask::stress::markdown(&rows);
            print_table(&table, markdown.as_deref())?;
            if rows.iter().any(|r| !r.problems.is_empty()) {
                return Ok(ExitCode::FAILURE);
            }
        }
        Command::Far {
            mesh,
            sizes,
            offsets,
            side,
            accels,
            threads,
            markdown,
        } => {
            let entries = match accels {
                Some(list) => registry::select(Some(&list))?,
                None => xtask::stress::default_entries()
                    .into_iter()
                    .filter(|e| e.name != "brute")
                    .collect(),
            };
            let numbers = |list: &str, what: &str| -> Result<Vec<f64>, String> {
                list.split(',')
                    .map(|x| match x.trim().parse::<f64>() {
                        Ok(v) if v.is_finite() && v.abs() <= 1e18 => Ok(v),
                        _ => Err(format!("--{what}: '{x}' is not a number within 1e18")),
                    })
                    .collect()
            };
            let sizes = numbers(&sizes, "sizes")?;
            if sizes.iter().any(|&s| s <= 0.0) {
                return Err("--sizes: every size must be positive".into());
            }
            let offsets = numbers(&offsets, "offsets")?;
            if !(1..=4096).contains(&side) {
                return Err(format!("--side must lie in 1..=4096, got {side}"));
            }
            let options = xtask::far::FarOptions {
                sizes,
                offsets,
                side,
                threads,
                repeat: 3,
            };
            let Some(tris) = xtask::bench::load_scene(&mesh)? else {
                return Err(format!("mesh {mesh} not found"));
            };
            let spinner = xtask::run::spinner("far".to_string());
            let rows = xtask::far::run(&tris, &entries, &options, &|m| {
                spinner.set_message(m.to_string())
            })?;
            spinner.finish_and_clear();
            let table = xtask::far::markdown(&rows);
            print_table(&table, markdown.as_deref())?;
        }
        Command::Fuzz { seconds, targets } => {
            xtask::fuzz::run(seconds, targets.as_deref())?;
        }
        Command::Verify { quick, accels } => {
            let ok = verify::verify(&verify::VerifyOptions { quick, accels })?;
            if !ok {
                return Ok(ExitCode::FAILURE);
            }
        }
        Command::Bench {
            quick,
            accels,
            scenes,
            json,
            threads,
            sweep,
            report,
            ..
        } => {
            if threads.is_empty() || threads.iter().any(|&t| t == 0 || t > 1024) {
                return Err("--threads takes counts from 1 to 1024".into());
            }
            if let Some(dir) = report {
                let command = std::iter::once("cargo xtask".to_string())
                    .chain(std::env::args().skip(1))
                    .collect::<Vec<_>>()
                    .join(" ");
                let index = report::report(&report::ReportOptions {
                    dir,
                    quick,
                    accels,
                    scenes,
                    threads,
                    command,
                })?;
                println!("wrote {}", index.display());
                return Ok(ExitCode::SUCCESS);
            }
            if sweep {
                sweep::sweep(&sweep::SweepOptions {
                    quick,
                    accels,
                    json,
                    threads: threads[0],
                })?;
                return Ok(ExitCode::SUCCESS);
            }
            bench::bench(&bench::BenchOptions {
                quick,
                accels,
                scenes,
                json,
                threads,
            })?;
        }
        Command::Render(args) if args.frames.is_some() => {
            let frames = args.frames.unwrap_or(1);
            let times = xtask::animate::animate(&args, frames)?;
            print!("{}", xtask::animate::table(&times));
        }
        Command::Heatmaps { size, out } => {
            let spinner = xtask::run::spinner("tracing every panel's eye rays".into());
            let lines = xtask::heatmap::figure(size, &out)?;
            spinner.finish_and_clear();
            for line in lines {
                println!("{line}");
            }
            println!("-> {}", out.display());
        }
        Command::View(args) => match args.frames {
            Some(frames) => println!("{}", view::headless(&args, frames)?),
            None => view::run_window(&args)?,
        },
        Command::Render(args) => {
            let summary = render::render(&args)?;
            for w in &summary.warnings {
                eprintln!("warning: {w}");
            }
            println!("{}", summary.line());
        }
        Command::Trace {
            mesh,
            rays,
            accel,
            occluded,
            threads,
            repeat,
            packet,
            width,
            out,
            native: _,
            warm,
        } => {
            let s = trace::trace(&trace::TraceOptions {
                mesh,
                rays,
                accel,
                occluded,
                threads,
                repeat,
                packet: packet.map(|(w, h)| (w as usize, h as usize)),
                width,
                warm,
                out,
            })?;
            println!("{}", s.line());
        }
        Command::Rays {
            mesh,
            set,
            size,
            out,
        } => {
            let n = trace::write_standard_rays(&trace::RaysOptions {
                mesh,
                set,
                size,
                out: out.clone(),
            })?;
            println!("wrote {n} rays to {}", out.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Prints a Markdown table, and writes it to `path` too when one is given.
fn print_table(table: &str, path: Option<&std::path::Path>) -> Result<(), String> {
    println!("{table}");
    match path {
        Some(path) => std::fs::write(path, table).map_err(|e| format!("{}: {e}", path.display())),
        None => Ok(()),
    }
}
