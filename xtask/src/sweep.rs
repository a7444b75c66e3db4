//! `cargo xtask bench --sweep`: the scaling sweep. Build time and time per ray against the
//! number of primitives N, on tessellated spheres and on random soups, for each structure:
//! the complexity claims (brute force O(N) per ray; trees O(log N) per ray and O(N log N) to
//! build; grids O(N^(1/3)) per ray) as measured series with fitted log-log slopes.

use crate::registry::{self, AccelEntry};
use crate::run;
use rt_geom::{Accel, Triangle, Vec3};
use rt_testkit::rays::View;
use rt_testkit::scenes;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct SweepOptions {
    pub quick: bool,
    pub accels: Option<String>,
    pub json: Option<PathBuf>,
    /// Threads for building and tracing.
    pub threads: usize,
}

/// One point of a series.
#[derive(Clone, Debug, Serialize)]
pub struct SweepRecord {
    /// `sphere` or `soup`.
    pub family: String,
    pub accel: String,
    /// Primitives.
    pub n: usize,
    pub threads: usize,
    pub build_ms: f64,
    /// `build_ms` over `N log2 N`, in nanoseconds: flat when the build is O(N log N).
    pub build_ns_per_nlogn: f64,
    /// Median wall time per primary ray (128 x 128 camera), in nanoseconds.
    pub ns_per_ray: f64,
    pub hits: usize,
    pub bytes: usize,
}

/// The structures swept by default: the baseline, each family's main builders, the reference.
pub const DEFAULT_ACCELS: &str = "brute,bvh,bvh8,kd,kd-midpoint,bsp,obvhs";

/// Brute force is swept up to this N (it is O(N) per ray).
const BRUTE_MAX: usize = 32_000;

fn sizes(quick: bool) -> Vec<usize> {
    if quick {
        vec![1_000, 10_000, 100_000]
    } else {
        vec![1_000, 3_200, 10_000, 32_000, 100_000, 320_000, 1_000_000]
    }
}

/// The scene of a family at size `n`. Soup triangles shrink as `N^(-1/3)` so that the soup
/// stays equally dense (and equally overlapping) at every size, as a tessellation does.
pub fn family_scene(family: &str, n: usize) -> Result<Vec<Triangle>, String> {
    match family {
        "sphere" => Ok(scenes::tessellated_sphere(n, Vec3::ZERO, 1.0)),
        "soup" => {
            let shrink = (1000.0 / n as f32).cbrt();
            Ok(scenes::random_soup(n, 17)
                .into_iter()
                .map(|t| {
                    let c = t.centroid();
                    Triangle {
                        v: t.v.map(|p| c + (p - c) * shrink),
                    }
                })
                .collect())
        }
        // A dense object in a large sparse stadium (the uniform grid's worst case).
        "stadium" => Ok(scenes::teapot_in_stadium(n)),
        _ => Err(format!(
            "unknown sweep family '{family}'; known: {}",
            FAMILIES.join(", ")
        )),
    }
}

pub const FAMILIES: [&str; 3] = ["sphere", "soup", "stadium"];

pub fn sweep(opts: &SweepOptions) -> Result<Vec<SweepRecord>, String> {
    let entries = registry::select(Some(opts.accels.as_deref().unwrap_or(DEFAULT_ACCELS)))?;
    let pool = run::pool(opts.threads)?;
    let sizes = sizes(opts.quick);
    let runs: usize = FAMILIES.len()
        * sizes
            .iter()
            .map(|&n| entries.iter().filter(|e| runs_at(e, n)).count())
            .sum::<usize>();
    eprintln!(
        "sweep: {} structures, N = {:?}, spheres, soups and stadiums, {} thread(s)",
        entries.len(),
        sizes,
        opts.threads
    );
    let pb = run::bar(runs as u64, "sweep");
    let mut records = Vec::new();
    for family in FAMILIES {
        for &n in &sizes {
            let tris = family_scene(family, n)?;
            let bounds = tris
                .iter()
                .fold(rt_geom::Aabb::EMPTY, |b, t| b.union(t.bounds()));
            let rays = View::front(&bounds).camera_rays(128, 128);
            for entry in entries.iter().filter(|e| runs_at(e, n)) {
                pb.set_message(format!("{family} {n} {}", entry.name));
                let start = Instant::now();
                let accel = pool
                    .install(|| (entry.build)(&tris))
                    .map_err(|e| format!("{}: {e}", entry.name))?;
                let build_ms = start.elapsed().as_secs_f64() * 1e3;
                run::trace_count(accel.as_ref(), &rays, false, &pool); // warm-up
                let mut hits = 0;
                let times = (0..3)
                    .map(|_| {
                        let (h, t) = run::trace_count(accel.as_ref(), &rays, false, &pool);
                        hits = h;
                        t
                    })
                    .collect();
                let per_ray = run::median(times).as_secs_f64() / rays.len() as f64;
                let n_real = tris.len();
                records.push(SweepRecord {
                    family: family.to_string(),
                    accel: entry.name.to_string(),
                    n: n_real,
                    threads: opts.threads,
                    build_ms,
                    build_ns_per_nlogn: build_ms * 1e6
                        / (n_real as f64 * (n_real as f64).log2().max(1.0)),
                    ns_per_ray: per_ray * 1e9,
                    hits,
                    bytes: accel.stats().bytes,
                });
                pb.inc(1);
            }
        }
    }
    pb.finish_and_clear();
    print_sweep(&records);
    if let Some(path) = &opts.json {
        let text = serde_json::to_string_pretty(&records).map_err(|e| e.to_string())?;
        std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))?;
        eprintln!("wrote {} records to {}", records.len(), path.display());
    }
    Ok(records)
}

fn runs_at(entry: &AccelEntry, n: usize) -> bool {
    let cap = if entry.name == "brute" {
        BRUTE_MAX
    } else {
        entry.bench_max_prims
    };
    n <= cap
}

/// Least-squares slope of `log y` against `log x`.
pub fn loglog_slope(points: &[(f64, f64)]) -> Option<f64> {
    let pts: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0)
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if pts.len() < 2 {
        return None;
    }
    let k = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / k,
        pts.iter().map(|p| p.1).sum::<f64>() / k,
    );
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

pub fn print_sweep(records: &[SweepRecord]) {
    println!(
        "{:<7} {:<12} {:>9} {:>10} {:>12} {:>10} {:>8}",
        "family", "accel", "N", "build_ms", "ns/(NlogN)", "ns/ray", "hits"
    );
    for r in records {
        println!(
            "{:<7} {:<12} {:>9} {:>10.1} {:>12.2} {:>10.1} {:>8}",
            r.family, r.accel, r.n, r.build_ms, r.build_ns_per_nlogn, r.ns_per_ray, r.hits
        );
    }
    println!();
    println!(
        "log-log slopes over the series (1 = linear in N; ~0.1-0.3 = logarithmic; 0.33 = N^(1/3)):"
    );
    println!(
        "{:<7} {:<12} {:>12} {:>12}",
        "family", "accel", "ns/ray ~ N^", "build ~ N^"
    );
    let mut seen: Vec<(&str, &str)> = Vec::new();
    for r in records {
        let key = (r.family.as_str(), r.accel.as_str());
        if seen.contains(&key) {
            continue;
        }
        seen.push(key);
        let series: Vec<&SweepRecord> = records
            .iter()
            .filter(|o| o.family == r.family && o.accel == r.accel)
            .collect();
        let per_ray: Vec<(f64, f64)> = series.iter().map(|o| (o.n as f64, o.ns_per_ray)).collect();
        let build: Vec<(f64, f64)> = series.iter().map(|o| (o.n as f64, o.build_ms)).collect();
        let fmt = |s: Option<f64>| s.map_or("-".to_string(), |s| format!("{s:.2}"));
        println!(
            "{:<7} {:<12} {:>12} {:>12}",
            r.family,
            r.accel,
            fmt(loglog_slope(&per_ray)),
            fmt(loglog_slope(&build))
        );
    }
}
