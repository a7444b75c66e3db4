//! Building a [`Bvh`](crate::Bvh): top-down over primitive references, one split strategy per
//! file ([`naive`], [`sah`]), then flattened depth-first into [`BvhNode`]s (pbrt's build →
//! flatten phases).

pub(crate) mod naive;
pub(crate) mod sah;
pub(crate) mod spatial;

use crate::node::BvhNode;
use crate::params::{BvhBuilder, BvhParams, MAX_DEPTH};
use rt_geom::{Aabb, Primitive, Vec3};

/// A primitive as the builders see it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PrimRef {
    pub bounds: Aabb,
    pub centroid: Vec3,
    pub index: u32,
}

/// The tree before flattening. `first` of a leaf indexes the reordered reference array.
pub(crate) enum BuildNode {
    Leaf {
        bounds: Aabb,
        first: u32,
        count: u32,
    },
    Inner {
        bounds: Aabb,
        axis: usize,
        children: Box<[BuildNode; 2]>,
    },
}

/// What a split strategy decides for a range of references.
pub(crate) enum Split {
    /// Make a leaf (the strategy found no split worth its cost).
    Leaf,
    /// The references are partitioned: `[..mid]` left, `[mid..]` right, split along `axis`.
    At { mid: usize, axis: usize },
}

pub(crate) fn prim_refs<P: Primitive>(prims: &[P]) -> Vec<PrimRef> {
    prims
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let bounds = p.bounds();
            PrimRef {
                bounds,
                // The box centre, not P::centroid: builders bin what they bound.
                centroid: bounds.center(),
                index: i as u32,
            }
        })
        .collect()
}

/// Builds the tree over `refs` (reordered in place so that every leaf is a contiguous range).
pub(crate) fn build_tree(refs: &mut [PrimRef], params: &BvhParams) -> (BuildNode, usize) {
    let mut nodes = 0;
    let root = build_range(refs, 0, 0, params, &mut nodes);
    (root, nodes)
}

fn bounds_of(refs: &[PrimRef]) -> (Aabb, Aabb) {
    refs.iter().fold((Aabb::EMPTY, Aabb::EMPTY), |(b, c), r| {
        (b.union(r.bounds), c.grow(r.centroid))
    })
}

fn build_range(
    refs: &mut [PrimRef],
    offset: u32,
    depth: usize,
    params: &BvhParams,
    nodes: &mut usize,
) -> BuildNode {
    *nodes += 1;
    let n = refs.len();
    let (bounds, centroids) = if n > params.parallel_threshold {
        sah::parallel_bounds(refs)
    } else {
        bounds_of(refs)
    };
    let leaf = BuildNode::Leaf {
        bounds,
        first: offset,
        count: n as u32,
    };
    if n <= 1 || depth + 1 >= MAX_DEPTH {
        return leaf;
    }
    let split = match params.builder {
        _ if n <= params.max_leaf_size as usize && params.builder_is_naive() => Split::Leaf,
        BvhBuilder::Midpoint => naive::midpoint(refs, &centroids),
        BvhBuilder::Median => naive::median(refs, &centroids),
        BvhBuilder::BinnedSah { bins } => sah::binned(refs, &bounds, &centroids, bins, params),
        BvhBuilder::SweepSah => sah::sweep(refs, &bounds, params),
    };
    let (mid, axis) = match split {
        Split::At { mid, axis } => (mid, axis),
        Split::Leaf if n <= params.max_leaf_size as usize => return leaf,
        // Too many for one leaf: split at the object median (all centroids may coincide).
        Split::Leaf => match naive::median(refs, &centroids) {
            Split::At { mid, axis } => (mid, axis),
            Split::Leaf => return leaf,
        },
    };
    debug_assert!(mid > 0 && mid < n);
    let (left, right) = refs.split_at_mut(mid);
    let right_offset = offset + mid as u32;
    let (l, r) = if n > params.parallel_threshold {
        let (mut nl, mut nr) = (0, 0);
        let (l, r) = rayon::join(
            || build_range(left, offset, depth + 1, params, &mut nl),
            || build_range(right, right_offset, depth + 1, params, &mut nr),
        );
        *nodes += nl + nr;
        (l, r)
    } else {
        (
            build_range(left, offset, depth + 1, params, nodes),
            build_range(right, right_offset, depth + 1, params, nodes),
        )
    };
    BuildNode::Inner {
        bounds,
        axis,
        children: Box::new([l, r]),
    }
}

impl BvhParams {
    fn builder_is_naive(&self) -> bool {
        matches!(self.builder, BvhBuilder::Midpoint | BvhBuilder::Median)
    }
}

/// Flattens the tree depth-first: the first child follows its parent, the second child's index
/// is stored in the parent.
pub(crate) fn flatten(root: &BuildNode, capacity: usize) -> Vec<BvhNode> {
    let mut nodes = Vec::with_capacity(capacity);
    flatten_into(root, &mut nodes);
    nodes
}

fn flatten_into(node: &BuildNode, nodes: &mut Vec<BvhNode>) -> u32 {
    let index = nodes.len();
    match node {
        BuildNode::Leaf {
            bounds,
            first,
            count,
        } => nodes.push(BvhNode::leaf(*bounds, *first, *count)),
        BuildNode::Inner {
            bounds,
            axis,
            children,
        } => {
            nodes.push(BvhNode::inner(*bounds, 0, *axis));
            flatten_into(&children[0], nodes);
            let second = flatten_into(&children[1], nodes);
            nodes[index] = BvhNode::inner(*bounds, second, *axis);
        }
    }
    index as u32
}

/// SAH cost of splitting into `(left area, left count)` and `(right area, right count)` under a
/// parent of area `parent` (all half areas). A flat or point parent (area 0) weighs both sides
/// fully.
#[inline]
pub(crate) fn split_cost(
    params: &BvhParams,
    parent: f32,
    (al, nl): (f32, usize),
    (ar, nr): (f32, usize),
) -> f32 {
    let inv = if parent > 0.0 { 1.0 / parent } else { 0.0 };
    let (wl, wr) = if parent > 0.0 {
        (al * inv, ar * inv)
    } else {
        (1.0, 1.0)
    };
    params.traversal_cost + params.intersection_cost * (wl * nl as f32 + wr * nr as f32)
}
