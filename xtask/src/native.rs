//! `bench` and `trace` measure code built for this CPU: the first time they run, `cargo xtask`
//! rebuilds itself in release mode with `-C target-cpu=native` into `target/native` and runs that
//! build with the same arguments. Set `RT_NO_NATIVE=1` to measure the portable build instead.
//! `render --count` re-runs itself the same way from a build with the `counters` feature.

use std::path::PathBuf;
use std::process::{Command, ExitCode};

/// Set in the environment of the native build so that it does not re-run itself.
const MARKER: &str = "RT_NATIVE";

/// Runs the native release build with the current arguments, unless this is that build (or
/// the user opted out); `Some(code)` when it ran.
pub fn rerun_natively() -> Option<ExitCode> {
    if std::env::var_os(MARKER).is_some() || std::env::var_os("RT_NO_NATIVE").is_some() {
        return None;
    }
    eprintln!("running the release build for this CPU (-C target-cpu=native, target/native)");
    Some(rerun("target/native", " -C target-cpu=native", &[]))
}

/// Runs the counting build (the `counters` feature: every bounding-volume and primitive test
/// counted) with the current arguments, unless this is that build.
pub fn rerun_counting() -> Option<ExitCode> {
    if rt_geom::counters::ENABLED {
        return None;
    }
    eprintln!("running the counting build (feature counters, target/counting)");
    Some(rerun("target/counting", "", &["counters"]))
}

/// `cargo run --release` of xtask into `target_dir` with extra `rustflags` and `features`
/// (plus this build's optional peers), with this process's arguments.
fn rerun(target_dir: &str, rustflags: &str, features: &[&str]) -> ExitCode {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut flags = std::env::var("RUSTFLAGS").unwrap_or_default();
    flags.push_str(rustflags);
    let mut features = features.to_vec();
    if cfg!(feature = "embree") {
        features.push("embree");
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
