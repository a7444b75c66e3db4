//! The integrator's ray rules and optics on small scenes worked out by hand.

use glam::Vec3;
use rt_geom::{Accel, BruteForce, Ray, Shape, Triangle};
use rt_shade::{
    Camera, Material, PointLight, RayStats, RenderOptions, Scene, ShadeOptions, Whitted, render,
};

fn looking_down_z() -> Camera {
    Camera::orthographic(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 1.0)
}

fn brute(s: &Scene) -> BruteForce<Shape> {
    BruteForce::build(&s.shapes).unwrap()
}

fn one_ray(s: &Scene, max_depth: u32) -> (Vec3, RayStats) {
    let accel = brute(s);
    let options = RenderOptions {
        width: 1,
        height: 1,
        samples_per_axis: 1,
        shade: ShadeOptions {
            max_depth,
            ..ShadeOptions::default()
        },
        ..RenderOptions::default()
    };
    let out = render(s, &accel, &options, &|_| {}).unwrap();
    (out.image.pixels[0], out.stats)
}

/// A glass slab between z = -1 and z = 0, light straight above it.
fn glass_slab() -> Scene {
    let mut s = Scene::new("slab", looking_down_z());
    let glass = s.add_material(
        Material::matte(Vec3::splat(0.1))
            .with_reflection(0.1)
            .with_transmission(Vec3::splat(0.9), 1.5),
    );
    s.add_box(Vec3::new(-3.0, -3.0, -1.0), Vec3::new(3.0, 3.0, 0.0), glass);
    s.lights.push(PointLight {
        position: Vec3::new(0.0, 0.0, 5.0),
        colour: Vec3::ONE,
    });
    s
}

#[test]
fn matte_square_counts() {
    // 4x4 pixels, a matte square over the left half of the view, one light in front of it
    // and one behind it: 16 eye rays, 8 hits, 8 shadow rays (the light behind casts none).
    let mut s = Scene::new("half", looking_down_z());
    let m = s.add_material(Material::matte(Vec3::ONE));
    let q = [
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(0.0, -1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
    ];
    s.add(Triangle::new(q[0], q[1], q[2]), m, None);
    s.add(Triangle::new(q[0], q[2], q[3]), m, None);
    s.lights.push(PointLight {
        position: Vec3::new(0.0, 0.0, 3.0),
        colour: Vec3::ONE,
    });
    s.lights.push(PointLight {
        position: Vec3::new(0.0, 0.0, -3.0),
        colour: Vec3::ONE,
    });
    let accel = brute(&s);
    let options = RenderOptions {
        width: 4,
        height: 4,
        ..RenderOptions::default()
    };
    let out = render(&s, &accel, &options, &|_| {}).unwrap();
    assert_eq!(
        out.stats,
        RayStats {
            eye_rays: 16,
            eye_hits: 8,
            reflected: 0,
            refracted: 0,
            shadow: 8,
            diffuse: 0
        }
    );
    // A mirror adds one reflection ray per hit (which then misses).
    s.materials[0] = s.materials[0].with_reflection(0.5);
    let out = render(&s, &accel, &options, &|_| {}).unwrap();
    assert_eq!(out.stats.reflected, 8);
    assert_eq!(out.stats.shadow, 8);
    // Left half lit, right half background.
    assert!(out.image.pixels[0].x > 0.5 && out.image.pixels[3] == Vec3::ZERO);
}

#[test]
fn glass_slab_counts_by_depth() {
    let s = glass_slab();
    // Depth 1: the eye ray only, and its shadow ray.
    let (_, st) = one_ray(&s, 1);
    assert_eq!(
        st,
        RayStats {
            eye_rays: 1,
            eye_hits: 1,
            reflected: 0,
            refracted: 0,
            shadow: 1,
            diffuse: 0
        }
    );
    // Depth 2: the front face spawns a reflection (misses) and a refraction, which hits the
    // back face from inside and casts a shadow ray there (the light is in front of that side of
    // the surface; the front face blocks it).
    let (_, st) = one_ray(&s, 2);
    assert_eq!(
        st,
        RayStats {
            eye_rays: 1,
            eye_hits: 1,
            reflected: 1,
            refracted: 1,
            shadow: 2,
            diffuse: 0
        }
    );
    // Depth 3: the back face spawns an internal reflection (which reaches the front face from
    // inside, facing away from the light: no shadow ray) and the exiting refraction (misses).
    let (_, st) = one_ray(&s, 3);
    assert_eq!(
        st,
        RayStats {
            eye_rays: 1,
            eye_hits: 1,
            reflected: 2,
            refracted: 2,
            shadow: 2,
            diffuse: 0
        }
    );
}

#[test]
fn slab_shifts_a_ray_as_snell_says() {
    let s = glass_slab();
    let accel = brute(&s);
    let w = Whitted::new(&s, &accel, ShadeOptions::default());
    let theta = 40f32.to_radians();
    let dir = Vec3::new(theta.sin(), 0.0, -theta.cos());
    let start = Vec3::new(-2.0 * dir.x, 0.0, 2.0 * theta.cos());
    let chain = w.refraction_chain(&Ray::new(start, dir), 4);
    assert_eq!(chain.len(), 2, "in through the top, out through the bottom");
    // Inside: sin(theta_t) = sin(theta) / 1.5.
    let sin_t = theta.sin() / 1.5;
    let inside = chain[0].dir();
    assert!((inside.x - sin_t).abs() < 1e-5, "{inside}");
    // Out: parallel to the incident ray, displaced by d sin(theta - theta_t) / cos(theta_t).
    let out = chain[1];
    assert!(out.dir().abs_diff_eq(dir, 1e-5), "{} vs {dir}", out.dir());
    let theta_t = sin_t.asin();
    let expect = (theta - theta_t).sin() / theta_t.cos();
    // Distance between the exit ray's line and the incident ray's line.
    let offset = (out.origin() - start).cross(dir).length();
    assert!(
        (offset - expect).abs() < 1e-4,
        "shift {offset}, Snell says {expect}"
    );
}

#[test]
fn total_internal_reflection_past_the_critical_angle() {
    let s = glass_slab();
    let accel = brute(&s);
    let w = Whitted::new(
        &s,
        &accel,
        ShadeOptions {
            max_depth: 2,
            ..ShadeOptions::default()
        },
    );
    let critical = (1.0f32 / 1.5).asin();
    let from_inside = |angle: f32| {
        let dir = Vec3::new(angle.sin(), 0.0, angle.cos());
        Ray::new(Vec3::new(0.0, 0.0, -0.5), dir)
    };
    // Below the critical angle the ray leaves; above it, it is reflected back inside.
    assert_eq!(
        w.refraction_chain(&from_inside(critical - 0.02), 1).len(),
        1
    );
    assert!(
        w.refraction_chain(&from_inside(critical + 0.02), 1)
            .is_empty()
    );
    let mut st = RayStats::default();
    w.eye(&from_inside(critical + 0.02), &mut st);
    assert_eq!(
        (st.reflected, st.refracted),
        (1, 0),
        "TIR: the reflection ray still goes"
    );
    let mut st = RayStats::default();
    w.eye(&from_inside(critical - 0.02), &mut st);
    assert_eq!((st.reflected, st.refracted), (1, 1));
}

#[test]
fn occluder_casts_a_shadow() {
    // A floor at z = 0, a light above, a small opaque square between them over x < 0.
    let mut s = Scene::new("shadow", looking_down_z());
    s.ambient = Vec3::splat(0.1);
    let m = s.add_material(Material::matte(Vec3::ONE));
    let quad = |s: &mut Scene, lo: Vec3, hi: Vec3| {
        let (a, b, c, d) = (
            lo,
            Vec3::new(hi.x, lo.y, lo.z),
            hi,
            Vec3::new(lo.x, hi.y, lo.z),
        );
        s.add(Triangle::new(a, b, c), m, None);
        s.add(Triangle::new(a, c, d), m, None);
    };
    quad(&mut s, Vec3::new(-3.0, -3.0, 0.0), Vec3::new(3.0, 3.0, 0.0));
    s.lights.push(PointLight {
        position: Vec3::new(0.0, 0.0, 10.0),
        colour: Vec3::ONE,
    });
    let shadowed = Vec3::new(-1.0, 0.0, 0.0);
    let lit = Vec3::new(1.0, 0.0, 0.0);
    // The occluder hangs at z = 5 over the shadowed point; the eye rays start below it (z = 2).
    quad(
        &mut s,
        Vec3::new(-1.5, -0.5, 5.0),
        Vec3::new(-0.5, 0.5, 5.0),
    );
    let accel = brute(&s);
    let w = Whitted::new(&s, &accel, ShadeOptions::default());
    let mut st = RayStats::default();
    let dark = w.eye(&Ray::new(shadowed + Vec3::Z * 2.0, -Vec3::Z), &mut st);
    let bright = w.eye(&Ray::new(lit + Vec3::Z * 2.0, -Vec3::Z), &mut st);
    assert_eq!(st.shadow, 2);
    assert_eq!(dark, Vec3::splat(0.1), "ambient only");
    let cos = Vec3::new(-1.0, 0.0, 10.0).normalize().z;
    assert!(
        (bright - Vec3::splat(0.1 + cos)).abs().max_element() < 1e-5,
        "{bright}"
    );
}

#[test]
fn scenes_without_lights_or_geometry_render_background() {
    let mut s = Scene::new("nothing", looking_down_z());
    s.background = Vec3::new(0.2, 0.3, 0.4);
    let accel = brute(&s);
    let options = RenderOptions {
        width: 3,
        height: 2,
        ..RenderOptions::default()
    };
    let out = render(&s, &accel, &options, &|_| {}).unwrap();
    assert!(out.image.pixels.iter().all(|&p| p == s.background));
    assert_eq!(out.stats.eye_hits, 0);
    let w = s.render_warnings();
    assert!(w.iter().any(|w| w.contains("no geometry")), "{w:?}");
    assert!(w.iter().any(|w| w.contains("no lights")), "{w:?}");
}

#[test]
fn bad_options_are_refused() {
    let s = glass_slab();
    let accel = brute(&s);
    for bad in [
        RenderOptions {
            width: 0,
            ..RenderOptions::default()
        },
        RenderOptions {
            width: 1 << 20,
            height: 1 << 20,
            ..RenderOptions::default()
        },
        RenderOptions {
            samples_per_axis: 0,
            ..RenderOptions::default()
        },
        RenderOptions {
            shade: ShadeOptions {
                max_depth: 0,
                ..ShadeOptions::default()
            },
            ..RenderOptions::default()
        },
        RenderOptions {
            shade: ShadeOptions {
                min_weight: f32::NAN,
                ..ShadeOptions::default()
            },
            ..RenderOptions::default()
        },
    ] {
        assert!(render(&s, &accel, &bad, &|_| {}).is_err(), "{bad:?}");
    }
    let _ = accel.stats();
}

/// A floor under a light inside a glass bulb: the bulb blocks every shadow ray unless it casts
/// no shadow (a ray mask), when the floor is lit as with no bulb at all.
#[test]
fn a_bulb_that_casts_no_shadow_lets_its_light_through() {
    let floor = |bulb: Option<Material>| {
        let mut s = Scene::new("bulb", looking_down_z());
        s.ambient = Vec3::ZERO;
        let m = s.add_material(Material::matte(Vec3::ONE));
        let q = [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
        ];
        s.add(Triangle::new(q[0], q[1], q[2]), m, None);
        let light = Vec3::new(0.9, -0.5, 1.0);
        s.lights.push(PointLight {
            position: light,
            colour: Vec3::ONE,
        });
        if let Some(bulb) = bulb {
            let b = s.add_material(bulb);
            s.add(rt_geom::Sphere::new(light, 0.1), b, None);
        }
        s
    };
    // The eye ray at (0.5, -0.5) meets the floor beside the bulb.
    let shade = |s: &Scene, accel: &dyn Accel| {
        let w = Whitted::new(s, accel, ShadeOptions::default());
        w.eye(
            &Ray::new(Vec3::new(0.5, -0.5, 5.0), -Vec3::Z),
            &mut RayStats::default(),
        )
    };
    let bare = floor(None);
    let lit = shade(&bare, &brute(&bare));
    assert!(lit.x > 0.1, "{lit}");
    let casting = floor(Some(Material::matte(Vec3::ONE)));
    assert_eq!(shade(&casting, &brute(&casting)), Vec3::ZERO);
    let masked = floor(Some(Material::matte(Vec3::ONE).without_shadow()));
    assert_eq!(shade(&masked, &brute(&masked)), lit);
    // `render` refuses the scene through a structure without filtered queries, whose shadow
    // rays could not skip the bulb.
    let plain = brute(&masked);
    let options = RenderOptions {
        width: 2,
        height: 2,
        ..RenderOptions::default()
    };
    let err = render(&masked, &rt_testkit::Unfiltered(&plain), &options, &|_| {}).unwrap_err();
    assert!(err.to_string().contains("cast no shadow"), "{err}");
}
