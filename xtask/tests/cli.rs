//! The command line as a user runs it: output formats, and clear errors (never a panic) on bad
//! input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn xtask(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(args)
        .env("RT_NO_RERUN", "1")
        .output()
        .expect("xtask runs")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn fails_cleanly(o: &Output, needle: &str) {
    let err = stderr(o);
    assert!(
        !o.status.success(),
        "expected failure; stdout: {}",
        stdout(o)
    );
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains(needle), "stderr lacks {needle:?}: {err}");
}

struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> Self {
        let p = std::env::temp_dir().join(format!("rt-cli-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&p).unwrap();
        Self(p)
    }
    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A small closed mesh (an octahedron) written as OBJ.
fn octahedron(path: &Path) {
    let obj = "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n\
               f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n";
    std::fs::write(path, obj).unwrap();
}

#[test]
fn accels_lists_one_name_per_line() {
    let o = xtask(&["accels"]);
    assert!(o.status.success());
    let names: Vec<_> = stdout(&o).lines().map(str::to_string).collect();
    assert!(names.contains(&"brute".to_string()));
    assert!(names.contains(&"obvhs".to_string()));
    assert!(names.contains(&"obvhs-cwbvh".to_string()));
    assert!(names.iter().all(|n| !n.contains(' ')));
}

#[test]
fn trace_round_trip_and_timing_line() {
    let dir = TempDir::new("trace");
    let mesh = dir.path("octa.obj");
    octahedron(&mesh);
    let rays = dir.path("r.rays");
    let o = xtask(&[
        "rays",
        "--mesh",
        mesh.to_str().unwrap(),
        "--size",
        "16",
        "--out",
        rays.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::metadata(&rays).unwrap().len(), 16 * 16 * 32);
    let mut per_accel = Vec::new();
    for accel in ["brute", "obvhs"] {
        let hits = dir.path(&format!("{accel}.hits"));
        let o = xtask(&[
            "trace",
            "--mesh",
            mesh.to_str().unwrap(),
            "--rays",
            rays.to_str().unwrap(),
            "--accel",
            accel,
            "--threads",
            "2",
            "--repeat",
            "3",
            "--out",
            hits.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let out = stdout(&o);
        let last = out.lines().last().unwrap();
        let keys: Vec<_> = last
            .split(' ')
            .map(|kv| kv.split('=').next().unwrap())
            .collect();
        assert_eq!(
            keys,
            ["rays", "hits", "build_ms", "trace_ms", "mrays_s"],
            "{last}"
        );
        assert!(last.starts_with("rays=256 hits="), "{last}");
        let bytes = std::fs::read(&hits).unwrap();
        assert_eq!(bytes.len(), 256 * 8);
        per_accel.push(bytes);
    }
    assert_eq!(
        per_accel[0], per_accel[1],
        "brute and obvhs wrote different hit files"
    );
}

#[test]
fn trace_counts_invalid_rays_as_misses() {
    let dir = TempDir::new("invalid");
    let mesh = dir.path("octa.obj");
    octahedron(&mesh);
    let mut bytes = Vec::new();
    for ray in [
        [0.0, 0.0, 5.0, 0.0, 0.0, 0.0, -1.0, f32::INFINITY], // hits
        [0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 0.0, f32::INFINITY],  // zero direction
        [0.0, 0.0, 5.0, 0.0, f32::NAN, 0.0, -1.0, f32::INFINITY],
    ] {
        for x in ray {
            bytes.extend_from_slice(&f32::to_le_bytes(x));
        }
    }
    let rays = dir.path("bad.rays");
    std::fs::write(&rays, bytes).unwrap();
    let hits = dir.path("bad.hits");
    let o = xtask(&[
        "trace",
        "--mesh",
        mesh.to_str().unwrap(),
        "--rays",
        rays.to_str().unwrap(),
        "--accel",
        "obvhs",
        "--out",
        hits.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("warning: 2 of 3 rays"),
        "{}",
        stderr(&o)
    );
    assert!(
        stdout(&o)
            .trim_end()
            .ends_with(&stdout(&o).lines().last().unwrap().to_string())
    );
    assert!(stdout(&o).contains("rays=3 hits=1 "), "{}", stdout(&o));
    let h = std::fs::read(&hits).unwrap();
    assert_eq!(f32::from_le_bytes(h[0..4].try_into().unwrap()), 4.0);
    assert_eq!(u32::from_le_bytes(h[12..16].try_into().unwrap()), u32::MAX);
}

#[test]
fn bad_input_gets_clear_errors() {
    let dir = TempDir::new("bad");
    let mesh = dir.path("octa.obj");
    octahedron(&mesh);
    let rays = dir.path("r.rays");
    std::fs::write(&rays, [0u8; 32 * 3 + 5]).unwrap();
    let m = mesh.to_str().unwrap();
    let r = rays.to_str().unwrap();

    let o = xtask(&["trace", "--mesh", m, "--rays", r, "--accel", "obvhs"]);
    fails_cleanly(&o, "not a multiple of 32 bytes");

    std::fs::write(&rays, [0u8; 64]).unwrap();
    let o = xtask(&["trace", "--mesh", m, "--rays", r, "--accel", "no-such-tree"]);
    fails_cleanly(&o, "unknown accel 'no-such-tree'");

    let o = xtask(&[
        "trace",
        "--mesh",
        "/no/such/mesh.obj",
        "--rays",
        r,
        "--accel",
        "brute",
    ]);
    fails_cleanly(&o, "/no/such/mesh.obj");

    let o = xtask(&[
        "trace",
        "--mesh",
        m,
        "--rays",
        "/no/such.rays",
        "--accel",
        "brute",
    ]);
    fails_cleanly(&o, "/no/such.rays");

    let bad = dir.path("nan.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let o = xtask(&[
        "trace",
        "--mesh",
        bad.to_str().unwrap(),
        "--rays",
        r,
        "--accel",
        "brute",
    ]);
    fails_cleanly(&o, "nan.obj:2");

    let bad = dir.path("broken.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap();
    let o = xtask(&[
        "trace",
        "--mesh",
        bad.to_str().unwrap(),
        "--rays",
        r,
        "--accel",
        "brute",
    ]);
    fails_cleanly(&o, "broken.obj:4");

    let empty = dir.path("empty.obj");
    std::fs::write(&empty, "").unwrap();
    let o = xtask(&[
        "trace",
        "--mesh",
        empty.to_str().unwrap(),
        "--rays",
        r,
        "--accel",
        "brute",
    ]);
    fails_cleanly(&o, "no faces");

    let o = xtask(&["bench", "--quick", "--scenes", "nowhere"]);
    fails_cleanly(&o, "unknown scene 'nowhere'");
    let o = xtask(&["bench", "--quick", "--threads", "0"]);
    fails_cleanly(&o, "--threads");
}

#[test]
fn sweep_options_are_checked() {
    let o = xtask(&["bench", "--sweep", "--scenes", "bunny"]);
    fails_cleanly(&o, "cannot be used with");
    let o = xtask(&["bench", "--sweep", "--accels", "no-such-tree"]);
    fails_cleanly(&o, "unknown accel 'no-such-tree'");
    let o = xtask(&["bench", "--sweep", "--threads", "0"]);
    fails_cleanly(&o, "--threads");
}

#[test]
fn render_writes_png_stats_and_clear_errors() {
    let dir = TempDir::new("render");
    let png = dir.0.join("c.png");
    let stats = dir.0.join("s.json");
    let o = xtask(&[
        "render",
        "--size",
        "32x24",
        "--accel",
        "grid2",
        "--out",
        png.to_str().unwrap(),
        "--stats",
        stats.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).starts_with("chess 32x24 with grid2: 768 eye rays"),
        "{}",
        stdout(&o)
    );
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    let json = std::fs::read_to_string(&stats).unwrap();
    assert!(json.contains("\"eye_rays\": 768"), "{json}");

    // A malformed NFF names its line; a scene with no lights renders, with a warning.
    let nff = dir.0.join("bad.nff");
    std::fs::write(
        &nff,
        "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 40\nhither 1\nresolution 8 8\ns 0 0 oops 1\n",
    )
    .unwrap();
    fails_cleanly(
        &xtask(&["render", "--scene", nff.to_str().unwrap()]),
        "bad.nff:8:",
    );
    std::fs::write(&nff, "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 40\nhither 1\nresolution 8 8\nf 1 0 0 1 0 1 0 0\ns 0 0 0 1\n").unwrap();
    let o = xtask(&[
        "render",
        "--scene",
        nff.to_str().unwrap(),
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("no lights"), "{}", stderr(&o));
    // Triangle-only structures cannot hold the sphere.
    fails_cleanly(
        &xtask(&[
            "render",
            "--scene",
            nff.to_str().unwrap(),
            "--accel",
            "bvh8-tri",
            "--out",
            png.to_str().unwrap(),
        ]),
        "triangles only",
    );
    fails_cleanly(&xtask(&["render", "--size", "0x5"]), "size");
    fails_cleanly(&xtask(&["render", "--size", "big"]), "WIDTHxHEIGHT");
    fails_cleanly(
        &xtask(&["render", "--depth", "0", "--size", "4x4"]),
        "depth",
    );
    fails_cleanly(
        &xtask(&["render", "--samples", "99", "--size", "4x4"]),
        "samples",
    );
    fails_cleanly(
        &xtask(&[
            "render",
            "--orthographic",
            "--aperture",
            "0.1",
            "--size",
            "4x4",
        ]),
        "aperture",
    );
    // Path tracing: the diffuse bounces are counted; no paths per pixel is refused.
    let o = xtask(&[
        "render",
        "--integrator",
        "path",
        "--spp",
        "2",
        "--size",
        "16x12",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).starts_with("chess 16x12 with bvh8, tiles as packets: 384 eye rays")
            && stdout(&o).contains(" diffuse, "),
        "{}",
        stdout(&o)
    );
    fails_cleanly(
        &xtask(&[
            "render",
            "--integrator",
            "path",
            "--spp",
            "0",
            "--size",
            "4x4",
        ]),
        "paths per pixel",
    );
}

#[test]
fn packets_trace_the_same_hit_file() {
    let dir = TempDir::new("packet");
    let mesh = dir.path("octa.obj");
    octahedron(&mesh);
    let rays = dir.path("r.rays");
    let (mesh_s, rays_s) = (mesh.to_str().unwrap(), rays.to_str().unwrap());
    let o = xtask(&[
        "rays", "--mesh", mesh_s, "--size", "24", "--set", "all", "--out", rays_s,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = xtask(&["accels", "--packet"]);
    let names: Vec<String> = stdout(&o).lines().map(str::to_string).collect();
    for name in ["bvh", "bvh4", "bvh8", "kd", "kd-mlrta"] {
        assert!(names.contains(&name.to_string()), "{names:?}");
    }
    assert!(!names.contains(&"grid".to_string()), "{names:?}");
    for accel in ["bvh", "bvh8", "kd", "kd-mlrta"] {
        let trace = |extra: &[&str], out: &str| {
            let hits = dir.path(out);
            let mut args = vec![
                "trace", "--mesh", mesh_s, "--rays", rays_s, "--accel", accel, "--out",
            ];
            args.push(hits.to_str().unwrap());
            args.extend_from_slice(extra);
            let o = xtask(&args);
            assert!(o.status.success(), "{}", stderr(&o));
            std::fs::read(hits).unwrap()
        };
        let single = trace(&[], "single.hits");
        for tile in ["2x2", "4x4", "8x8", "16x16", "4x2"] {
            assert_eq!(
                trace(&["--packet", tile, "--width", "24"], "p.hits"),
                single,
                "{accel} {tile}"
            );
        }
        let occluded = trace(&["--occluded"], "o1.hits");
        assert_eq!(
            trace(
                &["--occluded", "--packet", "8x8", "--width", "24"],
                "o2.hits"
            ),
            occluded,
            "{accel}"
        );
    }
    // Clear errors: no packet path, tiles too large, no or wrong width.
    let bad = |extra: &[&str]| {
        let mut args = vec!["trace", "--mesh", mesh_s, "--rays", rays_s];
        args.extend_from_slice(extra);
        xtask(&args)
    };
    fails_cleanly(
        &bad(&["--accel", "grid", "--packet", "4x4", "--width", "24"]),
        "no packet path",
    );
    fails_cleanly(
        &bad(&["--accel", "bvh", "--packet", "32x32", "--width", "24"]),
        "tiles need",
    );
    fails_cleanly(&bad(&["--accel", "bvh", "--packet", "4x4"]), "--width");
    fails_cleanly(
        &bad(&["--accel", "bvh", "--packet", "4x4", "--width", "0"]),
        "--width",
    );
}

#[test]
fn bench_records_packet_paths_beside_single_rays() {
    let dir = TempDir::new("bench");
    let json = dir.path("b.json");
    let o = xtask(&[
        "bench",
        "--quick",
        "--accels",
        "bvh,kd-mlrta",
        "--scenes",
        "soup-20k",
        "--threads",
        "1",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&json).unwrap();
    let records: Vec<serde_json::Value> = serde_json::from_str(&text).unwrap();
    let rays_of = |accel: &str| -> Vec<String> {
        records
            .iter()
            .filter(|r| r["accel"] == accel)
            .map(|r| r["rays"].as_str().unwrap().to_string())
            .collect()
    };
    assert_eq!(
        rays_of("bvh"),
        [
            "primary-8x8",
            "shadow-8x8",
            "diffuse-8x8",
            "primary",
            "shadow",
            "diffuse"
        ]
    );
    // A packet path over another entry's structure: packets only.
    assert_eq!(
        rays_of("kd-mlrta"),
        ["primary-8x8", "shadow-8x8", "diffuse-8x8"]
    );
    let find = |accel: &str, rays: &str| {
        records
            .iter()
            .find(|r| r["accel"] == accel && r["rays"] == rays)
            .unwrap()
    };
    // The same rays, the same hits; a ratio to obvhs's single rays.
    for (accel, set) in [
        ("bvh", "primary"),
        ("bvh", "shadow"),
        ("kd-mlrta", "primary"),
        ("kd-mlrta", "shadow"),
        ("kd-mlrta", "diffuse"),
    ] {
        let packet = find(accel, &format!("{set}-8x8"));
        assert_eq!(packet["hits"], find("bvh", set)["hits"], "{accel} {set}");
        assert_eq!(
            packet["ray_count"],
            find("bvh", set)["ray_count"],
            "{accel} {set}"
        );
        assert!(packet["mrays_s"].as_f64().unwrap() > 0.0);
        assert!(packet["ratio_vs_obvhs"].as_f64().is_some());
    }
}
