//! Wide BVHs (4 and 8 children per node), collapsed from a [`Bvh`]: one data-parallel slab
//! test for all children of a node, children visited nearest first.
//!
//! Node layout ([`WideNode<N>`], structure of arrays so that one lane is one child):
//!
//! ```text
//! min[axis][lane], max[axis][lane]   f32   child boxes; empty lanes have min = +inf, max = -inf
//! child[lane]                        u32   inner: node index; leaf: first primitive (leaf order)
//! count[lane]                        u32   0 for an inner child (or an empty lane), else the
//!                                          leaf's primitive count
//! ```
//!
//! 4-wide: 128 bytes, 8-wide: 256 bytes. The lane loops are written over fixed-size arrays so
//! that the compiler turns each into one SIMD instruction (SSE for 4 lanes; AVX for 8 lanes in
//! the `-C target-cpu=native` build of `cargo xtask bench`), with no `unsafe` and a portable
//! fallback on any target.

use crate::collapse::{Lane, SahCollapse, greedy_lanes};
use crate::node::BvhNode;
use crate::params::MAX_DEPTH;
use crate::stats::check_leaf_primitive;
use crate::{Bvh, BvhParams, WideCollapse};
use rt_geom::aabb::{SlabRay, pad_interval};
use rt_geom::all_referenced;
use rt_geom::{Aabb, Accel, AccelStats, BuildError, Hit, PrimHit, Primitive, Ray, replaces};

/// A node of a `N`-wide BVH.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct WideNode<const N: usize> {
    /// Per axis and child, the minimum corner of the child box.
    pub min: [[f32; N]; 3],
    /// Per axis and child, the maximum corner of the child box.
    pub max: [[f32; N]; 3],
    /// Per child, the node index (inner) or the first primitive (leaf).
    pub child: [u32; N],
    /// Per child, the primitive count of a leaf; 0 for an inner child or an unused lane.
    pub count: [u32; N],
}

const _: () = assert!(std::mem::size_of::<WideNode<4>>() == 128);
const _: () = assert!(std::mem::size_of::<WideNode<8>>() == 256);

impl<const N: usize> WideNode<N> {
    const EMPTY: Self = Self {
        min: [[f32::INFINITY; N]; 3],
        max: [[f32::NEG_INFINITY; N]; 3],
        child: [u32::MAX; N],
        count: [0; N],
    };

    fn set_bounds(&mut self, lane: usize, b: Aabb) {
        for a in 0..3 {
            self.min[a][lane] = b.min[a];
            self.max[a][lane] = b.max[a];
        }
    }

    /// Child `lane`'s box.
    pub fn bounds(&self, lane: usize) -> Aabb {
        Aabb::new(
            rt_geom::Vec3::new(self.min[0][lane], self.min[1][lane], self.min[2][lane]),
            rt_geom::Vec3::new(self.max[0][lane], self.max[1][lane], self.max[2][lane]),
        )
    }

    /// Whether the lane holds a child (inner or leaf).
    pub fn is_used(&self, lane: usize) -> bool {
        self.child[lane] != u32::MAX
    }
}

/// The topology of a wide BVH: nodes, root box, depth. Leaves are ranges of a leaf-ordered
/// primitive array kept by the owner ([`WideBvh`], or `TriBvh` with SIMD triangle leaves), which
/// supplies the leaf test to [`WideTree::traverse`].
#[derive(Clone, Debug)]
pub struct WideTree<const N: usize> {
    pub(crate) nodes: Vec<WideNode<N>>,
    pub(crate) root_bounds: Aabb,
    /// The root is a single leaf (`first`, `count`) when the whole scene fits one leaf.
    pub(crate) root_leaf: Option<(u32, u32)>,
    pub(crate) depth: usize,
}

/// What the owner of a wide topology's leaves ([`TriBvh`](crate::TriBvh)) needs of it:
/// [`WideTree`] and [`CompressedTree`](crate::CompressedTree) implement it.
pub trait WideTopology: Send + Sync {
    /// The stack traversal; `leaf(first, count, ray, best)` tests a leaf (see
    /// [`WideTree::traverse`]).
    fn traverse<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        leaf: impl FnMut(u32, u32, &mut Ray, &mut Option<(PrimHit, u32)>) -> bool,
    ) -> Option<Hit>;
    /// Checks the topology; `leaf(first, count, bounds)` checks each leaf.
    fn check(&self, leaf: impl FnMut(u32, u32, &Aabb) -> Result<(), String>) -> Result<(), String>;
}

impl<const N: usize> WideTopology for WideTree<N> {
    #[inline(always)]
    fn traverse<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        leaf: impl FnMut(u32, u32, &mut Ray, &mut Option<(PrimHit, u32)>) -> bool,
    ) -> Option<Hit> {
        WideTree::traverse::<ANY_HIT>(self, ray, leaf)
    }

    fn check(&self, leaf: impl FnMut(u32, u32, &Aabb) -> Result<(), String>) -> Result<(), String> {
        WideTree::check(self, leaf)
    }
}

/// A BVH with `N` children per node (`N` = 4 or 8), sharing the leaf-ordered primitives of the
/// binary tree it was collapsed from.
#[derive(Clone, Debug)]
pub struct WideBvh<P, const N: usize> {
    tree: WideTree<N>,
    prims: Vec<P>,
    ids: Vec<u32>,
    count: usize,
    params: BvhParams,
}

/// A 4-wide BVH over primitives `P`.
pub type Bvh4<P> = WideBvh<P, 4>;
/// An 8-wide BVH over primitives `P`.
pub type Bvh8<P> = WideBvh<P, 8>;

impl<P: Primitive, const N: usize> WideBvh<P, N> {
    /// Builds a binary BVH with `params` and collapses it.
    pub fn build(prims: &[P], params: BvhParams) -> Result<Self, BuildError> {
        Ok(Self::from_binary(Bvh::build(prims, params)?))
    }

    /// Collapses a binary BVH (see [`WideTree::collapse`]).
    pub fn from_binary(bvh: Bvh<P>) -> Self {
        let tree = WideTree::collapse(&bvh.nodes, &bvh.params);
        let Bvh {
            prims,
            ids,
            count,
            params,
            ..
        } = bvh;
        Self {
            tree,
            prims,
            ids,
            count,
            params,
        }
    }

    /// The wide topology.
    pub fn tree(&self) -> &WideTree<N> {
        &self.tree
    }

    /// Primitives in leaf order.
    pub fn prims(&self) -> &[P] {
        &self.prims
    }

    /// The caller's index of each primitive in leaf order.
    pub fn ids(&self) -> &[u32] {
        &self.ids
    }

    fn traverse<const ANY_HIT: bool>(&self, ray: &Ray) -> Option<Hit> {
        self.tree.traverse::<ANY_HIT>(ray, |first, count, r, best| {
            test_leaf::<P, ANY_HIT>(&self.prims, &self.ids, first, count, r, best)
        })
    }

    /// The parts: topology, leaf-ordered primitives, their ids, the primitive count, params.
    pub(crate) fn into_parts(self) -> (WideTree<N>, Vec<P>, Vec<u32>, usize, BvhParams) {
        (self.tree, self.prims, self.ids, self.count, self.params)
    }
}

/// Tests the leaf-ordered primitives `first..first + count` (closest hit, or any hit),
/// keeping the hit with the caller's id.
#[inline(always)]
pub(crate) fn test_leaf<P: Primitive, const ANY_HIT: bool>(
    prims: &[P],
    ids: &[u32],
    first: u32,
    count: u32,
    r: &mut Ray,
    best: &mut Option<(PrimHit, u32)>,
) -> bool {
    let first = first as usize;
    for i in first..first + count as usize {
        if let Some(h) = prims[i].intersect(r) {
            if ANY_HIT {
                *best = Some((h, ids[i]));
                return true;
            }
            if replaces(h.t, ids[i], best.map(|(b, id)| (b.t, id))) {
                *best = Some((h, ids[i]));
                r.tmax = h.t;
            }
        }
    }
    false
}

impl<const N: usize> WideTree<N> {
    /// Collapses a binary BVH built with `params` as `params.collapse` says: every wide node
    /// replaces an inner binary node, its lanes are a cut of that node's subtree (binary
    /// leaves, whole subtrees made one leaf, or inner nodes that head wide nodes of their
    /// own); see the `collapse` module. Leaves keep their primitive ranges.
    pub fn collapse(bin: &[BvhNode], params: &BvhParams) -> Self {
        assert!((2..=32).contains(&N), "2..=32 lanes");
        let mut tree = Self {
            nodes: Vec::new(),
            root_bounds: bin.first().map_or(Aabb::EMPTY, |n| n.bounds()),
            root_leaf: None,
            depth: 0,
        };
        match bin.first() {
            None => {}
            Some(root) if root.is_leaf() => tree.root_leaf = Some((root.offset, root.count())),
            Some(_) => {
                let area = |b: usize| bin[b].bounds().half_area();
                let greedy = |b: usize| greedy_lanes(bin, b, N);
                let out = &mut tree.nodes;
                tree.depth = match params.collapse {
                    WideCollapse::LargestArea => write_nodes(bin, 0, out, 1, &greedy),
                    WideCollapse::Sah => {
                        let plan = SahCollapse::<N>::plan(bin, params);
                        write_nodes(bin, 0, out, 1, &|b| plan.lanes(bin, b))
                    }
                    WideCollapse::LargestAreaThenSah { above } => {
                        let plan = SahCollapse::<N>::plan(bin, params);
                        let top = above * area(0);
                        let lanes = |b| {
                            if area(b) >= top {
                                greedy(b)
                            } else {
                                plan.lanes(bin, b)
                            }
                        };
                        write_nodes(bin, 0, out, 1, &lanes)
                    }
                };
            }
        }
        tree
    }

    /// The wide nodes, root first.
    pub fn nodes(&self) -> &[WideNode<N>] {
        &self.nodes
    }

    /// The box of the whole tree (rays that miss it miss everything).
    pub fn root_bounds(&self) -> Aabb {
        self.root_bounds
    }

    /// `Some((first, count))` when the whole tree is one leaf (and `nodes()` is empty).
    pub fn root_leaf(&self) -> Option<(u32, u32)> {
        self.root_leaf
    }

    /// The depth of the deepest leaf (the root is 0).
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Every leaf's `(first, count)`, in node order.
    pub fn leaves(&self) -> Vec<(u32, u32)> {
        let lanes = self.nodes.iter().flat_map(|n| {
            (0..N)
                .filter(|&l| n.is_used(l) && n.count[l] > 0)
                .map(|l| (n.child[l], n.count[l]))
        });
        self.root_leaf.into_iter().chain(lanes).collect()
    }

    /// Stack traversal; all children of a node are tested at once and pushed far to near.
    /// `leaf(first, count, ray, best)` tests a leaf, shrinking `ray.tmax` and updating `best`
    /// `(hit, caller's id)`; it returns true to stop (any-hit queries).
    #[inline(always)]
    pub fn traverse<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        leaf: impl FnMut(u32, u32, &mut Ray, &mut Option<(PrimHit, u32)>) -> bool,
    ) -> Option<Hit> {
        traverse_nodes::<_, N, ANY_HIT>(
            &self.nodes,
            &self.root_bounds,
            self.root_leaf,
            self.depth,
            ray,
            leaf,
        )
    }

    /// Statistics of the topology; `bytes` counts the nodes only.
    pub fn stats(&self, prims: usize, params: &BvhParams) -> AccelStats {
        let mut s = AccelStats {
            primitives: prims,
            nodes: self.nodes.len(),
            max_depth: self.depth,
            bytes: std::mem::size_of_val(self.nodes.as_slice()),
            ..AccelStats::default()
        };
        let root_area = self.root_bounds.half_area();
        let mut sah = 0.0f64;
        if let Some((_, count)) = self.root_leaf {
            s.leaves = 1;
            s.nodes = 1;
            s.references = count as usize;
            sah = root_area as f64
                * params.tests(count as usize) as f64
                * params.intersection_cost as f64;
        }
        for (i, n) in self.nodes.iter().enumerate() {
            if i == 0 {
                sah += root_area as f64 * params.traversal_cost as f64;
            }
            for lane in (0..N).filter(|&l| n.is_used(l)) {
                let area = n.bounds(lane).half_area() as f64;
                if n.count[lane] > 0 {
                    s.leaves += 1;
                    s.references += n.count[lane] as usize;
                    sah += area
                        * params.tests(n.count[lane] as usize) as f64
                        * params.intersection_cost as f64;
                } else {
                    sah += area * params.traversal_cost as f64;
                }
            }
        }
        s.nodes += s.leaves;
        s.sah_cost = Some(if root_area > 0.0 {
            (sah / root_area as f64) as f32
        } else {
            0.0
        });
        s
    }

    /// Checks the topology; `leaf(first, count, bounds)` checks each leaf's primitives.
    pub fn check(
        &self,
        mut leaf: impl FnMut(u32, u32, &Aabb) -> Result<(), String>,
    ) -> Result<(), String> {
        if let Some((first, count)) = self.root_leaf {
            return leaf(first, count, &self.root_bounds);
        }
        if self.nodes.is_empty() {
            return Ok(());
        }
        let mut stack = vec![(0usize, self.root_bounds, 0usize)];
        while let Some((i, parent, depth)) = stack.pop() {
            if depth > MAX_DEPTH {
                return Err(format!("node {i} deeper than {MAX_DEPTH}"));
            }
            let n = self
                .nodes
                .get(i)
                .ok_or(format!("child index {i} out of range"))?;
            for lane in (0..N).filter(|&l| n.is_used(l)) {
                let b = n.bounds(lane);
                if !parent.contains(&b) {
                    return Err(format!("node {i} lane {lane} pokes out of its parent"));
                }
                if n.count[lane] > 0 {
                    leaf(n.child[lane], n.count[lane], &b)?;
                } else {
                    if n.child[lane] as usize <= i {
                        return Err(format!("node {i} lane {lane} points backwards"));
                    }
                    stack.push((n.child[lane] as usize, b, depth + 1));
                }
            }
        }
        Ok(())
    }
}

/// A wide node as the traversal sees it: one entry distance per lane, and each lane's child.
pub(crate) trait WideLanes<const N: usize> {
    /// The lanes the ray enters within `[tmin, tmax]` (bit `lane`), and the entry distance
    /// per lane (meaningful for those).
    fn entries(&self, ray: &SlabRay, tmin: f32, tmax: f32) -> (u32, [f32; N]);
    /// Inner child: node index; leaf: first primitive; `u32::MAX` for an empty lane.
    fn child(&self, lane: usize) -> u32;
    /// 0 for an inner child, else the leaf's primitive count.
    fn count(&self, lane: usize) -> u32;
    /// Bit `lane` set for the lanes that hold a child.
    fn used_mask(&self) -> u32;
    /// Bit `lane` set for the lanes that hold a leaf (a count above 0): one compare of all
    /// lanes where the counts are an array.
    #[inline(always)]
    fn leaf_mask(&self) -> u32 {
        (0..N).fold(0, |m, l| m | ((self.count(l) > 0) as u32) << l)
    }
}

/// Bit `lane` set where `t0 <= t1` (false for NaN): one SIMD compare and mask extraction for
/// 4 and 8 lanes.
#[inline(always)]
fn le_lanes<const N: usize>(t0: &[f32; N], t1: &[f32; N]) -> u32 {
    use wide::{CmpLe, f32x4, f32x8};
    let (a, b) = (&t0[..], &t1[..]);
    if let (Ok(a), Ok(b)) = (<[f32; 8]>::try_from(a), <[f32; 8]>::try_from(b)) {
        return f32x8::from(a).cmp_le(f32x8::from(b)).move_mask() as u32;
    }
    if let (Ok(a), Ok(b)) = (<[f32; 4]>::try_from(a), <[f32; 4]>::try_from(b)) {
        return f32x4::from(a).cmp_le(f32x4::from(b)).move_mask() as u32;
    }
    (0..N).fold(0, |m, l| m | ((t0[l] <= t1[l]) as u32) << l)
}

impl<const N: usize> WideLanes<N> for WideNode<N> {
    #[inline(always)]
    fn entries(&self, ray: &SlabRay, tmin: f32, tmax: f32) -> (u32, [f32; N]) {
        lane_entries(&self.min, &self.max, ray, tmin, tmax)
    }

    #[inline(always)]
    fn child(&self, lane: usize) -> u32 {
        self.child[lane]
    }

    #[inline(always)]
    fn count(&self, lane: usize) -> u32 {
        self.count[lane]
    }

    /// Every lane: an empty lane's box (min = +inf, max = -inf) gives NaN for every valid ray
    /// (a near plane at +-inf puts the entry at +inf, the far one puts the exit at -inf).
    #[inline(always)]
    fn used_mask(&self) -> u32 {
        u32::MAX
    }
}

/// The stack traversal of every wide layout (see [`WideTree::traverse`]).
///
/// Per inner node: one SIMD slab test of all lanes, a bit mask of the lanes hit, and then
/// - no lane: the next entry is popped from the stack;
/// - one lane (the common case deep in the tree): that child is visited next, no stack traffic;
/// - several: all are pushed far to near and the nearest is popped (closest-hit queries);
///   any-hit queries push the inner children, then the leaves, and pop a leaf first.
///
/// Popped entries whose entry distance lies beyond the closest hit found since are skipped.
#[inline(always)]
pub(crate) fn traverse_nodes<Node: WideLanes<N>, const N: usize, const ANY_HIT: bool>(
    nodes: &[Node],
    root_bounds: &Aabb,
    root_leaf: Option<(u32, u32)>,
    depth: usize,
    ray: &Ray,
    mut leaf: impl FnMut(u32, u32, &mut Ray, &mut Option<(PrimHit, u32)>) -> bool,
) -> Option<Hit> {
    if !ray.is_valid() {
        return None;
    }
    let mut r = *ray;
    let mut best = None;
    if let Some((first, count)) = root_leaf {
        root_bounds.clip_ray(&r)?;
        leaf(first, count, &mut r, &mut best);
        return best.map(|(h, id)| Hit::new(h, id));
    }
    if nodes.is_empty() {
        return None;
    }
    let slab = SlabRay::new(ray);
    STACK.with(|cell| {
        let mut stack = cell.borrow_mut();
        // At most N - 1 pending siblings per level.
        let need = (N - 1) * (depth + 1) + N;
        if stack.len() < need {
            stack.resize(need, (0, 0, 0.0));
        }
        let stack = &mut stack[..need];
        let mut sp = 0usize;
        let mut next = (0u32, 0u32, r.tmin);
        loop {
            let (child, count, entry) = next;
            if entry <= r.tmax {
                if count > 0 {
                    if leaf(child, count, &mut r, &mut best) {
                        return;
                    }
                } else {
                    let node = &nodes[child as usize];
                    let (entered, t) = node.entries(&slab, r.tmin, r.tmax);
                    let mut mask = entered & node.used_mask();
                    if mask != 0 {
                        let lane = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        let item = (node.child(lane), node.count(lane), t[lane]);
                        if mask == 0 {
                            next = item;
                            continue;
                        }
                        if ANY_HIT {
                            // Any hit ends the query: leaves go on top of the stack (tested
                            // first), inner children under them, each group in lane order.
                            mask |= 1 << lane;
                            let leaves = node.leaf_mask();
                            for mut group in [mask & !leaves, mask & leaves] {
                                while group != 0 {
                                    let l = group.trailing_zeros() as usize;
                                    group &= group - 1;
                                    stack[sp] = (node.child(l), node.count(l), t[l]);
                                    sp += 1;
                                }
                            }
                        } else {
                            stack[sp] = item;
                            sp += 1;
                            let base = sp - 1;
                            while mask != 0 {
                                let lane = mask.trailing_zeros() as usize;
                                mask &= mask - 1;
                                let te = t[lane];
                                let item = (node.child(lane), node.count(lane), te);
                                let mut k = sp;
                                while k > base && stack[k - 1].2 < te {
                                    stack[k] = stack[k - 1];
                                    k -= 1;
                                }
                                stack[k] = item;
                                sp += 1;
                            }
                        }
                    }
                }
            }
            if sp == 0 {
                return;
            }
            sp -= 1;
            next = stack[sp];
        }
    });
    best.map(|(h, id)| Hit::new(h, id))
}

thread_local! {
    /// Traversal stacks are reused per thread: no allocation and no zeroing per ray.
    static STACK: std::cell::RefCell<Vec<(u32, u32, f32)>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// The lanes whose boxes `min..max` (per axis, per lane) the ray enters within `[tmin, tmax]`
/// (bit `lane`) and the entry distance per lane (meaningful for those; written as plain lane
/// loops: one SIMD operation each after vectorisation). The mask comes from the interval
/// compare itself (a lane's entry no later than its exit): no NaN written for the misses and
/// tested again. Conservative like [`SlabRay::entry`]: the entry returned is never later
/// than the true one and never before `tmin`.
#[inline(always)]
pub(crate) fn lane_entries<const N: usize>(
    min: &[[f32; N]; 3],
    max: &[[f32; N]; 3],
    ray: &SlabRay,
    tmin: f32,
    tmax: f32,
) -> (u32, [f32; N]) {
    let mut t0 = [tmin; N];
    let mut t1 = [tmax; N];
    for a in 0..3 {
        let (near, far) = if ray.neg[a] {
            (&max[a], &min[a])
        } else {
            (&min[a], &max[a])
        };
        let (o, inv_near, inv_far) = (ray.origin[a], ray.inv_near[a], ray.inv_far[a]);
        for l in 0..N {
            let tn = (near[l] - o) * inv_near;
            let tf = (far[l] - o) * inv_far;
            // NaN (origin on the plane, zero direction) leaves the interval unchanged.
            t0[l] = if tn > t0[l] { tn } else { t0[l] };
            t1[l] = if tf < t1[l] { tf } else { t1[l] };
        }
    }
    if ray.pad_after {
        for l in 0..N {
            (t0[l], t1[l]) = pad_interval(t0[l], t1[l], tmin);
        }
    }
    (le_lanes(&t0, &t1), t0)
}

/// Writes the wide node for inner binary node `b` with the lanes `lanes(b)` and its subtree;
/// returns the depth of the subtree.
fn write_nodes<const N: usize>(
    bin: &[BvhNode],
    b: usize,
    out: &mut Vec<WideNode<N>>,
    depth: usize,
    lanes: &impl Fn(usize) -> Vec<Lane>,
) -> usize {
    let index = out.len();
    out.push(WideNode::EMPTY);
    let mut node = WideNode::EMPTY;
    let mut deepest = depth;
    for (lane, kid) in lanes(b).into_iter().enumerate() {
        node.set_bounds(lane, bin[kid.node()].bounds());
        match kid {
            Lane::Leaf { first, count, .. } => {
                node.child[lane] = first;
                node.count[lane] = count;
            }
            Lane::Inner(k) => {
                node.child[lane] = out.len() as u32;
                deepest = deepest.max(write_nodes(bin, k, out, depth + 1, lanes));
            }
        }
    }
    out[index] = node;
    deepest
}

impl<P: Primitive, const N: usize> Accel for WideBvh<P, N> {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.traverse::<false>(ray)
    }

    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        self.traverse::<true>(ray).is_some()
    }

    fn stats(&self) -> AccelStats {
        let mut s = self.tree.stats(self.count, &self.params);
        s.bytes += std::mem::size_of_val(self.prims.as_slice())
            + std::mem::size_of_val(self.ids.as_slice());
        s
    }

    fn validate(&self) -> Result<(), String> {
        let mut seen = vec![false; self.count];
        self.tree.check(|first, count, bounds| {
            for k in first as usize..(first + count) as usize {
                let p = self.prims.get(k).ok_or("leaf points past the primitives")?;
                let split = self.params.splits_primitives();
                check_leaf_primitive(p, self.ids[k], bounds, &mut seen, split)?;
            }
            Ok(())
        })?;
        all_referenced(&seen)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_geom::{Sphere, Triangle};

    mod bvh4 {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| Bvh4::build(p, BvhParams::balanced()),
            spheres: |p: &[Sphere]| Bvh4::build(p, BvhParams::balanced()),
            shapes: |p: &[rt_geom::Shape]| Bvh4::build(p, BvhParams::balanced()),
        );
    }

    mod bvh8 {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| Bvh8::build(p, BvhParams::balanced()),
            spheres: |p: &[Sphere]| Bvh8::build(p, BvhParams::balanced()),
            shapes: |p: &[rt_geom::Shape]| Bvh8::build(p, BvhParams::balanced()),
        );
    }

    mod bvh8_pure_sah_collapse {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| Bvh8::build(p, BvhParams { collapse: WideCollapse::Sah, ..BvhParams::balanced() }),
        );
    }

    mod bvh4_greedy_collapse {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| Bvh4::build(p, BvhParams { collapse: WideCollapse::LargestArea, ..BvhParams::balanced() }),
        );
    }

    #[test]
    fn hybrid_collapse_spans_both_rules() {
        let tris = rt_testkit::scenes::tessellated_sphere(3000, rt_geom::Vec3::ZERO, 1.0);
        let bvh = Bvh::build(&tris, BvhParams::balanced()).unwrap();
        let with = |collapse| {
            let params = BvhParams {
                collapse,
                ..*bvh.params()
            };
            WideTree::<8>::collapse(&bvh.nodes, &params).nodes
        };
        let hybrid = |above| with(WideCollapse::LargestAreaThenSah { above });
        assert_eq!(hybrid(0.0), with(WideCollapse::LargestArea));
        assert_eq!(hybrid(1.5), with(WideCollapse::Sah));
        assert_ne!(with(WideCollapse::Sah), with(WideCollapse::LargestArea));
        for above in [-1.0, f32::NAN] {
            let params = BvhParams {
                collapse: WideCollapse::LargestAreaThenSah { above },
                ..BvhParams::balanced()
            };
            assert!(Bvh8::build(&tris, params).is_err());
        }
    }

    mod bvh8_leaf1 {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| Bvh8::build(p, BvhParams { max_leaf_size: 1, ..BvhParams::quality() }),
        );
    }
}
