//! obvhs behind the `Accel` trait: the reference that `verify` checks against, and a peer that
//! `bench` measures beside.
//!
//! - [`ObvhsBvh2`]: obvhs's binary BVH with rt's own watertight kernel in its leaves, the
//!   correctness reference (its traversal honours `tmin`/`tmax`): a disagreement can only come
//!   from obvhs's tree and box tests, never from a different triangle test.
//! - [`ObvhsCwBvh`]: obvhs's compressed 8-wide BVH with its own triangle test (Möller and
//!   Trumbore, triangles stored in the tree's order), the way its users run it: the speed
//!   peer. Its traversal drops hits closer than t = 1e-4, and its triangle test is not
//!   watertight, so `verify` compares it with a tolerance.
//! - [`ObvhsCwBvhRtKernel`]: the same tree with rt's kernel, for `verify`.

use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray as ORay, RayHit};
use rt_geom::{Accel, AccelStats, BuildError, Hit, Ray, Triangle, check_primitives};
use std::time::Duration;

/// The preset both adapters build with: obvhs's highest quality.
pub fn params() -> obvhs::BvhBuildParams {
    obvhs::BvhBuildParams::very_slow_build()
}

fn to_obvhs(tris: &[Triangle]) -> Vec<obvhs::triangle::Triangle> {
    tris.iter()
        .map(|t| obvhs::triangle::Triangle {
            v0: t.v[0].into(),
            v1: t.v[1].into(),
            v2: t.v[2].into(),
        })
        .collect()
}

/// The ray obvhs traverses with, and the scale between its `t` and rt's.
///
/// obvhs expects unit directions (its reciprocal clamps components below `f32::EPSILON`), so the
/// direction is normalised and `t` scaled by its length. obvhs accepts only `t < tmax` and does
/// not pad its box test, so every `tmax` it sees is larger than rt's by [`SLACK`]; rt's kernel
/// applies the exact closed interval, so the answers are unchanged and only the culling slack
/// grows.
fn obvhs_ray(ray: &Ray) -> (ORay, f32) {
    let scale = ray.dir().length();
    let tmax = slack(ray.tmax * scale);
    let oray = ORay::new(
        ray.origin().into(),
        (ray.dir() / scale).into(),
        ray.tmin * scale,
        tmax,
    );
    (oray, scale)
}

/// Relative culling slack: covers the rounding of a triangle's `t` on thin slivers (several
/// ulps) against obvhs's unpadded box entry.
const SLACK: f32 = 1e-5;

#[inline]
fn slack(t: f32) -> f32 {
    if t > 0.0 {
        t * (1.0 + SLACK)
    } else {
        t * (1.0 - SLACK)
    }
}

/// Closest hit among the primitives obvhs hands to `visit`; `visit` returns obvhs's `t`.
struct Closest<'a> {
    tris: &'a [Triangle],
    ray: Ray,
    scale: f32,
    best: Option<Hit>,
}

impl Closest<'_> {
    #[inline]
    fn visit(&mut self, oray: &ORay, prim: u32) -> f32 {
        let tmax = self.ray.tmax.min(slack(oray.tmax / self.scale));
        let r = self.ray.with_range(self.ray.tmin, tmax);
        match self.tris[prim as usize].intersect_watertight(&r) {
            Some(h) => {
                if self.best.is_none_or(|b| h.t < b.t) {
                    self.best = Some(Hit::new(h, prim));
                }
                slack(h.t * self.scale)
            }
            None => f32::INFINITY,
        }
    }

    fn hit(&self) -> Option<Hit> {
        self.best
    }
}

/// Shadow-ray visitor: any hit in rt's exact interval stops the traversal.
#[inline]
fn any_hit(tris: &[Triangle], ray: &Ray, prim: u32) -> f32 {
    match tris[prim as usize].intersect_watertight(ray) {
        Some(_) => f32::NEG_INFINITY,
        None => f32::INFINITY,
    }
}

/// What the adapter needs from an obvhs tree; [`Bvh2`] and [`CwBvh`] implement it.
pub trait ObvhsTree: Send + Sync + Sized {
    fn build(tris: &[obvhs::triangle::Triangle]) -> Self;
    /// Maps obvhs's primitive slots to the caller's triangle indices.
    fn indices(&self) -> &[u32];
    fn closest(&self, ray: ORay, hit: &mut RayHit, f: impl FnMut(&ORay, usize) -> f32) -> bool;
    /// True when nothing is hit.
    fn missed(&self, ray: ORay, f: impl FnMut(&ORay, usize) -> f32) -> bool;
    /// Nodes, leaves, references, depth, node bytes, SAH (primitives and triangle bytes are
    /// the adapter's).
    fn tree_stats(&self) -> AccelStats;
    /// Tree invariants, besides every primitive being referenced (checked by the adapter).
    fn check(&self) -> Result<(), String>;
}

/// An obvhs tree over triangles, traversed with rt's kernel, or with obvhs's own
/// (`OWN_KERNEL`).
pub struct Obvhs<T, const OWN_KERNEL: bool = false> {
    bvh: Option<T>,
    tris: Vec<Triangle>,
    /// obvhs's triangles in the tree's primitive order (empty unless `OWN_KERNEL`).
    slots: Vec<obvhs::triangle::Triangle>,
}

/// obvhs's `Bvh2` built with [`params`]: the correctness reference.
pub type ObvhsBvh2 = Obvhs<Bvh2>;
/// obvhs's compressed wide `CwBvh` built with [`params`], with its own triangle test: the
/// speed peer.
pub type ObvhsCwBvh = Obvhs<CwBvh, true>;
/// [`ObvhsCwBvh`]'s tree with rt's kernel in its leaves.
pub type ObvhsCwBvhRtKernel = Obvhs<CwBvh>;

impl<T: ObvhsTree, const OWN_KERNEL: bool> Obvhs<T, OWN_KERNEL> {
    pub fn build(tris: &[Triangle]) -> Result<Self, BuildError> {
        check_primitives(tris, u32::MAX as usize - 1)?;
        let otris = to_obvhs(tris);
        let bvh = (!tris.is_empty()).then(|| T::build(&otris));
        let slots = match (&bvh, OWN_KERNEL) {
            (Some(b), true) => b.indices().iter().map(|&i| otris[i as usize]).collect(),
            _ => Vec::new(),
        };
        Ok(Self {
            bvh,
            tris: tris.to_vec(),
            slots,
        })
    }

    /// The closest hit by obvhs's own triangle test, its barycentrics computed for the hit
    /// only, as obvhs's examples do.
    fn intersect_own(&self, bvh: &T, ray: &Ray) -> Option<Hit> {
        let (oray, scale) = obvhs_ray(ray);
        let mut hit = RayHit::none();
        if !bvh.closest(oray, &mut hit, |r, slot| self.slots[slot].intersect(r)) {
            return None;
        }
        let slot = hit.primitive_id as usize;
        let uv = self.slots[slot].compute_barycentric(&oray);
        Some(Hit {
            t: hit.t / scale,
            u: uv.x,
            v: uv.y,
            prim: bvh.indices()[slot],
        })
    }
}

impl<T: ObvhsTree, const OWN_KERNEL: bool> Accel for Obvhs<T, OWN_KERNEL> {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let bvh = self.bvh.as_ref().filter(|_| ray.is_valid())?;
        if OWN_KERNEL {
            return self.intersect_own(bvh, ray);
        }
        let (oray, scale) = obvhs_ray(ray);
        let mut c = Closest {
            tris: &self.tris,
            ray: *ray,
            scale,
            best: None,
        };
        let indices = bvh.indices();
        bvh.closest(oray, &mut RayHit::none(), |r, id| c.visit(r, indices[id]));
        c.hit()
    }

    fn occluded(&self, ray: &Ray) -> bool {
        let Some(bvh) = self.bvh.as_ref().filter(|_| ray.is_valid()) else {
            return false;
        };
        let indices = bvh.indices();
        if OWN_KERNEL {
            return !bvh.missed(obvhs_ray(ray).0, |r, slot| self.slots[slot].intersect(r));
        }
        !bvh.missed(obvhs_ray(ray).0, |_, id| {
            any_hit(&self.tris, ray, indices[id])
        })
    }

    fn stats(&self) -> AccelStats {
        let Some(bvh) = &self.bvh else {
            return AccelStats::default();
        };
        let mut s = bvh.tree_stats();
        s.primitives = self.tris.len();
        s.bytes += std::mem::size_of_val(bvh.indices())
            + if OWN_KERNEL {
                std::mem::size_of_val(self.slots.as_slice())
            } else {
                std::mem::size_of_val(self.tris.as_slice())
            };
        s
    }

    fn validate(&self) -> Result<(), String> {
        let Some(bvh) = &self.bvh else {
            return if self.tris.is_empty() {
                Ok(())
            } else {
                Err("no tree for a non-empty scene".into())
            };
        };
        bvh.check()?;
        let mut seen = vec![false; self.tris.len()];
        for &p in bvh.indices() {
            *seen
                .get_mut(p as usize)
                .ok_or_else(|| format!("primitive index {p} out of range"))? = true;
        }
        rt_geom::all_referenced(&seen)
    }
}

impl ObvhsTree for Bvh2 {
    fn build(tris: &[obvhs::triangle::Triangle]) -> Self {
        obvhs::bvh2::builder::build_bvh2_from_tris(tris, params(), &mut Duration::default())
    }

    fn indices(&self) -> &[u32] {
        &self.primitive_indices
    }

    fn closest(&self, ray: ORay, hit: &mut RayHit, f: impl FnMut(&ORay, usize) -> f32) -> bool {
        self.ray_traverse(ray, hit, f)
    }

    fn missed(&self, ray: ORay, f: impl FnMut(&ORay, usize) -> f32) -> bool {
        self.ray_traverse_miss(ray, f)
    }

    fn tree_stats(&self) -> AccelStats {
        let root_area = self.nodes[0].aabb().half_area().max(f32::MIN_POSITIVE);
        let (mut leaves, mut refs, mut depth, mut sah) = (0, 0, 0, 0.0f32);
        walk_bvh2(self, |node, d| {
            depth = depth.max(d);
            let area = node.aabb().half_area() / root_area;
            if node.is_leaf() {
                leaves += 1;
                refs += node.prim_count as usize;
                sah += area * node.prim_count as f32;
            } else {
                sah += area;
            }
        });
        AccelStats {
            nodes: self.nodes.len(),
            leaves,
            references: refs,
            max_depth: depth,
            bytes: std::mem::size_of_val(self.nodes.as_slice()),
            sah_cost: Some(sah),
            ..AccelStats::default()
        }
    }

    fn check(&self) -> Result<(), String> {
        let mut err = None;
        walk_bvh2(self, |node, _| {
            if node.is_leaf() {
                let end = node.first_index as usize + node.prim_count as usize;
                if end > self.primitive_indices.len() {
                    err = Some("leaf points past the primitive indices".to_string());
                }
            } else {
                let b = node.aabb();
                for child in [node.first_index, node.first_index + 1] {
                    let c = self.nodes[child as usize].aabb();
                    if !(b.min.cmple(c.min).all() && b.max.cmpge(c.max).all()) {
                        err = Some(format!("node {child} pokes out of its parent"));
                    }
                }
            }
        });
        err.map_or(Ok(()), Err)
    }
}

impl ObvhsTree for CwBvh {
    fn build(tris: &[obvhs::triangle::Triangle]) -> Self {
        obvhs::cwbvh::builder::build_cwbvh_from_tris(tris, params(), &mut Duration::default())
    }

    fn indices(&self) -> &[u32] {
        &self.primitive_indices
    }

    fn closest(&self, ray: ORay, hit: &mut RayHit, f: impl FnMut(&ORay, usize) -> f32) -> bool {
        self.ray_traverse(ray, hit, f)
    }

    fn missed(&self, ray: ORay, f: impl FnMut(&ORay, usize) -> f32) -> bool {
        self.ray_traverse_miss(ray, f)
    }

    fn tree_stats(&self) -> AccelStats {
        let (mut leaves, mut depth) = (0, 0);
        let mut stack = vec![(0u32, 0usize)];
        while let Some((i, d)) = stack.pop() {
            depth = depth.max(d);
            let node = &self.nodes[i as usize];
            for child in 0..8 {
                if node.is_child_empty(child) {
                    continue;
                }
                if node.is_leaf(child) {
                    leaves += 1;
                } else {
                    stack.push((node.child_node_index(child), d + 1));
                }
            }
        }
        AccelStats {
            nodes: self.nodes.len() + leaves,
            leaves,
            references: self.primitive_indices.len(),
            max_depth: depth + 1,
            bytes: std::mem::size_of_val(self.nodes.as_slice()),
            ..AccelStats::default()
        }
    }

    fn check(&self) -> Result<(), String> {
        for (i, node) in self.nodes.iter().enumerate() {
            for child in (0..8).filter(|&c| !node.is_child_empty(c)) {
                if node.is_leaf(child) {
                    let (first, count) = node.child_primitives(child);
                    if (first + count) as usize > self.primitive_indices.len() {
                        return Err(format!("node {i} child {child} points past the indices"));
                    }
                } else if node.child_node_index(child) as usize >= self.nodes.len() {
                    return Err(format!("node {i} child {child} points past the nodes"));
                }
            }
        }
        Ok(())
    }
}

fn walk_bvh2(bvh: &Bvh2, mut f: impl FnMut(&obvhs::bvh2::node::Bvh2Node, usize)) {
    let mut stack = vec![(0u32, 0usize)];
    while let Some((i, d)) = stack.pop() {
        let node = &bvh.nodes[i as usize];
        f(node, d);
        if !node.is_leaf() {
            stack.push((node.first_index, d + 1));
            stack.push((node.first_index + 1, d + 1));
        }
    }
}
