//! The library's units that the command-line tests do not reach directly: the report's
//! tables, verdicts and plots from given records, and the sweep's slopes and scenes.
use xtask::bench::Record;
use xtask::report::{ReportOptions, SpdRow, register_font, write};
use xtask::sweep::{self, SweepRecord, family_scene, loglog_slope};

fn record(accel: &str, scene: &str, rays: &str, mrays_s: f64, build_ms: f64) -> Record {
    Record {
        accel: accel.into(),
        scene: scene.into(),
        rays: rays.into(),
        threads: 2,
        build_ms,
        mrays_s,
        bytes: 1 << 20,
        ratio_vs_obvhs: Some(mrays_s / 2.0),
        ratio_vs_embree: None,
        ratio_vs_embree_fast: None,
        ratio_vs_tinybvh: None,
        ray_count: 1000,
        hits: 500,
        prims: if scene == "big" { 100_000 } else { 1000 },
        sah_cost: Some(3.0),
        tests_per_ray: (accel == "counted").then_some((20.0, 3.5)),
    }
}

#[test]
fn counted_records_get_test_columns() {
    let plain = xtask::table::text(&[record("bvh8", "small", "primary", 8.0, 40.0)]);
    assert!(!plain.contains("prims/ray"), "{plain}");
    let counted = [record("counted", "small", "primary", 8.0, 40.0)];
    for table in [
        xtask::table::text(&counted),
        xtask::table::markdown(&counted),
    ] {
        assert!(
            table.contains("boxes/ray") && table.contains("prims/ray"),
            "{table}"
        );
        assert!(table.contains("20.0") && table.contains("3.5"), "{table}");
    }
}

#[test]
fn report_from_records_has_verdicts_tables_and_plots() {
    let mut records = Vec::new();
    for scene in ["small", "big"] {
        for set in ["primary", "shadow", "diffuse"] {
            records.push(record("bvh8", scene, set, 8.0, 40.0));
            records.push(record("kd", scene, set, 6.0, 300.0));
            records.push(record("obvhs", scene, set, 2.0, 500.0));
        }
        // Packet paths: a structure's own, and one over kd's single rays.
        records.push(record("bvh", scene, "primary", 4.0, 10.0));
        records.push(record("bvh", scene, "primary-16x16", 10.0, 10.0));
        records.push(record("kd-mlrta", scene, "primary-16x16", 9.0, 300.0));
        records.push(record("kd-mlrta", scene, "shadow-8x8", 12.0, 300.0));
    }
    let mut sweep = Vec::new();
    for family in sweep::FAMILIES {
        for (accel, k) in [("brute", 1.0), ("grid", 0.33), ("bvh", 0.1)] {
            for n in [1_000usize, 10_000, 100_000] {
                sweep.push(SweepRecord {
                    family: family.into(),
                    accel: accel.into(),
                    n,
                    threads: 2,
                    build_ms: n as f64 * 1e-3,
                    build_ns_per_nlogn: 1.0,
                    ns_per_ray: 100.0 * (n as f64).powf(k),
                    hits: 10,
                    bytes: n * 64,
                });
            }
        }
    }
    let spd = vec![
        SpdRow {
            scene: "balls".into(),
            prims: 7383,
            accel: "bvh8".into(),
            size: 64,
            build_ms: 5.0,
            seconds: 0.1,
            rays: 100_000,
        },
        SpdRow {
            scene: "balls".into(),
            prims: 7383,
            accel: "kd".into(),
            size: 64,
            build_ms: 40.0,
            seconds: 0.2,
            rays: 100_000,
        },
    ];
    let dir = std::env::temp_dir().join(format!("rt-report-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let opts = ReportOptions {
        dir: dir.clone(),
        quick: true,
        accels: None,
        scenes: None,
        threads: vec![2],
        command: "cargo xtask bench --report x --quick".into(),
    };
    // A quick report is a smoke test: tables and plots, no verdicts.
    let index = write(&opts, &records, &sweep, &spd, 2).unwrap();
    let text = std::fs::read_to_string(&index).unwrap();
    assert!(
        text.contains("a smoke test") && !text.contains("renders fastest"),
        "{text}"
    );
    assert!(!text.contains("Verdict per scene"), "{text}");
    let opts = ReportOptions {
        quick: false,
        command: "cargo xtask bench --report x".into(),
        ..opts
    };
    let index = write(&opts, &records, &sweep, &spd, 2).unwrap();
    let text = std::fs::read_to_string(&index).unwrap();
    assert!(
        text.contains("- command: `cargo xtask bench --report x`"),
        "{text}"
    );
    assert!(
        text.contains("- machine: ") && text.contains("- commit: `"),
        "{text}"
    );
    assert!(
        text.contains("- **primary**: `bvh8` at 8.00 Mrays/s, 1.33x the next (kd)"),
        "{text}"
    );
    assert!(
        text.contains("- **primary packets**: `bvh` 16x16 at 10.00 Mrays/s, 2.50x its single rays"),
        "{text}"
    );
    assert!(
        text.contains(
            "- **shadow packets**: `kd-mlrta` 8x8 at 12.00 Mrays/s, 2.00x its single rays"
        ),
        "{text}"
    );
    assert!(!text.contains("**diffuse packets**"), "{text}");
    assert!(text.contains("| soup | grid | 0.33 | 1.00 |"), "{text}");
    assert!(
        text.contains("- **balls**: `bvh8` renders fastest, 2.00x `kd`"),
        "{text}"
    );
    assert!(register_font(), "the embedded plot font registers");
    {
        for png in [
            "throughput.png",
            "tradeoff.png",
            "packets.png",
            "sweep-sphere.png",
            "sweep-soup.png",
        ] {
            let bytes = std::fs::read(dir.join(png)).unwrap_or_else(|e| panic!("{png}: {e}"));
            assert!(bytes.starts_with(b"\x89PNG"), "{png}");
            assert!(
                text.contains(&format!("![{png}]({png})")),
                "{png} not linked"
            );
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn slopes_of_known_series() {
    let linear: Vec<_> = (1..6)
        .map(|k| (10f64.powi(k), 3.0 * 10f64.powi(k)))
        .collect();
    assert!((loglog_slope(&linear).unwrap() - 1.0).abs() < 1e-9);
    let cube_root: Vec<_> = (1..6)
        .map(|k| (10f64.powi(k), 10f64.powi(k).cbrt()))
        .collect();
    assert!((loglog_slope(&cube_root).unwrap() - 1.0 / 3.0).abs() < 1e-9);
    assert_eq!(loglog_slope(&[(1.0, 1.0)]), None);
}

#[test]
fn family_scenes_have_the_size_asked_for() {
    for n in [1000, 10_000] {
        let s = family_scene("sphere", n).unwrap();
        assert!(
            (s.len() as f64 - n as f64).abs() < 0.1 * n as f64,
            "{}",
            s.len()
        );
        assert_eq!(family_scene("soup", n).unwrap().len(), n);
        let stadium = family_scene("stadium", n).unwrap().len();
        assert!(
            (stadium as f64 - n as f64).abs() < 0.1 * n as f64,
            "{stadium}"
        );
    }
    assert!(family_scene("nope", 10).is_err());
}
