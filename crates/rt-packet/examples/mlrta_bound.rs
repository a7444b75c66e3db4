//! How much multi-level ray tracing could gain at most over plain kd-tree packets: primary
//! rays of the bench's standard camera in 16x16 tiles, one thread, on the packet paths' kd-tree
//! (`KdParams::wald_havran`), timed five times in turn (medians):
//!
//! - `fill`: the packets built and dropped, not traced (what every path pays);
//! - `plain`: plain packets, every block of 16 lanes from the root;
//! - `mlrta`: multi-level ray tracing, entry points searched once per packet (`kd-mlrta`);
//! - `per-block`: entry points searched for every block of 16 lanes on its own, the deepest
//!   starts the walk can use (`MlrtaKdTree::intersect_packet_per_block`);
//! - `searches`: those per-block searches alone;
//! - `packet searches`: one search per packet alone, as `mlrta` makes them.
//!
//! `per-block - searches` is the time of the walks from the best starts; with `fill`, it gives
//! the bound `plain / (fill + walks)`: the speed-up of entry points that cost nothing to find.
//!
//! `cargo run --release -p rt-packet --features measure --example mlrta_bound -- MESH.obj [SIDE]` (`SIDE`: the
//! camera's resolution, 1024 as in the bench; `sphere:N` for a tessellated sphere).

use rt_accel_kd::{KdParams, KdTree};
use rt_geom::{Aabb, Hit, Ray};
use rt_packet::kd::KD_BLOCK;
use rt_packet::{Beam, MlrtaKdTree, PacketTraversal, RayPacket, tiles};
use std::hint::black_box;
use std::time::Instant;

const TILE: usize = 16;
const N: usize = TILE * TILE;
const ROUNDS: usize = 5;

/// Seconds per pass of `run` over all packets, and the number of hits it reports.
fn time(run: &mut dyn FnMut() -> usize) -> (f64, usize) {
    let t = Instant::now();
    let hits = run();
    (t.elapsed().as_secs_f64(), hits)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Hits of `trace` over every packet of `rays` (tiles in order).
fn traced(rays: &[Ray], trace: impl Fn(&mut RayPacket<'_, N>) -> [Option<Hit>; N]) -> usize {
    rays.chunks(N)
        .map(|c| {
            let mut p = RayPacket::<N>::new(c);
            let hits = trace(&mut p);
            p.recycle();
            hits.iter().filter(|h| h.is_some()).count()
        })
        .sum()
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first() else {
        return Err("usage: mlrta_bound MESH.obj|sphere:N [SIDE]".into());
    };
    let side: usize = match args.get(1) {
        Some(s) => s
            .parse()
            .map_err(|_| format!("SIDE must be a number, not {s:?}"))?,
        None => 1024,
    };
    if side == 0 || side % TILE != 0 {
        return Err(format!(
            "SIDE must be a positive multiple of {TILE}, not {side}"
        ));
    }
    let tris = rt_testkit::scenes::mesh_or_sphere(path)?;
    let bounds = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(t.bounds()));
    let view = rt_testkit::View::standard(path, &bounds);
    let camera = view.camera_rays(side, side);
    let rays: Vec<Ray> = tiles(side, side, TILE, TILE)
        .concat()
        .into_iter()
        .map(|i| camera[i])
        .collect();
    let tree = KdTree::build(&tris, KdParams::wald_havran()).map_err(|e| e.to_string())?;
    let m = MlrtaKdTree::new(tree);
    println!(
        "{path}: {} triangles, {side}x{side} primary rays in {TILE}x{TILE} tiles, 1 thread, median of {ROUNDS}",
        tris.len()
    );

    let mut fill = || {
        rays.chunks(N)
            .map(|c| {
                let p = black_box(RayPacket::<N>::new(c));
                let active = p.active_count();
                p.recycle();
                active
            })
            .sum()
    };
    let mut plain = || traced(&rays, |p| m.tree().intersect_packet(p));
    let mut mlrta = || traced(&rays, |p| m.intersect_packet(p));
    let mut per_block = || traced(&rays, |p| m.intersect_packet_per_block(p));
    let mut searches = || {
        rays.chunks(N)
            .map(|c| {
                let p = RayPacket::<N>::new(c);
                let cells: usize = (0..N)
                    .step_by(KD_BLOCK)
                    .map(|b| black_box(m.entry_points(&Beam::new(&p, b..b + KD_BLOCK))).len())
                    .sum();
                p.recycle();
                cells
            })
            .sum()
    };
    let mut packet_searches = || {
        rays.chunks(N)
            .map(|c| {
                let p = RayPacket::<N>::new(c);
                let cells = black_box(m.entry_points(&Beam::new(&p, 0..N))).len();
                p.recycle();
                cells
            })
            .sum()
    };
    let names = [
        "fill",
        "plain",
        "mlrta",
        "per-block",
        "searches",
        "packet searches",
    ];
    let mut runs: [&mut dyn FnMut() -> usize; 6] = [
        &mut fill,
        &mut plain,
        &mut mlrta,
        &mut per_block,
        &mut searches,
        &mut packet_searches,
    ];
    let mut times = vec![Vec::new(); names.len()];
    let mut counts = [0; 6];
    for _ in 0..ROUNDS {
        for (k, run) in runs.iter_mut().enumerate() {
            let (t, n) = time(*run);
            times[k].push(t);
            counts[k] = n;
        }
    }
    // The three traced paths must agree (each equals the single rays lane by lane).
    if counts[1] != counts[2] || counts[1] != counts[3] {
        return Err(format!(
            "hit counts differ: plain {}, mlrta {}, per-block {}",
            counts[1], counts[2], counts[3]
        ));
    }
    let t: Vec<f64> = times.into_iter().map(median).collect();
    let rate = |s: f64| rays.len() as f64 / s / 1e6;
    for (k, name) in names.iter().enumerate() {
        println!(
            "{name:<16} {:8.2} Mrays/s  ({:.1} ms)",
            rate(t[k]),
            t[k] * 1e3
        );
    }
    let walks = t[3] - t[4];
    println!("hits: {} of {} rays", counts[1], rays.len());
    println!("mlrta x plain:                       {:.2}x", t[1] / t[2]);
    println!(
        "walks from per-block entry points:   {:.2}x plain's walks ({:.1} ms against {:.1} ms)",
        (t[1] - t[0]) / walks,
        walks * 1e3,
        (t[1] - t[0]) * 1e3
    );
    println!(
        "bound (entry points found for free): {:.2}x plain",
        t[1] / (t[0] + walks)
    );
    println!(
        "time left for searches at 1.3x:      {:.1} ms per pass (one search per packet takes {:.1} ms)",
        (t[1] / 1.3 - t[0] - walks) * 1e3,
        (t[5] - t[0]) * 1e3
    );
    Ok(())
}
