//! `cargo xtask fuzz`: runs the fuzz targets of `fuzz/` (cargo-fuzz and libFuzzer, on the
//! nightly toolchain) for a given time each, from a seed corpus, and prints per target the
//! executions and what failed. The properties themselves are [`checks`], which the stable test
//! suite runs on every seed and every saved failure too.

pub mod checks;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// What one target's run did.
#[derive(Clone, Debug)]
pub struct FuzzRun {
    /// The target's name.
    pub target: String,
    /// Seconds it ran (libFuzzer's count).
    pub seconds: u64,
    /// Inputs executed.
    pub executions: u64,
    /// Inputs in the corpus afterwards.
    pub corpus: usize,
    /// The failing input libFuzzer saved, if it found one.
    pub crash: Option<PathBuf>,
}

/// The `fuzz/` folder of the checkout.
pub fn fuzz_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz");
    dir.canonicalize().unwrap_or(dir)
}

/// Whether rustup has a nightly toolchain (cargo-fuzz needs one).
pub fn has_nightly() -> bool {
    Command::new("rustup")
        .args(["toolchain", "list"])
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).contains("nightly"))
}

/// Runs `targets` (all when `None`) for `seconds` each, one after the other; installs
/// cargo-fuzz first if it is missing. Fails when a target finds a failing input.
pub fn run(seconds: u64, targets: Option<&str>) -> Result<Vec<FuzzRun>, String> {
    let names: Vec<&str> = match targets {
        None => checks::TARGETS.iter().map(|(n, _)| *n).collect(),
        Some(list) => list
            .split(',')
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(|n| match checks::target(n) {
                Some(_) => Ok(n),
                None => Err(format!(
                    "unknown fuzz target '{n}'; known: {}",
                    checks::TARGETS.map(|(n, _)| n).join(", ")
                )),
            })
            .collect::<Result<_, _>>()?,
    };
    if seconds == 0 {
        return Err("--seconds must be at least 1".into());
    }
    if !has_nightly() {
        return Err(
            "cargo-fuzz needs a nightly toolchain: `rustup toolchain install nightly`".into(),
        );
    }
    ensure_cargo_fuzz()?;
    let dir = fuzz_dir();
    // Sanitizers off: the fuzzed code has no `unsafe` (Embree is not linked), and libFuzzer
    // then runs several times as many inputs; debug assertions (overflow checks) stay on.
    status(
        Command::new("cargo")
            .args(["+nightly", "fuzz", "build", "-s", "none"])
            .current_dir(&dir),
        "cargo fuzz build",
    )?;
    let mut runs = Vec::new();
    for name in names {
        let corpus = prepare_corpus(&dir, name)?;
        eprintln!(
            "fuzzing {name} for {seconds} s ({} seeds)",
            count_files(&corpus)
        );
        runs.push(run_target(&dir, name, &corpus, seconds)?);
    }
    print_table(&runs);
    match runs.iter().find(|r| r.crash.is_some()) {
        Some(r) => Err(format!(
            "{} found a failing input: {} (reproduce: cargo +nightly fuzz run -s none {} {}; \
             keep it as a regression: copy it into fuzz/regressions/{})",
            r.target,
            r.crash.as_ref().unwrap().display(),
            r.target,
            r.crash.as_ref().unwrap().display(),
            r.target
        )),
        None => Ok(runs),
    }
}

fn ensure_cargo_fuzz() -> Result<(), String> {
    let installed = Command::new("cargo")
        .args(["+nightly", "fuzz", "--version"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if installed {
        return Ok(());
    }
    eprintln!("installing cargo-fuzz (cargo install cargo-fuzz --locked)");
    status(
        Command::new("cargo").args(["install", "cargo-fuzz", "--locked"]),
        "cargo install cargo-fuzz",
    )
}

fn status(cmd: &mut Command, what: &str) -> Result<(), String> {
    match cmd.status() {
        Ok(s) if s.success() => Ok(()),
        Ok(s) => Err(format!("{what} failed ({s})")),
        Err(e) => Err(format!("{what}: {e}")),
    }
}

/// `fuzz/corpus/<target>` (not committed): the committed seeds, the saved failures, the
/// generated seeds, cut-down shared models and SPD scenes where `../shared` is present, and
/// whatever earlier runs added.
fn prepare_corpus(dir: &Path, name: &str) -> Result<PathBuf, String> {
    let corpus = dir.join("corpus").join(name);
    std::fs::create_dir_all(&corpus).map_err(|e| format!("{}: {e}", corpus.display()))?;
    let mut seeds = Vec::new();
    for sub in ["seeds", "regressions"] {
        seeds.extend(read_folder(&dir.join(sub).join(name))?);
    }
    seeds.extend(generated_seeds(name));
    seeds.extend(shared_seeds(name));
    for (file, bytes) in seeds {
        let path = corpus.join(file);
        std::fs::write(&path, bytes).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(corpus)
}

/// Every file of a folder (none when it does not exist), by name.
pub fn read_folder(dir: &Path) -> Result<Vec<(String, Vec<u8>)>, String> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for e in entries.flatten() {
        let path = e.path();
        if path.is_file() {
            let bytes = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
            out.push((e.file_name().to_string_lossy().into_owned(), bytes));
        }
    }
    out.sort();
    Ok(out)
}

/// Seeds written by code: binary ray files and scene bytes.
pub fn generated_seeds(name: &str) -> Vec<(String, Vec<u8>)> {
    use rt_geom::{Ray, Vec3};
    match name {
        "rays" => {
            let rays = [
                Ray::new(Vec3::new(0.0, 0.0, -3.0), Vec3::Z),
                Ray::segment(Vec3::ZERO, Vec3::X, -1.0, 1.0),
                Ray::new(Vec3::new(1.0, 0.0, -3.0), Vec3::new(0.0, 0.0, 1.0)),
                Ray::new(Vec3::ZERO, Vec3::ZERO),
                Ray::segment(Vec3::splat(f32::NAN), Vec3::Y, 0.0, f32::INFINITY),
            ];
            let mut out = vec![("gen-rays".into(), crate::rayfile::encode_rays(&rays))];
            let hits = [
                crate::rayfile::HitRecord::from_hit(None),
                crate::rayfile::HitRecord::from_occluded(true),
            ];
            out.push(("gen-hits".into(), crate::rayfile::encode_hits(&hits)));
            out
        }
        "load_bvh" => {
            use rt_accel_bvh::{Bvh, Bvh8, BvhParams, CompressedTriBvh8, TriBvh4, TriBvh8};
            let tris = checks::load_bvh_triangles();
            let spatial = BvhParams::spatial().for_soa_leaves();
            let saved = [
                (
                    "gen-tri8",
                    TriBvh8::build_for_tracing(&tris).map(|b| b.to_bytes()),
                ),
                (
                    "gen-tri8-spatial",
                    TriBvh8::build(&tris, spatial).map(|b| b.to_bytes()),
                ),
                (
                    "gen-tri4",
                    TriBvh4::build_for_tracing(&tris).map(|b| b.to_bytes()),
                ),
                (
                    "gen-tri8c",
                    CompressedTriBvh8::build_for_tracing(&tris).map(|b| b.to_bytes()),
                ),
                (
                    "gen-bvh8",
                    Bvh8::build(&tris, spatial).map(|b| b.to_bytes()),
                ),
                ("gen-bvh2", Bvh::build(&tris, spatial).map(|b| b.to_bytes())),
                (
                    "gen-kd",
                    rt_accel_kd::KdTree::build(&tris, rt_accel_kd::KdParams::sah())
                        .map(|b| b.to_bytes()),
                ),
                (
                    "gen-kd-midpoint",
                    rt_accel_kd::KdTree::build(&tris, rt_accel_kd::KdParams::midpoint())
                        .map(|b| b.to_bytes()),
                ),
                (
                    "gen-grid",
                    rt_accel_grid::Grid::build(&tris, rt_accel_grid::GridParams::uniform())
                        .map(|b| b.to_bytes()),
                ),
                (
                    "gen-grid2",
                    rt_accel_grid::Grid::build(&tris, rt_accel_grid::GridParams::two_level())
                        .map(|b| b.to_bytes()),
                ),
                (
                    "gen-grid-adaptive",
                    rt_accel_grid::Grid::build(&tris, rt_accel_grid::GridParams::adaptive())
                        .map(|b| b.to_bytes()),
                ),
                (
                    "gen-instances",
                    rt_accel_bvh::InstanceBvh::build(
                        vec![checks::load_bvh_object(&tris)],
                        &[rt_accel_bvh::Instance {
                            object: 0,
                            transform: rt_geom::glam::Affine3A::IDENTITY,
                        }],
                        BvhParams::balanced(),
                    )
                    .map(|b| b.to_bytes()),
                ),
                (
                    "gen-octree",
                    rt_accel_octree::Octree::build(
                        &tris,
                        rt_accel_octree::OctreeParams::standard(),
                    )
                    .map(|b| b.to_bytes()),
                ),
            ];
            saved
                .into_iter()
                .filter_map(|(name, b)| Some((name.to_string(), b.ok()?)))
                .collect()
        }
        "build_trace" => vec![
            // Triangles: two sharing an edge, one degenerate, rays down the axes.
            (
                "gen-tris".into(),
                vec![
                    0, 3, 0, 112, 112, 112, 120, 112, 112, 112, 120, 112, 0, 120, 120, 112, 120,
                    112, 112, 112, 120, 112, 0, 112, 112, 112, 112, 112, 112, 116, 116, 116, 114,
                    114, 100, 112, 112, 120, 0,
                ],
            ),
            // Mixed: a sphere, a cone, a triangle.
            (
                "gen-shapes".into(),
                vec![
                    1, 3, 1, 112, 112, 112, 116, 2, 112, 112, 104, 116, 112, 112, 120, 114, 0, 100,
                    100, 100, 124, 100, 100, 100, 124, 100, 112, 112, 90, 112, 112, 120, 1, 0, 230,
                ],
            ),
        ],
        _ => Vec::new(),
    }
}

/// Small pieces of the shared models and SPD scenes, when `../shared` is present: the first
/// vertices of each OBJ and the faces among them; the head of each NFF file.
pub fn shared_seeds(name: &str) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    match name {
        "obj" | "obj_scene" => {
            let Some(dir) = rt_testkit::models::models_dir() else {
                rt_testkit::models::skip("the shared models' seeds (../shared/models not found)");
                return out;
            };
            for model in rt_testkit::models::MODEL_NAMES {
                if let Ok(text) = std::fs::read_to_string(dir.join(format!("{model}.obj"))) {
                    out.push((
                        format!("shared-{model}.obj"),
                        obj_head(&text, 60).into_bytes(),
                    ));
                }
            }
        }
        "nff" => {
            for scene in rt_testkit::models::SPD_NAMES {
                let Some(path) = rt_testkit::models::spd_path(scene) else {
                    rt_testkit::models::skip(&format!("the seed of SPD scene {scene} (not found)"));
                    continue;
                };
                {
                    if let Ok(text) = std::fs::read_to_string(path) {
                        let head: Vec<&str> = text.lines().take(40).collect();
                        out.push((format!("shared-{scene}.nff"), head.join("\n").into_bytes()));
                    }
                }
            }
        }
        _ => {}
    }
    out
}

/// The first `n` vertices of an OBJ file and the faces that use only them (up to `n`), with
/// the other statements met before the last of them.
fn obj_head(text: &str, n: usize) -> String {
    let mut out = Vec::new();
    let (mut vertices, mut faces) = (0, 0);
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") if vertices < n => {
                vertices += 1;
                out.push(line);
            }
            Some("v") => {}
            Some("f") if faces < n => {
                let inside = words.all(|w| {
                    w.split('/')
                        .next()
                        .and_then(|i| i.parse::<i64>().ok())
                        .is_some_and(|i| i > 0 && i <= vertices as i64)
                });
                if inside {
                    faces += 1;
                    out.push(line);
                }
            }
            Some("f") => {}
            _ if vertices < n => out.push(line),
            _ => {}
        }
    }
    out.join("\n")
}

fn count_files(dir: &Path) -> usize {
    std::fs::read_dir(dir).map_or(0, |d| d.count())
}

fn run_target(dir: &Path, name: &str, corpus: &Path, seconds: u64) -> Result<FuzzRun, String> {
    let artifacts = dir.join("artifacts").join(name);
    std::fs::create_dir_all(&artifacts).map_err(|e| format!("{}: {e}", artifacts.display()))?;
    let before: Vec<_> = read_folder(&artifacts)?
        .into_iter()
        .map(|(n, _)| n)
        .collect();
    let output = Command::new("cargo")
        .args(["+nightly", "fuzz", "run", "-s", "none", name])
        .arg(corpus)
        .arg("--")
        .arg(format!("-max_total_time={seconds}"))
        // An input is a hang at the timeout; below it, a slow one (libFuzzer reports those
        // from 10 s on, as an artifact, which would count as a failure here) is not: the
        // build-and-trace check builds every structure, with overflow checks and coverage
        // counters on, and a busy machine's input can take longer than 10 s.
        .args(["-timeout=30", "-report_slow_units=30"])
        .args(["-rss_limit_mb=4096", "-print_final_stats=1"])
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .output()
        .map_err(|e| format!("cargo fuzz run {name}: {e}"))?;
    let log = String::from_utf8_lossy(&output.stderr);
    let stat = |key: &str| {
        log.lines()
            .filter_map(|l| l.strip_prefix(key))
            .filter_map(|v| v.trim().parse::<u64>().ok())
            .next_back()
    };
    let crash = read_folder(&artifacts)?
        .into_iter()
        .map(|(n, _)| n)
        .find(|n| !before.contains(n))
        .map(|n| artifacts.join(n));
    if crash.is_some() || !output.status.success() {
        // The failure's own message (a panic's first lines, or libFuzzer's error), then the
        // log's end: the backtrace between them can push the message out of a short tail.
        let lines: Vec<&str> = log.lines().collect();
        if let Some(at) = lines
            .iter()
            .position(|l| l.contains("panicked at") || l.contains("ERROR: libFuzzer"))
        {
            eprintln!("{}", lines[at..(at + 4).min(lines.len())].join("\n"));
        }
        let tail = &lines[lines.len().saturating_sub(40)..];
        eprintln!("{}", tail.join("\n"));
    }
    if crash.is_none() && !output.status.success() {
        return Err(format!("cargo fuzz run {name} failed ({})", output.status));
    }
    Ok(FuzzRun {
        target: name.to_string(),
        // libFuzzer's last line: "Done N runs in S second(s)".
        seconds: log
            .lines()
            .filter_map(|l| l.split(" runs in ").nth(1))
            .filter_map(|s| s.split_whitespace().next()?.parse().ok())
            .next_back()
            .unwrap_or(seconds),
        executions: stat("stat::number_of_executed_units:").unwrap_or(0),
        corpus: count_files(corpus),
        crash,
    })
}

fn print_table(runs: &[FuzzRun]) {
    println!("| target | seconds | executions | exec/s | corpus | failing input |");
    println!("|---|---|---|---|---|---|");
    for r in runs {
        println!(
            "| {} | {} | {} | {:.0} | {} | {} |",
            r.target,
            r.seconds,
            r.executions,
            r.executions as f64 / r.seconds.max(1) as f64,
            r.corpus,
            r.crash
                .as_ref()
                .map_or("none".to_string(), |p| p.display().to_string())
        );
    }
}
