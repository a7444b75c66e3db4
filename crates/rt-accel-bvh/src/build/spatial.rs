//! Spatial splits (SBVH: Stich, Friedrich & Dietrich, "Spatial Splits in Bounding Volume
//! Hierarchies", HPG 2009).
//!
//! At every node the best binned object split is compared with the best *spatial* split: the
//! node's box is cut into bins along each axis, every reference is clipped into the bins it
//! overlaps ([`Primitive::clipped_bounds`], in the build's [`Frame`]), and the SAH is evaluated from the clipped boxes
//! and the entry/exit counts. Spatial splits are only tried where the two sides of the object
//! split overlap by more than `alpha` of the root's area, and stop once the references have
//! grown by the duplication budget. A primitive straddling the chosen plane is referenced from
//! both sides, each with the box of its part on that side.

use super::sah::{Bins, best_binned};
use super::{BuildNode, PrimRef, split_cost};
use crate::params::{BvhParams, MAX_DEPTH};
use rt_geom::{Aabb, Frame, Primitive};
use std::sync::atomic::{AtomicUsize, Ordering};

thread_local! {
    /// The object-split bins of this thread's nodes.
    static SCRATCH: std::cell::RefCell<Bins> = std::cell::RefCell::default();
}

/// What the spatial builder needs besides the parameters.
struct Ctx<'a, P> {
    prims: &'a [P],
    /// The frame the references' boxes are in.
    frame: &'a Frame,
    params: &'a BvhParams,
    bins: usize,
    /// `alpha` times the root's half area.
    min_overlap: f32,
    /// References that may still be added by splitting.
    budget: AtomicUsize,
}

/// The tree with leaves as lists of primitive indices (a primitive may be in several).
enum Node {
    Leaf(Aabb, Vec<u32>),
    Inner(Aabb, usize, Box<[Node; 2]>),
}

/// Builds with spatial splits; returns the tree, its node count and the leaf-ordered primitive
/// indices (with repetitions) that the leaves' ranges refer to.
pub(crate) fn build<P: Primitive>(
    prims: &[P],
    frame: &Frame,
    refs: Vec<PrimRef>,
    params: &BvhParams,
    bins: u32,
    alpha: f32,
    budget: f32,
) -> (BuildNode, usize, Vec<u32>) {
    let root = super::bounds_of(&refs).0;
    let ctx = Ctx {
        prims,
        frame,
        params,
        bins: bins as usize,
        min_overlap: alpha * root.half_area(),
        budget: AtomicUsize::new((refs.len() as f32 * budget) as usize),
    };
    let tree = node(&ctx, refs, 0);
    let mut order = Vec::new();
    let mut count = 0;
    let root = convert(tree, &mut order, &mut count);
    (root, count, order)
}

fn convert(n: Node, order: &mut Vec<u32>, count: &mut usize) -> BuildNode {
    *count += 1;
    match n {
        Node::Leaf(bounds, ids) => {
            let first = order.len() as u32;
            order.extend(&ids);
            BuildNode::Leaf {
                bounds,
                first,
                count: ids.len() as u32,
            }
        }
        Node::Inner(bounds, axis, children) => {
            let [l, r] = *children;
            let l = convert(l, order, count);
            let r = convert(r, order, count);
            BuildNode::Inner {
                bounds,
                axis,
                children: Box::new([l, r]),
            }
        }
    }
}

fn leaf(bounds: Aabb, refs: &[PrimRef]) -> Node {
    Node::Leaf(bounds, refs.iter().map(PrimRef::index).collect())
}

fn node<P: Primitive>(ctx: &Ctx<'_, P>, mut refs: Vec<PrimRef>, depth: usize) -> Node {
    let n = refs.len();
    let (bounds, centroids) = super::bounds_of(&refs);
    if n <= 1 || depth + 1 >= MAX_DEPTH {
        return leaf(bounds, &refs);
    }
    let params = ctx.params;
    let object = SCRATCH.with_borrow_mut(|scratch| {
        best_binned(&refs, &bounds, &centroids, ctx.bins as u32, params, scratch)
    });
    let overlap = object
        .as_ref()
        .map_or(f32::INFINITY, |o| o.left.intersection(o.right).half_area());
    let spatial = if overlap > ctx.min_overlap && ctx.budget.load(Ordering::Relaxed) > 0 {
        best_spatial(ctx, &refs, &bounds)
    } else {
        None
    };
    let object_cost = object.as_ref().map_or(f32::INFINITY, |o| o.cost);
    let best_cost = object_cost.min(spatial.as_ref().map_or(f32::INFINITY, |s| s.cost));
    let leaf_cost = params.leaf_cost(n);
    if n <= params.max_leaf_size as usize && leaf_cost <= best_cost {
        return leaf(bounds, &refs);
    }
    let (left, right, axis) = match (spatial, object) {
        (Some(s), _) if s.cost < object_cost => match split_refs(ctx, &refs, s.axis, s.plane) {
            Some((l, r)) => (l, r, s.axis),
            None => return object_or_median(ctx, refs, bounds, depth),
        },
        (_, Some(o)) => {
            let (l, r): (Vec<_>, Vec<_>) = refs.iter().partition(|r| o.is_left(r));
            (l, r, o.axis)
        }
        (_, None) => return object_or_median(ctx, refs, bounds, depth),
    };
    drop(std::mem::take(&mut refs));
    let (l, r) = if n > params.parallel_threshold {
        rayon::join(
            || node(ctx, left, depth + 1),
            || node(ctx, right, depth + 1),
        )
    } else {
        (node(ctx, left, depth + 1), node(ctx, right, depth + 1))
    };
    Node::Inner(bounds, axis, Box::new([l, r]))
}

/// No useful SAH split (all centroids equal): split the references in half if they are too
/// many for one leaf.
fn object_or_median<P: Primitive>(
    ctx: &Ctx<'_, P>,
    mut refs: Vec<PrimRef>,
    bounds: Aabb,
    depth: usize,
) -> Node {
    if refs.len() <= ctx.params.max_leaf_size as usize {
        return leaf(bounds, &refs);
    }
    let right = refs.split_off(refs.len() / 2);
    Node::Inner(
        bounds,
        0,
        Box::new([node(ctx, refs, depth + 1), node(ctx, right, depth + 1)]),
    )
}

struct SpatialSplit {
    cost: f32,
    axis: usize,
    plane: f32,
}

/// The cheapest spatial split over equal bins of the node's box along its largest axis (8 bins
/// at most: chopping references into bins is most of the build time, and the other axes
/// rarely win).
fn best_spatial<P: Primitive>(
    ctx: &Ctx<'_, P>,
    refs: &[PrimRef],
    bounds: &Aabb,
) -> Option<SpatialSplit> {
    let k = ctx.bins.min(8);
    let parent = bounds.half_area();
    let mut best: Option<SpatialSplit> = None;
    let mut bin_box = vec![Aabb::EMPTY; k];
    let mut enter = vec![0usize; k];
    let mut exit = vec![0usize; k];
    let mut right_box = vec![Aabb::EMPTY; k];
    {
        let axis = bounds.largest_axis();
        let (lo, hi) = (bounds.min[axis], bounds.max[axis]);
        let width = (hi - lo) / k as f32;
        if !(width > 0.0) {
            return None;
        }
        let plane = |i: usize| if i == k { hi } else { lo + width * i as f32 };
        let bin_of = |x: f32| (((x - lo) / width) as usize).min(k - 1);
        bin_box.fill(Aabb::EMPTY);
        enter.fill(0);
        exit.fill(0);
        for r in refs {
            let bounds = r.bounds();
            let (first, last) = (bin_of(bounds.min[axis]), bin_of(bounds.max[axis]));
            enter[first] += 1;
            exit[last] += 1;
            if first == last {
                bin_box[first] = bin_box[first].union(bounds);
                continue;
            }
            let prim = &ctx.prims[r.index() as usize];
            for (b, slot) in bin_box.iter_mut().enumerate().take(last + 1).skip(first) {
                let mut cell = bounds;
                cell.min[axis] = cell.min[axis].max(plane(b));
                cell.max[axis] = cell.max[axis].min(plane(b + 1));
                *slot = slot.union(ctx.frame.clipped_bounds(prim, &cell));
            }
        }
        let mut acc = Aabb::EMPTY;
        for i in (1..k).rev() {
            acc = acc.union(bin_box[i]);
            right_box[i] = acc;
        }
        let (mut left, mut nl) = (Aabb::EMPTY, 0);
        let mut nr: usize = exit.iter().sum();
        for i in 1..k {
            left = left.union(bin_box[i - 1]);
            nl += enter[i - 1];
            nr -= exit[i - 1];
            if nl == 0 || nr == 0 {
                continue;
            }
            let cost = split_cost(
                ctx.params,
                parent,
                (left.half_area(), nl),
                (right_box[i].half_area(), nr),
            );
            if best.as_ref().is_none_or(|b| cost < b.cost) {
                best = Some(SpatialSplit {
                    cost,
                    axis,
                    plane: plane(i),
                });
            }
        }
    }
    best
}

/// Distributes the references to the two sides of `plane`; a straddling reference goes to both,
/// each with the box of its part on that side. `None` when a side would be empty or would keep
/// every reference (no progress) or the duplication budget is spent.
fn split_refs<P: Primitive>(
    ctx: &Ctx<'_, P>,
    refs: &[PrimRef],
    axis: usize,
    plane: f32,
) -> Option<(Vec<PrimRef>, Vec<PrimRef>)> {
    let (mut left, mut right) = (Vec::new(), Vec::new());
    let mut duplicated = 0;
    for r in refs {
        let bounds = r.bounds();
        if bounds.max[axis] <= plane {
            left.push(*r);
        } else if bounds.min[axis] >= plane {
            right.push(*r);
        } else {
            let prim = &ctx.prims[r.index() as usize];
            let (mut lbox, mut rbox) = (bounds, bounds);
            lbox.max[axis] = plane;
            rbox.min[axis] = plane;
            let clip = |b: &Aabb| ctx.frame.clipped_bounds(prim, b);
            let (lb, rb) = (clip(&lbox), clip(&rbox));
            for (b, side) in [(lb, &mut left), (rb, &mut right)] {
                if !b.is_empty() {
                    side.push(PrimRef::new(b, r.index()));
                }
            }
            if !lb.is_empty() && !rb.is_empty() {
                duplicated += 1;
            }
        }
    }
    let n = refs.len();
    if left.is_empty() || right.is_empty() || left.len() >= n && right.len() >= n {
        return None;
    }
    // Claim the duplicates from the budget; give up on this split if it is spent.
    let claimed = ctx
        .budget
        .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |b| {
            b.checked_sub(duplicated)
        });
    claimed.ok()?;
    Some((left, right))
}
