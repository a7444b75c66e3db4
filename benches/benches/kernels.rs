//! The hot kernels: ray/box, ray/triangle (watertight and Möller–Trumbore), ray/sphere and the
//! bounding volumes, each over a fixed batch of rays (throughput in rays).

use criterion::{Criterion, Throughput, black_box, criterion_group, criterion_main};
use rt_geom::{Aabb, BoundingSphere, BoundingVolume, Frame, Kdop7, Ray, Sphere, Triangle, Vec3};
use rt_testkit::Rng;

fn rays(n: usize) -> Vec<Ray> {
    let mut rng = Rng::new(1);
    (0..n)
        .map(|_| {
            let o = rng.point_in(Vec3::splat(-2.0), Vec3::splat(2.0)) + Vec3::new(0.0, 0.0, 4.0);
            let target = rng.point_in(Vec3::splat(-0.6), Vec3::splat(0.6));
            Ray::new(o, target - o)
        })
        .collect()
}

fn kernels(c: &mut Criterion) {
    let rays = rays(4096);
    let tri = Triangle::new(
        Vec3::new(-0.5, -0.5, 0.0),
        Vec3::new(0.5, -0.5, 0.1),
        Vec3::new(0.0, 0.5, -0.1),
    );
    let bounds = tri.bounds();
    let sphere = Sphere::new(Vec3::ZERO, 0.5);
    let bsphere = BoundingSphere::enclosing(&[tri], &Frame::WORLD);
    let kdop = Kdop7::enclosing(&[tri], &Frame::WORLD);
    let mut g = c.benchmark_group("kernels");
    g.throughput(Throughput::Elements(rays.len() as u64));
    g.bench_function("aabb_clip_ray", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| black_box(&bounds).clip_ray(r).is_some())
                .count()
        })
    });
    g.bench_function("triangle_watertight", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| black_box(&tri).intersect_watertight(r).is_some())
                .count()
        })
    });
    g.bench_function("triangle_moller_trumbore", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| black_box(&tri).intersect_moller_trumbore(r).is_some())
                .count()
        })
    });
    g.bench_function("sphere", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| black_box(&sphere).intersect(r).is_some())
                .count()
        })
    });
    g.bench_function("bounding_sphere", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| {
                    black_box(&bsphere)
                        .entry_distance(r, &Frame::WORLD)
                        .is_some()
                })
                .count()
        })
    });
    g.bench_function("kdop7", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| black_box(&kdop).entry_distance(r, &Frame::WORLD).is_some())
                .count()
        })
    });
    let aabb = Aabb::around(&[tri]);
    g.bench_function("aabb_volume", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| black_box(&aabb).entry_distance(r, &Frame::WORLD).is_some())
                .count()
        })
    });
    g.finish();
}

criterion_group!(benches, kernels);
criterion_main!(benches);
