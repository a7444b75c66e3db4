//! `bench` and `trace` measure rt as a dependent crate gets it: the first time they run,
//! `cargo xtask` (a dev build) rebuilds itself with cargo's default release settings (no LTO,
//! 16 codegen units: what `cargo build --release` of a crate depending on rt compiles, not
//! rt's own release profile) into `target/plain` and runs that build with the same arguments.
//! `trace --native` measures a `-C target-cpu=native` build into `target/native` instead;
//! `bench --native` runs both builds in alternation and gives their figures side by side. Set
//! `RT_NO_RERUN=1` to measure the running build itself. `render --count` re-runs itself from
//! a build with the `counters` feature.

use crate::table::Record;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};

/// Set in the environment of the rebuilt binary so that it does not re-run itself.
const MARKER: &str = "RT_RERUN";

/// A build that measures: where it goes, its extra compiler flags and cargo settings.
struct Build {
    /// Short name (file names, messages).
    name: &'static str,
    dir: &'static str,
    rustflags: &'static str,
    envs: &'static [(&'static str, &'static str)],
}

/// Cargo's default release settings, which a dependent crate's `cargo build --release` uses
/// (rt's own release profile, in the workspace manifest, differs).
const DEFAULT_RELEASE: &[(&str, &str)] = &[
    ("CARGO_PROFILE_RELEASE_LTO", "false"),
    ("CARGO_PROFILE_RELEASE_CODEGEN_UNITS", "16"),
];

/// The release build a dependent crate gets.
const PLAIN: Build = Build {
    name: "plain",
    dir: "target/plain",
    rustflags: "",
    envs: DEFAULT_RELEASE,
};

/// rt's release profile compiled for this CPU.
const NATIVE: Build = Build {
    name: "native",
    dir: "target/native",
    rustflags: " -C target-cpu=native",
    envs: &[],
};

/// Whether this process measures itself: it is a measuring build, or the user asked so.
fn measures_itself() -> bool {
    std::env::var_os(MARKER).is_some() || std::env::var_os("RT_NO_RERUN").is_some()
}

/// Runs the measuring build (plain release, or with `native` for this CPU) with the current
/// arguments, unless this is that build (or the user opted out); `Some(code)` when it ran.
pub fn rerun_for_measuring(native: bool) -> Option<ExitCode> {
    if measures_itself() {
        return None;
    }
    if native {
        eprintln!("running the release build for this CPU (-C target-cpu=native, target/native)");
        Some(rerun(&NATIVE, &[]))
    } else {
        eprintln!("running the release build a dependent crate gets (no LTO, target/plain)");
        Some(rerun(&PLAIN, &[]))
    }
}

/// Runs of each build that `bench --native` alternates.
const NATIVE_RUNS: usize = 3;

/// `bench --native`: the plain build and the one for this CPU run the same bench in
/// alternation, `NATIVE_RUNS` runs each (the machine's speed swings over minutes; builds timed
/// in alternation meet the same swings), and one table gives each row's median Mrays/s in
/// both, the native build's lead, and each build's ratio to Embree default (tinybvh's, which
/// only AVX2 builds carry, from the native runs). Unless this is a measuring build already
/// (`None`: it measures itself).
pub fn bench_plain_and_native() -> Option<ExitCode> {
    if measures_itself() {
        return None;
    }
    Some(match plain_and_native() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    })
}

/// The workspace's directory.
fn root() -> PathBuf {
    let xtask = Path::new(env!("CARGO_MANIFEST_DIR"));
    xtask.parent().unwrap_or(xtask).to_path_buf()
}

fn plain_and_native() -> Result<(), String> {
    let root = root();
    let builds = [PLAIN, NATIVE];
    for b in &builds {
        eprintln!("building the {} release build ({})", b.name, b.dir);
        let status = cargo("build", b, &[])
            .status()
            .map_err(|e| format!("could not run cargo: {e}"))?;
        if !status.success() {
            return Err(format!("the {} build failed", b.name));
        }
    }
    let out = root.join("target/plain-native");
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let args: Vec<OsString> = std::env::args_os()
        .skip(1)
        .filter(|a| a != "--native")
        .collect();
    let mut runs: [Vec<Vec<Record>>; 2] = Default::default();
    for k in 0..NATIVE_RUNS {
        for (b, runs) in builds.iter().zip(&mut runs) {
            eprintln!("run {} of {NATIVE_RUNS}: the {} build", k + 1, b.name);
            let json = out.join(format!("{}-{k}.json", b.name));
            let status = Command::new(root.join(b.dir).join("release/xtask"))
                .args(&args)
                .arg("--json")
                .arg(&json)
                .env(MARKER, "1")
                .stdout(Stdio::null())
                .status()
                .map_err(|e| format!("could not run the {} build: {e}", b.name))?;
            if !status.success() {
                return Err(format!("the {} build's bench failed", b.name));
            }
            runs.push(read_records(&json)?);
        }
    }
    print!("{}", side_by_side(&runs[0], &runs[1]));
    eprintln!(
        "medians of {NATIVE_RUNS} runs of each build, in alternation; records in {}",
        out.display()
    );
    Ok(())
}

fn read_records(path: &Path) -> Result<Vec<Record>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// One row per structure, scene, ray set and thread count (in the order the runs give them):
/// the median over each build's runs of Mrays/s and of the ratios to Embree default and to
/// tinybvh, and the native build's Mrays/s over the plain one's.
fn side_by_side(plain: &[Vec<Record>], native: &[Vec<Record>]) -> String {
    type Key<'a> = (&'a str, &'a str, &'a str, usize);
    fn key(r: &Record) -> Key<'_> {
        (&r.accel, &r.scene, &r.rays, r.threads)
    }
    let median = |runs: &[Vec<Record>], k: Key, f: fn(&Record) -> Option<f64>| {
        let mut v: Vec<f64> = runs
            .iter()
            .flatten()
            .filter(|r| key(r) == k)
            .filter_map(f)
            .collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied()
    };
    let mut keys: Vec<Key> = Vec::new();
    for r in plain.iter().chain(native).flatten() {
        if !keys.contains(&key(r)) {
            keys.push(key(r));
        }
    }
    let title = [
        "structure",
        "scene",
        "rays",
        "threads",
        "plain Mrays/s",
        "native Mrays/s",
        "native / plain",
        "plain vs embree default",
        "native vs embree default",
        "native vs tinybvh",
    ];
    let mut rows = vec![title.map(String::from).to_vec()];
    let num = |x: Option<f64>| x.map_or("-".into(), |x| format!("{x:.2}"));
    let ratio = |x: Option<f64>| x.map_or("-".into(), |x| format!("{x:.2}x"));
    for k in keys {
        let rate = |r: &Record| Some(r.mrays_s);
        let vs_embree = |r: &Record| r.ratio_vs_embree_fast;
        let (p, n) = (median(plain, k, rate), median(native, k, rate));
        rows.push(vec![
            k.0.to_string(),
            k.1.to_string(),
            k.2.to_string(),
            k.3.to_string(),
            num(p),
            num(n),
            ratio(p.zip(n).map(|(p, n)| n / p)),
            ratio(median(plain, k, vs_embree)),
            ratio(median(native, k, vs_embree)),
            ratio(median(native, k, |r| r.ratio_vs_tinybvh)),
        ]);
    }
    crate::table::aligned(&rows, 3)
}

/// Runs the release build with the window (the `window` feature, `target/view`, cargo's
/// default release settings, as a dependent crate gets them; with `counting`, the counting
/// build of it, `target/view-counting`) with the current arguments, unless this is that build.
pub fn rerun_view(counting: bool) -> Option<ExitCode> {
    let this = cfg!(feature = "window") && rt_geom::counters::ENABLED == counting;
    if this || std::env::var_os(MARKER).is_some() {
        return None;
    }
    let (dir, features): (&str, &[&str]) = match counting {
        false => ("target/view", &["window"]),
        true => ("target/view-counting", &["window", "counters"]),
    };
    eprintln!(
        "running the release build with the window ({}, {dir})",
        features.join(", ")
    );
    let build = Build {
        name: "view",
        dir,
        rustflags: "",
        envs: DEFAULT_RELEASE,
    };
    Some(rerun(&build, features))
}

/// Runs the counting build (the `counters` feature: every bounding-volume and primitive test
/// counted) with the current arguments, unless this is that build.
pub fn rerun_counting() -> Option<ExitCode> {
    if rt_geom::counters::ENABLED {
        return None;
    }
    eprintln!("running the counting build (feature counters, target/counting)");
    let build = Build {
        name: "counting",
        dir: "target/counting",
        rustflags: "",
        envs: &[],
    };
    Some(rerun(&build, &["counters"]))
}

/// `cargo run --release` of xtask as `build` makes it (with `features` and this build's
/// optional peers), with this process's arguments, marked as a measuring build.
fn rerun(build: &Build, features: &[&str]) -> ExitCode {
    let status = cargo("run", build, features)
        .arg("--")
        .args(std::env::args_os().skip(1))
        .env(MARKER, "1")
        .status();
    match status {
        Ok(s) => ExitCode::from(s.code().unwrap_or(1).clamp(0, 255) as u8),
        Err(e) => {
            eprintln!(
                "error: could not run cargo for the {} build: {e}",
                build.dir
            );
            ExitCode::FAILURE
        }
    }
}

/// `cargo VERB --release` of xtask into `build`'s target directory with its flags and
/// settings, `features` and this build's optional peers.
fn cargo(verb: &str, build: &Build, features: &[&str]) -> Command {
    let root = root();
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut flags = std::env::var("RUSTFLAGS").unwrap_or_default();
    flags.push_str(build.rustflags);
    let mut features = features.to_vec();
    if cfg!(feature = "embree") {
        features.push("embree");
    }
    if cfg!(feature = "tinybvh") {
        features.push("tinybvh");
    }
    let mut command = Command::new(cargo);
    command
        .args([
            verb,
            "--release",
            "--quiet",
            "--package",
            "xtask",
            "--manifest-path",
        ])
        .arg(root.join("Cargo.toml"))
        .arg("--target-dir")
        .arg(root.join(build.dir))
        .args(if features.is_empty() {
            vec![]
        } else {
            vec!["--features".to_string(), features.join(",")]
        })
        .env("RUSTFLAGS", flags.trim())
        .envs(build.envs.iter().copied());
    command
}

/// What is being measured: the build (plain release, or for this CPU) and the instruction set
/// the kernels run ([`rt_geom::Isa::selected`]).
pub fn build_description() -> String {
    let build = if cfg!(target_feature = "avx2") {
        "release build for this CPU (-C target-cpu=native or similar)"
    } else {
        "plain release build (the baseline instruction set)"
    };
    format!(
        "{build}, kernels chosen at run time: {}",
        rt_geom::Isa::selected()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(accel: &str, mrays_s: f64, vs_embree: Option<f64>) -> Record {
        Record {
            accel: accel.into(),
            scene: "bunny".into(),
            rays: "primary".into(),
            threads: 2,
            build_ms: 1.0,
            mrays_s,
            bytes: 0,
            ratio_vs_obvhs: None,
            ratio_vs_embree: None,
            ratio_vs_embree_fast: vs_embree,
            ratio_vs_tinybvh: None,
            ray_count: 1,
            hits: 1,
            prims: 1,
            sah_cost: None,
            tests_per_ray: None,
        }
    }

    /// Medians over each build's runs, native over plain, and rows that only one build has.
    #[test]
    fn side_by_side_takes_medians_per_build() {
        let plain: Vec<Vec<Record>> = [10.0, 30.0, 20.0]
            .map(|m| vec![record("bvh8-tri", m, Some(m / 40.0))])
            .into();
        let mut native: Vec<Vec<Record>> = [22.0, 24.0, 90.0]
            .map(|m| vec![record("bvh8-tri", m, Some(m / 40.0))])
            .into();
        native[0].push(record("tinybvh", 25.0, None));
        let text = side_by_side(&plain, &native);
        let rows: Vec<Vec<&str>> = text
            .lines()
            .map(|l| l.split_whitespace().collect())
            .collect();
        assert_eq!(rows.len(), 3, "{text}");
        assert_eq!(
            rows[1],
            [
                "bvh8-tri", "bunny", "primary", "2", "20.00", "24.00", "1.20x", "0.50x", "0.60x",
                "-"
            ]
        );
        assert_eq!(
            rows[2][..6],
            ["tinybvh", "bunny", "primary", "2", "-", "25.00"]
        );
    }
}
