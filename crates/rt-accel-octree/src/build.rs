//! Top-down: a node holding more than `max_prims` primitives is split at its centre into
//! eight octants; each primitive goes to every octant it really overlaps (clipped to the
//! octant, not just boxed), empty octants are not stored.

use crate::node::{ChildRef, OctLeaf, OctNode, content_step, octant, quantize_content};
use crate::params::OctreeParams;
use rayon::prelude::*;
use rt_geom::{Aabb, Frame, Primitive};

pub(crate) enum BuildNode {
    /// Primitives and their content box (clipped to the cell).
    Leaf(Vec<u32>, Aabb),
    /// The eight octants (`None` for an empty one) and the union of their content boxes.
    Inner(Box<[Option<BuildNode>; 8]>, Aabb),
}

impl BuildNode {
    fn content(&self) -> Aabb {
        match self {
            BuildNode::Leaf(_, c) | BuildNode::Inner(_, c) => *c,
        }
    }
}

/// A leaf, with the union of its primitives clipped to its cell.
fn leaf<P: Primitive>(ctx: &Ctx<P>, ids: Vec<u32>, bounds: &Aabb) -> BuildNode {
    let content = ids.iter().fold(Aabb::EMPTY, |c, &id| {
        c.union(ctx.frame.clipped_bounds(&ctx.prims[id as usize], bounds))
    });
    BuildNode::Leaf(ids, content.intersection(*bounds))
}

pub(crate) struct Ctx<'a, P> {
    pub prims: &'a [P],
    pub params: &'a OctreeParams,
    /// The frame the cells are in.
    pub frame: Frame,
}

/// The primitives of each octant of `bounds`.
pub(crate) fn distribute<P: Primitive>(ctx: &Ctx<P>, ids: &[u32], bounds: &Aabb) -> [Vec<u32>; 8] {
    let c = bounds.center();
    let boxes: [Aabb; 8] = std::array::from_fn(|i| octant(bounds, i));
    let mut out: [Vec<u32>; 8] = Default::default();
    for &id in ids {
        let p = &ctx.prims[id as usize];
        let b = ctx.frame.clipped_bounds(p, bounds);
        // The octants its (clipped) box reaches; more than one: clip to each.
        let sides = |a: usize| -> [bool; 2] { [b.min[a] <= c[a], b.max[a] >= c[a]] };
        let (sx, sy, sz) = (sides(0), sides(1), sides(2));
        let reach = (0..8).filter(|&i| sx[i & 1] && sy[i >> 1 & 1] && sz[i >> 2 & 1]);
        let single = reach.clone().count() == 1;
        for i in reach {
            if single || !ctx.frame.clipped_bounds(p, &boxes[i]).is_empty() {
                out[i].push(id);
            }
        }
    }
    out
}

/// Builds the subtree of `ids` in `bounds`; `budget` bounds its references (see
/// [`OctreeParams::reference_budget`]).
pub(crate) fn build<P: Primitive>(
    ctx: &Ctx<P>,
    ids: Vec<u32>,
    bounds: Aabb,
    depth: u32,
    budget: usize,
) -> BuildNode {
    let n = ids.len();
    let splittable = bounds.extent().max_element() > 0.0;
    if n <= ctx.params.max_prims as usize || depth >= ctx.params.max_depth || !splittable {
        return leaf(ctx, ids, &bounds);
    }
    let lists = distribute(ctx, &ids, &bounds);
    let total: usize = lists.iter().map(Vec::len).sum();
    // Over budget, or no progress: several non-empty octants, each holding everything (all
    // the primitives cross the centre). One octant holding everything is progress: the other
    // seven are empty space cut away (a scene in one corner of its cube), bounded by the depth.
    let occupied = lists.iter().filter(|l| !l.is_empty()).count();
    if total > budget || (occupied > 1 && lists.iter().all(|l| l.is_empty() || l.len() == n)) {
        return leaf(ctx, ids, &bounds);
    }
    drop(ids);
    // Each octant's share of the budget: at least its count, the shares adding up to it.
    let mut shares = [0usize; 8];
    let mut given = 0usize;
    for (i, l) in lists.iter().enumerate() {
        shares[i] = (budget as u128 * l.len() as u128 / total as u128) as usize;
        given += shares[i];
    }
    if let Some(i) = (0..8).rev().find(|&i| !lists[i].is_empty()) {
        shares[i] += budget - given;
    }
    let make = |(i, l): (usize, Vec<u32>)| {
        (!l.is_empty()).then(|| build(ctx, l, octant(&bounds, i), depth + 1, shares[i]))
    };
    let children: Vec<Option<BuildNode>> = if n > ctx.params.parallel_threshold {
        lists.into_par_iter().enumerate().map(make).collect()
    } else {
        lists.into_iter().enumerate().map(make).collect()
    };
    let children: [Option<BuildNode>; 8] = children.try_into().unwrap_or_else(|_| unreachable!());
    let content = children
        .iter()
        .flatten()
        .fold(Aabb::EMPTY, |c, child| c.union(child.content()));
    BuildNode::Inner(Box::new(children), content)
}

/// The flattened arrays of [`crate::Octree`].
#[derive(Default)]
pub(crate) struct Flat {
    pub nodes: Vec<OctNode>,
    pub leaves: Vec<OctLeaf>,
    pub indices: Vec<u32>,
}

impl Flat {
    /// Flattens the tree `root` of cell `cell`; returns the reference to its root.
    pub fn add_root(&mut self, root: &BuildNode, cell: &Aabb) -> ChildRef {
        match root {
            BuildNode::Leaf(ids, _) => self.add_leaf(ids),
            BuildNode::Inner(children, _) => {
                self.nodes.push(OctNode::new(0, 0));
                self.add_inner(children, cell, 0);
                ChildRef::inner(0)
            }
        }
    }

    fn add_leaf(&mut self, ids: &[u32]) -> ChildRef {
        self.leaves.push(OctLeaf {
            first: self.indices.len() as u32,
            count: ids.len() as u32,
        });
        self.indices.extend_from_slice(ids);
        ChildRef::leaf(self.leaves.len() - 1)
    }

    /// Writes the inner node of `children` (whose cell is `cell`) into `nodes[slot]`: its
    /// leaves at the end of `leaves`, its inner octants contiguously at the end of `nodes`,
    /// then their subtrees depth first.
    fn add_inner(&mut self, children: &[Option<BuildNode>; 8], cell: &Aabb, slot: usize) {
        let inner_base = self.nodes.len();
        let mut node = OctNode::new(inner_base as u32, self.leaves.len() as u32);
        let mut inner = Vec::with_capacity(8);
        for (i, child) in children.iter().enumerate() {
            let Some(child) = child else { continue };
            let b = octant(cell, i);
            let leaf = match child {
                BuildNode::Leaf(ids, _) => {
                    self.add_leaf(ids);
                    true
                }
                BuildNode::Inner(grandchildren, _) => {
                    inner.push((grandchildren, b));
                    false
                }
            };
            let q = quantize_content(&b, content_step(cell), &child.content());
            node.set_octant(i, leaf, q);
        }
        self.nodes[slot] = node;
        self.nodes
            .resize(inner_base + inner.len(), OctNode::new(0, 0));
        for (k, (grandchildren, b)) in inner.into_iter().enumerate() {
            self.add_inner(grandchildren, &b, inner_base + k);
        }
    }
}
