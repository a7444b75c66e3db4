//! Top-down BSP construction: at each node, candidate planes from a sample of the node's own
//! primitives (autopartition) plus the three axis-aligned planes through the median centroid;
//! each scored by a surface area cost over the bounding boxes of the two convex cells; the
//! cheapest is taken while it beats a leaf.

use super::{BspParams, SplitPlane};
use crate::build::{BuildNode, join, leaf, share_budget};
use rt_geom::{Aabb, Frame, Primitive, Vec3};

/// Where a primitive lies relative to a plane, with the plane's margin as a band.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Side {
    Below,
    Above,
    Both,
    /// Within the band on both sides: in the plane.
    InPlane,
}

/// The side of `p` relative to `plane` (in `frame`).
#[inline]
pub(crate) fn classify<P: Primitive>(p: &P, plane: &SplitPlane, frame: &Frame) -> Side {
    let (lo, hi) = extent(p, plane.normal, frame);
    let (lo, hi) = (lo - plane.d, hi - plane.d);
    let m = plane.margin;
    match (lo >= -m, hi <= m) {
        (true, true) => Side::InPlane,
        (false, true) => Side::Below,
        (true, false) => Side::Above,
        (false, false) => Side::Both,
    }
}

/// The slab `p` occupies along `n` in `frame`: `extent_along` (in `f32`) in the world
/// frame, `extent_along_from` the anchor elsewhere.
#[inline]
fn extent<P: Primitive>(p: &P, n: Vec3, frame: &Frame) -> (f32, f32) {
    if frame.is_world() {
        p.extent_along(n)
    } else {
        p.extent_along_from(frame.anchor, n)
    }
}

/// The bounding box of the part of `cell` below (`n . p <= d`) or above the plane.
pub(crate) fn clip_cell(cell: &Aabb, plane: &SplitPlane, below: bool) -> Aabb {
    if cell.is_empty() {
        return Aabb::EMPTY;
    }
    let corner = |i: usize| {
        Vec3::new(
            if i & 1 == 0 { cell.min.x } else { cell.max.x },
            if i & 2 == 0 { cell.min.y } else { cell.max.y },
            if i & 4 == 0 { cell.min.z } else { cell.max.z },
        )
    };
    let sign = if below { -1.0 } else { 1.0 };
    let dist: [f32; 8] = std::array::from_fn(|i| sign * (plane.normal.dot(corner(i)) - plane.d));
    let mut out = Aabb::EMPTY;
    for (i, &s) in dist.iter().enumerate() {
        if s >= 0.0 {
            out = out.grow(corner(i));
        }
        for bit in [1, 2, 4] {
            let j = i | bit;
            if i & bit == 0 && (s > 0.0) != (dist[j] > 0.0) && s != dist[j] {
                let t = s / (s - dist[j]);
                out = out.grow(corner(i) + (corner(j) - corner(i)) * t);
            }
        }
    }
    out.intersection(*cell)
}

pub(super) struct Ctx<'a, P> {
    pub prims: &'a [P],
    pub params: &'a BspParams,
    pub depth_cap: u32,
    /// Largest absolute coordinate of the scene in `frame`: the scale of the planes' margins.
    pub scale: f32,
    /// The frame the planes and cells are in.
    pub frame: Frame,
}

impl<P> Ctx<'_, P> {
    /// The plane `n . p = d` (in the frame) with its rounding margin: `extent_along_from`
    /// is off by at most its rounding to `f32` (a `gamma(3) (|d| + |n|_1 scale)` for the
    /// default, `extent_along` in `f32`); a margin of `1e-6` times that is safe.
    fn plane(&self, normal: Vec3, d: f32) -> SplitPlane {
        SplitPlane {
            normal,
            d,
            margin: 1e-6 * (d.abs() + normal.abs().element_sum() * self.scale),
        }
    }
}

/// The candidate planes of a node.
fn candidates<P: Primitive>(ctx: &Ctx<P>, ids: &[u32], cell: &Aabb) -> Vec<SplitPlane> {
    let want = ctx.params.candidates as usize;
    let mut planes = Vec::with_capacity(want + 3);
    if let Some(stride) = ids.len().checked_div(want) {
        for &id in ids.iter().step_by(stride.max(1)).take(want) {
            let p = &ctx.prims[id as usize];
            if let Some((n, d)) = p.plane() {
                // The plane's offset in the frame: its own in the world's, elsewhere the
                // middle of the primitive's extent from the anchor.
                let d = if ctx.frame.is_world() {
                    d
                } else {
                    let (lo, hi) = extent(p, n, &ctx.frame);
                    (0.5 * (lo as f64 + hi as f64)) as f32
                };
                planes.push(ctx.plane(n, d));
            }
        }
    }
    if ctx.params.axis_planes {
        let mut c: Vec<f32> = Vec::with_capacity(ids.len());
        for axis in 0..3 {
            c.clear();
            c.extend(
                ids.iter()
                    .map(|&i| ctx.frame.local_point(ctx.prims[i as usize].centroid())[axis]),
            );
            let mid = c.len() / 2;
            let (_, &mut median, _) = c.select_nth_unstable_by(mid, f32::total_cmp);
            if median > cell.min[axis] && median < cell.max[axis] {
                planes.push(ctx.plane(Vec3::AXES[axis], median));
            }
        }
    }
    planes
}

/// The best plane of a node and its cost, with where primitives in the plane go.
fn best_split<P: Primitive>(ctx: &Ctx<P>, ids: &[u32], cell: &Aabb) -> Option<(SplitPlane, bool)> {
    let area = cell.half_area();
    if !(area > 0.0) {
        return None;
    }
    let (kt, ki) = (ctx.params.traversal_cost, ctx.params.intersection_cost);
    let mut best: Option<(f32, SplitPlane, bool)> = None;
    for plane in candidates(ctx, ids, cell) {
        let (mut below, mut above, mut in_plane) = (0usize, 0usize, 0usize);
        for &id in ids {
            match classify(&ctx.prims[id as usize], &plane, &ctx.frame) {
                Side::Below => below += 1,
                Side::Above => above += 1,
                Side::Both => {
                    below += 1;
                    above += 1;
                }
                Side::InPlane => in_plane += 1,
            }
        }
        let a_below = clip_cell(cell, &plane, true).half_area();
        let a_above = clip_cell(cell, &plane, false).half_area();
        let cost =
            |nb: usize, na: usize| kt + ki * (a_below * nb as f32 + a_above * na as f32) / area;
        let (c_below, c_above) = (cost(below + in_plane, above), cost(below, above + in_plane));
        let (c, planar_below) = if c_below <= c_above {
            (c_below, true)
        } else {
            (c_above, false)
        };
        if best.is_none_or(|(bc, ..)| c < bc) {
            best = Some((c, plane, planar_below));
        }
    }
    let leaf_cost = ki * ids.len() as f32;
    best.filter(|(c, ..)| *c < leaf_cost)
        .map(|(_, plane, planar_below)| (plane, planar_below))
}

/// Builds one subtree over `ids` in the convex cell whose bounding box is `cell`.
pub(super) fn build_node<P: Primitive>(
    ctx: &Ctx<P>,
    ids: Vec<u32>,
    cell: Aabb,
    depth: u32,
    budget: usize,
) -> BuildNode<SplitPlane> {
    let n = ids.len();
    if n <= ctx.params.max_leaf_size as usize || depth >= ctx.depth_cap {
        return leaf(ids);
    }
    let Some((plane, planar_below)) = best_split(ctx, &ids, &cell) else {
        return leaf(ids);
    };
    let (mut below, mut above) = (Vec::new(), Vec::new());
    for &id in &ids {
        let side = classify(&ctx.prims[id as usize], &plane, &ctx.frame);
        if matches!(side, Side::Below | Side::Both) || (side == Side::InPlane && planar_below) {
            below.push(id);
        }
        if matches!(side, Side::Above | Side::Both) || (side == Side::InPlane && !planar_below) {
            above.push(id);
        }
    }
    let (nb, na) = (below.len(), above.len());
    if (nb == n && na == n) || nb + na > budget {
        return leaf(ids);
    }
    drop(ids);
    let (budget_below, budget_above) = share_budget(budget, nb, na);
    let (cell_below, cell_above) = (
        clip_cell(&cell, &plane, true),
        clip_cell(&cell, &plane, false),
    );
    let children = join(
        n > ctx.params.parallel_threshold,
        || build_node(ctx, below, cell_below, depth + 1, budget_below),
        || build_node(ctx, above, cell_above, depth + 1, budget_above),
    );
    BuildNode::Inner {
        split: plane,
        children: Box::new(children),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_a_box_by_a_diagonal_plane() {
        let cell = Aabb::new(Vec3::ZERO, Vec3::ONE);
        let n = Vec3::new(1.0, 1.0, 0.0).normalize();
        let plane = SplitPlane {
            normal: n,
            d: n.dot(Vec3::new(0.5, 0.0, 0.0)),
            margin: 0.0,
        };
        // x + y <= 0.5: the corner triangle, box [0, 0.5]^2 x [0, 1].
        let b = clip_cell(&cell, &plane, true);
        assert!((b.max.x - 0.5).abs() < 1e-6 && (b.max.y - 0.5).abs() < 1e-6);
        assert_eq!((b.min, b.max.z), (Vec3::ZERO, 1.0));
        let a = clip_cell(&cell, &plane, false);
        assert_eq!((a.max, a.min.z), (Vec3::ONE, 0.0));
        assert!(a.min.x.abs() < 1e-6 && a.min.y.abs() < 1e-6);
        // A plane missing the box: one side is the box, the other empty.
        let away = SplitPlane {
            normal: Vec3::X,
            d: 5.0,
            margin: 0.0,
        };
        assert_eq!(clip_cell(&cell, &away, true), cell);
        assert!(clip_cell(&cell, &away, false).is_empty());
    }
}
