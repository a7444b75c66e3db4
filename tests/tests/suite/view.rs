//! The viewer's frames: the headless frame-rate mode, the shadings, the structure `Tab`
//! switches to. (The window itself is tested under Xvfb by `.ci/view`.)

use xtask::view::{Shading, ViewArgs, Viewer, headless, next_structure, orbit};

fn args(shading: Shading) -> ViewArgs {
    ViewArgs {
        scene: "chess".into(),
        accel: "bvh8-tri".into(),
        size: (48, 36),
        shading,
        frames: Some(3),
        threads: 1,
        no_refine: true,
        counting: false,
    }
}

/// Every shading renders along the orbit and reports a frame rate.
#[test]
fn headless_mode_reports_frames_per_second() {
    for shading in [Shading::Whitted, Shading::Eye, Shading::Path] {
        let line = headless(&args(shading), 3).unwrap();
        assert!(
            line.contains("frames/s") && line.contains(shading.name()),
            "{line}"
        );
    }
    assert!(headless(&args(Shading::Whitted), 0).is_err());
}

/// Eye-ray shading casts the eye rays alone, Whitted shading more; the heatmaps count tests
/// in the counting build (which the tests' build is) and are refused elsewhere (`M` offers
/// them only there); the orbit's first step is the scene's
/// camera and a turn is not; `Tab` goes through the structures in order.
#[test]
fn frames_shadings_orbit_and_structures() {
    let viewer = Viewer::new("chess", "bvh8-tri", 1).unwrap();
    let frame = |s: Shading| viewer.frame(s, &s.options((48, 36), 0));
    let eye = frame(Shading::Eye).unwrap();
    assert_eq!(eye.rays, 48 * 36);
    assert!(frame(Shading::Whitted).unwrap().rays > eye.rays);
    if rt_geom::counters::ENABLED {
        let boxes = frame(Shading::Boxes).unwrap();
        let (per_ray, _) = boxes.tests.unwrap();
        assert!(per_ray > 1.0 && boxes.rays == 48 * 36, "{per_ray}");
        assert_eq!(Shading::Path.next(), Shading::Boxes);
    } else {
        assert!(frame(Shading::Boxes).is_err());
        assert_eq!(Shading::Path.next(), Shading::Whitted);
    }
    let cam = viewer.scene.camera;
    assert_eq!(orbit(&cam, 0.0).eye, cam.eye);
    assert!((orbit(&cam, 1.0).eye - cam.eye).length() > 1e-3);
    assert_eq!(next_structure("bvh8-tri"), "bvh8");
    assert_eq!(next_structure("bsp"), "bvh8-tri");
    assert_eq!(next_structure("no-such"), "bvh8-tri");
}
