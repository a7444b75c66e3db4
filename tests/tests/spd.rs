//! Haines' SPD scenes (`../shared/scenes/spd`, NFF) load with the counts their README states and
//! render the same with structures of different kinds. Skips, saying so, without the files.

use rt_geom::Shape;
use rt_shade::{RenderOptions, load_nff, render};
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
