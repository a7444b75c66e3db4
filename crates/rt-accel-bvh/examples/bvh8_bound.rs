//! Where a single ray's time goes in the 8-wide triangle BVH (`TriBvh8::build_for_tracing`,
//! the `bvh8-tri` entry): the walk and the leaf tests timed apart, each cold, warm and with its
//! memory prefetched, one thread, median of 5 interleaved passes over a ray file.
//!
//! Parts:
//! - **whole**: `Accel::intersect` / `occluded`, as a renderer calls them;
//! - **leaves alone**: each ray's leaves, recorded once from its own walk, tested again in
//!   order without the walk (what a free traversal would give);
//! - **walk alone**: the walk with leaves that cost nothing, told the answer in advance
//!   (closest hit: the interval ends at the hit; any hit: the walk stops at the leaf that
//!   answered), so it visits no more nodes than the real walk (what a free kernel would give).
//!
//! Conditions:
//! - **cold**: the rays in file order, as a renderer traces them;
//! - **warm**: each ray's part run twice in a row, the second run's time (its nodes and leaves
//!   in the cache, its branches just seen by the predictor: what a free memory and a perfect
//!   predictor would give, together);
//! - **prefetched**: the lines of the nodes and leaves of the ray a few places ahead
//!   prefetched before each ray (memory free, the predictor as cold as in a render).
//!
//! Also per ray: leaves and triangles tested, and child boxes tested (by the whole query and by
//! the walk alone) when built with the `rt-geom/counters` feature. The same ray files go to
//! `cargo xtask trace --threads 1` (with `--warm` for its warm figure) for a peer's time on
//! the same rays.
//!
//! With `--against KEY=VALUE[,KEY=VALUE..]`, instead: the whole query against the same
//! structure with changes (another instruction set, `isa=baseline`, another leaf kernel,
//! `kernel=moller-trumbore`, or build parameters such as `leaf_block=8`), the two timed in
//! turn on alternate chunks of rays, so that the machine's swings in speed over seconds fall
//! on both alike. `--kernel moller-trumbore` gives both trees that leaf kernel (the
//! `bvh8-tri-mt` entry); `--base KEY=VALUE[,..]` makes the changes to the tree that every part
//! measures (and `--against` changes further).
//!
//! `cargo run --release -p rt-accel-bvh --features measure --example bvh8_bound -- MESH.obj RAYS.rays [--occluded] [--kernel K] [--base KEY=VALUE[,..]] [--against KEY=VALUE[,..]]`
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

/// Which part of a query a pass times (see the module documentation).
#[derive(Clone, Copy, PartialEq)]
enum Part {
    Whole,
    Leaves,
    Walk,
}

/// How a pass runs each ray's part (see the module documentation).
#[derive(Clone, Copy, PartialEq)]
enum Condition {
    Cold,
    Twice,
    Prefetched,
}

/// Rays ahead whose lines a prefetched pass requests.
const AHEAD: usize = 6;

/// A timed pass over the recorded rays, compiled for the structure's instruction set as its
/// queries are.
struct Pass<'a, const ANY_HIT: bool> {
    bvh: &'a TriBvh8,
    rays: &'a [Ray],
    recorded: &'a [Recorded],
    part: Part,
    condition: Condition,
}

/// A ray's leaves, its answer, the leaf that gave it, and the nodes whose boxes it enters.
struct Recorded {
    leaves: Vec<(u32, u32)>,
    answer: Option<Hit>,
    last: Option<(u32, u32)>,
    nodes: Vec<u32>,
}

impl<const ANY_HIT: bool> Kernel for Pass<'_, ANY_HIT> {
    type Output = ();
    #[inline(always)]
    fn run<L: Level>(self, level: L) {
        let runs = if self.condition == Condition::Twice {
            2
        } else {
            1
        };
        for (i, (ray, rec)) in self.rays.iter().zip(self.recorded).enumerate() {
            if self.condition == Condition::Prefetched {
                if let Some(ahead) = self.recorded.get(i + AHEAD) {
                    let leaves: &[_] = if self.part == Part::Walk {
                        &[]
                    } else {
                        &ahead.leaves
                    };
                    let nodes: &[_] = if self.part == Part::Leaves {
                        &[]
                    } else {
                        &ahead.nodes
                    };
                    prefetch(self.bvh, nodes, leaves);
                }
            }
            for _ in 0..runs {
                let ray = black_box(ray);
                match self.part {
                    Part::Whole if ANY_HIT => black_box(self.bvh.occluded(ray) as u8),
                    Part::Whole => black_box(self.bvh.intersect(ray).is_some() as u8),
                    Part::Leaves => black_box(
                        replay::<ANY_HIT, L>(level, self.bvh, ray, &rec.leaves).is_some() as u8,
                    ),
                    Part::Walk => black_box(
                        walk::<ANY_HIT, L>(level, self.bvh, ray, rec.answer, rec.last).is_some()
                            as u8,
                    ),
                };
            }
        }
    }
}

/// The nodes whose boxes the ray enters within `[tmin, t_end]` (a scalar walk of all of them,
/// boxes widened a little): about the nodes the real walk tests boxes of, for prefetching.
fn entered_nodes(bvh: &TriBvh8, ray: &Ray, t_end: f32) -> Vec<u32> {
    let nodes = bvh.tree().nodes();
    let mut out = Vec::new();
    let mut stack = if nodes.is_empty() { vec![] } else { vec![0u32] };
    let (o, d) = (ray.origin(), ray.dir());
    while let Some(n) = stack.pop() {
        out.push(n);
        let node = &nodes[n as usize];
        for l in 0..8 {
            if node.child[l] == u32::MAX || node.count[l] > 0 {
                continue;
            }
            let (mut t0, mut t1) = (ray.tmin, t_end);
            for a in 0..3 {
                let inv = 1.0 / d[a];
                let ta = (node.min[a][l] - o[a]) * inv;
                let tb = (node.max[a][l] - o[a]) * inv;
                if !ta.is_nan() && !tb.is_nan() {
                    t0 = t0.max(ta.min(tb));
                    t1 = t1.min(ta.max(tb) * 1.0001 + 1e-6);
                }
            }
            if t0 <= t1 {
                stack.push(node.child[l]);
            }
        }
    }
    out
}

/// Requests the cache lines of `nodes` and of `leaves`' triangle rows.
#[inline(always)]
fn prefetch(bvh: &TriBvh8, nodes: &[u32], leaves: &[(u32, u32)]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let line = |p: *const i8| {
            // SAFETY: a prefetch only hints the cache; it reads nothing the program sees and
            // cannot fault.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p) }
        };
        let all = bvh.tree().nodes();
        for &n in nodes {
            let p = (&all[n as usize] as *const rt_accel_bvh::WideNode<8>).cast::<i8>();
            (0..4).for_each(|k| line(p.wrapping_add(64 * k)));
        }
        let rows = bvh.triangles().rows();
        for &(first, count) in leaves {
            let leaf = &rows[9 * first as usize..9 * (first + count) as usize];
            let p = leaf.as_ptr().cast::<i8>();
            (0..=(4 * leaf.len()) / 64).for_each(|k| line(p.wrapping_add(64 * k)));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (bvh, nodes, leaves);
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
        let nodes = entered_nodes(bvh, ray, answer.map_or(ray.tmax, |h| h.t));
        recorded.push(Recorded {
            leaves: tested,
            answer,
            last,
            nodes,
        });
    }
    let isa = bvh.isa();
    let pass = |part, condition| Pass::<ANY_HIT> {
        bvh,
        rays,
        recorded: &recorded,
        part,
        condition,
    };
    // Child boxes tested per ray, from a build with the counters on: by the whole query, and by
    // the walk alone, which knows the answer from the start (the whole walk finds its hit on
    // the way, and the boxes beyond it that it tests before then are the difference).
    let _ = rt_geom::counters::take();
    rt_geom::isa::run(isa, pass(Part::Whole, Condition::Cold));
    let nodes = rt_geom::counters::take().nodes as usize;
    rt_geom::isa::run(isa, pass(Part::Walk, Condition::Cold));
    let walk_nodes = rt_geom::counters::take().nodes as usize;
    let parts = [Part::Whole, Part::Leaves, Part::Walk];
    let conditions = [Condition::Cold, Condition::Twice, Condition::Prefetched];
    let mut times = vec![vec![Vec::new(); conditions.len()]; parts.len()];
    for _ in 0..ROUNDS {
        for (p, &part) in parts.iter().enumerate() {
            for (c, &condition) in conditions.iter().enumerate() {
                let t = Instant::now();
                rt_geom::isa::run(isa, pass(part, condition));
                times[p][c].push(t.elapsed().as_secs_f64());
            }
        }
    }
    let rate = |s: f64| rays.len() as f64 / s / 1e6;
    let per_ray = |n: usize| n as f64 / rays.len().max(1) as f64;
    // Mrays/s per part: cold, warm (the second run of the pair alone), prefetched.
    let rates: Vec<[f64; 3]> = times
        .into_iter()
        .map(|t| {
            let [cold, twice, fetched] = [0, 1, 2].map(|c| median(t[c].clone()));
            [rate(cold), rate(twice - cold), rate(fetched)]
        })
        .collect();
    println!("Mrays/s     whole  leaves alone  walk alone");
    for (c, name) in ["cold", "warm", "prefetched"].iter().enumerate() {
        println!(
            "{name:10} {:6.2}  {:12.2}  {:10.2}",
            rates[0][c], rates[1][c], rates[2][c]
        );
    }
    println!(
        "per ray: {:.2} leaves, {:.2} triangles, boxes (whole, walk alone) {}",
        per_ray(leaves),
        per_ray(prims),
        if rt_geom::counters::ENABLED {
            format!("{:.2}, {:.2}", per_ray(nodes), per_ray(walk_nodes))
        } else {
            "(counters off)".into()
        }
    );
    let [whole, alone, walked] = [0, 1, 2].map(|p| rates[p][0]);
    println!(
        "share of a cold query: walk {:.0}%, leaves {:.0}% (times of each alone over the whole)",
        100.0 * whole / walked,
        100.0 * whole / alone
    );
    Ok(())
}

/// Rays per chunk of [`against`].
const CHUNK: usize = 1024;

/// `b`'s speed over `a`'s on the whole query, one figure per pair of passes. Chunks of rays are
/// timed in turn with `a` and `b`: each chunk queried once by one structure (cold), the next
/// chunk by the other, and the next pass swaps them, so that a pair of passes covers every
/// ray with both, close in time: the machine's swings over seconds cancel.
fn against<const ANY_HIT: bool>(a: &TriBvh8, b: &TriBvh8, rays: &[Ray]) -> Vec<f64> {
    let query = |bvh: &TriBvh8, rays: &[Ray]| {
        let t = Instant::now();
        for ray in rays {
            if ANY_HIT {
                black_box(bvh.occluded(ray));
            } else {
                black_box(bvh.intersect(ray));
            }
        }
        t.elapsed().as_secs_f64()
    };
    (0..2 * ROUNDS)
        .map(|_| {
            let mut t = [0.0f64; 2];
            for pass in 0..2 {
                for (k, chunk) in rays.chunks(CHUNK).enumerate() {
                    let side = (k + pass) % 2;
                    t[side] += query([a, b][side], chunk);
                }
            }
            t[0] / t[1]
        })
        .collect()
}

/// `bvh` with the changes of `--against` (comma-separated): `isa=baseline|avx2|avx512`,
/// `kernel=watertight|moller-trumbore`, `prefetch=true|false`, or one of the build's
/// parameters (`leaf_block=N`, `max_leaf=N`, `traversal_cost=X`, `reinsertion=X`, `bins=N`,
/// `spatial=ALPHA`, `budget=X`, `collapse=greedy|sah|ABOVE`), each as a change to
/// [`rt_accel_bvh::BvhParams::fastest_trace`]; `built` is what `bvh` was built with, and the
/// tree is rebuilt (with `bvh`'s leaf kernel) where the parameters differ from it. Returns the
/// tree and its parameters.
fn variant(
    (bvh, built): (&TriBvh8, rt_accel_bvh::BvhParams),
    tris: &[rt_geom::Triangle],
    changes: &str,
) -> Result<(TriBvh8, rt_accel_bvh::BvhParams), String> {
    let mut params = rt_accel_bvh::BvhParams::fastest_trace();
    let (mut isa, mut kernel, mut prefetch) = (None, bvh.kernel(), None);
    for change in changes.split(',') {
        let (key, value) = change
            .split_once('=')
            .ok_or_else(|| format!("--against takes KEY=VALUE, got {change:?}"))?;
        param(
            &mut params,
            &mut isa,
            &mut kernel,
            &mut prefetch,
            key,
            value,
        )
        .map_err(|e| format!("--against {change}: {e}"))?;
    }
    let mut tree = if params == built {
        bvh.clone()
    } else {
        params.validate().map_err(|e| e.to_string())?;
        TriBvh8::build(tris, params).map_err(|e| e.to_string())?
    };
    tree = tree.with_kernel(kernel);
    if let Some(isa) = isa {
        tree = tree.with_isa(isa);
    }
    if let Some(on) = prefetch {
        tree = tree.with_prefetch(on);
    }
    Ok((tree, params))
}

/// One `KEY=VALUE` of [`variant`].
fn param(
    params: &mut rt_accel_bvh::BvhParams,
    isa: &mut Option<rt_geom::Isa>,
    kernel: &mut rt_geom::TriangleKernel,
    prefetch: &mut Option<bool>,
    key: &str,
    value: &str,
) -> Result<(), String> {
    let bad = |e: &dyn std::fmt::Display| e.to_string();
    match key {
        "isa" => *isa = Some(rt_geom::Isa::parse(value)?),
        "kernel" => *kernel = parse_kernel(value)?,
        "prefetch" => *prefetch = Some(value.parse().map_err(|e| bad(&e))?),
        "leaf_block" => params.leaf_block = value.parse().map_err(|e| bad(&e))?,
        "max_leaf" => params.max_leaf_size = value.parse().map_err(|e| bad(&e))?,
        "traversal_cost" => params.traversal_cost = value.parse().map_err(|e| bad(&e))?,
        "reinsertion" => params.reinsertion = value.parse().map_err(|e| bad(&e))?,
        "bins" => {
            params.builder = rt_accel_bvh::BvhBuilder::BinnedSah {
                bins: value.parse().map_err(|e| bad(&e))?,
            }
        }
        "spatial" => params.spatial_alpha = Some(value.parse().map_err(|e| bad(&e))?),
        "budget" => params.spatial_budget = value.parse().map_err(|e| bad(&e))?,
        "collapse" => {
            params.collapse = match value {
                "greedy" => rt_accel_bvh::WideCollapse::LargestArea,
                "sah" => rt_accel_bvh::WideCollapse::Sah,
                v => rt_accel_bvh::WideCollapse::LargestAreaThenSah {
                    above: v.parse().map_err(|e| bad(&e))?,
                },
            }
        }
        _ => {
            return Err(bad(
                &"unknown key (isa, kernel, prefetch, leaf_block, max_leaf, traversal_cost, reinsertion, \
                   bins, spatial, budget, collapse)",
            ));
        }
    }
    Ok(())
}

/// A leaf kernel by name.
fn parse_kernel(name: &str) -> Result<rt_geom::TriangleKernel, String> {
    match name {
        "watertight" => Ok(rt_geom::TriangleKernel::Watertight),
        "moller-trumbore" => Ok(rt_geom::TriangleKernel::MollerTrumbore),
        _ => Err("kernel: watertight or moller-trumbore".into()),
    }
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: bvh8_bound MESH.obj RAYS.rays [--occluded] [--kernel K] [--base KEY=VALUE[,..]] [--against KEY=VALUE[,..]]";
    let [mesh, rays, rest @ ..] = &args[..] else {
        return Err(usage.into());
    };
    let (mut occluded, mut change, mut kernel, mut base) = (false, None, None, None);
    let mut rest = rest.iter();
    while let Some(arg) = rest.next() {
        match arg.as_str() {
            "--occluded" => occluded = true,
            "--against" => change = Some(rest.next().ok_or(usage)?.clone()),
            "--base" => base = Some(rest.next().ok_or(usage)?.clone()),
            "--kernel" => kernel = Some(parse_kernel(rest.next().ok_or(usage)?)?),
            _ => return Err(format!("unexpected argument {arg:?}; {usage}")),
        }
    }
    let tris = rt_geom::load_obj(mesh)
        .map_err(|e| e.to_string())?
        .triangles();
    let mut bvh = TriBvh8::build_for_tracing(&tris).map_err(|e| e.to_string())?;
    let mut built = rt_accel_bvh::BvhParams::fastest_trace();
    if let Some(kernel) = kernel {
        bvh = bvh.with_kernel(kernel);
    }
    if let Some(changes) = &base {
        (bvh, built) = variant((&bvh, built), &tris, changes)?;
    }
    let rays = read_rays(rays)?;
    println!(
        "{mesh}: {} triangles, {} rays{}, 1 thread, median of {ROUNDS}",
        tris.len(),
        rays.len(),
        if occluded { ", any hit" } else { "" }
    );
    if let Some(change) = change {
        let (other, _) = variant((&bvh, built), &tris, &change)?;
        let mut speed = if occluded {
            against::<true>(&bvh, &other, &rays)
        } else {
            against::<false>(&bvh, &other, &rays)
        };
        speed.sort_by(f64::total_cmp);
        let text: Vec<String> = speed.iter().map(|s| format!("{s:.3}")).collect();
        println!(
            "{change} against the default, whole query, speed ratio: median {:.3} ({})",
            speed[speed.len() / 2],
            text.join(" ")
        );
        return Ok(());
    }
    if occluded {
        race::<true>(&bvh, &rays)
    } else {
        race::<false>(&bvh, &rays)
    }
}
