//! Refit against a full build of the same layout, and trace speed after a large deformation:
//! `cargo run --release -p rt-accel-bvh --features measure --example refit_vs_build -- MESH.obj [RAYS]`.

use rt_accel_bvh::{BvhParams, CompressedTriBvh8, Refit, TriBvh4, TriBvh8};
use rt_geom::{Accel, Ray, Triangle, Vec3};
use std::time::Instant;

/// A twist about the vertical axis by up to a quarter turn and a stretch to 1.5x the height.
fn deform(tris: &[Triangle], bounds: (Vec3, Vec3)) -> Vec<Triangle> {
    let (lo, hi) = bounds;
    let centre = (lo + hi) * 0.5;
    tris.iter()
        .map(|t| Triangle {
            v: t.v.map(|p| {
                let q = p - centre;
                let h = (p.y - lo.y) / (hi.y - lo.y).max(1e-30);
                let (s, c) = (h * std::f32::consts::FRAC_PI_2).sin_cos();
                centre + Vec3::new(c * q.x - s * q.z, q.y * 1.5, s * q.x + c * q.z)
            }),
        })
        .collect()
}

/// Rays from a sphere around the mesh towards points near its centre.
fn rays(n: usize, bounds: (Vec3, Vec3)) -> Vec<Ray> {
    let (lo, hi) = bounds;
    let (centre, r) = ((lo + hi) * 0.5, (hi - lo).length());
    let mut s = 0x2545_f491u32;
    let mut f = move || {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        s as f32 / u32::MAX as f32 * 2.0 - 1.0
    };
    (0..n)
        .map(|_| {
            let o = centre + Vec3::new(f(), f(), f()).normalize_or_zero() * r;
            let target = centre + Vec3::new(f(), f(), f()) * r * 0.2;
            Ray::new(o, target - o)
        })
        .collect()
}

fn seconds(f: impl FnOnce()) -> f64 {
    let t = Instant::now();
    f();
    t.elapsed().as_secs_f64()
}

fn trace(accel: &dyn Accel, rays: &[Ray]) -> (f64, usize) {
    let mut hits = 0;
    let s = seconds(|| hits = rays.iter().filter(|r| accel.intersect(r).is_some()).count());
    (rays.len() as f64 / s / 1e6, hits)
}

fn run<A: Accel + Refit<Triangle>>(
    name: &str,
    build: impl Fn(&[Triangle]) -> A,
    tris: &[Triangle],
    moved: &[Triangle],
    rays: &[Ray],
) {
    let mut refitted = build(tris);
    let build_s = seconds(|| drop(build(tris)));
    let refit_s = seconds(|| refitted.refit(moved).unwrap());
    let rebuilt = build(moved);
    let (refit_mrays, h1) = trace(&refitted, rays);
    let (rebuilt_mrays, h2) = trace(&rebuilt, rays);
    assert_eq!(h1, h2);
    println!(
        "{name:<22} build {build_s:>7.3} s  refit {refit_s:>7.4} s ({:>5.1}x faster)  after the deformation: refit {refit_mrays:>6.2} Mrays/s, rebuilt {rebuilt_mrays:>6.2} Mrays/s ({:.2}x)",
        build_s / refit_s,
        refit_mrays / rebuilt_mrays
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let Some(path) = args.get(1) else {
        eprintln!("usage: refit_vs_build MESH.obj [RAYS]");
        std::process::exit(2);
    };
    let n: usize = args
        .get(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1_000_000);
    let mesh = rt_geom::load_obj(path).unwrap_or_else(|e| {
        eprintln!("{path}: {e}");
        std::process::exit(1)
    });
    let tris = mesh.triangles();
    let b = mesh.bounds();
    let moved = deform(&tris, (b.min, b.max));
    let mb = moved
        .iter()
        .fold(rt_geom::Aabb::EMPTY, |a, t| a.union(t.bounds()));
    let rays = rays(n, (mb.min, mb.max));
    println!(
        "{} triangles, {} rays, {} rayon threads",
        tris.len(),
        n,
        rayon::current_num_threads()
    );
    run(
        "bvh8-tri (fastest)",
        |t| TriBvh8::build_for_tracing(t).unwrap(),
        &tris,
        &moved,
        &rays,
    );
    run(
        "bvh8-tri (balanced)",
        |t| TriBvh8::build(t, BvhParams::balanced().for_soa_leaves()).unwrap(),
        &tris,
        &moved,
        &rays,
    );
    run(
        "bvh4-tri (balanced)",
        |t| TriBvh4::build(t, BvhParams::balanced().for_soa_leaves()).unwrap(),
        &tris,
        &moved,
        &rays,
    );
    run(
        "bvh8-tri-compressed",
        |t| CompressedTriBvh8::build(t, BvhParams::fastest_trace()).unwrap(),
        &tris,
        &moved,
        &rays,
    );
}
