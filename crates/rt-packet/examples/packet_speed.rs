//! Primary rays of the standard camera through rt's BVH, single rays against packets of every
//! tile size, one thread: `cargo run --release -p rt-packet --example packet_speed -- [MESH.obj]`
//! (default: a tessellated sphere of 200k triangles).

use rt_accel_bvh::{Bvh, BvhParams};
use rt_geom::{Aabb, Accel, Ray, Triangle, Vec3};
use rt_packet::{PacketTraversal, TILE_SIDES, tiles};
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

fn main() -> Result<(), String> {
    let tris: Vec<Triangle> = match std::env::args().nth(1) {
        Some(path) => rt_geom::load_obj(&path)
            .map_err(|e| e.to_string())?
            .triangles(),
        None => rt_testkit::scenes::tessellated_sphere(200_000, Vec3::ZERO, 1.0),
    };
    let bvh = Bvh::build(&tris, BvhParams::balanced()).map_err(|e| e.to_string())?;
    let bounds = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(t.bounds()));
    let (w, h) = (512, 512);
    let rays = rt_testkit::View::front(&bounds).camera_rays(w, h);
    let (single, hits) = median_mrays(rays.len(), || {
        rays.iter().filter(|r| bvh.intersect(r).is_some()).count()
    });
    println!("{} triangles, {w}x{h} primary rays, 1 thread", tris.len());
    println!("single rays      {single:7.2} Mrays/s  ({hits} hits)");
    for side in TILE_SIDES {
        let tiled: Vec<Ray> = tiles(w, h, side, side)
            .concat()
            .into_iter()
            .map(|i| rays[i])
            .collect();
        let (rate, hits) = median_mrays(tiled.len(), || {
            let hits = match side {
                2 => bvh.intersect_rays::<4>(&tiled),
                4 => bvh.intersect_rays::<16>(&tiled),
                8 => bvh.intersect_rays::<64>(&tiled),
                _ => bvh.intersect_rays::<256>(&tiled),
            };
            hits.iter().filter(|h| h.is_some()).count()
        });
        println!(
            "{side:>2}x{side:<2} packets    {rate:7.2} Mrays/s  ({hits} hits)  {:.2}x single",
            rate / single
        );
    }
    Ok(())
}
