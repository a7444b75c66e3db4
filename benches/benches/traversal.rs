//! Traversal per registered structure: closest-hit and shadow queries on a procedural scene
//! (no files needed), throughput in rays. `cargo xtask bench` covers the shared meshes.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rt_geom::Vec3;
use rt_testkit::{RaySets, scenes};
use xtask::registry::REGISTRY;

fn traversal(c: &mut Criterion) {
    let tris = scenes::tessellated_sphere(50_000, Vec3::ZERO, 1.0);
    let reference = (xtask::registry::find("obvhs").unwrap().build)(&tris).unwrap();
    let sets = RaySets::generate("sphere-50k", &tris, reference.as_ref(), 64, 64, 1);
    for entry in REGISTRY {
        if tris.len() > entry.bench_max_prims {
            continue;
        }
        let accel = (entry.build)(&tris).unwrap();
        let mut g = c.benchmark_group(format!("traversal/{}", entry.name));
        for (set, occluded) in [("primary", false), ("shadow", true), ("diffuse", false)] {
            let rays = sets.by_name(set).unwrap();
            g.throughput(Throughput::Elements(rays.len() as u64));
            g.bench_function(set, |b| {
                b.iter(|| xtask::run::count_hits(accel.as_ref(), rays, occluded))
            });
        }
        g.finish();
    }
}

criterion_group!(benches, traversal);
criterion_main!(benches);
