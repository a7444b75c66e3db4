//! Primary rays of the standard camera, single rays against packets of every tile size, one
//! thread, for rt's BVH, the SAH kd-tree and the kd-tree with multi-level ray tracing:
//! `cargo run --release -p rt-packet --features measure --example packet_speed -- [MESH.obj|-] [bvh|bvh8|kd|kd-mlrta] [SIDE]`
//! (default: a tessellated sphere of 200k triangles, all three structures; `PACKETS_ONLY=1`
//! skips the single rays). `cargo xtask bench` measures the same on 2 threads beside obvhs.

use rt_accel_bvh::{Bvh, Bvh8, BvhParams};
use rt_accel_kd::{KdParams, KdTree};
use rt_geom::{Aabb, Accel, Ray, Triangle, Vec3};
use rt_packet::{MlrtaKdTree, PacketTraversal, RayPacket, TILE_SIDES, tiles};
use std::time::Instant;

fn median_mrays(rays: usize, mut run: impl FnMut() -> usize) -> (f64, usize) {
    let mut times = Vec::new();
    let mut hits = 0;
    for _ in 0..5 {
        let t = Instant::now();
        hits = run();
        times.push(t.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    (rays as f64 / times[2] / 1e6, hits)
}

/// Single rays, then packets of every tile size, of one structure.
fn report<T: Accel + PacketTraversal>(name: &str, accel: &T, rays: &[Ray], (w, h): (usize, usize)) {
    // `PACKETS_ONLY=1` skips the single rays (for a profile of the packets alone).
    let (single, hits) = if std::env::var_os("PACKETS_ONLY").is_some() {
        (f64::NAN, 0)
    } else {
        median_mrays(rays.len(), || {
            rays.iter().filter(|r| accel.intersect(r).is_some()).count()
        })
    };
    println!("{name:<10} single rays  {single:7.2} Mrays/s  ({hits} hits)");
    let only: Option<usize> = std::env::args().nth(3).and_then(|s| s.parse().ok());
    for side in TILE_SIDES
        .into_iter()
        .filter(|s| only.is_none_or(|o| o == *s))
    {
        let tiled: Vec<Ray> = tiles(w, h, side, side)
            .concat()
            .into_iter()
            .map(|i| rays[i])
            .collect();
        let (rate, hits) = median_mrays(tiled.len(), || {
            let hits = match side {
                2 => accel.intersect_rays::<4>(&tiled),
                4 => accel.intersect_rays::<16>(&tiled),
                8 => accel.intersect_rays::<64>(&tiled),
                _ => accel.intersect_rays::<256>(&tiled),
            };
            hits.iter().filter(|h| h.is_some()).count()
        });
        if side == 16 {
            // What filling the packets alone costs (reading the rays, writing their lanes).
            let (rate, _) = median_mrays(tiled.len(), || {
                tiled
                    .chunks(256)
                    .map(|c| {
                        let packet = std::hint::black_box(RayPacket::<256>::new(c));
                        let active = packet.active_count();
                        packet.recycle();
                        active
                    })
                    .sum()
            });
            println!("{name:<10} 16x16 packets filled, not traced {rate:7.2} Mrays/s");
        }
        println!(
            "{name:<10} {side:>2}x{side:<2} packets {rate:7.2} Mrays/s  ({hits} hits)  {:.2}x single",
            rate / single
        );
    }
}

fn main() -> Result<(), String> {
    let tris: Vec<Triangle> = match std::env::args().nth(1) {
        Some(path) if path != "-" => rt_geom::load_obj(&path)
            .map_err(|e| e.to_string())?
            .triangles(),
        _ => rt_testkit::scenes::tessellated_sphere(200_000, Vec3::ZERO, 1.0),
    };
    let bounds = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(t.bounds()));
    let size = (512, 512);
    let rays = rt_testkit::View::front(&bounds).camera_rays(size.0, size.1);
    println!(
        "{} triangles, {}x{} primary rays, 1 thread",
        tris.len(),
        size.0,
        size.1
    );
    let only = std::env::args().nth(2);
    let wanted = |name: &str| only.as_deref().is_none_or(|o| o == name);
    if wanted("bvh") {
        let bvh = Bvh::build(&tris, BvhParams::balanced()).map_err(|e| e.to_string())?;
        report("bvh", &bvh, &rays, size);
    }
    if wanted("bvh8") {
        let bvh8 = Bvh8::build(&tris, BvhParams::balanced()).map_err(|e| e.to_string())?;
        report("bvh8", &bvh8, &rays, size);
    }
    // The kd-tree the packet paths use (the registry's `kd` packets): smaller leaves.
    let kd = || KdTree::build(&tris, KdParams::wald_havran()).map_err(|e| e.to_string());
    if wanted("kd") {
        report("kd", &kd()?, &rays, size);
    }
    if wanted("kd-mlrta") {
        report("kd-mlrta", &MlrtaKdTree::new(kd()?), &rays, size);
    }
    Ok(())
}
