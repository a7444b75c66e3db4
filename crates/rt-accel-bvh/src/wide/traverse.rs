//! The walk: one stack loop over any wide node layout ([`NodeLayout`]), all of a node's children
//! tested at once, the hit lanes taken as one bit mask; the leaf test of primitives kept in
//! leaf order.

use super::NodeLayout;
use crate::params::MAX_DEPTH;
use rt_geom::aabb::{SlabRay, pad_interval};
use rt_geom::{Aabb, Hit, Keep, Level, Primitive, Ray};
use std::mem::MaybeUninit;

/// Tests the leaf-ordered primitives `first..first + count` (closest hit, or any hit),
/// offering each hit to `best` with the caller's id.
#[inline(always)]
pub(crate) fn test_leaf<P: Primitive, K: Keep, const ANY_HIT: bool>(
    prims: &[P],
    ids: &[u32],
    first: u32,
    count: u32,
    r: &mut Ray,
    best: &mut K,
) -> bool {
    let first = first as usize;
    for i in first..first + count as usize {
        if K::SKIPS && best.skips(ids[i]) {
            continue;
        }
        if let Some(h) = prims[i].intersect(r) {
            if best.keep::<ANY_HIT>(h, ids[i], &mut r.tmax) {
                return true;
            }
        }
    }
    false
}

/// Bit `lane` set where `a <= b` (signed integers): one SIMD compare and mask extraction for
/// 4 and 8 lanes (eight in one compare of `level`'s vectors).
#[inline(always)]
fn le_lanes_i32<const N: usize, V: Level>(level: V, a: &[i32; N], b: &[i32; N]) -> u32 {
    use wide::{CmpGt, i32x4};
    let (a, b) = (&a[..], &b[..]);
    if let (Ok(a), Ok(b)) = (<&[i32; 8]>::try_from(a), <&[i32; 8]>::try_from(b)) {
        return level.le_bits8_i32(a, b);
    }
    if let (Ok(a), Ok(b)) = (<[i32; 4]>::try_from(a), <[i32; 4]>::try_from(b)) {
        return !(i32x4::from(a).cmp_gt(i32x4::from(b)).move_mask() as u32) & 0xf;
    }
    (0..N).fold(0, |m, l| m | ((a[l] <= b[l]) as u32) << l)
}

/// The stack traversal of every wide layout (see [`WideTree::traverse`]).
///
/// Per inner node: one SIMD slab test of all lanes, a bit mask of the lanes hit, and then
/// - no lane: the next entry is popped from the stack;
/// - one lane (the common case deep in the tree): that child is visited next, no stack traffic;
/// - two: the nearer (any-hit queries: a leaf) is visited next and the other pushed, as
///   Embree's walk does;
/// - more: all but the nearest are pushed far to near and the nearest is visited next
///   (closest-hit queries: ordered by a sorting network in vectors, as in Embree's and
///   Fuetterling et al.'s wide walks, where the level has one; by insertion at the baseline);
///   any-hit queries push the inner children, then the leaves, and pop a leaf first.
///
/// Popped entries whose entry distance lies beyond the closest hit found since are skipped
/// (closest-hit queries; any-hit ones keep no distances). With `prefetch`, every child a
/// node's test enters is asked for as soon as the test is done: inner nodes by the walk,
/// leaves at the address `prefetch` gives for their first primitive.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn traverse_nodes<
    Node: NodeLayout<N>,
    const N: usize,
    const ANY_HIT: bool,
    V: Level,
    K: Keep,
>(
    level: V,
    nodes: &[Node],
    root_bounds: &Aabb,
    root_leaf: Option<(u32, u32)>,
    depth: usize,
    ray: &Ray,
    best: impl FnOnce() -> K,
    mut leaf: impl FnMut(u32, u32, &mut Ray, &mut K) -> bool,
    prefetch: Option<impl Fn(u32) -> *const u8>,
) -> Option<Hit> {
    if !ray.is_valid() {
        return None;
    }
    let mut best = best();
    // The walk's own ray, whose `tmax` it lowers (in words where one 512-bit move would
    // slow the walk: `Level::copy_ray`).
    let mut r = level.copy_ray(ray);
    if let Some((first, count)) = root_leaf {
        root_bounds.clip_ray(&r)?;
        leaf(first, count, &mut r, &mut best);
        return best.best();
    }
    if nodes.is_empty() {
        return None;
    }
    let slab = SlabRay::new(ray);
    // At most N - 1 pending siblings per level, and every tree is at most `MAX_DEPTH + 1`
    // levels deep (the build, the reinsertion and loading all hold it there), and the sorted
    // push writes N entries from the top: `STACK` entries always suffice. The stack lies in
    // the walk's own frame, uninitialised: zeroing it, or taking a reused one from a
    // thread-local, cost more per query than a walk through a small tree's few nodes.
    let need = (N - 1) * (depth + 1) + N;
    assert!(need <= STACK, "a tree deeper than MAX_DEPTH + 1 levels");
    let mut stack = [MaybeUninit::<Entry>::uninit(); STACK];
    walk_stack::<Node, N, ANY_HIT, V, K>(
        level, nodes, &slab, &mut stack, &mut r, &mut best, leaf, prefetch,
    );
    best.best()
}

/// The stack loop of [`traverse_nodes`] from the root, over `stack` (large enough; its
/// entries are read only after the walk has written them). Every index is taken modulo
/// `STACK` (a power of two: one mask, no bounds check, and no change, since the walk never
/// holds more than `STACK` entries).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn walk_stack<Node: NodeLayout<N>, const N: usize, const ANY_HIT: bool, V: Level, K: Keep>(
    level: V,
    nodes: &[Node],
    slab: &SlabRay,
    stack: &mut [MaybeUninit<Entry>; STACK],
    r: &mut Ray,
    best: &mut K,
    mut leaf: impl FnMut(u32, u32, &mut Ray, &mut K) -> bool,
    prefetch: Option<impl Fn(u32) -> *const u8>,
) {
    let slot = |i: usize| i & (STACK - 1);
    let mut sp = 0usize;
    // The root, then each child taken straight from its node's test (which entered it within
    // the interval) or popped (checked against the closest hit found since it was pushed).
    let mut next = (0u32, 0u32, r.tmin);
    loop {
        let (child, count, _) = next;
        if count > 0 {
            if leaf(child, count, r, best) {
                return;
            }
        } else {
            let node = &nodes[child as usize];
            if rt_geom::counters::ENABLED {
                let used = (0..N).filter(|&l| node.child(l) != u32::MAX).count();
                rt_geom::counters::nodes(used as u32);
            }
            let (entered, t) = node.entries(level, slab, r.tmin, r.tmax);
            let entry = |l: usize| stack_entry::<Node, N, ANY_HIT>(node, &t, l);
            let mut mask = entered & node.used_mask();
            if let Some(leaf_at) = &prefetch {
                // Every child entered asked for at once, before the walk reaches it: a
                // node's lines or as many of a leaf's data, the address picked without a
                // branch (a prefetch reads nothing, so any address serves).
                let lines = std::mem::size_of::<Node>().div_ceil(64);
                let mut hit = mask;
                while hit != 0 {
                    let l = hit.trailing_zeros() as usize;
                    hit &= hit - 1;
                    let child = node.child(l);
                    let node_at = nodes.as_ptr().wrapping_add(child as usize).cast::<u8>();
                    let at = if node.count(l) > 0 {
                        leaf_at(child)
                    } else {
                        node_at
                    };
                    rt_geom::isa::prefetch(at, lines);
                }
            }
            if mask != 0 {
                let lane = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let item = entry(lane);
                if mask == 0 {
                    next = item;
                    continue;
                }
                if mask & (mask - 1) == 0 {
                    // Two children: one visited next straight from the node, the other
                    // pushed (no trip through the stack for the next node's index).
                    // Closest hit: the nearer next; any hit: a leaf first.
                    let other = entry(mask.trailing_zeros() as usize);
                    let item_first = if ANY_HIT {
                        item.1 > 0 && other.1 == 0
                    } else {
                        item.2 <= other.2
                    };
                    let (first, then) = if item_first {
                        (item, other)
                    } else {
                        (other, item)
                    };
                    stack[slot(sp)].write(then);
                    sp += 1;
                    next = first;
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
                            stack[slot(sp)].write(entry(l));
                            sp += 1;
                        }
                    }
                } else if let Some(sorted) = far_to_near(level, node, &t, mask | 1 << lane) {
                    // Three children or more, ordered by a sorting network: all eight lanes
                    // written (the hit ones first, far to near), the nearest taken next.
                    // The writes past the hit lanes stay above the stack's top.
                    let hits = (mask | 1 << lane).count_ones() as usize;
                    for i in 0..N.min(8) {
                        let e = (sorted.child[i], sorted.count[i], sorted.t[i]);
                        stack[slot(sp + i)].write(e);
                    }
                    let near = (hits - 1) & 7;
                    next = (sorted.child[near], sorted.count[near], sorted.t[near]);
                    sp += hits - 1;
                    continue;
                } else {
                    stack[slot(sp)].write(item);
                    sp += 1;
                    let base = sp - 1;
                    while mask != 0 {
                        let lane = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        let item = entry(lane);
                        let te = item.2;
                        let mut k = sp;
                        // SAFETY: `k - 1 < sp`, and every entry below `sp` is written (the
                        // walk's invariant: see the pop below).
                        while k > base && unsafe { stack[slot(k - 1)].assume_init() }.2 < te {
                            stack[slot(k)] = stack[slot(k - 1)];
                            k -= 1;
                        }
                        stack[slot(k)].write(item);
                        sp += 1;
                    }
                }
            }
        }
        // Pop the next pending subtree; it may have been passed by the closest hit.
        loop {
            if sp == 0 {
                return;
            }
            sp -= 1;
            // SAFETY: every entry below `sp` is written: `sp` starts at 0, each push writes
            // `stack[sp]` before `sp` grows past it, the sorted push writes eight entries from
            // `stack[sp]` on before `sp` grows by fewer, and the ordered insertion moves written
            // entries up by one (the top one into `stack[sp]`) and writes the new entry into
            // the slot left, before `sp` grows.
            next = unsafe { stack[slot(sp)].assume_init() };
            if ANY_HIT || next.2 <= r.tmax {
                break;
            }
        }
    }
}

/// The lanes of `hit` (three or more) far to near, then the others
/// ([`Level::far_to_near8`]), for eight-wide nodes at levels that sort in vectors.
#[inline(always)]
fn far_to_near<Node: NodeLayout<N>, const N: usize, V: Level>(
    level: V,
    node: &Node,
    t: &[f32; N],
    hit: u32,
) -> Option<rt_geom::SortedLanes> {
    let t: &[f32; 8] = t[..].try_into().ok()?;
    let child: &[u32; 8] = node.children()[..].try_into().ok()?;
    let count: &[u32; 8] = node.counts()[..].try_into().ok()?;
    level.far_to_near8(hit, t, child, count)
}

/// A pending subtree: child, count, entry distance.
type Entry = (u32, u32, f32);

/// Lane `l` of `node`, entered at `t[l]`, as a stack entry. Any-hit queries end at their first
/// hit and never lower `tmax` before: their entries carry no distance (0), and their pops
/// check none.
#[inline(always)]
fn stack_entry<Node: NodeLayout<N>, const N: usize, const ANY_HIT: bool>(
    node: &Node,
    t: &[f32; N],
    l: usize,
) -> Entry {
    (
        node.child(l),
        node.count(l),
        if ANY_HIT { 0.0 } else { t[l] },
    )
}

/// Stack entries in the walk's frame: enough for 8-wide trees of `MAX_DEPTH + 1` levels (the
/// deepest any tree is), rounded up to a power of two so that a masked index needs no check.
const STACK: usize = 512;
const _: () = assert!(STACK.is_power_of_two() && 7 * (MAX_DEPTH + 2) + 8 <= STACK);

/// Each axis's near and far planes of the boxes `min..max` (per axis, per lane), picked by
/// the ray's sign.
#[inline(always)]
pub(crate) fn near_far<'a, const N: usize>(
    min: &'a [[f32; N]; 3],
    max: &'a [[f32; N]; 3],
    ray: &SlabRay,
) -> [(&'a [f32; N], &'a [f32; N]); 3] {
    std::array::from_fn(|a| {
        if ray.neg[a] {
            (&max[a], &min[a])
        } else {
            (&min[a], &max[a])
        }
    })
}

/// The lanes whose boxes (each axis's near and far planes, per lane) the ray enters within
/// `[tmin, tmax]` (bit `lane`) and the entry distance per lane (meaningful for those; written
/// as plain lane loops, one output each: one SIMD operation each after vectorisation), in
/// [`SlabRay`]'s fused form at levels with fused multiply-add. The mask comes from the
/// interval compare itself (a lane's entry no later than its exit): no NaN written for the
/// misses and tested again. Conservative like [`SlabRay::entry`]: the entry returned is never
/// later than the true one and never before `tmin`.
#[inline(always)]
pub(crate) fn lane_entries<const N: usize, V: Level>(
    level: V,
    planes: [(&[f32; N], &[f32; N]); 3],
    ray: &SlabRay,
    tmin: f32,
    tmax: f32,
) -> (u32, [f32; N]) {
    let mut t0 = [tmin; N];
    let mut t1 = [tmax; N];
    if !V::FMA {
        for (a, (near, far)) in planes.iter().enumerate() {
            let (o, inv_near, inv_far) = (ray.origin[a], ray.inv_near[a], ray.inv_far[a]);
            for l in 0..N {
                let (tn, tf) = ((near[l] - o) * inv_near, (far[l] - o) * inv_far);
                // NaN (origin on the plane, zero direction) leaves the interval unchanged.
                t0[l] = if tn > t0[l] { tn } else { t0[l] };
                t1[l] = if tf < t1[l] { tf } else { t1[l] };
            }
        }
        let enter = padded_misses(&mut t0, &mut t1, ray, tmin);
        return (le_lanes_i32(level, &enter, &[0; N]), t0);
    }
    // The fused form gives no NaN (empty lanes enter at +inf and leave at -inf on every axis):
    // the three axes and the interval combine as a tree of maxima and minima, two steps deep
    // instead of a chain of three.
    let mut tn = [[0.0; N]; 3];
    let mut tf = [[0.0; N]; 3];
    for (a, (near, far)) in planes.iter().enumerate() {
        for l in 0..N {
            (tn[a][l], tf[a][l]) = ray.fused_distances(a, near[l], far[l]);
        }
    }
    // The interval compare on integers (`enter <= leave`), one cycle per step where the float
    // operations take up to four.
    let mut enter = [0i32; N];
    let mut leave = [0i32; N];
    if tmin >= 0.0 {
        // Every entry's maximum includes `tmin >= +0` (`+ 0.0` turns -0.0 into +0.0): such a
        // maximum, and its compare with the exit, order the floats' bits as signed integers
        // do (a non-negative float's bits order as its value; any negative one, which the
        // integer maximum does not pick, lies below them all). The exit's integer minimum may
        // pick another negative value than the float one would: both lie below every entry,
        // so the lane misses either way. No operand is NaN, and no far plane's distance is
        // -0.0 (its offset never is).
        let bits = |x: f32| x.to_bits() as i32;
        let (lo, hi) = (bits(tmin + 0.0), bits(tmax + 0.0));
        let most = |x: i32, y: i32| if x > y { x } else { y };
        let least = |x: i32, y: i32| if x < y { x } else { y };
        for l in 0..N {
            let (n0, n1, n2) = (bits(tn[0][l]), bits(tn[1][l]), bits(tn[2][l]));
            enter[l] = most(most(n0, n1), most(n2, lo));
        }
        for l in 0..N {
            let (f0, f1, f2) = (bits(tf[0][l]), bits(tf[1][l]), bits(tf[2][l]));
            leave[l] = least(least(f0, f1), least(f2, hi));
        }
        for l in 0..N {
            t0[l] = f32::from_bits(enter[l] as u32);
        }
    } else {
        // An interval from behind the origin: in floats.
        let most = |x: f32, y: f32| if x > y { x } else { y };
        let least = |x: f32, y: f32| if x < y { x } else { y };
        for l in 0..N {
            t0[l] = most(most(tn[0][l], tn[1][l]), most(tn[2][l], tmin));
            t1[l] = least(least(tf[0][l], tf[1][l]), least(tf[2][l], tmax));
        }
        enter = padded_misses(&mut t0, &mut t1, ray, tmin);
    }
    (le_lanes_i32(level, &enter, &leave), t0)
}

/// An interval in floats (`t0..t1` per lane) padded as the ray asks, and the answer of its
/// compare as integers to compare with 0 (0 for a lane entered, 1 for a miss or a NaN).
#[inline(always)]
fn padded_misses<const N: usize>(
    t0: &mut [f32; N],
    t1: &mut [f32; N],
    ray: &SlabRay,
    tmin: f32,
) -> [i32; N] {
    if ray.pad_after {
        for l in 0..N {
            (t0[l], t1[l]) = pad_interval(t0[l], t1[l], tmin);
        }
    }
    let mut miss = [0i32; N];
    for l in 0..N {
        miss[l] = !(t0[l] <= t1[l]) as i32;
    }
    miss
}
