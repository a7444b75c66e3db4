//! obvhs behind the `Accel` trait: the reference that `verify` and `bench` measure beside.
//!
//! Both adapters run rt's own watertight kernel inside obvhs's traversal, so a disagreement can
//! only come from obvhs's trees and box tests, never from a different triangle test.
//! - [`ObvhsBvh2`]: obvhs's binary BVH, the correctness reference (its traversal honours
//!   `tmin`/`tmax`).
//! - [`ObvhsCwBvh`]: obvhs's compressed 8-wide BVH, a speed reference only: its traversal drops
//!   hits closer than t = 1e-4, so `verify` compares it with that tolerance.

use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray as ORay, RayHit};
use rt_geom::{Accel, AccelStats, BuildError, Hit, PrimHit, Ray, Triangle, check_primitives};
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
    best: Option<(PrimHit, u32)>,
}

impl Closest<'_> {
    #[inline]
    fn visit(&mut self, oray: &ORay, prim: u32) -> f32 {
        let tmax = self.ray.tmax.min(slack(oray.tmax / self.scale));
        let r = self.ray.with_range(self.ray.tmin, tmax);
        match self.tris[prim as usize].intersect_watertight(&r) {
            Some(h) => {
                if self.best.is_none_or(|(b, _)| h.t < b.t) {
                    self.best = Some((h, prim));
                }
                slack(h.t * self.scale)
            }
            None => f32::INFINITY,
        }
    }

    fn hit(&self) -> Option<Hit> {
        self.best.map(|(h, p)| Hit::new(h, p))
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

/// obvhs's `Bvh2` built with [`params`].
pub struct ObvhsBvh2 {
    bvh: Option<Bvh2>,
    tris: Vec<Triangle>,
}

impl ObvhsBvh2 {
    pub fn build(tris: &[Triangle]) -> Result<Self, BuildError> {
        check_primitives(tris, u32::MAX as usize - 1)?;
        let bvh = (!tris.is_empty()).then(|| {
            obvhs::bvh2::builder::build_bvh2_from_tris(
                &to_obvhs(tris),
                params(),
                &mut Duration::default(),
            )
        });
        Ok(Self {
            bvh,
            tris: tris.to_vec(),
        })
    }
}

impl Accel for ObvhsBvh2 {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let bvh = self.bvh.as_ref().filter(|_| ray.is_valid())?;
        let (oray, scale) = obvhs_ray(ray);
        let mut c = Closest {
            tris: &self.tris,
            ray: *ray,
            scale,
            best: None,
        };
        let mut hit = RayHit::none();
        bvh.ray_traverse(oray, &mut hit, |r, id| {
            c.visit(r, bvh.primitive_indices[id])
        });
        c.hit()
    }

    fn occluded(&self, ray: &Ray) -> bool {
        let Some(bvh) = self.bvh.as_ref().filter(|_| ray.is_valid()) else {
            return false;
        };
        !bvh.ray_traverse_miss(obvhs_ray(ray).0, |_, id| {
            any_hit(&self.tris, ray, bvh.primitive_indices[id])
        })
    }

    fn stats(&self) -> AccelStats {
        let Some(bvh) = &self.bvh else {
            return empty_stats();
        };
        let root_area = bvh.nodes[0].aabb().half_area().max(f32::MIN_POSITIVE);
        let (mut leaves, mut refs, mut depth, mut sah) = (0, 0, 0, 0.0f32);
        walk_bvh2(bvh, |node, d| {
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
            primitives: self.tris.len(),
            nodes: bvh.nodes.len(),
            leaves,
            references: refs,
            max_depth: depth,
            bytes: std::mem::size_of_val(bvh.nodes.as_slice())
                + std::mem::size_of_val(bvh.primitive_indices.as_slice())
                + std::mem::size_of_val(self.tris.as_slice()),
            sah_cost: Some(sah),
        }
    }

    fn validate(&self) -> Result<(), String> {
        let Some(bvh) = &self.bvh else {
            return if self.tris.is_empty() {
                Ok(())
            } else {
                Err("no tree for a non-empty scene".into())
            };
        };
        let mut seen = vec![false; self.tris.len()];
        let mut err = None;
        walk_bvh2(bvh, |node, _| {
            if node.is_leaf() {
                let first = node.first_index as usize;
                for &p in &bvh.primitive_indices[first..first + node.prim_count as usize] {
                    match seen.get_mut(p as usize) {
                        Some(s) => *s = true,
                        None => err = Some(format!("primitive index {p} out of range")),
                    }
                }
            } else {
                let b = node.aabb();
                for child in [node.first_index, node.first_index + 1] {
                    let c = bvh.nodes[child as usize].aabb();
                    if !(b.min.cmple(c.min).all() && b.max.cmpge(c.max).all()) {
                        err = Some(format!("node {child} pokes out of its parent"));
                    }
                }
            }
        });
        if let Some(e) = err {
            return Err(e);
        }
        match seen.iter().position(|s| !s) {
            Some(p) => Err(format!("primitive {p} is in no leaf")),
            None => Ok(()),
        }
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

fn empty_stats() -> AccelStats {
    AccelStats {
        leaves: 0,
        nodes: 0,
        ..AccelStats::default()
    }
}

/// obvhs's compressed wide `CwBvh` built with [`params`] (speed reference).
pub struct ObvhsCwBvh {
    bvh: Option<CwBvh>,
    tris: Vec<Triangle>,
}

impl ObvhsCwBvh {
    pub fn build(tris: &[Triangle]) -> Result<Self, BuildError> {
        check_primitives(tris, u32::MAX as usize - 1)?;
        let bvh = (!tris.is_empty()).then(|| {
            obvhs::cwbvh::builder::build_cwbvh_from_tris(
                &to_obvhs(tris),
                params(),
                &mut Duration::default(),
            )
        });
        Ok(Self {
            bvh,
            tris: tris.to_vec(),
        })
    }
}

impl Accel for ObvhsCwBvh {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let bvh = self.bvh.as_ref().filter(|_| ray.is_valid())?;
        let (oray, scale) = obvhs_ray(ray);
        let mut c = Closest {
            tris: &self.tris,
            ray: *ray,
            scale,
            best: None,
        };
        let mut hit = RayHit::none();
        bvh.ray_traverse(oray, &mut hit, |r, id| {
            c.visit(r, bvh.primitive_indices[id])
        });
        c.hit()
    }

    fn occluded(&self, ray: &Ray) -> bool {
        let Some(bvh) = self.bvh.as_ref().filter(|_| ray.is_valid()) else {
            return false;
        };
        !bvh.ray_traverse_miss(obvhs_ray(ray).0, |_, id| {
            any_hit(&self.tris, ray, bvh.primitive_indices[id])
        })
    }

    fn stats(&self) -> AccelStats {
        let Some(bvh) = &self.bvh else {
            return empty_stats();
        };
        let (mut leaves, mut depth) = (0, 0);
        let mut stack = vec![(0u32, 0usize)];
        while let Some((i, d)) = stack.pop() {
            depth = depth.max(d);
            let node = &bvh.nodes[i as usize];
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
            primitives: self.tris.len(),
            nodes: bvh.nodes.len() + leaves,
            leaves,
            references: bvh.primitive_indices.len(),
            max_depth: depth + 1,
            bytes: std::mem::size_of_val(bvh.nodes.as_slice())
                + std::mem::size_of_val(bvh.primitive_indices.as_slice())
                + std::mem::size_of_val(self.tris.as_slice()),
            sah_cost: None,
        }
    }

    fn validate(&self) -> Result<(), String> {
        let Some(bvh) = &self.bvh else {
            return Ok(());
        };
        let mut seen = vec![false; self.tris.len()];
        for &p in &bvh.primitive_indices {
            *seen
                .get_mut(p as usize)
                .ok_or_else(|| format!("primitive index {p} out of range"))? = true;
        }
        match seen.iter().position(|s| !s) {
            Some(p) => Err(format!("primitive {p} is in no leaf")),
            None => Ok(()),
        }
    }
}
