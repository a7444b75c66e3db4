//! Closest-hit and any-hit traversal, written once (`walk_ray::<ANY_HIT>`) over any leaf test: the
//! primitives of [`Bvh`], or the instances of the top level of an
//! [`InstanceBvh`](crate::InstanceBvh).

use crate::Bvh;
use crate::node::BvhNode;
use crate::params::MAX_DEPTH;
use crate::wide::test_leaf;
use rt_geom::aabb::SlabRay;
use rt_geom::{Hit, Keep, Primitive, Ray};

/// Entry distance into the node's box within `[tmin, tmax]` ([`SlabRay::entry`]).
#[inline(always)]
fn entry(boxes: &SlabRay, node: &BvhNode, tmin: f32, tmax: f32) -> Option<f32> {
    boxes.entry(&node.min, &node.max, tmin, tmax)
}

impl<P> Bvh<P> {
    /// Depth-first traversal with an explicit stack, nearer child first (by entry distance);
    /// subtrees entered beyond the closest hit so far are skipped. `leaf(first, count, ray,
    /// best)` tests the leaf-ordered slots `first..first + count`, offering its hits to `best`
    /// ([`Keep`]), which shrinks `ray.tmax` to a kept one; it returns true to stop (any-hit
    /// queries). Returns the hit `best` kept.
    #[inline(always)]
    pub(crate) fn walk_ray<const ANY_HIT: bool, K: Keep>(
        &self,
        ray: &Ray,
        best: impl FnOnce() -> K,
        mut leaf: impl FnMut(u32, u32, &mut Ray, &mut K) -> bool,
    ) -> Option<Hit> {
        if self.nodes.is_empty() || !ray.is_valid() {
            return None;
        }
        let mut best = best();
        let boxes = SlabRay::new(ray);
        let mut r = *ray;
        rt_geom::counters::nodes(1);
        entry(&boxes, &self.nodes[0], r.tmin, r.tmax)?;
        // The build caps depth at MAX_DEPTH, so the far children pending never exceed it.
        let mut stack = [(0u32, 0.0f32); MAX_DEPTH + 1];
        let mut sp = 0;
        let mut index = 0usize;
        loop {
            let node = &self.nodes[index];
            if node.is_leaf() {
                if leaf(node.offset, node.count(), &mut r, &mut best) {
                    return best.best();
                }
            } else {
                rt_geom::counters::nodes(2);
                let (a, b) = (index + 1, node.offset as usize);
                let ta = entry(&boxes, &self.nodes[a], r.tmin, r.tmax);
                let tb = entry(&boxes, &self.nodes[b], r.tmin, r.tmax);
                match (ta, tb) {
                    (Some(ta), Some(tb)) => {
                        let (near, far, tfar) = if ta <= tb { (a, b, tb) } else { (b, a, ta) };
                        stack[sp] = (far as u32, tfar);
                        sp += 1;
                        index = near;
                        continue;
                    }
                    (Some(_), None) => {
                        index = a;
                        continue;
                    }
                    (None, Some(_)) => {
                        index = b;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next pending subtree; it may have been passed by the closest hit.
            loop {
                if sp == 0 {
                    return best.best();
                }
                sp -= 1;
                let (next, entry) = stack[sp];
                if entry <= r.tmax {
                    index = next as usize;
                    break;
                }
            }
        }
    }
}

impl<P: Primitive> Bvh<P> {
    /// The walk over the tree's own primitives. With `ANY_HIT`, returns the first hit found.
    #[inline(always)]
    pub(crate) fn traverse<const ANY_HIT: bool, K: Keep>(
        &self,
        ray: &Ray,
        best: impl FnOnce() -> K,
    ) -> Option<Hit> {
        self.walk_ray::<ANY_HIT, K>(
            ray,
            best,
            #[inline(always)]
            |first, count, r, best| {
                test_leaf::<P, _, ANY_HIT>(&self.prims, &self.ids, first, count, r, best)
            },
        )
    }
}
