//! Front-to-back traversal, iterative (explicit stack) and recursive, closest-hit and any-hit.
//!
//! Both walk the same rule, [`step`]: at a split plane the ray's interval `[t0, t1]` is cut at
//! the crossing distance. The crossing is computed in `f32`, so the cut is padded by the same
//! relative margin as the box test ([`rt_geom::aabb::PAD`]): the part before the plane ends a
//! little after it, the part after starts a little before it. A primitive hit on the plane, or
//! one whose `t` rounds across it, is then found in either cell. Rays parallel to the plane
//! visit only the side they lie on, rays lying *in* the plane visit both, and a ray starting on
//! the plane crosses it at `t = 0`. Pending cells are skipped once the closest hit lies before
//! their entry, which is the classic "stop when the hit lies inside the current cell".

use crate::bsp::PlaneRay;
use crate::params::{KdTraversal, MAX_DEPTH};
use crate::{KdNode, KdTree};
use rt_geom::aabb::{PAD, SlabRay};
use rt_geom::{Aabb, BaseLevel, Hit, Keep, LeafPrims, Level, Primitive, Ray, test_primitives};

/// Which children of an inner node the ray visits, first = on the side of the origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Only the child the ray starts in (it does not reach the plane within `[t0, t1]`).
    First,
    /// Only the other child (the ray crosses the plane before `t0`).
    Second,
    /// Both: the first over `[t0, first_end]`, then the second over `[second_start, t1]`.
    Both {
        /// Where the ray leaves the first child.
        first_end: f32,
        /// Where it enters the second.
        second_start: f32,
    },
}

/// True when the child below the plane is the first one the ray visits: the one it is in
/// before it crosses the plane, below for a ray heading up (a direction of `+0` counts as up,
/// `-0` as down, as the sign of `1 / dir`). The ray's interval may start behind its origin
/// (`tmin < 0`), so the order follows the direction, not the side the origin lies on.
#[inline(always)]
pub fn below_first(dir: f32) -> bool {
    !dir.is_sign_negative()
}

/// The padded crossing `[lo, hi]` around `ts`, for either sign: the same two products as the
/// box test's padding (`ts (1 -+ PAD)`), which keep `ts = +-inf` infinite; NaN stays NaN.
#[inline(always)]
pub fn padded_crossing(ts: f32) -> (f32, f32) {
    let (a, b) = (ts * (1.0 - PAD), ts * (1.0 + PAD));
    (a.min(b), a.max(b))
}

/// The step at a plane for one axis of a ray over `[t0, t1]`, first and second child as
/// [`below_first`] orders them.
///
/// The padded crossing (see [`padded_crossing`]) lies beyond `t1` (which covers a ray
/// parallel to the plane on the first side, `ts = +inf`: first only), before `t0` (a crossing
/// behind the interval, or a parallel ray on the second side, `ts = -inf`: second only), or
/// inside: both. A ray lying in the plane gives `ts = NaN`, which fails every comparison and
/// lands in the last case, where `min`/`max` ignore the NaN: both children over the whole
/// interval.
#[inline(always)]
pub fn step(origin: f32, inv_dir: f32, split: f32, t0: f32, t1: f32) -> Step {
    let (lo, hi) = padded_crossing((split - origin) * inv_dir);
    step_between(lo, hi, t0, t1)
}

/// [`step`] from the padded crossing `[lo, hi]`.
///
/// Walks of rays with `tmin >= 0` get it cheaper from the reciprocals with the padding folded
/// in ([`SlabRay`]): `lo = (split - origin) inv_near`, `hi = (split - origin) inv_far` is the
/// padded crossing when it lies ahead of the origin; behind it, both are negative (in the
/// wrong order), so the crossing lies before `t0 >= 0` either way: [`Step::Second`], as with
/// [`padded_crossing`].
#[inline(always)]
pub fn step_between(lo: f32, hi: f32, t0: f32, t1: f32) -> Step {
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

/// [`step`] with the ray's [`SlabRay`] reciprocals (see [`step_between`]).
#[inline(always)]
fn step_folded(slab: &SlabRay, a: usize, split: f32, t0: f32, t1: f32) -> Step {
    let d = split - slab.origin[a];
    let (lo, hi) = if slab.pad_after {
        // Plain reciprocals (`inv_near = inv_far = inv`): pad the crossing itself.
        padded_crossing(d * slab.inv_near[a])
    } else {
        (d * slab.inv_near[a], d * slab.inv_far[a])
    };
    step_between(lo, hi, t0, t1)
}

/// What the walk needs of a tree: its nodes, the index array, and how a ray meets the plane
/// of an inner node. [`KdTree`] and [`BspTree`](crate::BspTree) implement it; the walks below
/// are written once for both.
pub(crate) trait SplitPlanes {
    /// Per-ray constants (reciprocal direction, ...), from the ray and its reciprocal
    /// direction `inv` (computed once per query, also for the clip to the root cell).
    type RayData;
    fn ray_data(&self, ray: &Ray, inv: [f32; 3]) -> Self::RayData;
    fn nodes(&self) -> &[KdNode];
    fn indices(&self) -> &[u32];
    /// `(first, second, step)` at inner node `i` for the ray's interval `[t0, t1]`.
    fn at(&self, ray: &Self::RayData, i: usize, t0: f32, t1: f32) -> (usize, usize, Step);
}

/// The first and second child of inner node `i` (child below the plane at `i + 1`), selected
/// by index rather than by a branch that the ray's direction makes unpredictable.
#[inline(always)]
pub(crate) fn ordered_children(i: usize, node: &KdNode, below_first: bool) -> (usize, usize) {
    let children = [i + 1, node.above()];
    let f = !below_first as usize;
    (children[f], children[f ^ 1])
}

/// What leaves test: the caller's primitives (a leaf of one names it in its node), the
/// listed copies of the leaves of several ([`LeafPrims`], ranges of the index array), and the
/// level their triangle windows run at ([`Level`]).
pub(crate) type LeafData<'a, P, V> = (&'a [P], &'a LeafPrims<P>, V);

/// Tests leaf `node`'s primitives against `r`, shrinking `r.tmax` to the closest hit.
/// Returns true when `ANY_HIT` and something was hit.
#[inline(always)]
pub(crate) fn test_leaf<P: Primitive, const ANY_HIT: bool, V: Level>(
    (prims, listed, level): LeafData<'_, P, V>,
    node: &KdNode,
    indices: &[u32],
    r: &mut Ray,
    best: &mut impl Keep,
) -> bool {
    match node.list() {
        Some((first, count)) => {
            let places = (first as usize, count as usize);
            listed.test_at::<ANY_HIT, V>(level, places, indices, r, best, |_| false)
        }
        None => test_primitives::<P, ANY_HIT>(prims, node.leaf_prims(indices), r, best, |_| false),
    }
}

/// Iterative front-to-back traversal with an explicit stack of pending far cells, from the
/// ray's interval `[t0, t1]` inside the root cell. `on_leaf` sees each leaf before it is
/// tested (queries pass one that does nothing; [`crate::KdTree::leaves_tested`] records them).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn iterative<T: SplitPlanes, P: Primitive, const ANY_HIT: bool, K: Keep, V: Level>(
    tree: &T,
    leaves: LeafData<'_, P, V>,
    ray: &Ray,
    data: T::RayData,
    (mut t0, mut t1): (f32, f32),
    best: impl FnOnce() -> K,
    mut on_leaf: impl FnMut(usize),
) -> Option<Hit> {
    let mut best = best();
    let (nodes, indices) = (tree.nodes(), tree.indices());
    let mut r = *ray;
    // One pending cell per level at most: the depth cap bounds the stack. On the call's own
    // stack, so the walk's state stays in registers (a thread-local stack, reached through
    // `LocalKey::with`, left it in memory where `with` was not inlined).
    let mut stack = [(0u32, 0.0f32, 0.0f32); MAX_DEPTH as usize + 1];
    let mut sp = 0;
    let mut i = 0usize;
    loop {
        rt_geom::counters::nodes(1);
        if !nodes[i].is_leaf() {
            let (first, second, step) = tree.at(&data, i, t0, t1);
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
        on_leaf(i);
        if test_leaf::<P, ANY_HIT, V>(leaves, &nodes[i], indices, &mut r, &mut best) {
            return best.best();
        }
        // The next pending cell that starts before the closest hit.
        loop {
            if sp == 0 {
                return best.best();
            }
            sp -= 1;
            let (n, a, b) = stack[sp];
            if best.best().is_none() || a <= r.tmax {
                (i, t0, t1) = (n as usize, a, b);
                break;
            }
        }
    }
}

/// The classic recursive traversal: the near child, then, unless a hit already lies before
/// the far child, the far child. Its leaves run at the baseline level: a recursive function
/// is not inlined into a level's copy of the query.
pub(crate) fn recursive<T: SplitPlanes, P: Primitive, const ANY_HIT: bool, K: Keep>(
    tree: &T,
    leaves: LeafData<'_, P, BaseLevel>,
    ray: &Ray,
    data: T::RayData,
    (t0, t1): (f32, f32),
    best: impl FnOnce() -> K,
) -> Option<Hit> {
    struct Walk<'a, T: SplitPlanes, P, K> {
        tree: &'a T,
        leaves: LeafData<'a, P, BaseLevel>,
        data: T::RayData,
        r: Ray,
        best: K,
    }
    impl<T: SplitPlanes, P: Primitive, K: Keep> Walk<'_, T, P, K> {
        /// Returns true when the search is over (any-hit found).
        fn visit<const ANY_HIT: bool>(&mut self, i: usize, t0: f32, t1: f32) -> bool {
            rt_geom::counters::nodes(1);
            let node = &self.tree.nodes()[i];
            if node.is_leaf() {
                let indices = self.tree.indices();
                return test_leaf::<P, ANY_HIT, BaseLevel>(
                    self.leaves,
                    node,
                    indices,
                    &mut self.r,
                    &mut self.best,
                );
            }
            let (first, second, step) = self.tree.at(&self.data, i, t0, t1);
            match step {
                Step::First => self.visit::<ANY_HIT>(first, t0, t1),
                Step::Second => self.visit::<ANY_HIT>(second, t0, t1),
                Step::Both {
                    first_end,
                    second_start,
                } => {
                    if self.visit::<ANY_HIT>(first, t0, first_end) {
                        return true;
                    }
                    if self.best.best().is_some() && second_start > self.r.tmax {
                        return false;
                    }
                    self.visit::<ANY_HIT>(second, second_start, t1)
                }
            }
        }
    }
    let mut walk = Walk {
        tree,
        leaves,
        data,
        r: *ray,
        best: best(),
    };
    walk.visit::<ANY_HIT>(0, t0, t1);
    walk.best.best()
}

/// The ray as the kd-tree's planes need it. Arrays, not `Vec3`: indexing by the node's axis
/// is then a load, not a branch.
pub(crate) struct AxisRay {
    dir: [f32; 3],
    /// The reciprocals with the padding folded in, or plain ones with `pad_after`.
    slab: SlabRay,
}

impl<P: Primitive> SplitPlanes for KdTree<P> {
    type RayData = AxisRay;

    fn ray_data(&self, ray: &Ray, inv: [f32; 3]) -> AxisRay {
        AxisRay {
            dir: ray.dir().to_array(),
            slab: SlabRay::with_inv_dir(ray, inv),
        }
    }

    #[inline(always)]
    fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    #[inline(always)]
    fn indices(&self) -> &[u32] {
        &self.indices
    }

    #[inline(always)]
    fn at(&self, ray: &AxisRay, i: usize, t0: f32, t1: f32) -> (usize, usize, Step) {
        let node = &self.nodes[i];
        let a = node.axis();
        let split = node.split();
        let (first, second) = ordered_children(i, node, below_first(ray.dir[a]));
        (first, second, step_folded(&ray.slab, a, split, t0, t1))
    }
}

/// A kd-tree whose planes lie in a frame away from the world's origin (naive planes far from
/// it): the crossing is computed in `f64` from the ray's exact local origin, rounded to `f32`
/// and padded as in the world frame, then the same step rule.
pub(crate) struct InFrame<'a, P>(pub &'a KdTree<P>);

impl<P: Primitive> SplitPlanes for InFrame<'_, P> {
    type RayData = PlaneRay;

    fn ray_data(&self, ray: &Ray, _inv: [f32; 3]) -> PlaneRay {
        PlaneRay::new(ray, &self.0.frame)
    }

    #[inline(always)]
    fn nodes(&self) -> &[KdNode] {
        &self.0.nodes
    }

    #[inline(always)]
    fn indices(&self) -> &[u32] {
        &self.0.indices
    }

    #[inline(always)]
    fn at(&self, ray: &PlaneRay, i: usize, t0: f32, t1: f32) -> (usize, usize, Step) {
        let node = &self.0.nodes[i];
        let a = node.axis();
        let d = ray.dir[a];
        let ts = ((node.split() as f64 - ray.origin[a]) / d) as f32;
        let (first, second) = ordered_children(i, node, below_first(d as f32));
        let (lo, hi) = padded_crossing(ts);
        (first, second, step_between(lo, hi, t0, t1))
    }
}

/// A whole query: empty trees and invalid rays miss; otherwise the ray is clipped to the root
/// cell `bounds` and walked the configured way.
#[inline(always)]
pub(crate) fn query<T: SplitPlanes, P: Primitive, const ANY_HIT: bool, K: Keep, V: Level>(
    tree: &T,
    leaves: LeafData<'_, P, V>,
    bounds: &Aabb,
    traversal: KdTraversal,
    ray: &Ray,
    best: impl FnOnce() -> K,
) -> Option<Hit> {
    query_with::<T, P, ANY_HIT, K, V>(tree, leaves, bounds, traversal, ray, best, |_| {})
}

/// [`query`], the iterative walk handing each leaf to `on_leaf` before testing it.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn query_with<T: SplitPlanes, P: Primitive, const ANY_HIT: bool, K: Keep, V: Level>(
    tree: &T,
    leaves: LeafData<'_, P, V>,
    bounds: &Aabb,
    traversal: KdTraversal,
    ray: &Ray,
    best: impl FnOnce() -> K,
    on_leaf: impl FnMut(usize),
) -> Option<Hit> {
    if tree.nodes().is_empty() || !ray.is_valid() {
        return None;
    }
    let inv = ray.inv_dir().to_array();
    let span = bounds.clip_ray_with_inv(ray, &inv)?;
    let data = tree.ray_data(ray, inv);
    match traversal {
        KdTraversal::Iterative => {
            iterative::<T, P, ANY_HIT, K, V>(tree, leaves, ray, data, span, best, on_leaf)
        }
        KdTraversal::Recursive => {
            let leaves = (leaves.0, leaves.1, BaseLevel);
            recursive::<T, P, ANY_HIT, K>(tree, leaves, ray, data, span, best)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folded_steps_are_as_conservative_as_padded_ones() {
        // Random planes and intervals from t0 >= 0, many of them with the crossing on an end
        // or behind the origin: the folded step takes the same children as the padded one
        // except within the padding, and never cuts a child's interval short of the exact
        // (f64) crossing.
        let mut rng = rt_testkit::rng::Rng::new(4242);
        let mut rnd = || rng.f32();
        let mut differ = 0;
        for i in 0..200_000 {
            let o = rnd() * 20.0 - 10.0;
            let d = [rnd() * 2.0 - 1.0, 0.0, -0.0][(i % 9 == 0) as usize + (i % 18 == 0) as usize];
            let split = [rnd() * 20.0 - 10.0, o][(i % 7 == 0) as usize];
            let ray = Ray::new(
                rt_geom::Vec3::new(o, 0.0, 0.0),
                rt_geom::Vec3::new(d, 1.0, 0.0),
            );
            let exact = (split as f64 - o as f64) / d as f64;
            let t0 = rnd() * 5.0 * (i % 3 != 0) as u8 as f32;
            let t1 = [t0 + rnd() * 5.0, (exact as f32).max(t0), t0][i % 3];
            let slab = SlabRay::new(&ray);
            let (got, want) = (
                step_folded(&slab, 0, split, t0, t1),
                step(o, ray.inv_dir().x, split, t0, t1),
            );
            let kind = |s: &Step| std::mem::discriminant(s);
            if kind(&got) != kind(&want) {
                differ += 1;
            }
            if let Step::Both {
                first_end,
                second_start,
            } = got
            {
                assert!(
                    first_end as f64 >= exact.min(t1 as f64) || exact.is_nan(),
                    "{got:?} {exact}"
                );
                assert!(
                    second_start as f64 <= exact.max(t0 as f64) || exact.is_nan(),
                    "{got:?} {exact}"
                );
            }
            if exact > t1 as f64 {
                assert!(got != Step::Second, "{got:?} {exact} [{t0}, {t1}]");
            }
            if exact < t0 as f64 {
                assert!(got != Step::First, "{got:?} {exact} [{t0}, {t1}]");
            }
        }
        assert!(differ < 50, "{differ} steps differ");
    }

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
        // Crossing after the interval, before it, behind the origin (the ray heads away:
        // it stays on the second side, the origin's).
        assert_eq!(step(0.0, 1.0, 20.0, 0.0, 10.0), Step::First);
        assert_eq!(step(0.0, 1.0, 2.0, 5.0, 10.0), Step::Second);
        assert_eq!(step(0.0, -1.0, 2.0, 0.0, 10.0), Step::Second);
        // Parallel (1/0 = inf), on either side, with either zero sign: the origin's side.
        assert_eq!(step(0.0, f32::INFINITY, 2.0, 0.0, 10.0), Step::First);
        assert_eq!(step(0.0, f32::NEG_INFINITY, 2.0, 0.0, 10.0), Step::Second);
        assert_eq!(step(3.0, f32::INFINITY, 2.0, 0.0, 10.0), Step::Second);
        assert_eq!(step(3.0, f32::NEG_INFINITY, 2.0, 0.0, 10.0), Step::First);
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
        // An interval starting behind the origin crosses a plane behind it too: the part
        // before the crossing is on the first side.
        let Step::Both {
            first_end,
            second_start,
        } = step(0.0, 1.0, -2.0, -5.0, 10.0)
        else {
            panic!()
        };
        assert!(first_end >= -2.0 && second_start <= -2.0);
        assert!(first_end + 2.0 < 1e-5 && -2.0 - second_start < 1e-5);
        assert_eq!(step(0.0, 1.0, -2.0, -1.0, 10.0), Step::Second);
        assert_eq!(step(0.0, -1.0, 2.0, -10.0, -5.0), Step::First);
        assert!(below_first(1.0) && below_first(0.0));
        assert!(!below_first(-1.0) && !below_first(-0.0));
    }
}
