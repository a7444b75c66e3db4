//! `cargo xtask stress`: every rt structure built on pathological scenes (many copies of one
//! triangle, triangles collapsed to a point, coordinates near the ends of the float range,
//! a million needles beside one huge triangle, a teapot in a stadium, scenes flat in one or two
//! axes), with the build's time and peak memory, the structure's size against the flat
//! triangle array, and its answers checked against brute force. A structure may reject a scene
//! only with a clear error, and only where brute force rejects it too.

use crate::registry::{AccelEntry, REGISTRY};
use rt_geom::{Accel, BruteForce, Hit, Primitive, Triangle, TriangleKernel, Vec3};
use rt_testkit::conformance::{MollerTrumbore, Tolerance, compare_with_expected};
use rt_testkit::rays::conformance_rays;
use rt_testkit::scenes;
use std::time::Instant;

/// The largest size a structure may have, in flat triangle arrays (36 bytes a triangle), with
/// a fixed allowance for small scenes: `bytes <= MEMORY_BOUND * 36 n + MEMORY_SLACK`. The
/// grids set it: they cap references at 32 per primitive (`GridParams::max_refs_per_prim`),
/// each an index and a copy of the primitive for the cell test; every other structure stays
/// far below.
pub const MEMORY_BOUND: usize = 48;
/// See [`MEMORY_BOUND`].
pub const MEMORY_SLACK: usize = 1 << 20;
/// The most resident memory a build may add, in flat triangle arrays, with a small fixed
/// allowance (the allocator's arenas, the thread pool's stacks): `peak <= BUILD_PEAK_BOUND *
/// 36 n + BUILD_PEAK_SLACK`. The allowance is small against the scene at every size the tests
/// run, so a build that grows out of proportion fails there too. The largest structures (the
/// grids, up to [`MEMORY_BOUND`]) hold their build's temporaries beside themselves, and
/// parallel sub-builds overlap as the scheduler lets them: the adaptive grid on `needles`
/// (20k triangles) peaked at 62x on one run and 75x on another of the same build.
pub const BUILD_PEAK_BOUND: u64 = 96;
/// See [`BUILD_PEAK_BOUND`].
pub const BUILD_PEAK_SLACK: u64 = 4 << 20;

/// A pathological scene.
pub struct StressScene {
    /// Short name (the table's row).
    pub name: &'static str,
    /// What makes it hard.
    pub about: &'static str,
    /// Its triangles.
    pub tris: Vec<Triangle>,
}

/// How large the pathological scenes are made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StressSize {
    /// `stress --full`: 200k copies, 1M needles, a 1M-triangle teapot in a stadium.
    Full,
    /// `stress` and the test suite with `RT_LONG_TESTS=1` (CI): a tenth to a fiftieth of that.
    Tests,
    /// A quick `cargo test`: half of `Tests`.
    Quick,
}

/// The scenes at `size`.
pub fn stress_scenes(size: StressSize) -> Vec<StressScene> {
    let big = |full_n: usize, ci_n: usize| match size {
        StressSize::Full => full_n,
        StressSize::Tests => ci_n,
        StressSize::Quick => ci_n / 2,
    };
    let one = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
    let soup = scenes::random_soup(big(10_000, 2_000), 7);
    let point = Vec3::new(0.25, 0.5, 0.75);
    let needles_n = big(1_000_000, 20_000);
    let mut needles: Vec<Triangle> = scenes::random_soup(needles_n, 11)
        .iter()
        .map(|t| Triangle {
            v: t.v.map(|p| p * 1e-3),
        })
        .collect();
    // One triangle 1e6 times the size of the others, through their middle.
    needles.push(Triangle::new(
        Vec3::new(-200.0, 0.0005, -200.0),
        Vec3::new(200.0, 0.0005, -200.0),
        Vec3::new(0.0, 0.0005, 400.0),
    ));
    let flat: Vec<Triangle> = soup
        .iter()
        .map(|t| Triangle {
            v: t.v.map(|p| Vec3::new(p.x, p.y, 0.0)),
        })
        .collect();
    let line: Vec<Triangle> = soup
        .iter()
        .map(|t| Triangle {
            v: t.v.map(|p| Vec3::new(p.x, 0.0, 0.0)),
        })
        .collect();
    vec![
        StressScene {
            name: "copies",
            about: "one triangle, repeated",
            tris: vec![one; big(200_000, 20_000)],
        },
        StressScene {
            name: "point",
            about: "triangles collapsed to one point",
            tris: vec![Triangle::new(point, point, point); big(10_000, 10_000)],
        },
        StressScene {
            name: "huge",
            about: "coordinates near 1e38 (beyond MAX_COORDINATE: rejected)",
            tris: scenes::transformed(&soup, 1e38, Vec3::ZERO),
        },
        StressScene {
            name: "tiny",
            about: "coordinates near 1e-38",
            tris: scenes::transformed(&soup, 1e-38, Vec3::ZERO),
        },
        StressScene {
            name: "needles",
            about: "tiny triangles and one 1e6 times their size",
            tris: needles,
        },
        StressScene {
            name: "stadium",
            about: "a dense teapot in a stadium",
            tris: scenes::teapot_in_stadium(big(1_000_000, 20_000)),
        },
        StressScene {
            name: "flat",
            about: "bounding box flat in one axis (z = 0)",
            tris: flat,
        },
        StressScene {
            name: "line",
            about: "bounding box flat in two axes (all on the x axis)",
            tris: line,
        },
    ]
}

/// One structure on one scene.
#[derive(Clone, Debug)]
pub struct StressRow {
    /// The scene.
    pub scene: &'static str,
    /// The structure.
    pub accel: &'static str,
    /// Triangles.
    pub prims: usize,
    /// Build time.
    pub build_seconds: f64,
    /// Peak resident memory during the build above the resident memory before it (`None`
    /// where the OS does not say).
    pub build_peak_bytes: Option<u64>,
    /// The structure's own size (`stats().bytes`).
    pub bytes: usize,
    /// Rays compared with brute force.
    pub rays: usize,
    /// Disagreements with brute force, validation or the memory bound; empty when correct.
    pub problems: Vec<String>,
    /// The build's error, where both it and brute force rejected the scene.
    pub rejected: Option<String>,
}

/// Builds every selected entry (rt's own structures by default) on every scene and checks it.
pub fn run(
    scenes: &[StressScene],
    entries: &[&AccelEntry],
    progress: &dyn Fn(&str),
) -> Vec<StressRow> {
    let mut rows = Vec::new();
    for scene in scenes {
        let tris = &scene.tris;
        let brute = BruteForce::build(tris);
        let rays = match &brute {
            Ok(b) => conformance_rays(tris, b, 12, 0x57e5 ^ tris.len() as u64),
            Err(_) => Vec::new(),
        };
        let expected: Vec<Option<Hit>> = match &brute {
            Ok(b) => rays.iter().map(|r| b.intersect(&r.ray)).collect(),
            Err(_) => Vec::new(),
        };
        // Entries on Möller–Trumbore's kernel answer as brute force with that kernel.
        let mt: Vec<MollerTrumbore> = tris.iter().copied().map(MollerTrumbore).collect();
        let expected_mt: Vec<Option<Hit>> = match BruteForce::build(&mt) {
            Ok(b)
                if entries
                    .iter()
                    .any(|e| e.kernel == TriangleKernel::MollerTrumbore) =>
            {
                rays.iter().map(|r| b.intersect(&r.ray)).collect()
            }
            _ => Vec::new(),
        };
        for entry in entries {
            progress(&format!(
                "{} on {} ({} triangles)",
                entry.name,
                scene.name,
                tris.len()
            ));
            let before = memory::reset_peak();
            let start = Instant::now();
            let built = (entry.build)(tris);
            let build_seconds = start.elapsed().as_secs_f64();
            let build_peak_bytes = before.and_then(|b| Some(memory::peak()?.saturating_sub(b)));
            let mut row = StressRow {
                scene: scene.name,
                accel: entry.name,
                prims: tris.len(),
                build_seconds,
                build_peak_bytes,
                bytes: 0,
                rays: 0,
                problems: Vec::new(),
                rejected: None,
            };
            match (&brute, built) {
                (Err(_), Err(e)) => row.rejected = Some(e.to_string()),
                (Err(_), Ok(_)) => row
                    .problems
                    .push("built a scene brute force rejects".into()),
                (Ok(_), Err(e)) => row.problems.push(format!("rejected a valid scene: {e}")),
                (Ok(_), Ok(accel)) if entry.kernel == TriangleKernel::MollerTrumbore => check(
                    &mut row,
                    &mt,
                    &rays,
                    &expected_mt,
                    accel.as_ref(),
                    entry.tolerance,
                ),
                (Ok(_), Ok(accel)) => check(
                    &mut row,
                    tris,
                    &rays,
                    &expected,
                    accel.as_ref(),
                    entry.tolerance,
                ),
            }
            rows.push(row);
        }
    }
    rows
}

fn check<P: Primitive>(
    row: &mut StressRow,
    tris: &[P],
    rays: &[rt_testkit::TestRay],
    expected: &[Option<Hit>],
    accel: &dyn Accel,
    tolerance: Tolerance,
) {
    if let Err(e) = accel.validate() {
        row.problems.push(format!("validate: {e}"));
    }
    let stats = accel.stats();
    row.bytes = stats.bytes;
    let bound = MEMORY_BOUND * 36 * tris.len() + MEMORY_SLACK;
    if stats.bytes > bound {
        row.problems.push(format!(
            "{} bytes, above the bound of {bound} ({MEMORY_BOUND}x the triangles + 1 MiB)",
            stats.bytes
        ));
    }
    let peak_bound = BUILD_PEAK_BOUND * 36 * tris.len() as u64 + BUILD_PEAK_SLACK;
    if let Some(peak) = row.build_peak_bytes.filter(|&p| p > peak_bound) {
        row.problems.push(format!(
            "the build added {peak} bytes of resident memory, above the bound of {peak_bound} \
             ({BUILD_PEAK_BOUND}x the triangles + {} MiB)",
            BUILD_PEAK_SLACK >> 20
        ));
    }
    let report = compare_with_expected("stress", tris, rays, expected, accel, tolerance);
    row.rays = report.rays;
    if let Some(m) = report.mismatches.first() {
        row.problems.push(format!(
            "{} of {} rays disagree with brute force, first: {m}",
            report.mismatch_count, report.rays
        ));
    }
}

/// The rows as a Markdown table.
pub fn markdown(rows: &[StressRow]) -> String {
    let mut out = String::from(
        "| scene | triangles | structure | build s | build peak MiB | size MiB | size / triangles | rays checked | result |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let mib = |b: f64| b / (1024.0 * 1024.0);
        let result = match (&r.rejected, r.problems.first()) {
            (_, Some(p)) => format!("**{}**", p.replace('|', "\\|")),
            (Some(e), None) => format!("rejected: {}", e.replace('|', "\\|")),
            (None, None) => "ok".into(),
        };
        out.push_str(&format!(
            "| {} | {} | {} | {:.3} | {} | {:.2} | {:.2} | {} | {} |\n",
            r.scene,
            r.prims,
            r.accel,
            r.build_seconds,
            r.build_peak_bytes
                .map_or("n/a".into(), |b| format!("{:.1}", mib(b as f64))),
            mib(r.bytes as f64),
            r.bytes as f64 / (36.0 * r.prims.max(1) as f64),
            r.rays,
            result
        ));
    }
    out
}

/// The entries `stress` runs by default: rt's own structures (the peers are measured, not
/// hardened, here).
pub fn default_entries() -> Vec<&'static AccelEntry> {
    REGISTRY.iter().filter(|e| !e.external).collect()
}

/// Peak resident memory, where Linux reports it (`/proc/self/status`).
mod memory {
    fn status_kib(key: &str) -> Option<u64> {
        let s = std::fs::read_to_string("/proc/self/status").ok()?;
        let line = s.lines().find(|l| l.starts_with(key))?;
        line.split_whitespace().nth(1)?.parse().ok()
    }

    /// Resets the peak to the current resident memory; returns that, in bytes.
    pub fn reset_peak() -> Option<u64> {
        std::fs::write("/proc/self/clear_refs", "5").ok()?;
        Some(status_kib("VmRSS:")? * 1024)
    }

    /// The peak resident memory since the last reset, in bytes.
    pub fn peak() -> Option<u64> {
        Some(status_kib("VmHWM:")? * 1024)
    }
}
