//! Closest-hit and any-hit traversal, written once (`traverse::<ANY_HIT>`).

use crate::Bvh;
use crate::node::BvhNode;
use crate::params::MAX_DEPTH;
use rt_geom::aabb::SlabRay;
use rt_geom::{Hit, Primitive, Ray, keep_hit};

/// Entry distance into the node's box within `[tmin, tmax]` ([`SlabRay::entry`]).
#[inline(always)]
fn entry(boxes: &SlabRay, node: &BvhNode, tmin: f32, tmax: f32) -> Option<f32> {
    boxes.entry(&node.min, &node.max, tmin, tmax)
}

impl<P: Primitive> Bvh<P> {
    /// Depth-first traversal with an explicit stack, nearer child first (by entry distance);
    /// subtrees entered beyond the closest hit so far are skipped. With `ANY_HIT`, returns the
    /// first hit found.
    #[inline]
    pub(crate) fn traverse<const ANY_HIT: bool>(&self, ray: &Ray) -> Option<Hit> {
        if self.nodes.is_empty() || !ray.is_valid() {
            return None;
        }
        let boxes = SlabRay::new(ray);
        let mut r = *ray;
        entry(&boxes, &self.nodes[0], r.tmin, r.tmax)?;
        let mut best: Option<Hit> = None;
        // The build caps depth at MAX_DEPTH, so the far children pending never exceed it.
        let mut stack = [(0u32, 0.0f32); MAX_DEPTH + 1];
        let mut sp = 0;
        let mut index = 0usize;
        loop {
            let node = &self.nodes[index];
            if node.is_leaf() {
                let first = node.offset as usize;
                for i in first..first + node.count() as usize {
                    if let Some(h) = self.prims[i].intersect(&r) {
                        if keep_hit::<ANY_HIT>(h, self.ids[i], &mut r.tmax, &mut best) {
                            return best;
                        }
                    }
                }
            } else {
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
                    return best;
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
