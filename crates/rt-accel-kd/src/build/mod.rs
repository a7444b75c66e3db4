//! Top-down construction: choose a plane (SAH sweep or a naive rule), partition the node's
//! primitives and events, recurse (subtrees in parallel), then flatten to [`KdNode`]s.
//!
//! Every primitive is kept as its box *clipped to the node* (perfect splits): a primitive that
//! straddles the plane is clipped again to each child and dropped from a child it does not
//! really enter. Primitives that end exactly on the plane go to the side they lie on;
//! primitives lying in the plane go to the side the SAH prefers.

mod events;
mod naive;
mod sah;

use crate::node::KdNode;
use crate::params::{KdBuilder, KdParams};
use events::{AxisEvents, END, PLANAR, START};
use rt_geom::{Aabb, Frame, Primitive};

pub(crate) use events::MAX_LOCAL;

/// A chosen plane.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Split {
    pub axis: usize,
    pub pos: f32,
    /// Primitives lying in the plane go below it (else above).
    pub planar_below: bool,
}

/// The tree before flattening; `S` is the plane (`(axis, position)` for kd-trees, a general
/// plane for BSP trees).
pub(crate) enum BuildNode<S> {
    /// Global primitive indices, ascending.
    Leaf(Vec<u32>),
    Inner {
        split: S,
        children: Box<[BuildNode<S>; 2]>,
    },
}

/// The kd-tree's plane: axis and position.
pub(crate) type AxisPlane = (usize, f32);

/// What a node is built from.
pub(crate) struct NodeInput {
    /// `ids[local]`: the caller's index of the node's primitive `local`.
    pub ids: Vec<u32>,
    pub events: AxisEvents,
    pub bounds: Aabb,
}

/// Shared, read-only state of one build.
pub(crate) struct Ctx<'a, P> {
    pub prims: &'a [P],
    /// The frame node boxes and planes are in.
    pub frame: &'a Frame,
    pub params: &'a KdParams,
    pub depth_cap: u32,
}

/// Builds the tree over all of `prims` inside `bounds` (in `frame`); returns the root.
pub(crate) fn build_tree<P: Primitive>(
    prims: &[P],
    bounds: Aabb,
    params: &KdParams,
    frame: &Frame,
) -> BuildNode<AxisPlane> {
    let n = prims.len();
    let mut events: AxisEvents = std::array::from_fn(|_| Vec::with_capacity(2 * n));
    for (i, p) in prims.iter().enumerate() {
        events::push_box(&mut events, i as u32, &frame.to_local(&p.bounds()));
    }
    events::sort(&mut events);
    let ctx = Ctx {
        prims,
        frame,
        params,
        depth_cap: params.depth_cap(n),
    };
    let input = NodeInput {
        ids: (0..n as u32).collect(),
        events,
        bounds,
    };
    build_node(&ctx, input, 0, root_budget(params.reference_budget, n))
}

/// A leaf, its primitives in ascending order.
pub(crate) fn leaf<S>(mut ids: Vec<u32>) -> BuildNode<S> {
    ids.sort_unstable();
    BuildNode::Leaf(ids)
}

/// The references the whole tree may hold: `factor * n`, at least `n`.
pub(crate) fn root_budget(factor: f32, n: usize) -> usize {
    ((factor as f64 * n as f64).floor() as usize).max(n)
}

/// A node's budget shared by its children in proportion to their counts (`n_below +
/// n_above <= budget`): each child gets at least its count, and the two shares add up to the
/// parent's, so by induction the leaves never hold more than the root's budget.
pub(crate) fn share_budget(budget: usize, n_below: usize, n_above: usize) -> (usize, usize) {
    let below = (budget as u128 * n_below as u128 / (n_below + n_above).max(1) as u128) as usize;
    (below, budget - below)
}

/// Builds the two children, in parallel when the node is large.
pub(crate) fn join<S: Send>(
    parallel: bool,
    below: impl FnOnce() -> BuildNode<S> + Send,
    above: impl FnOnce() -> BuildNode<S> + Send,
) -> [BuildNode<S>; 2] {
    if parallel {
        let (b, a) = rayon::join(below, above);
        [b, a]
    } else {
        [below(), above()]
    }
}

/// Builds one subtree. `budget` bounds the references its leaves may hold (see
/// [`KdParams::reference_budget`]): a split is made only if both children together fit, and
/// the budget is shared in proportion to their counts, so the whole tree stays within the
/// root's.
fn build_node<P: Primitive>(
    ctx: &Ctx<P>,
    input: NodeInput,
    depth: u32,
    budget: usize,
) -> BuildNode<AxisPlane> {
    let n = input.ids.len();
    if n == 0 || depth >= ctx.depth_cap {
        return leaf(input.ids);
    }
    let split = match ctx.params.builder {
        KdBuilder::Sah => sah::best_split(&input, ctx.params),
        KdBuilder::Midpoint | KdBuilder::Centroid => {
            if n <= ctx.params.max_leaf_size as usize {
                None
            } else {
                naive::choose(&input, ctx.params.builder)
            }
        }
    };
    let Some(split) = split else {
        return leaf(input.ids);
    };
    let (below, above) = partition(ctx, &input, split);
    let (nb, na) = (below.ids.len(), above.ids.len());
    // No progress (every primitive on both sides), or over budget: stop here.
    if (nb == n && na == n) || nb + na > budget {
        return leaf(input.ids);
    }
    drop(input);
    let (budget_below, budget_above) = share_budget(budget, nb, na);
    let children = join(
        n > ctx.params.parallel_threshold,
        || build_node(ctx, below, depth + 1, budget_below),
        || build_node(ctx, above, depth + 1, budget_above),
    );
    BuildNode::Inner {
        split: (split.axis, split.pos),
        children: Box::new(children),
    }
}

/// The two halves of `bounds` at `split`.
pub(crate) fn child_bounds(bounds: &Aabb, axis: usize, pos: f32) -> (Aabb, Aabb) {
    let mut below = *bounds;
    let mut above = *bounds;
    below.max[axis] = pos;
    above.min[axis] = pos;
    (below, above)
}

const BELOW: u8 = 1;
const ABOVE: u8 = 2;
const BOTH: u8 = BELOW | ABOVE;
/// Marks a primitive whose events are regenerated from its clipped boxes.
const CLIPPED: u8 = 4;

/// Splits the node's primitives and events. Primitives entirely on one side keep their events
/// (renumbered, still sorted); straddlers are clipped to each child box, their new events
/// sorted and merged in (Wald & Havran's O(N log N) step).
fn partition<P: Primitive>(
    ctx: &Ctx<P>,
    input: &NodeInput,
    split: Split,
) -> (NodeInput, NodeInput) {
    let n = input.ids.len();
    let Split {
        axis,
        pos,
        planar_below,
    } = split;
    // Classify from the events of the split axis (section 4.3 of the paper).
    let mut side = vec![BOTH; n];
    for e in &input.events[axis] {
        let l = e.local() as usize;
        match e.kind() {
            END if e.pos <= pos => side[l] = BELOW,
            START if e.pos >= pos => side[l] = ABOVE,
            PLANAR => {
                side[l] = if e.pos < pos || (e.pos == pos && planar_below) {
                    BELOW
                } else {
                    ABOVE
                }
            }
            _ => {}
        }
    }
    // Clip the straddlers to each child; one may turn out to miss a child entirely.
    let (box_below, box_above) = child_bounds(&input.bounds, axis, pos);
    let mut clipped = Vec::new();
    for (l, s) in side.iter_mut().enumerate() {
        if *s == BOTH {
            let p = &ctx.prims[input.ids[l] as usize];
            let clip = |cell: &Aabb| ctx.frame.clipped_bounds(p, cell);
            let (b, a) = (clip(&box_below), clip(&box_above));
            *s = CLIPPED
                | if b.is_empty() { 0 } else { BELOW }
                | if a.is_empty() { 0 } else { ABOVE };
            clipped.push((l as u32, b, a));
        }
    }
    // Number the primitives of each child.
    const NONE: u32 = u32::MAX;
    let mut local_below = vec![NONE; n];
    let mut local_above = vec![NONE; n];
    let (mut ids_below, mut ids_above) = (Vec::new(), Vec::new());
    for (l, &s) in side.iter().enumerate() {
        if s & BELOW != 0 {
            local_below[l] = ids_below.len() as u32;
            ids_below.push(input.ids[l]);
        }
        if s & ABOVE != 0 {
            local_above[l] = ids_above.len() as u32;
            ids_above.push(input.ids[l]);
        }
    }
    // Events of the one-sided primitives, in order.
    let mut ev_below: AxisEvents = Default::default();
    let mut ev_above: AxisEvents = Default::default();
    for k in 0..3 {
        let all = &input.events[k];
        ev_below[k].reserve(2 * ids_below.len());
        ev_above[k].reserve(2 * ids_above.len());
        for e in all {
            let l = e.local() as usize;
            match side[l] {
                BELOW => ev_below[k].push(e.renumbered(local_below[l])),
                ABOVE => ev_above[k].push(e.renumbered(local_above[l])),
                _ => {} // clipped: new events below
            }
        }
    }
    // New events of the straddlers, sorted, merged in.
    let mut new_below: AxisEvents = Default::default();
    let mut new_above: AxisEvents = Default::default();
    for (l, b, a) in &clipped {
        let l = *l as usize;
        if local_below[l] != NONE {
            events::push_box(&mut new_below, local_below[l], b);
        }
        if local_above[l] != NONE {
            events::push_box(&mut new_above, local_above[l], a);
        }
    }
    events::sort(&mut new_below);
    events::sort(&mut new_above);
    let merge_all = |kept: AxisEvents, new: AxisEvents| -> AxisEvents {
        let [k0, k1, k2] = kept;
        let [n0, n1, n2] = new;
        [
            events::merge(k0, n0),
            events::merge(k1, n1),
            events::merge(k2, n2),
        ]
    };
    (
        NodeInput {
            ids: ids_below,
            events: merge_all(ev_below, new_below),
            bounds: box_below,
        },
        NodeInput {
            ids: ids_above,
            events: merge_all(ev_above, new_above),
            bounds: box_above,
        },
    )
}

/// Flattens the tree depth-first (the child below the plane right after its parent); leaves
/// of more than one primitive get a range of `indices`. `inner(plane, above)` makes the node
/// of a plane whose child above is node `above`.
pub(crate) fn flatten<S>(
    node: &BuildNode<S>,
    nodes: &mut Vec<KdNode>,
    indices: &mut Vec<u32>,
    inner: &mut impl FnMut(&S, u32) -> KdNode,
) {
    match node {
        BuildNode::Leaf(ids) => nodes.push(match ids.len() {
            0 => KdNode::leaf(0, 0),
            1 => KdNode::leaf(1, ids[0]),
            n => {
                let first = indices.len() as u32;
                indices.extend_from_slice(ids);
                KdNode::leaf(n as u32, first)
            }
        }),
        BuildNode::Inner { split, children } => {
            let me = nodes.len();
            nodes.push(KdNode::leaf(0, 0));
            flatten(&children[0], nodes, indices, inner);
            let above = nodes.len() as u32;
            flatten(&children[1], nodes, indices, inner);
            nodes[me] = inner(split, above);
        }
    }
}
