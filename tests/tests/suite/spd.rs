//! Haines' SPD scenes (`../shared/scenes/spd`, NFF) load with the counts their README states and
//! render the same with structures of different kinds. Skips, saying so, without the files.

use rt_geom::Shape;
use rt_shade::{RenderOptions, load_nff, render};
use rt_testkit::Unfiltered;
use rt_testkit::models::{SPD_NAMES, skip, spd_path};
use xtask::registry;

/// (name, spheres, cones and cylinders, lights, polygons + patches) from the SPD README.
const COUNTS: [(&str, usize, usize, usize, usize); 9] = [
    ("balls", 7381, 0, 3, 1),
    ("gears", 0, 0, 5, 9345),
    ("mount", 4, 0, 1, 8192),
    ("rings", 4200, 4200, 3, 1),
    ("teapot", 0, 0, 2, 144 + 9120),
    ("tetra", 0, 0, 1, 4096),
    ("tree", 4095, 4095, 7, 1),
    ("lattice", 2197, 6084, 6, 0),
    ("shells", 5761, 0, 1, 0),
];

#[test]
fn spd_scenes_load_and_agree_across_structures() {
    let mut found = 0;
    for name in SPD_NAMES {
        let Some(path) = spd_path(name) else {
            skip(&format!(
                "SPD scene {name} not found (looked in $RT_SPD and ../shared/scenes/spd)"
            ));
            continue;
        };
        found += 1;
        let scene = load_nff(&path).unwrap_or_else(|e| panic!("{e}"));
        let &(_, spheres, cones, lights, polygons) = COUNTS.iter().find(|c| c.0 == name).unwrap();
        let count = |f: fn(&Shape) -> bool| scene.shapes.iter().filter(|s| f(s)).count();
        assert_eq!(
            count(|s| matches!(s, Shape::Sphere(_))),
            spheres,
            "{name} spheres"
        );
        assert_eq!(
            count(|s| matches!(s, Shape::Cone(_))),
            cones,
            "{name} cones"
        );
        assert_eq!(scene.lights.len(), lights, "{name} lights");
        let tris = count(|s| matches!(s, Shape::Triangle(_)));
        assert!(
            tris >= polygons,
            "{name}: {tris} triangles from {polygons} polygons"
        );
        assert_eq!(scene.resolution, Some((512, 512)));
        assert!(scene.warnings.is_empty(), "{name}: {:?}", scene.warnings);

        let options = RenderOptions {
            width: 48,
            height: 48,
            ..RenderOptions::default()
        };
        let mut images = Vec::new();
        for accel in ["bvh8", "kd", "grid2", "octree"] {
            let a = registry::find(accel)
                .unwrap()
                .build_any(&scene.shapes)
                .unwrap();
            let out = render(&scene, a.as_ref(), &options, &|_| {}).unwrap();
            assert!(out.stats.eye_hits > 0, "{name}");
            images.push((accel, out.image));
        }
        for (accel, img) in &images[1..] {
            assert!(
                img.pixels == images[0].1.pixels,
                "{name}: {accel} differs from bvh8"
            );
        }
    }
    eprintln!("{found} SPD scenes checked");
}

#[test]
fn gear_faces_are_triangulated_not_fanned() {
    let Some(path) = spd_path("gears") else {
        skip("SPD gears not found");
        return;
    };
    let scene = load_nff(&path).unwrap();
    // 9217 quads give 2 triangles each; 128 concave 144-gons give 142 each.
    let tris = scene
        .shapes
        .iter()
        .filter(|s| matches!(s, Shape::Triangle(_)))
        .count();
    assert_eq!(tris, 9217 * 2 + 128 * 142);
}

/// Rays that leave a triangle start on it and skip it (filtered queries); without filters
/// they start off the surface. The two rules cast the same rays but for the few that graze a
/// surface or its neighbours: per scene, every count within 0.5% of the other rule's.
#[test]
fn leaving_by_filter_casts_the_rays_of_the_offset_rule() {
    for name in SPD_NAMES {
        let Some(path) = spd_path(name) else {
            skip(&format!("SPD scene {name} not found"));
            continue;
        };
        let scene = load_nff(&path).unwrap_or_else(|e| panic!("{e}"));
        let accel = registry::find("bvh8")
            .unwrap()
            .build_any(&scene.shapes)
            .unwrap();
        let options = RenderOptions {
            width: 128,
            height: 128,
            ..RenderOptions::default()
        };
        let filtered = render(&scene, accel.as_ref(), &options, &|_| {})
            .unwrap()
            .stats;
        let offset = render(&scene, &Unfiltered(accel.as_ref()), &options, &|_| {})
            .unwrap()
            .stats;
        let counts = |s: rt_shade::RayStats| [s.eye_hits, s.reflected, s.refracted, s.shadow];
        eprintln!(
            "{name}: filtered {:?}, offset {:?}",
            counts(filtered),
            counts(offset)
        );
        for (a, b) in counts(filtered).into_iter().zip(counts(offset)) {
            assert!(
                a.abs_diff(b) as f64 <= 0.005 * b.max(1) as f64,
                "{name}: {:?} with filters, {:?} with offsets",
                counts(filtered),
                counts(offset)
            );
        }
    }
}
