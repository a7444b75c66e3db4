//! The path tracer against answers known in closed form, each within the Monte Carlo error the
//! test computes from its own samples.

use glam::Vec3;
use rt_geom::{BruteForce, Ray, Shape, Triangle};
use rt_shade::{
    Camera, Integrator, Material, PathOptions, PointLight, RenderOptions, Rendered, Scene, render,
};

fn path_render(s: &Scene, size: u32, samples: u32) -> Rendered {
    let accel = BruteForce::<Shape>::build(&s.shapes).unwrap();
    let options = RenderOptions {
        width: size,
        height: size,
        integrator: Integrator::Path(PathOptions {
            samples,
            seed: 7,
            ..PathOptions::default()
        }),
        ..RenderOptions::default()
    };
    render(s, &accel, &options, &|_| {}).unwrap()
}

/// A diffuse plane `y = 0` (from -1 to 1 in x and z) of albedo `rho` under one point light of
/// colour `i` at height 2 above its centre, seen from straight above through an orthographic
/// camera that frames it exactly, against a black sky: each pixel's radiance is the direct
/// light `rho * i * cos(theta)` (the plane cannot see itself, bounces go to the black sky),
/// averaged over the pixel. The expected value and the spread of the formula over each pixel
/// come from a 16x16 grid of points in it; the render must lie within five standard errors of
/// its jittered samples.
#[test]
fn a_diffuse_plane_under_a_point_light_gives_the_direct_light_formula() {
    let (rho, i, light) = (Vec3::new(0.8, 0.5, 0.3), Vec3::new(1.0, 0.9, 0.7), 2.0);
    let camera = Camera::orthographic(Vec3::new(0.0, 5.0, 0.0), Vec3::ZERO, Vec3::Z, 2.0);
    let mut s = Scene::new("plane", camera);
    let m = s.add_material(Material::matte(rho));
    let [a, b, c, d] = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .map(|(x, z)| Vec3::new(x * 1.5, 0.0, z * 1.5));
    s.add_facing(Triangle::new(a, b, c), Vec3::Y, m, None);
    s.add_facing(Triangle::new(a, c, d), Vec3::Y, m, None);
    s.lights.push(PointLight {
        position: Vec3::new(0.0, light, 0.0),
        colour: i,
    });
    let (size, samples) = (8u32, 256u32);
    let out = path_render(&s, size, samples);
    let frame = s.camera.frame(size, size);
    // Where the ray through pixel coordinates (x, y) meets the plane.
    let on_plane = |x: f32, y: f32| {
        let r: Ray = frame.ray(x, y, (0.5, 0.5));
        let t = -r.origin().y / r.dir().y;
        r.origin() + r.dir() * t
    };
    let direct = |p: Vec3| {
        let to = Vec3::new(0.0, light, 0.0) - p;
        rho * i * (to.normalize().y)
    };
    let grid = 16;
    let mut worst = 0.0f32;
    for py in 0..size {
        for px in 0..size {
            let values: Vec<Vec3> = (0..grid * grid)
                .map(|k| {
                    let (gx, gy) = ((k % grid) as f32 + 0.5, (k / grid) as f32 + 0.5);
                    let p = on_plane(px as f32 + gx / grid as f32, py as f32 + gy / grid as f32);
                    direct(p)
                })
                .collect();
            let n = values.len() as f32;
            let mean = values.iter().sum::<Vec3>() / n;
            let var = values
                .iter()
                .map(|v| (*v - mean) * (*v - mean))
                .sum::<Vec3>()
                / n;
            let tolerance = 5.0 * (var / samples as f32).powf(0.5) + Vec3::splat(1e-5);
            let got = out.image.pixels[(py * size + px) as usize];
            let err = (got - mean).abs();
            assert!(
                err.cmple(tolerance).all(),
                "pixel ({px}, {py}): got {got}, expected {mean} within {tolerance}"
            );
            worst = worst.max((err / tolerance).max_element());
        }
    }
    // Every path's eye ray hits the plane and casts one shadow ray; each diffuse bounce leaves.
    let rays = (size * size * samples) as u64;
    assert_eq!((out.stats.eye_hits, out.stats.shadow), (rays, rays));
    assert!(worst < 1.0);
}

/// The furnace: a closed cube whose inner walls all have albedo `a` and give off radiance `e`.
/// Light bounces forever, so every ray sees `e + a e + a^2 e + ... = e / (1 - a)` per channel.
/// The pixels are independent estimates of it; their mean must lie within five standard
/// errors (from the pixels' own spread) of the geometric series, which Russian roulette and
/// the bounce cap must leave unbiased.
#[test]
fn a_closed_glowing_diffuse_room_converges_to_the_geometric_series() {
    let (a, e) = (Vec3::new(0.5, 0.3, 0.7), Vec3::new(1.0, 0.5, 0.25));
    let camera = Camera::perspective(
        Vec3::new(0.1, 0.2, 0.3),
        Vec3::new(1.0, 0.5, 0.2),
        Vec3::Y,
        90.0,
    );
    let mut s = Scene::new("furnace", camera);
    let m = s.add_material(Material::matte(a).with_emission(e));
    for axis in 0..3 {
        for side in [-1.0f32, 1.0] {
            let n = Vec3::AXES[axis] * side;
            let (u, v) = (Vec3::AXES[(axis + 1) % 3], Vec3::AXES[(axis + 2) % 3]);
            let corner = |su: f32, sv: f32| n + u * su + v * sv;
            let q = [
                corner(-1.0, -1.0),
                corner(1.0, -1.0),
                corner(1.0, 1.0),
                corner(-1.0, 1.0),
            ];
            // Facing inwards.
            s.add_facing(Triangle::new(q[0], q[1], q[2]), -n, m, None);
            s.add_facing(Triangle::new(q[0], q[2], q[3]), -n, m, None);
        }
    }
    let (size, samples) = (16u32, 64u32);
    let out = path_render(&s, size, samples);
    let expected = e / (Vec3::ONE - a);
    let px = &out.image.pixels;
    let n = px.len() as f32;
    let mean = px.iter().sum::<Vec3>() / n;
    let var = px.iter().map(|v| (*v - mean) * (*v - mean)).sum::<Vec3>() / (n - 1.0);
    let standard_error = (var / n).powf(0.5);
    assert!(
        (mean - expected).abs().cmple(standard_error * 5.0).all(),
        "mean {mean}, expected {expected}, standard error {standard_error}"
    );
    // The estimate is not a constant: paths did bounce, and roulette ended them.
    assert!(standard_error.min_element() > 0.0);
    assert!(out.stats.diffuse > out.stats.eye_rays, "{:?}", out.stats);
    // No ray escapes the closed room.
    assert_eq!(out.stats.eye_hits, out.stats.eye_rays);
    println!("furnace: mean {mean}, expected {expected}, standard error {standard_error}");
}

/// The same seed gives the same image and ray counts; another seed another image. Every kind
/// of bounce happens on the chess scene.
#[test]
fn path_traced_images_repeat_for_a_seed() {
    let mut s = rt_shade::chess();
    s.resolution = None;
    let accel = BruteForce::build(&s.shapes).unwrap();
    let options = |seed| RenderOptions {
        width: 24,
        height: 18,
        integrator: Integrator::Path(PathOptions {
            samples: 2,
            seed,
            ..PathOptions::default()
        }),
        ..RenderOptions::default()
    };
    let once = render(&s, &accel, &options(1), &|_| {}).unwrap();
    let again = render(&s, &accel, &options(1), &|_| {}).unwrap();
    let other = render(&s, &accel, &options(2), &|_| {}).unwrap();
    assert_eq!(once.image, again.image);
    assert_eq!(once.stats, again.stats);
    assert_ne!(once.image, other.image);
    let (st, n) = (once.stats, 24 * 18 * 2);
    assert_eq!(st.eye_rays, n);
    assert!(st.diffuse > 0 && st.reflected > 0 && st.refracted > 0 && st.shadow > 0);
}

#[test]
fn path_options_out_of_range_are_refused() {
    let s = rt_shade::chess();
    let accel = BruteForce::build(&s.shapes).unwrap();
    for bad in [
        PathOptions {
            samples: 0,
            ..PathOptions::default()
        },
        PathOptions {
            max_bounces: 100_000,
            ..PathOptions::default()
        },
    ] {
        let options = RenderOptions {
            width: 4,
            height: 4,
            integrator: Integrator::Path(bad),
            ..RenderOptions::default()
        };
        let e = render(&s, &accel, &options, &|_| {}).unwrap_err();
        assert!(e.to_string().contains("must lie in"), "{e}");
    }
}
