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

/// Eye-ray shading casts the eye rays alone; a frame from the scene's camera is what
/// `render` makes of it; the orbit's first step is that camera and a quarter turn is not.
#[test]
fn frames_are_the_renderers() {
    let viewer = Viewer::new("chess", "bvh8-tri", 1).unwrap();
    let eye = viewer.frame(&Shading::Eye.options((48, 36), 0)).unwrap();
    assert_eq!(eye.rays, 48 * 36);
    let whitted = viewer
        .frame(&Shading::Whitted.options((48, 36), 0))
        .unwrap();
    assert!(whitted.rays > eye.rays);
    let cam = viewer.scene.camera;
    assert_eq!(orbit(&cam, 0.0).eye, cam.eye);
    assert!((orbit(&cam, 1.0).eye - cam.eye).length() > 1e-3);
    assert_eq!(next_structure("bvh8-tri"), "bvh8");
    assert_eq!(next_structure("bsp"), "bvh8-tri");
    assert_eq!(next_structure("no-such"), "bvh8-tri");
}
