//! Packet traversal of [`KdTree`] (Wald, Slusallek, Benthin & Wagner 2001, "Interactive
//! Rendering with Coherent Ray Tracing"); multi-level ray tracing over the same walk is
//! [`MlrtaKdTree`](crate::MlrtaKdTree).
//!
//! **Packets.** The lanes go through the tree a block of 16 at a time ([`KD_BLOCK`]; 8 or 4 in
//! smaller packets), each lane's interval held in SIMD registers from step to step. Lanes
//! whose directions share their signs on all three axes walk together (a block of mixed signs
//! is split by octant, as Wald et al. split such packets): at an inner node every lane
//! computes its own step at the plane ([`rt_accel_kd::traverse::step`], the single-ray rule,
//! padding included), the near child (by the common signs) is visited by the lanes that reach
//! it, and the far child is pushed with each lane's own interval. A lane leaves a pending cell
//! as soon as its closest hit lies before the cell's entry, as a single ray does; a leaf tests
//! its primitives against all lanes that reach it at once ([`PacketPrimitive`]).
//!
//! **Exactness.** Every lane's answer equals its single ray's: the leaf test keeps the closest
//! hit over all primitives tested, ties to the lower id ([`rt_geom::replaces`]), so a lane's
//! answer depends only on *which* leaves it tests; each lane tests every leaf its single-ray
//! walk would need (the same padded steps at every plane).

use crate::api::{each_lane, each_lane_occluded};
use crate::lanes::{
    BlockRegs, PacketPrimitive, active_mask, block_width, clip_block, le_bits, load, negative_bits,
    registers, select_lanes, test_block,
};
use crate::simd::{F8, PacketKernel, Query};
use crate::{PacketTraversal, RayPacket};
use rt_accel_kd::{KdTree, MAX_DEPTH};
use rt_geom::aabb::PAD;
use rt_geom::{Aabb, Hit, Walk};

/// The lanes of the block at `base` in `lanes`, traced from node `start` whose cell is `cell`.
/// Each lane's interval starts as its ray clipped to the cell (the single-ray query clips to
/// the root cell the same way); a lane whose closest hit so far lies before the cell skips it.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn trace_block<
    V: F8,
    P: PacketPrimitive,
    const N: usize,
    const W: usize,
    const ANY_HIT: bool,
>(
    tree: &KdTree<P>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
    base: usize,
    lanes: u32,
    start: usize,
    cell: &Aabb,
    stack: &mut Stack<V>,
) {
    // Each lane's ray clipped to the cell, over `[tmin, tmax]` with `tmax` its closest hit so
    // far: a lane whose hit lies before the cell skips it (a cell after the first).
    let (t0, t1, entering) =
        clip_block::<V, N, W>(&cell.min.to_array(), &cell.max.to_array(), p, base);
    let mut live = lanes & entering;
    if live == 0 {
        return;
    }
    // Split by direction octant: lanes of one octant share the near child at every plane.
    let negative = negative_bits::<V, N, W>(p, base);
    while live != 0 {
        let first = live.trailing_zeros();
        let mut group = live;
        let mut octant = 0;
        for (a, &neg) in negative.iter().enumerate() {
            let first_negative = neg >> first & 1;
            octant |= first_negative << a;
            group &= if first_negative == 1 { neg } else { !neg };
        }
        live &= !group;
        let (a, b) = (
            select_lanes(group, &t0, f32::INFINITY),
            select_lanes(group, &t1, f32::NEG_INFINITY),
        );
        walk::<V, P, N, W, ANY_HIT>(tree, p, best, base, start, (a, b), octant, stack);
    }
}

/// Pending far cells with each lane's interval: one per level at most, so the depth cap
/// bounds it (the capacity reserved). Reused from block to block.
pub(crate) type Stack<V> = Vec<(u32, BlockRegs<V>, BlockRegs<V>)>;

/// An empty [`Stack`] with room for the deepest tree (one per query, reused by every block).
#[inline(always)]
pub(crate) fn new_stack<V: F8>() -> Stack<V> {
    Vec::with_capacity(MAX_DEPTH as usize + 1)
}

/// One octant group of a block (the other lanes' intervals are empty) from node `start`.
/// The lanes' intervals stay in SIMD registers from step to step.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn walk<V: F8, P: PacketPrimitive, const N: usize, const W: usize, const ANY_HIT: bool>(
    tree: &KdTree<P>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
    base: usize,
    start: usize,
    (mut t0, mut t1): (BlockRegs<V>, BlockRegs<V>),
    octant: u32,
    stack: &mut Stack<V>,
) {
    let (nodes, indices, prims) = (tree.nodes(), tree.indices(), tree.prims());
    // The lanes with a hit so far, kept up to date from the leaf tests; any-hit lanes that hit
    // are done (inactive), other lanes keep their activity for the whole walk.
    let mut hit = 0u32;
    for (l, h) in best[base..base + W].iter().enumerate() {
        hit |= (h.is_some() as u32) << l;
    }
    let active = active_mask::<N, W>(p, base);
    let active = |hit: u32| if ANY_HIT { active & !hit } else { active };
    stack.clear();
    let mut i = start;
    loop {
        let node = &nodes[i];
        if !node.is_leaf() {
            let axis = node.axis();
            let split = node.split();
            let negative = octant >> axis & 1 == 1;
            let (below, above) = (i + 1, node.above());
            let (near, far) = if negative {
                (above, below)
            } else {
                (below, above)
            };
            let mut next = [[V::zero(); 2]; 4];
            let (mut any_near, mut any_far) = (0, 0);
            for h in 0..registers(W) {
                let o = load::<V, N, W>(&p.origin[axis], base + 8 * h);
                let inv = load::<V, N, W>(&p.inv_dir[axis], base + 8 * h);
                let [n0, n1, f0, f1] = step8(split, o, inv, t0[h], t1[h]);
                any_near |= n0.le(n1).bits();
                any_far |= f0.le(f1).bits();
                (next[0][h], next[1][h], next[2][h], next[3][h]) = (n0, n1, f0, f1);
            }
            let [n0, n1, f0, f1] = next;
            if any_near != 0 {
                if any_far != 0 {
                    stack.push((far as u32, f0, f1));
                }
                (i, t0, t1) = (near, n0, n1);
                continue;
            }
            if any_far != 0 {
                (i, t0, t1) = (far, f0, f1);
                continue;
            }
        } else {
            let lanes = le_bits::<V, W>(&t0, &t1) & active(hit);
            let leaf = node
                .leaf_prims(indices)
                .iter()
                .map(|&id| (&prims[id as usize], id));
            hit |= test_block::<V, P, N, W, ANY_HIT>(leaf, p, best, base, lanes);
        }
        // The next pending cell that some lane enters before its closest hit.
        loop {
            let Some((n, a, b)) = stack.pop() else {
                return;
            };
            // Per lane: active, a non-empty interval, and no hit yet or the cell starting by
            // the closest hit.
            let mut tmax = [V::zero(); 2];
            for (h, r) in tmax.iter_mut().enumerate().take(registers(W)) {
                *r = load::<V, N, W>(&p.tmax, base + 8 * h);
            }
            let keep = le_bits::<V, W>(&a, &b) & (!hit | le_bits::<V, W>(&a, &tmax)) & active(hit);
            if keep != 0 {
                // The lanes not kept start past their end: an empty interval.
                let mut a = a;
                for (h, r) in a.iter_mut().enumerate().take(registers(W)) {
                    *r = V::from_bits(keep >> (8 * h)).select(*r, V::splat(f32::INFINITY));
                }
                (i, t0, t1) = (n as usize, a, b);
                break;
            }
        }
    }
}

/// `rt_accel_kd::traverse::step` for 8 lanes over `[t0, t1]` at the plane `split`, as the
/// intervals of the near and the far child: `[near0, near1, far0, far1]`, an empty interval
/// as `(inf, -inf)` (and an empty input interval gives two empty ones). The near child (by the
/// group's direction signs) is the single-ray walk's first child
/// (`rt_accel_kd::traverse::below_first`).
///
/// Without branches: after a crossing before `t0` (second child only), `lo` is below `t0`, so
/// the second child's start `max(lo, t0)` is `t0` as it must be; `hi.min(t1)` and
/// `lo.max(t0)` are comparisons (a NaN crossing, from a ray lying in the plane, gives the
/// interval's ends).
#[inline(always)]
fn step8<V: F8>(split: f32, o: V, inv: V, t0: V, t1: V) -> [V; 4] {
    let (inf, ninf) = (V::splat(f32::INFINITY), V::splat(f32::NEG_INFINITY));
    let ts = (V::splat(split) - o) * inv;
    // `padded_crossing` lane by lane: the smaller and larger of the two products (a NaN
    // crossing gives NaN either way, as `f32::min` of two NaNs does).
    let (a, b) = (ts * V::splat(1.0 - PAD), ts * V::splat(1.0 + PAD));
    let (lo, hi) = (a.lt(b).select(a, b), a.gt(b).select(a, b));
    let first_only = lo.gt(t1);
    let second_only = hi.lt(t0).and_not(first_only);
    let a0 = second_only.select(inf, t0);
    // `hi` where it ends the first child before `t1` (and the plane is crossed in range).
    let a1 = hi.lt(t1).and_not(first_only).select(hi, t1);
    let a1 = second_only.select(ninf, a1);
    let b0 = lo.gt(t0).select(lo, t0);
    let b0 = first_only.select(inf, b0);
    let b1 = first_only.select(ninf, t1);
    [a0, a1, b0, b1]
}

/// Every block of lanes in `range` from `entry`.
#[inline(always)]
pub(crate) fn trace_from<
    V: F8,
    P: PacketPrimitive,
    const N: usize,
    const W: usize,
    const ANY_HIT: bool,
>(
    tree: &KdTree<P>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
    range: std::ops::Range<usize>,
    entry: (usize, &Aabb),
    stack: &mut Stack<V>,
) {
    for base in range.step_by(W) {
        let lanes = active_mask::<N, W>(p, base);
        if lanes != 0 {
            let (node, cell) = entry;
            trace_block::<V, P, N, W, ANY_HIT>(tree, p, best, base, lanes, node, cell, stack);
        }
    }
}

/// Runs `$query::<V, P, N, W, ANY_HIT>` with the block width of `N`.
macro_rules! with_block_width {
    ($n:expr, $query:ident :: <$v:ty, $p:ty, $any:tt> ($($arg:expr),*)) => {
        if $n % KD_BLOCK == 0 {
            $query::<$v, $p, N, KD_BLOCK, $any>($($arg),*)
        } else if block_width($n) == 8 {
            $query::<$v, $p, N, 8, $any>($($arg),*)
        } else {
            $query::<$v, $p, N, 4, $any>($($arg),*)
        }
    };
}
pub(crate) use with_block_width;

/// Lanes that walk the kd-tree together (packets of 16 lanes and more).
pub const KD_BLOCK: usize = 16;

/// Plain packet traversal: every block from the root. A tree whose planes lie in a frame of
/// their own (naive planes far from the origin) traces its lanes one by one: the packet walk
/// computes crossings in world coordinates.
impl<P: PacketPrimitive> PacketTraversal for KdTree<P> {
    fn ray_by_ray(&self, _: usize) -> bool {
        !self.frame().is_world()
    }

    fn intersect_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [Option<Hit>; N] {
        if !self.frame().is_world() {
            return each_lane(self, packet);
        }
        let mut best = [None; N];
        if !self.nodes().is_empty() {
            crate::simd::run(self.isa(), Query::<_, N, false>(self, packet, &mut best));
        }
        best
    }

    fn occluded_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [bool; N] {
        if !self.frame().is_world() {
            return each_lane_occluded(self, packet);
        }
        let mut best = [None; N];
        if !self.nodes().is_empty() {
            crate::simd::run(self.isa(), Query::<_, N, true>(self, packet, &mut best));
        }
        best.map(|h| h.is_some())
    }
}

impl<P: PacketPrimitive, const N: usize, const ANY_HIT: bool> PacketKernel
    for Query<'_, '_, KdTree<P>, N, ANY_HIT>
{
    type Output = ();
    #[inline(always)]
    fn run<V: F8>(self) {
        let Query(tree, p, best) = self;
        let (root, stack) = ((0, &tree.bounds()), &mut new_stack());
        with_block_width!(
            N,
            trace_from::<V, P, ANY_HIT>(tree, p, best, 0..N, root, stack)
        );
    }
}

/// A kd-tree traced by multi-level ray tracing: packets start at the entry point of their
#[cfg(test)]
mod tests {
    use super::*;
    use crate::MlrtaKdTree;
    use crate::check::{all_sizes, camera_tiles, conformance_rays, groups};
    use rt_accel_kd::KdParams;
    use rt_testkit::scenes;

    /// Every conformance scene's rays in packets of every size through kd-trees built with
    /// `params`, plain and with multi-level ray tracing, at every instruction set (one test
    /// per build, so that they run in parallel).
    fn conformance_rays_in_packets(params: KdParams) {
        // On every instruction set this CPU runs (each level's vectors, `crate::simd`).
        for isa in rt_geom::Isa::available() {
            for scene in scenes::conformance_triangle_scenes() {
                let rays = conformance_rays(&scene.prims, 60, 7);
                let kd = KdTree::build(&scene.prims, params).unwrap().with_isa(isa);
                all_sizes(&kd, &rays, &format!("{} {isa}", scene.name));
                let name = format!("{} mlrta {isa}", scene.name);
                all_sizes(&MlrtaKdTree::new(kd), &rays, &name);
            }
        }
    }

    #[test]
    fn conformance_rays_in_packets_equal_single_rays_sah() {
        conformance_rays_in_packets(KdParams::sah());
    }

    #[test]
    fn conformance_rays_in_packets_equal_single_rays_wald_havran() {
        conformance_rays_in_packets(KdParams::wald_havran());
    }

    #[test]
    fn conformance_rays_in_packets_equal_single_rays_midpoint() {
        conformance_rays_in_packets(KdParams::midpoint());
    }

    #[test]
    fn camera_tiles_equal_single_rays() {
        let tris = scenes::tessellated_sphere(5000, rt_geom::Vec3::splat(0.5), 0.4);
        let kd = KdTree::build(&tris, KdParams::sah()).unwrap();
        camera_tiles(&kd, &tris);
        camera_tiles(&MlrtaKdTree::new(kd), &tris);
        let build = |t: &[rt_geom::Triangle]| KdTree::build(t, KdParams::sah()).unwrap();
        crate::check::enclosed_tiles(|t| MlrtaKdTree::new(build(t)));
    }

    #[test]
    fn groups_of_any_size_equal_single_rays() {
        let tris = scenes::random_soup(3000, 9);
        let kd = KdTree::build(&tris, KdParams::sah()).unwrap();
        let rays = conformance_rays(&tris, 40, 5);
        groups(&kd, &rays);
        groups(&MlrtaKdTree::new(kd), &rays);
    }

    #[test]
    fn mixed_shapes_and_empty() {
        let scene = scenes::shape_scene("shapes");
        let kd = KdTree::build(&scene.prims, KdParams::sah()).unwrap();
        let rays = conformance_rays(&scene.prims, 60, 3);
        all_sizes(&kd, &rays, "shapes");
        all_sizes(&MlrtaKdTree::new(kd), &rays, "shapes mlrta");
        let empty = KdTree::<rt_geom::Triangle>::build(&[], KdParams::sah()).unwrap();
        assert_eq!(empty.intersect_rays::<4>(&rays[..3]), vec![None; 3]);
        let empty = MlrtaKdTree::new(empty);
        assert_eq!(empty.intersect_rays::<8>(&rays[..3]), vec![None; 3]);
    }
}
