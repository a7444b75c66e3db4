//! `bench` and `trace` measure rt as a dependent crate gets it: the first time they run,
//! `cargo xtask` (a dev build) rebuilds itself with cargo's default release settings (no LTO,
//! 16 codegen units: what `cargo build --release` of a crate depending on rt compiles, not
//! rt's own release profile) into `target/plain` and runs that build with the same arguments.
//! `--native` measures a `-C target-cpu=native` build into `target/native` instead. Set
//! `RT_NO_RERUN=1` to measure the running build itself. `render --count` re-runs itself from
//! a build with the `counters` feature.

use std::path::PathBuf;
use std::process::{Command, ExitCode};

/// Set in the environment of the rebuilt binary so that it does not re-run itself.
const MARKER: &str = "RT_RERUN";

/// Runs the measuring build (plain release, or with `native` for this CPU) with the current
/// arguments, unless this is that build (or the user opted out); `Some(code)` when it ran.
pub fn rerun_for_measuring(native: bool) -> Option<ExitCode> {
    if std::env::var_os(MARKER).is_some() || std::env::var_os("RT_NO_RERUN").is_some() {
        return None;
    }
    if native {
        eprintln!("running the release build for this CPU (-C target-cpu=native, target/native)");
        Some(rerun("target/native", " -C target-cpu=native", &[], &[]))
    } else {
        eprintln!("running the release build a dependent crate gets (no LTO, target/plain)");
        let defaults = [
            ("CARGO_PROFILE_RELEASE_LTO", "false"),
            ("CARGO_PROFILE_RELEASE_CODEGEN_UNITS", "16"),
        ];
        Some(rerun("target/plain", "", &[], &defaults))
    }
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
    let defaults = [
        ("CARGO_PROFILE_RELEASE_LTO", "false"),
        ("CARGO_PROFILE_RELEASE_CODEGEN_UNITS", "16"),
    ];
    Some(rerun(dir, "", features, &defaults))
}

/// Runs the counting build (the `counters` feature: every bounding-volume and primitive test
/// counted) with the current arguments, unless this is that build.
pub fn rerun_counting() -> Option<ExitCode> {
    if rt_geom::counters::ENABLED {
        return None;
    }
    eprintln!("running the counting build (feature counters, target/counting)");
    Some(rerun("target/counting", "", &["counters"], &[]))
}

/// `cargo run --release` of xtask into `target_dir` with extra `rustflags`, `features` (plus
/// this build's optional peers) and environment `envs`, with this process's arguments.
fn rerun(target_dir: &str, rustflags: &str, features: &[&str], envs: &[(&str, &str)]) -> ExitCode {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut flags = std::env::var("RUSTFLAGS").unwrap_or_default();
    flags.push_str(rustflags);
    let mut features = features.to_vec();
    if cfg!(feature = "embree") {
        features.push("embree");
    }
    if cfg!(feature = "tinybvh") {
        features.push("tinybvh");
    }
    let status = Command::new(cargo)
        .args([
            "run",
            "--release",
            "--quiet",
            "--package",
            "xtask",
            "--manifest-path",
        ])
        .arg(root.join("Cargo.toml"))
        .arg("--target-dir")
        .arg(root.join(target_dir))
        .args(if features.is_empty() {
            vec![]
        } else {
            vec!["--features".to_string(), features.join(",")]
        })
        .arg("--")
        .args(std::env::args_os().skip(1))
        .env("RUSTFLAGS", flags.trim())
        .envs(envs.iter().copied())
        .env(MARKER, "1")
        .status();
    match status {
        Ok(s) => ExitCode::from(s.code().unwrap_or(1).clamp(0, 255) as u8),
        Err(e) => {
            eprintln!("error: could not run cargo for the {target_dir} build: {e}");
            ExitCode::FAILURE
        }
    }
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
