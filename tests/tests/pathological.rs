//! Every rt structure on the pathological scenes of `cargo xtask stress`, at the sizes that fit
//! the test suite: builds finish, answers equal brute force's, `validate()` holds, sizes stay
//! within the stated bound, and scenes beyond the coordinate range are rejected with a clear
//! error (`cargo xtask stress --full` runs the full sizes; this test runs half of `stress`'s
//! sizes, and the same with `RT_LONG_TESTS=1`).

use xtask::stress::{StressSize, default_entries, run, stress_scenes};

#[test]
fn pathological_scenes_are_built_bounded_and_answered_exactly() {
    let scenes = stress_scenes(match rt_testkit::long_tests() {
        true => StressSize::Tests,
        false => StressSize::Quick,
    });
    let rows = run(&scenes, &default_entries(), &|_| {});
    let problems: Vec<String> = rows
        .iter()
        .flat_map(|r| {
            r.problems
                .iter()
                .map(move |p| format!("{} on {}: {p}", r.accel, r.scene))
        })
        .collect();
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    // The scene beyond the coordinate range is rejected by every structure, and says why.
    for r in rows.iter().filter(|r| r.scene == "huge") {
        let e = r.rejected.as_deref().unwrap_or_default();
        assert!(e.contains("beyond"), "{}: {e:?}", r.accel);
    }
    // Every other scene is built and checked with rays.
    for r in rows.iter().filter(|r| r.scene != "huge") {
        assert!(
            r.rejected.is_none() && r.rays > 0,
            "{} on {}",
            r.accel,
            r.scene
        );
    }
}
