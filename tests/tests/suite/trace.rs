//! `cargo xtask trace` end to end on a tiny mesh, and its clear errors for absurd parameters.

use rt_geom::{Ray, Vec3};
use xtask::trace::{TraceOptions, trace};

#[test]
fn trace_writes_hits_and_rejects_absurd_parameters() {
    let dir = std::env::temp_dir().join(format!("rt-trace-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mesh = dir.join("quad.obj");
    std::fs::write(&mesh, "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3 4\n").unwrap();
    let rays = dir.join("r.rays");
    let list = [
        Ray::new(Vec3::new(0.5, -0.5, 2.0), -Vec3::Z),
        Ray::new(Vec3::new(5.0, 5.0, 2.0), -Vec3::Z),
    ];
    xtask::rayfile::write_rays(&rays, &list).unwrap();
    let opts = TraceOptions {
        mesh: mesh.clone(),
        rays: rays.clone(),
        accel: "bvh8-tri".into(),
        occluded: false,
        threads: 1,
        repeat: 1,
        packet: None,
        width: None,
        warm: false,
        // A folder that does not exist yet is created.
        out: Some(dir.join("new/folder/h.hits")),
    };
    let s = trace(&opts).unwrap();
    assert_eq!((s.rays, s.hits), (2, 1));
    let hits = xtask::rayfile::parse_hits(&std::fs::read(dir.join("new/folder/h.hits")).unwrap());
    assert_eq!(hits.unwrap()[0].prim, 0);
    assert_eq!(s.warm_mrays_s, None);
    // Each ray twice in a row: the same answers, and the second query's rate.
    let warm = trace(&TraceOptions {
        warm: true,
        repeat: 3,
        ..opts.clone()
    })
    .unwrap();
    assert_eq!((warm.rays, warm.hits), (2, 1));
    assert!(warm.warm_mrays_s.is_some_and(|w| w > 0.0), "{warm:?}");
    assert!(warm.line().contains("warm_mrays_s="), "{}", warm.line());
    for (what, o, expect) in [
        (
            "10^5 threads",
            TraceOptions {
                threads: 100_000,
                ..opts.clone()
            },
            "threads",
        ),
        (
            "0 repetitions",
            TraceOptions {
                repeat: 0,
                ..opts.clone()
            },
            "repeat",
        ),
        (
            "10^6 repetitions",
            TraceOptions {
                repeat: 1_000_000,
                ..opts.clone()
            },
            "repeat",
        ),
        (
            "warm packets",
            TraceOptions {
                warm: true,
                packet: Some((1, 1)),
                width: Some(2),
                ..opts.clone()
            },
            "--warm",
        ),
        (
            "missing mesh",
            TraceOptions {
                mesh: dir.join("none.obj"),
                ..opts.clone()
            },
            "none.obj",
        ),
    ] {
        let e = trace(&o).err().unwrap_or_default();
        assert!(e.contains(expect), "{what}: {e:?}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
