//! Front-to-back traversal, iterative (explicit stack) and recursive, closest-hit and any-hit.
//!
//! Both walk the same rule, [`step`]: at a split plane the ray's interval `[t0, t1]` is cut at
//! the crossing distance. The crossing is computed in `f32`, so the cut is padded by the same
//! relative margin as the box test ([`rt_geom::aabb::PAD`]): the part before the plane ends a
//! little after it, the part after starts a little before it. A primitive hit on the plane, or
//! one whose `t` rounds across it, is then found in either cell. Rays parallel to the plane
//! visit only the side they lie on, rays lying *in* the plane visit both, and a ray starting on
//! the plane crosses it at `t = 0`. Pending cells are skipped once the closest hit lies before
//! their entry, which is the seeds' "stop when the hit lies inside the current cell".

use crate::KdTree;
use crate::params::MAX_DEPTH;
use rt_geom::aabb::PAD;
use rt_geom::{Hit, Primitive, Ray};

/// Which children of an inner node the ray visits, first = on the side of the origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Only the child the ray starts in (it does not reach the plane within `[t0, t1]`).
    First,
    /// Only the other child (the ray crosses the plane before `t0`).
    Second,
    /// Both: the first over `[t0, first_end]`, then the second over `[second_start, t1]`.
    Both { first_end: f32, second_start: f32 },
}

/// True when the child below the plane is the first one the ray visits: the origin is below
/// the plane, or on it with the ray heading up (it crosses at `t = 0`, coming from below).
#[inline(always)]
pub fn below_first(origin: f32, dir: f32, split: f32) -> bool {
    (origin < split) | ((origin == split) & (dir > 0.0))
}

/// The step at a plane for one axis of a ray over `[t0, t1]`.
///
/// The crossing `ts` is behind the origin (`ts < 0`: first only), beyond `t1` (which covers a
/// ray parallel to the plane, `ts = inf`: first only), before `t0` (second only), or inside:
/// both. A ray lying in the plane gives `ts = NaN`, which fails every comparison and lands in
/// the last case, where `min`/`max` ignore the NaN: both children over the whole interval.
#[inline(always)]
pub fn step(origin: f32, inv_dir: f32, split: f32, t0: f32, t1: f32) -> Step {
    let ts = (split - origin) * inv_dir;
    if ts < 0.0 {
        return Step::First;
    }
    // ts >= 0 (or NaN) here: the padding of `pad_down`/`pad_up` as one product each, which
    // keeps ts = inf infinite.
    let lo = ts * (1.0 - PAD);
    let hi = ts * (1.0 + PAD);
    if lo > t1 {
        Step::First
    } else if hi < t0 {
        Step::Second
    } else {
        Step::Both {
            first_end: hi.min(t1),
            second_start: lo.max(t0),
        }
    }
}

/// The per-ray constants of the walk.
struct Walk {
    // Arrays, not `Vec3`: indexing by the node's axis is then a load, not a branch.
    origin: [f32; 3],
    dir: [f32; 3],
    inv: [f32; 3],
}

impl Walk {
    fn new(ray: &Ray) -> Self {
        Self {
            origin: ray.origin().to_array(),
            dir: ray.dir().to_array(),
            inv: ray.inv_dir().to_array(),
        }
    }

    /// `(first, second, step)` at inner node `i`.
    #[inline(always)]
    fn at(&self, tree_nodes: &[crate::KdNode], i: usize, t0: f32, t1: f32) -> (usize, usize, Step) {
        let node = &tree_nodes[i];
        let a = node.axis();
        let split = node.split();
        // Selected by index, not by a branch the ray's direction makes unpredictable.
        let children = [i + 1, node.above()];
        let f = !below_first(self.origin[a], self.dir[a], split) as usize;
        let (first, second) = (children[f], children[f ^ 1]);
        (
            first,
            second,
            step(self.origin[a], self.inv[a], split, t0, t1),
        )
    }
}

impl<P: Primitive> KdTree<P> {
    /// Tests a leaf's primitives against `r`, shrinking `r.tmax` to the closest hit. Returns
    /// true when `ANY_HIT` and something was hit.
    #[inline(always)]
    fn test_leaf<const ANY_HIT: bool>(
        &self,
        i: usize,
        r: &mut Ray,
        best: &mut Option<Hit>,
    ) -> bool {
        for &p in self.nodes[i].leaf_prims(&self.indices) {
            if let Some(h) = self.prims[p as usize].intersect(r) {
                *best = Some(Hit::new(h, p));
                if ANY_HIT {
                    return true;
                }
                r.tmax = h.t;
            }
        }
        false
    }

    /// Iterative front-to-back traversal with an explicit stack of pending far cells.
    pub(crate) fn traverse_iterative<const ANY_HIT: bool>(&self, ray: &Ray) -> Option<Hit> {
        if self.nodes.is_empty() || !ray.is_valid() {
            return None;
        }
        let (mut t0, mut t1) = self.bounds.clip_ray(ray)?;
        let walk = Walk::new(ray);
        let mut r = *ray;
        let mut best = None;
        // One pending cell per level at most: the depth cap bounds the stack.
        let mut stack = [(0u32, 0.0f32, 0.0f32); MAX_DEPTH as usize + 1];
        let mut sp = 0;
        let mut i = 0usize;
        loop {
            if !self.nodes[i].is_leaf() {
                let (first, second, step) = walk.at(&self.nodes, i, t0, t1);
                match step {
                    Step::First => i = first,
                    Step::Second => i = second,
                    Step::Both {
                        first_end,
                        second_start,
                    } => {
                        stack[sp] = (second as u32, second_start, t1);
                        sp += 1;
                        i = first;
                        t1 = first_end;
                    }
                }
                continue;
            }
            if self.test_leaf::<ANY_HIT>(i, &mut r, &mut best) {
                return best;
            }
            // The next pending cell that starts before the closest hit.
            loop {
                if sp == 0 {
                    return best;
                }
                sp -= 1;
                let (n, a, b) = stack[sp];
                if best.is_none() || a <= r.tmax {
                    (i, t0, t1) = (n as usize, a, b);
                    break;
                }
            }
        }
    }

    /// The seeds' recursive traversal: the near child, then, unless a hit already lies
    /// before the far child, the far child.
    pub(crate) fn traverse_recursive<const ANY_HIT: bool>(&self, ray: &Ray) -> Option<Hit> {
        if self.nodes.is_empty() || !ray.is_valid() {
            return None;
        }
        let (t0, t1) = self.bounds.clip_ray(ray)?;
        let walk = Walk::new(ray);
        let mut r = *ray;
        let mut best = None;
        self.recurse::<ANY_HIT>(&walk, 0, t0, t1, &mut r, &mut best);
        best
    }

    /// Returns true when the search is over (any-hit found).
    fn recurse<const ANY_HIT: bool>(
        &self,
        walk: &Walk,
        i: usize,
        t0: f32,
        t1: f32,
        r: &mut Ray,
        best: &mut Option<Hit>,
    ) -> bool {
        if self.nodes[i].is_leaf() {
            return self.test_leaf::<ANY_HIT>(i, r, best);
        }
        let (first, second, step) = walk.at(&self.nodes, i, t0, t1);
        match step {
            Step::First => self.recurse::<ANY_HIT>(walk, first, t0, t1, r, best),
            Step::Second => self.recurse::<ANY_HIT>(walk, second, t0, t1, r, best),
            Step::Both {
                first_end,
                second_start,
            } => {
                if self.recurse::<ANY_HIT>(walk, first, t0, first_end, r, best) {
                    return true;
                }
                if best.is_some() && second_start > r.tmax {
                    return false;
                }
                self.recurse::<ANY_HIT>(walk, second, second_start, t1, r, best)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_at_a_plane() {
        // Crossing ahead, inside the interval.
        let Step::Both {
            first_end,
            second_start,
        } = step(0.0, 1.0, 2.0, 0.0, 10.0)
        else {
            panic!()
        };
        assert!(first_end >= 2.0 && second_start <= 2.0);
        assert!(first_end - 2.0 < 1e-5 && 2.0 - second_start < 1e-5);
        // Crossing after the interval, before it, behind the origin.
        assert_eq!(step(0.0, 1.0, 20.0, 0.0, 10.0), Step::First);
        assert_eq!(step(0.0, 1.0, 2.0, 5.0, 10.0), Step::Second);
        assert_eq!(step(0.0, -1.0, 2.0, 0.0, 10.0), Step::First);
        // Parallel (1/0 = inf), on either side, with either zero sign.
        assert_eq!(step(0.0, f32::INFINITY, 2.0, 0.0, 10.0), Step::First);
        assert_eq!(step(0.0, f32::NEG_INFINITY, 2.0, 0.0, 10.0), Step::First);
        assert_eq!(step(3.0, f32::INFINITY, 2.0, 0.0, 10.0), Step::First);
        // In the plane: both sides, whole interval.
        assert_eq!(
            step(2.0, f32::INFINITY, 2.0, 0.0, 10.0),
            Step::Both {
                first_end: 10.0,
                second_start: 0.0
            }
        );
        // Starting on the plane: crosses at 0.
        assert_eq!(
            step(2.0, 1.0, 2.0, 0.0, 10.0),
            Step::Both {
                first_end: 0.0,
                second_start: 0.0
            }
        );
        assert_eq!(step(2.0, 1.0, 2.0, 0.5, 10.0), Step::Second);
        assert!(below_first(2.0, 1.0, 2.0) && !below_first(2.0, -1.0, 2.0));
        assert!(below_first(1.0, -1.0, 2.0) && !below_first(3.0, 1.0, 2.0));
    }
}
