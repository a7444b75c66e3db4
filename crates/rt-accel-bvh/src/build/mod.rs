//! Building a [`Bvh`](crate::Bvh): top-down over primitive references, one split strategy per
//! file ([`naive`], [`sah`], [`spatial`]), then flattened depth-first into [`BvhNode`]s (pbrt's
//! build → flatten phases), then optionally improved by moving subtrees ([`reinsert`]).

pub(crate) mod naive;
pub(crate) mod reinsert;
pub(crate) mod sah;
pub(crate) mod spatial;

use crate::node::BvhNode;
use crate::params::{BvhBuilder, BvhParams, MAX_DEPTH};
use rt_geom::glam::Vec4;
use rt_geom::{Aabb, Primitive, Vec3};

/// A box in SIMD lanes (x, y, z, unused w): what the builders accumulate per bin and per side.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Box4 {
    pub lo: Vec4,
    pub hi: Vec4,
}

impl Box4 {
    pub const EMPTY: Box4 = Box4 {
        lo: Vec4::INFINITY,
        hi: Vec4::NEG_INFINITY,
    };

    #[inline]
    pub fn union(self, o: Box4) -> Box4 {
        Box4 {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }

    #[inline]
    pub fn grow(self, p: Vec4) -> Box4 {
        Box4 {
            lo: self.lo.min(p),
            hi: self.hi.max(p),
        }
    }

    /// Half the surface area of a non-empty box (the same operations as [`Aabb::half_area`]).
    #[inline]
    pub fn half_area(self) -> f32 {
        let e = self.hi - self.lo;
        e.x * e.y + e.y * e.z + e.z * e.x
    }

    #[inline]
    pub fn aabb(self) -> Aabb {
        Aabb::new(self.lo.truncate(), self.hi.truncate())
    }
}

/// A primitive as the builders see it: its box, and the caller's index in the two `w` lanes
/// (low and high 16 bits, each as an exact float, so that the lanes the SIMD arithmetic carries
/// along are never denormals, which would cost a microcode assist per operation). 32 bytes, two
/// SIMD loads.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PrimRef {
    lo: Vec4,
    hi: Vec4,
}

impl PrimRef {
    #[inline]
    pub fn new(bounds: Aabb, index: u32) -> Self {
        Self {
            lo: bounds.min.extend((index & 0xffff) as f32),
            hi: bounds.max.extend((index >> 16) as f32),
        }
    }

    #[inline]
    pub fn index(&self) -> u32 {
        self.lo.w as u32 | (self.hi.w as u32) << 16
    }

    #[inline]
    pub fn bounds(&self) -> Aabb {
        Aabb::new(self.lo.truncate(), self.hi.truncate())
    }

    /// The box centre in lanes x, y, z (`w` is meaningless): builders bin what they bound.
    #[inline]
    pub fn centroid4(&self) -> Vec4 {
        (self.lo + self.hi) * 0.5
    }

    /// The box centre (equal to `bounds().center()`).
    #[inline]
    pub fn centroid(&self) -> Vec3 {
        self.centroid4().truncate()
    }

    #[inline]
    pub fn box4(&self) -> Box4 {
        Box4 {
            lo: self.lo,
            hi: self.hi,
        }
    }
}

/// The tree before flattening. `first` of a leaf indexes the reordered reference array.
/// Subtrees small enough to be built by one thread come already flattened (`Flat`).
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
    /// Nodes in final depth-first order, but with each inner node's second child counted from
    /// the first node of this chunk (leaves' `first` are final).
    Flat(Vec<BvhNode>),
}

/// Box and centroid box of one side of a split.
pub(crate) type SideBounds = (Aabb, Aabb);

/// What a split strategy decides for a range of references.
pub(crate) enum Split {
    /// Make a leaf (the strategy found no split worth its cost).
    Leaf,
    /// The references are partitioned: `[..mid]` left, `[mid..]` right, split along `axis`;
    /// `sides` are the two sides' boxes when the strategy knows them already.
    At {
        mid: usize,
        axis: usize,
        sides: Option<[SideBounds; 2]>,
    },
}

/// Boxes of references (world coordinates), in parallel for large inputs.
#[cfg(test)]
pub(crate) fn prim_refs<P: Primitive>(prims: &[P]) -> Vec<PrimRef> {
    prim_refs_in(prims, &rt_geom::Frame::WORLD)
}

/// Boxes of references in `frame` (rounded outward), in parallel for large inputs: far from
/// the origin their centres keep the precision binning needs.
pub(crate) fn prim_refs_in<P: Primitive>(prims: &[P], frame: &rt_geom::Frame) -> Vec<PrimRef> {
    use rayon::prelude::*;
    prims
        .par_iter()
        .with_min_len(1 << 14)
        .enumerate()
        .map(|(i, p)| PrimRef::new(frame.to_local(&p.bounds()), i as u32))
        .collect()
}

/// Builds the tree over `refs` (reordered in place so that every leaf is a contiguous range).
pub(crate) fn build_tree(refs: &mut [PrimRef], params: &BvhParams) -> (BuildNode, usize) {
    let mut nodes = 0;
    let sides = side_bounds(refs, params);
    let root = build_range(refs, sides, 0, 0, params, &mut nodes);
    (root, nodes)
}

/// Box and centroid box of `refs` (in parallel above the parallel threshold).
fn side_bounds(refs: &[PrimRef], params: &BvhParams) -> SideBounds {
    if refs.len() > params.parallel_threshold {
        sah::parallel_bounds(refs)
    } else {
        bounds_of(refs)
    }
}

pub(crate) fn bounds_of(refs: &[PrimRef]) -> SideBounds {
    let (b, c) = refs.iter().fold((Box4::EMPTY, Box4::EMPTY), |(b, c), r| {
        (b.union(r.box4()), c.grow(r.centroid4()))
    });
    (b.aabb(), c.aabb())
}

/// How a range of references is split: `None` for a leaf, otherwise the references are
/// partitioned at `mid` along `axis` and the two sides' boxes are returned.
fn decide(
    refs: &mut [PrimRef],
    (bounds, centroids): SideBounds,
    depth: usize,
    params: &BvhParams,
    bins: &mut sah::Bins,
) -> Option<(usize, usize, [SideBounds; 2])> {
    let n = refs.len();
    if n <= 1 || depth + 1 >= MAX_DEPTH {
        return None;
    }
    let split = match params.builder {
        _ if n <= params.max_leaf_size as usize && params.builder_is_naive() => Split::Leaf,
        BvhBuilder::Midpoint => naive::midpoint(refs, &centroids),
        BvhBuilder::Median => naive::median(refs, &centroids),
        BvhBuilder::BinnedSah { bins: k } => {
            sah::binned(refs, &bounds, &centroids, k, params, bins)
        }
        BvhBuilder::SweepSah => sah::sweep(refs, &bounds, params),
    };
    let (mid, axis, sides) = match split {
        Split::At { mid, axis, sides } => (mid, axis, sides),
        Split::Leaf if n <= params.max_leaf_size as usize => return None,
        // Too many for one leaf: split at the object median (all centroids may coincide).
        Split::Leaf => match naive::median(refs, &centroids) {
            Split::At { mid, axis, sides } => (mid, axis, sides),
            Split::Leaf => return None,
        },
    };
    debug_assert!(mid > 0 && mid < n);
    let sides = sides.unwrap_or_else(|| {
        let (left, right) = refs.split_at(mid);
        [side_bounds(left, params), side_bounds(right, params)]
    });
    Some((mid, axis, sides))
}

/// The parallel top of the tree: ranges above the parallel threshold split here and build
/// their two sides with `rayon::join`; smaller ranges become flat chunks ([`build_flat`]).
fn build_range(
    refs: &mut [PrimRef],
    sides: SideBounds,
    offset: u32,
    depth: usize,
    params: &BvhParams,
    nodes: &mut usize,
) -> BuildNode {
    let mut bins = sah::Bins::default();
    if refs.len() <= params.parallel_threshold {
        let mut flat = Vec::new();
        build_flat(refs, sides, offset, depth, params, &mut flat, &mut bins);
        *nodes += flat.len();
        return BuildNode::Flat(flat);
    }
    *nodes += 1;
    let bounds = sides.0;
    let Some((mid, axis, [ls, rs])) = decide(refs, sides, depth, params, &mut bins) else {
        return BuildNode::Leaf {
            bounds,
            first: offset,
            count: refs.len() as u32,
        };
    };
    let (left, right) = refs.split_at_mut(mid);
    let (mut nl, mut nr) = (0, 0);
    let (l, r) = rayon::join(
        || build_range(left, ls, offset, depth + 1, params, &mut nl),
        || build_range(right, rs, offset + mid as u32, depth + 1, params, &mut nr),
    );
    *nodes += nl + nr;
    BuildNode::Inner {
        bounds,
        axis,
        children: Box::new([l, r]),
    }
}

/// Builds a subtree on this thread straight into depth-first nodes appended to `out`; second
/// children are counted from `out`'s first node.
fn build_flat(
    refs: &mut [PrimRef],
    sides: SideBounds,
    offset: u32,
    depth: usize,
    params: &BvhParams,
    out: &mut Vec<BvhNode>,
    bins: &mut sah::Bins,
) {
    let bounds = sides.0;
    let Some((mid, axis, [ls, rs])) = decide(refs, sides, depth, params, bins) else {
        out.push(BvhNode::leaf(bounds, offset, refs.len() as u32));
        return;
    };
    let index = out.len();
    out.push(BvhNode::inner(bounds, 0, axis));
    let (left, right) = refs.split_at_mut(mid);
    build_flat(left, ls, offset, depth + 1, params, out, bins);
    let second = out.len() as u32;
    build_flat(right, rs, offset + mid as u32, depth + 1, params, out, bins);
    out[index] = BvhNode::inner(bounds, second, axis);
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
        BuildNode::Flat(chunk) => nodes.extend(chunk.iter().map(|n| {
            let mut n = *n;
            if !n.is_leaf() {
                n.offset += index as u32;
            }
            n
        })),
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
    params.traversal_cost
        + params.intersection_cost * (wl * params.tests(nl) + wr * params.tests(nr))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_testkit::scenes;

    #[test]
    fn prim_ref_round_trips_index_and_bounds() {
        let b = Aabb::new(Vec3::new(-1.5, 2.0, 1e-30), Vec3::new(3.0, 2.0, 7.25));
        for index in [0, 1, 0xffff, 0x1_0000, 0x1234_5678, u32::MAX - 1] {
            let r = PrimRef::new(b, index);
            assert_eq!(r.index(), index);
            assert_eq!(r.bounds(), b);
            assert_eq!(r.centroid(), b.center());
            assert_eq!(r.box4().half_area(), b.half_area());
        }
    }

    /// The two sides' boxes of a split, as `build_flat` would receive them, must be the boxes
    /// of the references the partition put on each side.
    #[test]
    fn binned_splits_report_their_sides_exactly() {
        let tris = scenes::random_soup(3000, 11);
        for n in [2, 3, 5, 8, 9, 40, 3000] {
            let mut refs = prim_refs(&tris[..n]);
            let (bounds, centroids) = bounds_of(&refs);
            let mut bins = sah::Bins::default();
            let params = BvhParams::balanced();
            let Split::At { mid, sides, .. } =
                sah::binned(&mut refs, &bounds, &centroids, 16, &params, &mut bins)
            else {
                continue;
            };
            let [l, r] = sides.expect("the binned builder knows its sides");
            assert_eq!(l, bounds_of(&refs[..mid]), "n = {n}");
            assert_eq!(r, bounds_of(&refs[mid..]), "n = {n}");
        }
    }

    /// Up to eight references are split by an exact sweep: the same cost as the full sweep
    /// builder's (distinct centroids, so both see the same candidate splits).
    #[test]
    fn small_ranges_get_the_exact_sah_split() {
        let tris = scenes::random_soup(8 * 200, 5);
        let params = BvhParams {
            max_leaf_size: 1,
            ..BvhParams::balanced()
        };
        let cost = |refs: &[PrimRef], split: Split| match split {
            Split::At { mid, .. } => split_cost(
                &params,
                bounds_of(refs).0.half_area(),
                (bounds_of(&refs[..mid]).0.half_area(), mid),
                (bounds_of(&refs[mid..]).0.half_area(), refs.len() - mid),
            ),
            Split::Leaf => f32::INFINITY,
        };
        for (i, group) in tris.chunks(8).enumerate() {
            let n = 2 + i % 7;
            let mut a = prim_refs(&group[..n]);
            let mut b = a.clone();
            let (bounds, centroids) = bounds_of(&a);
            let mut bins = sah::Bins::default();
            let small = sah::binned(&mut a, &bounds, &centroids, 16, &params, &mut bins);
            let sweep = sah::sweep(&mut b, &bounds, &params);
            let (cs, cw) = (cost(&a, small), cost(&b, sweep));
            assert!(
                (cs - cw).abs() <= 1e-5 * cw,
                "n = {n}: small {cs}, sweep {cw}"
            );
        }
    }
}
