//! How fast the SAH kd-tree's single rays could be if its traversal cost nothing: each ray's
//! walk is recorded once (the leaves it tests, in order, until its answer), then the leaf tests
//! alone are replayed and timed against the whole query (`Accel::intersect` / `occluded`),
//! one thread, median of 5 interleaved passes, on the mesh's standard primary, shadow and
//! diffuse rays. `whole / leaves` bounds what any faster walk of the same tree could gain.
//!
//! `cargo run --release -p rt-accel-kd --example kd_leaf_bound -- MESH.obj [SIDE]` (`SIDE`: the
//! camera's resolution, default 512; `sphere:N` for a tessellated sphere).

use rt_accel_kd::traverse::{Step, below_first, step};
use rt_accel_kd::{KdNode, KdParams, KdTree};
use rt_geom::{Accel, Hit, LeafPrims, Ray, Triangle, test_primitives};
use rt_testkit::RaySets;
use std::hint::black_box;
use std::time::Instant;

const ROUNDS: usize = 5;

/// The tree's leaf data for replaying leaf tests: the listed copies (as the tree lays them out)
/// and the primitives of one-primitive leaves.
struct Leaves<'a> {
    tree: &'a KdTree<Triangle>,
    listed: LeafPrims<Triangle>,
}

impl Leaves<'_> {
    /// Tests leaf `node`; true when `ANY_HIT` found a hit.
    fn test<const ANY_HIT: bool>(
        &self,
        node: &KdNode,
        r: &mut Ray,
        best: &mut Option<Hit>,
    ) -> bool {
        let indices = self.tree.indices();
        match node.list() {
            Some((first, count)) => self.listed.test::<ANY_HIT>(
                (first as usize, count as usize),
                indices,
                r,
                best,
                |_| false,
            ),
            None => test_primitives::<Triangle, ANY_HIT>(
                self.tree.prims(),
                node.leaf_prims(indices),
                r,
                best,
                |_| false,
            ),
        }
    }

    /// The walk of `ray` (front to back, the single-ray step rule), testing leaves as it goes:
    /// the leaves tested, in order, and the answer.
    fn record<const ANY_HIT: bool>(&self, ray: &Ray) -> (Vec<u32>, Option<Hit>) {
        let nodes = self.tree.nodes();
        let mut tested = Vec::new();
        let mut best = None;
        let Some((mut t0, mut t1)) = self.tree.bounds().clip_ray(ray) else {
            return (tested, best);
        };
        if nodes.is_empty() {
            return (tested, best);
        }
        let (o, inv) = (ray.origin().to_array(), ray.inv_dir().to_array());
        let dir = ray.dir().to_array();
        let mut r = *ray;
        let mut stack: Vec<(usize, f32, f32)> = Vec::new();
        let mut i = 0;
        loop {
            let node = &nodes[i];
            if !node.is_leaf() {
                let a = node.axis();
                let children = [i + 1, node.above()];
                let f = !below_first(dir[a]) as usize;
                let (first, second) = (children[f], children[f ^ 1]);
                match step(o[a], inv[a], node.split(), t0, t1) {
                    Step::First => i = first,
                    Step::Second => i = second,
                    Step::Both {
                        first_end,
                        second_start,
                    } => {
                        stack.push((second, second_start, t1));
                        (i, t1) = (first, first_end);
                    }
                }
                continue;
            }
            tested.push(i as u32);
            if self.test::<ANY_HIT>(node, &mut r, &mut best) {
                return (tested, best);
            }
            loop {
                let Some((n, a, b)) = stack.pop() else {
                    return (tested, best);
                };
                if best.is_none() || a <= r.tmax {
                    (i, t0, t1) = (n, a, b);
                    break;
                }
            }
        }
    }

    /// The recorded leaves of one ray tested again, in order, until the answer.
    fn replay<const ANY_HIT: bool>(&self, ray: &Ray, leaves: &[u32]) -> Option<Hit> {
        let nodes = self.tree.nodes();
        let mut r = *ray;
        let mut best = None;
        for &l in leaves {
            if self.test::<ANY_HIT>(&nodes[l as usize], &mut r, &mut best) {
                break;
            }
        }
        best
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Times the whole queries and the leaf replay of one ray set: both rates (Mrays/s), and the
/// leaves (empty ones too) and primitives tested per ray.
fn race<const ANY_HIT: bool>(
    leaves: &Leaves<'_>,
    rays: &[Ray],
) -> Result<(f64, f64, f64, f64), String> {
    let tree = leaves.tree;
    let mut recorded = Vec::with_capacity(rays.len());
    let (mut tests, mut prims) = (0usize, 0usize);
    for (k, ray) in rays.iter().enumerate() {
        let (tested, answer) = leaves.record::<ANY_HIT>(ray);
        // The recorded walk answers as the tree does (any hit: whether there is one).
        let same = if ANY_HIT {
            answer.is_some() == tree.occluded(ray)
        } else {
            answer == tree.intersect(ray)
        };
        if !same {
            return Err(format!(
                "ray {k}: the recorded walk disagrees with the tree"
            ));
        }
        tests += tested.len();
        prims += tested
            .iter()
            .map(|&l| tree.nodes()[l as usize].count())
            .sum::<usize>();
        recorded.push(tested);
    }
    let (mut whole, mut replay) = (Vec::new(), Vec::new());
    for _ in 0..ROUNDS {
        let t = Instant::now();
        for ray in rays {
            if ANY_HIT {
                black_box(tree.occluded(ray));
            } else {
                black_box(tree.intersect(ray));
            }
        }
        whole.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        for (ray, tested) in rays.iter().zip(&recorded) {
            black_box(leaves.replay::<ANY_HIT>(ray, tested));
        }
        replay.push(t.elapsed().as_secs_f64());
    }
    let rate = |s: f64| rays.len() as f64 / s / 1e6;
    let per_ray = |n: usize| n as f64 / rays.len().max(1) as f64;
    Ok((
        rate(median(whole)),
        rate(median(replay)),
        per_ray(tests),
        per_ray(prims),
    ))
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first() else {
        return Err("usage: kd_leaf_bound MESH.obj|sphere:N [SIDE]".into());
    };
    let side: usize = match args.get(1) {
        Some(s) => s
            .parse()
            .map_err(|_| format!("SIDE must be a number, not {s:?}"))?,
        None => 512,
    };
    if side == 0 {
        return Err("SIDE must be positive".into());
    }
    let tris = rt_testkit::scenes::mesh_or_sphere(path)?;
    let tree = KdTree::build(&tris, KdParams::sah()).map_err(|e| e.to_string())?;
    let lists = tree.nodes().iter().filter_map(|n| n.list());
    let listed = LeafPrims::new(tree.prims(), tree.indices(), lists);
    let leaves = Leaves {
        tree: &tree,
        listed,
    };
    let sets = RaySets::generate(path, &tris, &tree, side, side, 7);
    println!(
        "{path}: {} triangles, {side}x{side} camera, 1 thread, median of {ROUNDS}",
        tris.len()
    );
    println!("rays      whole Mrays/s  leaf tests alone  bound  leaves per ray  triangles per ray");
    for (name, rays, any) in [
        ("primary", &sets.primary, false),
        ("shadow", &sets.shadow, true),
        ("diffuse", &sets.diffuse, false),
    ] {
        let (whole, alone, per_ray, tris_per_ray) = if any {
            race::<true>(&leaves, rays)?
        } else {
            race::<false>(&leaves, rays)?
        };
        println!(
            "{name:<9} {whole:13.2}  {alone:16.2}  {:5.2}x  {per_ray:14.1}  {tris_per_ray:17.1}",
            alone / whole
        );
    }
    Ok(())
}
