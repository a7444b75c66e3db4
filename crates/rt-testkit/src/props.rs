//! The set-up every generated-property suite (proptest) shares: the case count and the lattice
//! coordinates their scenes and rays are made of (feature `proptest`).

use proptest::prelude::*;
use rt_geom::Vec3;

/// `cases` generated cases, or `PROPTEST_CASES` when set (longer runs). A failure is saved
/// beside the test file (`<test>.proptest-regressions`, committed) and replayed before any new
/// case on every later run.
pub fn config(cases: u32) -> ProptestConfig {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(cases);
    ProptestConfig {
        cases,
        max_global_rejects: cases.max(1024),
        ..ProptestConfig::default()
    }
}

/// A coordinate: most of the time a point of the half-unit lattice `-n/2..=n/2` (shared
/// vertices, axis-aligned and coincident geometry), else any value in `-range..range`.
pub fn coord(n: i32, range: f32) -> impl Strategy<Value = f32> {
    prop_oneof![
        3 => (-n..=n).prop_map(|i| i as f32 * 0.5),
        1 => -range..range,
    ]
}

/// A point of [`coord`]s.
pub fn point(n: i32, range: f32) -> impl Strategy<Value = Vec3> {
    (coord(n, range), coord(n, range), coord(n, range)).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}
