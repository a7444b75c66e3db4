//! Where a single ray's time goes in the 8-wide triangle BVH (`TriBvh8::build_for_tracing`,
//! the `bvh8-tri` entry): the walk and the leaf tests timed apart, one thread, median of 5
//! interleaved passes over a ray file.
//!
//! - **whole**: `Accel::intersect` / `occluded`, as a renderer calls them;
//! - **leaves alone**: each ray's leaves, recorded once from its own walk, tested again in
//!   order without the walk (what a free traversal would give);
//! - **walk alone**: the walk with leaves that cost nothing, told the answer in advance
//!   (closest hit: the interval ends at the hit; any hit: the walk stops at the leaf that
//!   answered), so it visits no more nodes than the real walk (what a free kernel would give).
//!
//! Also per ray: leaves and triangles tested, and child boxes tested (by the whole query and by
//! the walk alone) when built with the `rt-geom/counters` feature. The same ray files go to
//! `cargo xtask trace --threads 1` for a peer's time on the same rays.
//!
//! `cargo run --release -p rt-accel-bvh --features measure --example bvh8_bound -- MESH.obj RAYS.rays [--occluded]`
//! (`cargo xtask rays` writes the ray files).

use rt_accel_bvh::TriBvh8;
use rt_geom::{Accel, BaseLevel, Hit, Kernel, Level, Ray, Walk};
use std::hint::black_box;
use std::time::Instant;

const ROUNDS: usize = 5;

/// Reads a `.rays` file.
fn read_rays(path: &str) -> Result<Vec<Ray>, String> {
    rt_testkit::rayfile::read_rays(std::path::Path::new(path))
}

/// The leaves one ray's walk tests, in order, and its answer.
fn record<const ANY_HIT: bool>(bvh: &TriBvh8, ray: &Ray) -> (Vec<(u32, u32)>, Option<Hit>) {
    let mut leaves = Vec::new();
    let answer = bvh.tree().traverse::<ANY_HIT, _, _>(
        BaseLevel,
        ray,
        || None,
        |first, count, r, best| {
            leaves.push((first, count));
            test::<ANY_HIT, _>(BaseLevel, bvh, first, count, r, best)
        },
    );
    (leaves, answer)
}

#[inline(always)]
fn test<const ANY_HIT: bool, L: Level>(
    level: L,
    bvh: &TriBvh8,
    first: u32,
    count: u32,
    r: &mut Ray,
    best: &mut Option<Hit>,
) -> bool {
    bvh.triangles().intersect_range::<ANY_HIT, L>(
        level,
        first as usize,
        count as usize,
        r,
        bvh.ids(),
        best,
    )
}

/// The recorded leaves tested again, in order, until the answer.
#[inline(always)]
fn replay<const ANY_HIT: bool, L: Level>(
    level: L,
    bvh: &TriBvh8,
    ray: &Ray,
    leaves: &[(u32, u32)],
) -> Option<Hit> {
    let mut r = *ray;
    let mut best = None;
    for &(first, count) in leaves {
        if test::<ANY_HIT, L>(level, bvh, first, count, &mut r, &mut best) {
            break;
        }
    }
    best
}

/// A timed pass over the recorded rays, compiled for the structure's instruction set as its
/// queries are: the leaves alone (`LEAVES`) or the walk alone.
struct Pass<'a, const ANY_HIT: bool, const LEAVES: bool> {
    bvh: &'a TriBvh8,
    rays: &'a [Ray],
    recorded: &'a [Recorded],
}

/// A ray's leaves, its answer and the leaf that gave it.
type Recorded = (Vec<(u32, u32)>, Option<Hit>, Option<(u32, u32)>);

impl<const ANY_HIT: bool, const LEAVES: bool> Kernel for Pass<'_, ANY_HIT, LEAVES> {
    type Output = ();
    #[inline(always)]
    fn run<L: Level>(self, level: L) {
        for (ray, (tested, answer, last)) in self.rays.iter().zip(self.recorded) {
            if LEAVES {
                black_box(replay::<ANY_HIT, L>(level, self.bvh, ray, tested));
            } else {
                black_box(walk::<ANY_HIT, L>(level, self.bvh, ray, *answer, *last));
            }
        }
    }
}

/// The walk with free leaves, told the answer: the ray ends at its hit (closest hit), or the
/// walk stops at the leaf that answered (any hit). Returns that answer.
#[inline(always)]
fn walk<const ANY_HIT: bool, L: Level>(
    level: L,
    bvh: &TriBvh8,
    ray: &Ray,
    answer: Option<Hit>,
    last: Option<(u32, u32)>,
) -> Option<Hit> {
    let mut r = *ray;
    if !ANY_HIT {
        if let Some(h) = answer {
            r.tmax = h.t;
        }
    }
    bvh.tree().traverse::<ANY_HIT, L, _>(
        level,
        &r,
        || None,
        |first, count, _, best| {
            black_box(first);
            if ANY_HIT && answer.is_some() && last == Some((first, count)) {
                *best = answer;
                return true;
            }
            false
        },
    )
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn race<const ANY_HIT: bool>(bvh: &TriBvh8, rays: &[Ray]) -> Result<(), String> {
    let mut recorded = Vec::with_capacity(rays.len());
    let (mut leaves, mut prims) = (0usize, 0usize);
    for (k, ray) in rays.iter().enumerate() {
        let (tested, answer) = record::<ANY_HIT>(bvh, ray);
        if replay::<ANY_HIT, _>(BaseLevel, bvh, ray, &tested) != answer {
            return Err(format!("ray {k}: the leaves alone answer otherwise"));
        }
        let last = tested.last().copied();
        if ANY_HIT
            && walk::<ANY_HIT, _>(BaseLevel, bvh, ray, answer, last).is_some() != answer.is_some()
        {
            return Err(format!("ray {k}: the walk alone answers otherwise"));
        }
        leaves += tested.len();
        prims += tested.iter().map(|&(_, c)| c as usize).sum::<usize>();
        recorded.push((tested, answer, last));
    }
    // Child boxes tested per ray, from a build with the counters on.
    let _ = rt_geom::counters::take();
    for ray in rays {
        black_box(if ANY_HIT {
            bvh.occluded(ray) as u8
        } else {
            bvh.intersect(ray).is_some() as u8
        });
    }
    let nodes = rt_geom::counters::take().nodes as usize;
    // And by the walk alone, which knows the answer from the start: the whole walk finds its
    // hit on the way, and the boxes beyond it that it tests before then are the difference.
    let walk_alone = Pass::<ANY_HIT, false> {
        bvh,
        rays,
        recorded: &recorded,
    };
    rt_geom::isa::run(bvh.isa(), walk_alone);
    let walk_nodes = rt_geom::counters::take().nodes as usize;
    let (mut whole, mut alone, mut walked) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..ROUNDS {
        let t = Instant::now();
        for ray in rays {
            if ANY_HIT {
                black_box(bvh.occluded(ray));
            } else {
                black_box(bvh.intersect(ray));
            }
        }
        whole.push(t.elapsed().as_secs_f64());
        let isa = bvh.isa();
        let t = Instant::now();
        let pass = |rays, recorded| Pass::<ANY_HIT, true> {
            bvh,
            rays,
            recorded,
        };
        rt_geom::isa::run(isa, pass(rays, &recorded));
        alone.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        let pass = |rays, recorded| Pass::<ANY_HIT, false> {
            bvh,
            rays,
            recorded,
        };
        rt_geom::isa::run(isa, pass(rays, &recorded));
        walked.push(t.elapsed().as_secs_f64());
    }
    let rate = |s: f64| rays.len() as f64 / s / 1e6;
    let per_ray = |n: usize| n as f64 / rays.len().max(1) as f64;
    let (whole, alone, walked) = (
        rate(median(whole)),
        rate(median(alone)),
        rate(median(walked)),
    );
    println!(
        "whole Mrays/s  leaves alone  walk alone  leaves/ray  triangles/ray  boxes/ray (whole, walk alone)"
    );
    println!(
        "{whole:13.2}  {alone:12.2}  {walked:10.2}  {:10.2}  {:13.2}  {}",
        per_ray(leaves),
        per_ray(prims),
        if rt_geom::counters::ENABLED {
            format!("{:.2}, {:.2}", per_ray(nodes), per_ray(walk_nodes))
        } else {
            "(counters off)".into()
        }
    );
    println!(
        "share of a query: walk {:.0}%, leaves {:.0}% (times of each alone over the whole)",
        100.0 * whole / walked,
        100.0 * whole / alone
    );
    Ok(())
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [mesh, rays, rest @ ..] = &args[..] else {
        return Err("usage: bvh8_bound MESH.obj RAYS.rays [--occluded]".into());
    };
    let occluded = match rest {
        [] => false,
        [flag] if flag == "--occluded" => true,
        _ => return Err(format!("unexpected arguments {rest:?}")),
    };
    let tris = rt_geom::load_obj(mesh)
        .map_err(|e| e.to_string())?
        .triangles();
    let bvh = TriBvh8::build_for_tracing(&tris).map_err(|e| e.to_string())?;
    let rays = read_rays(rays)?;
    println!(
        "{mesh}: {} triangles, {} rays{}, 1 thread, median of {ROUNDS}",
        tris.len(),
        rays.len(),
        if occluded { ", any hit" } else { "" }
    );
    if occluded {
        race::<true>(&bvh, &rays)
    } else {
        race::<false>(&bvh, &rays)
    }
}
