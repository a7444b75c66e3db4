//! Packet traversal of [`KdTree`] (Wald, Slusallek, Benthin & Wagner 2001, "Interactive
//! Rendering with Coherent Ray Tracing") and multi-level ray tracing (Reshetov, Soupikov &
//! Hurley 2005, "Multi-Level Ray Tracing Algorithm"), [`MlrtaKdTree`].
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
//! **Multi-level ray tracing.** Before the walk, the packet's rays are bounded as a beam
//! ([`Beam`]), and the tree is searched for the deepest node that is a valid *entry point*:
//! every non-empty leaf that any of the rays can reach lies below it. From the root down, a
//! child is dropped when its subtree holds no primitive or when the beam cannot enter its cell
//! (inverse frustum culling against the split planes); when both children stay, the near one
//! is searched first and the far one is kept for later. The lanes then start at the entry
//! point, their intervals clipped to its cell, which skips the top of the tree for the whole
//! packet; the far sides kept follow, nearest the entry point first, each taken down the
//! levels where the beam reaches one child only and skipped by the whole beam once every
//! ray's closest hit lies before it. A beam whose search keeps more than a few far sides (it
//! straddles many planes) is subdivided into quarters, each with its own search.
//!
//! **Exactness.** Every answer equals the single-ray one: the leaf test keeps the closest hit
//! over all primitives tested, ties to the lower id ([`rt_geom::replaces`]), so a lane's
//! answer depends only on *which* leaves it tests; each lane tests every leaf its single-ray
//! walk would need (the same padded steps, and an entry-point cell that holds every non-empty
//! leaf the ray can reach, by conservative interval arithmetic).

use crate::beam::Beam;
use crate::lanes::{
    BlockRegs, PacketPrimitive, active_mask, block_width, clip_block, lane_mask, le_bits, load,
    negative_bits, registers, select_lanes, test_block,
};
use crate::{PacketTraversal, RayPacket};
use rt_accel_kd::{KdTree, MAX_DEPTH};
use rt_geom::aabb::PAD;
use rt_geom::{Aabb, Hit, Ray};
use wide::{CmpGt, CmpLe, CmpLt, f32x8};

/// Beams of this many rays or more may be split into quarters where they are not coherent
/// (see [`MLRTA_MAX_CELLS`]).
pub const MLRTA_MIN_SPLIT: usize = 32;

/// Beams of fewer rays start at the root: the search would cost more than it saves.
pub const MLRTA_MIN_BEAM: usize = 64;

/// Beams whose search keeps more far sides than this (the beam straddles many planes: it is
/// not coherent there) are split into quarters; so are beams whose rays go both ways across a
/// plane they straddle (the search stops above the leaves).
pub const MLRTA_MAX_CELLS: usize = 12;

/// A node to start from and its cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EntryPoint {
    /// The node.
    pub node: usize,
    /// The node's cell.
    pub cell: Aabb,
    /// Depth of `node` (the root is 0).
    pub depth: u32,
}

/// The lanes of the block at `base` in `lanes`, traced from node `start` whose cell is `cell`.
/// Each lane's interval starts as its ray clipped to the cell (the single-ray query clips to
/// the root cell the same way); a lane whose closest hit so far lies before the cell skips it.
#[allow(clippy::too_many_arguments)]
fn trace_block<P: PacketPrimitive, const N: usize, const W: usize, const ANY_HIT: bool>(
    tree: &KdTree<P>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
    base: usize,
    lanes: u32,
    start: usize,
    cell: &Aabb,
    stack: &mut Stack,
) {
    // Each lane's ray clipped to the cell, over `[tmin, tmax]` with `tmax` its closest hit so
    // far: a lane whose hit lies before the cell skips it (a cell after the first).
    let (t0, t1, entering) =
        clip_block::<N, W>(&cell.min.to_array(), &cell.max.to_array(), p, base);
    let mut live = lanes & entering;
    if live == 0 {
        return;
    }
    // Split by direction octant: lanes of one octant share the near child at every plane.
    let negative = negative_bits::<N, W>(p, base);
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
        walk::<P, N, W, ANY_HIT>(tree, p, best, base, start, (a, b), octant, stack);
    }
}

/// Pending far cells with each lane's interval: one per level at most, so the depth cap
/// bounds it (the capacity reserved). Reused from block to block.
type Stack = Vec<(u32, BlockRegs, BlockRegs)>;

/// An empty [`Stack`] with room for the deepest tree (one per query, reused by every block).
fn new_stack() -> Stack {
    Vec::with_capacity(MAX_DEPTH as usize + 1)
}

/// One octant group of a block (the other lanes' intervals are empty) from node `start`.
/// The lanes' intervals stay in SIMD registers from step to step.
#[allow(clippy::too_many_arguments)]
fn walk<P: PacketPrimitive, const N: usize, const W: usize, const ANY_HIT: bool>(
    tree: &KdTree<P>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
    base: usize,
    start: usize,
    (mut t0, mut t1): (BlockRegs, BlockRegs),
    octant: u32,
    stack: &mut Stack,
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
            let mut next = [[f32x8::ZERO; 2]; 4];
            let (mut any_near, mut any_far) = (0, 0);
            for h in 0..registers(W) {
                let o = load::<N, W>(&p.origin[axis], base + 8 * h);
                let inv = load::<N, W>(&p.inv_dir[axis], base + 8 * h);
                let [n0, n1, f0, f1] = step8(split, o, inv, t0[h], t1[h]);
                any_near |= n0.cmp_le(n1).move_mask();
                any_far |= f0.cmp_le(f1).move_mask();
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
            let lanes = le_bits::<W>(&t0, &t1) & active(hit);
            let leaf = node
                .leaf_prims(indices)
                .iter()
                .map(|&id| (&prims[id as usize], id));
            hit |= test_block::<P, N, W, ANY_HIT>(leaf, p, best, base, lanes);
        }
        // The next pending cell that some lane enters before its closest hit.
        loop {
            let Some((n, a, b)) = stack.pop() else {
                return;
            };
            // Per lane: active, a non-empty interval, and no hit yet or the cell starting by
            // the closest hit.
            let mut tmax = [f32x8::ZERO; 2];
            for (h, r) in tmax.iter_mut().enumerate().take(registers(W)) {
                *r = load::<N, W>(&p.tmax, base + 8 * h);
            }
            let keep = le_bits::<W>(&a, &b) & (!hit | le_bits::<W>(&a, &tmax)) & active(hit);
            if keep != 0 {
                // The lanes not kept start past their end: an empty interval.
                let mut a = a;
                for (h, r) in a.iter_mut().enumerate().take(registers(W)) {
                    *r = lane_mask(keep >> (8 * h)).blend(*r, f32x8::splat(f32::INFINITY));
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
/// (`rt_accel_kd::traverse::below_first`). `wide`: AVX where the build has it, two SSE halves
/// or scalar code elsewhere.
///
/// Without branches: after a crossing before `t0` (second child only), `lo` is below `t0`, so
/// the second child's start `max(lo, t0)` is `t0` as it must be; `hi.min(t1)` and
/// `lo.max(t0)` are comparisons (a NaN crossing, from a ray lying in the plane, gives the
/// interval's ends).
#[inline(always)]
fn step8(split: f32, o: f32x8, inv: f32x8, t0: f32x8, t1: f32x8) -> [f32x8; 4] {
    let (inf, ninf) = (f32x8::splat(f32::INFINITY), f32x8::splat(f32::NEG_INFINITY));
    let ts = (f32x8::splat(split) - o) * inv;
    // `padded_crossing` lane by lane: the smaller and larger of the two products (a NaN
    // crossing gives NaN either way, as `f32::min` of two NaNs does).
    let (a, b) = (ts * f32x8::splat(1.0 - PAD), ts * f32x8::splat(1.0 + PAD));
    let (lo, hi) = (a.cmp_lt(b).blend(a, b), a.cmp_gt(b).blend(a, b));
    let first_only = lo.cmp_gt(t1);
    let second_only = !first_only & hi.cmp_lt(t0);
    let a0 = second_only.blend(inf, t0);
    let a1 = (first_only | !hi.cmp_lt(t1)).blend(t1, hi);
    let a1 = second_only.blend(ninf, a1);
    let b0 = lo.cmp_gt(t0).blend(lo, t0);
    let b0 = first_only.blend(inf, b0);
    let b1 = first_only.blend(ninf, t1);
    [a0, a1, b0, b1]
}

/// Every block of lanes in `range` from `entry`.
fn trace_from<P: PacketPrimitive, const N: usize, const W: usize, const ANY_HIT: bool>(
    tree: &KdTree<P>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
    range: std::ops::Range<usize>,
    entry: (usize, &Aabb),
    stack: &mut Stack,
) {
    for base in range.step_by(W) {
        let lanes = active_mask::<N, W>(p, base);
        if lanes != 0 {
            let (node, cell) = entry;
            trace_block::<P, N, W, ANY_HIT>(tree, p, best, base, lanes, node, cell, stack);
        }
    }
}

/// Runs `$query::<P, N, W, ANY_HIT>` with the block width of `N`.
macro_rules! with_block_width {
    ($n:expr, $query:ident :: <$p:ty, $any:literal> ($($arg:expr),*)) => {
        if $n % KD_BLOCK == 0 {
            $query::<$p, N, KD_BLOCK, $any>($($arg),*)
        } else if block_width($n) == 8 {
            $query::<$p, N, 8, $any>($($arg),*)
        } else {
            $query::<$p, N, 4, $any>($($arg),*)
        }
    };
}

/// Lanes that walk the kd-tree together (packets of 16 lanes and more).
pub const KD_BLOCK: usize = 16;

/// Plain packet traversal: every block from the root.
impl<P: PacketPrimitive> PacketTraversal for KdTree<P> {
    fn intersect_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [Option<Hit>; N] {
        let mut best = [None; N];
        if !self.nodes().is_empty() {
            let root = (0, &self.bounds());
            with_block_width!(
                N,
                trace_from::<P, false>(self, packet, &mut best, 0..N, root, &mut new_stack())
            );
        }
        best
    }

    fn occluded_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [bool; N] {
        let mut best = [None; N];
        if !self.nodes().is_empty() {
            let root = (0, &self.bounds());
            with_block_width!(
                N,
                trace_from::<P, true>(self, packet, &mut best, 0..N, root, &mut new_stack())
            );
        }
        best.map(|h| h.is_some())
    }
}

/// A kd-tree traced by multi-level ray tracing: packets start at the entry point of their
/// beam. Single rays ([`rt_geom::Accel`]) are the tree's own.
#[derive(Clone, Debug)]
pub struct MlrtaKdTree<P> {
    tree: KdTree<P>,
    /// Per node: whether its subtree references any primitive.
    occupied: Vec<bool>,
}

impl<P: PacketPrimitive> MlrtaKdTree<P> {
    /// Multi-level ray tracing over `tree`.
    pub fn new(tree: KdTree<P>) -> Self {
        let nodes = tree.nodes();
        let mut occupied = vec![false; nodes.len()];
        // Children come after their parent in the depth-first layout.
        for i in (0..nodes.len()).rev() {
            let n = &nodes[i];
            occupied[i] = if n.is_leaf() {
                n.count() > 0
            } else {
                occupied[i + 1] || occupied[n.above()]
            };
        }
        Self { tree, occupied }
    }

    /// The kd-tree.
    pub fn tree(&self) -> &KdTree<P> {
        &self.tree
    }

    /// The cells the beam's rays are traced from, in order: the entry point (the first
    /// non-empty leaf the beam reaches, found by descending near child first), then the far
    /// siblings passed on the way down, deepest first, each taken down to where the beam may
    /// reach both children (the levels where it reaches one child only are skipped). Every
    /// non-empty leaf that any ray of the beam can reach lies below one of them; children the
    /// beam cannot enter, and subtrees without primitives, are left out. Empty when the beam
    /// reaches no primitive.
    pub fn entry_points(&self, beam: &Beam) -> Vec<EntryPoint> {
        let nodes = self.tree.nodes();
        let root = EntryPoint {
            node: 0,
            cell: self.tree.bounds(),
            depth: 0,
        };
        let mut fars = Vec::new();
        if nodes.is_empty() || !self.reaches(beam, &root) {
            return fars;
        }
        let mut at = Some(root);
        while let Some(e) = at.take() {
            let node = &nodes[e.node];
            if node.is_leaf() {
                fars.push(e);
                break;
            }
            let (below, above) = self.children(&e);
            let (b, a) = (self.reaches(beam, &below), self.reaches(beam, &above));
            at = match (b, a, beam.sign(node.axis())) {
                (true, false, _) => Some(below),
                (false, true, _) => Some(above),
                // Both sides: the near one first, the far one after it.
                (true, true, Some(negative)) => {
                    let (near, far) = if negative {
                        (above, below)
                    } else {
                        (below, above)
                    };
                    fars.push(far);
                    Some(near)
                }
                // Both sides, but the rays go both ways: start here.
                (true, true, None) => {
                    fars.push(e);
                    break;
                }
                // Neither: go on with the last far side passed.
                (false, false, _) => fars.pop(),
            };
        }
        fars.reverse();
        // Each far side down to where the beam reaches both children: the lanes start below
        // the levels where it reaches only one (a far side it reaches neither child of holds
        // nothing any lane can hit).
        if fars.len() > 1 {
            let mut deeper = Vec::with_capacity(fars.len());
            deeper.push(fars[0]);
            for &far in &fars[1..] {
                if let Some(e) = self.one_sided(beam, far) {
                    deeper.push(e);
                }
            }
            fars = deeper;
        }
        fars
    }

    /// From `e`, the first node whose both children the beam may reach (or a leaf), through
    /// the ones where it reaches one child only; `None` when it reaches no child.
    fn one_sided(&self, beam: &Beam, mut e: EntryPoint) -> Option<EntryPoint> {
        let nodes = self.tree.nodes();
        loop {
            let node = &nodes[e.node];
            if node.is_leaf() {
                return Some(e);
            }
            let (below, above) = self.children(&e);
            e = match (self.reaches(beam, &below), self.reaches(beam, &above)) {
                (true, false) => below,
                (false, true) => above,
                (true, true) => return Some(e),
                (false, false) => return None,
            };
        }
    }

    /// The children of inner node `e.node`, below and above its plane, with their cells.
    fn children(&self, e: &EntryPoint) -> (EntryPoint, EntryPoint) {
        let node = &self.tree.nodes()[e.node];
        let (below, above) = split_cell(&e.cell, node.axis(), node.split());
        let child = |node, cell| EntryPoint {
            node,
            cell,
            depth: e.depth + 1,
        };
        (child(e.node + 1, below), child(node.above(), above))
    }

    /// Whether the beam may reach a primitive below `e`: the subtree holds some, and the beam
    /// may enter its cell.
    fn reaches(&self, beam: &Beam, e: &EntryPoint) -> bool {
        self.occupied[e.node] && beam.may_enter(&e.cell.min.to_array(), &e.cell.max.to_array())
    }

    /// The lanes of `range`, from the entry points of their beam, or quarter by quarter when
    /// the beam is not coherent (see [`MLRTA_MAX_CELLS`]).
    fn trace_range<const N: usize, const W: usize, const ANY_HIT: bool>(
        &self,
        p: &mut RayPacket<'_, N>,
        best: &mut [Option<Hit>; N],
        range: std::ops::Range<usize>,
        stack: &mut Stack,
    ) {
        if range.len() < MLRTA_MIN_BEAM {
            let root = (0, &self.tree.bounds());
            if !self.tree.nodes().is_empty() {
                trace_from::<P, N, W, ANY_HIT>(&self.tree, p, best, range, root, stack);
            }
            return;
        }
        let mut beam = Beam::new(p, range.clone());
        let entries = self.entry_points(&beam);
        let len = range.len();
        let incoherent = entries.len() > MLRTA_MAX_CELLS
            || entries
                .first()
                .is_some_and(|e| !self.tree.nodes()[e.node].is_leaf());
        if incoherent && len >= MLRTA_MIN_SPLIT && len % (4 * W) == 0 {
            for q in 0..4 {
                let quarter = range.start + q * len / 4..range.start + (q + 1) * len / 4;
                self.trace_range::<N, W, ANY_HIT>(p, best, quarter, stack);
            }
            return;
        }
        for (k, e) in entries.iter().enumerate() {
            if k > 0 {
                // Cells beyond every lane's closest hit so far are culled for the whole beam.
                beam.limit_to_lanes(p, range.clone());
                if !beam.may_enter(&e.cell.min.to_array(), &e.cell.max.to_array()) {
                    continue;
                }
            }
            let entry = (e.node, &e.cell);
            trace_from::<P, N, W, ANY_HIT>(&self.tree, p, best, range.clone(), entry, stack);
        }
    }

    /// [`PacketTraversal::intersect_packet`] with entry points searched for every block of
    /// lanes on its own (the [`KD_BLOCK`] lanes that walk the tree together; 8 or 4 in
    /// smaller packets), from the root, instead of once per packet: the deepest start each
    /// block can have. The same answers; slower in practice, since a search per block costs
    /// more than it saves. Kept to measure what entry points could save at most: the walks
    /// from these starts, without the searches' cost, bound multi-level ray tracing's speed-up
    /// over plain packets (the `mlrta_bound` example). Behind the `research` feature.
    #[cfg(feature = "research")]
    pub fn intersect_packet_per_block<const N: usize>(
        &self,
        packet: &mut RayPacket<'_, N>,
    ) -> [Option<Hit>; N] {
        let mut best = [None; N];
        with_block_width!(N, per_block::<P, false>(self, packet, &mut best));
        best
    }
}

/// Every block of `p` from the entry points of its own beam.
#[cfg(feature = "research")]
fn per_block<P: PacketPrimitive, const N: usize, const W: usize, const ANY_HIT: bool>(
    m: &MlrtaKdTree<P>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
) {
    let stack = &mut new_stack();
    for base in (0..N).step_by(W) {
        if active_mask::<N, W>(p, base) == 0 {
            continue;
        }
        let beam = Beam::new(p, base..base + W);
        for e in m.entry_points(&beam) {
            let live = active_mask::<N, W>(p, base);
            if live != 0 {
                trace_block::<P, N, W, ANY_HIT>(
                    &m.tree, p, best, base, live, e.node, &e.cell, stack,
                );
            }
        }
    }
}

/// The cells below and above a plane.
fn split_cell(cell: &Aabb, axis: usize, split: f32) -> (Aabb, Aabb) {
    let (mut below, mut above) = (*cell, *cell);
    below.max[axis] = split;
    above.min[axis] = split;
    (below, above)
}

/// A helper with the `trace_range` signature of `with_block_width!`.
fn mlrta<P: PacketPrimitive, const N: usize, const W: usize, const ANY_HIT: bool>(
    m: &MlrtaKdTree<P>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
) {
    m.trace_range::<N, W, ANY_HIT>(p, best, 0..N, &mut new_stack());
}

impl<P: PacketPrimitive> PacketTraversal for MlrtaKdTree<P> {
    fn intersect_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [Option<Hit>; N] {
        let mut best = [None; N];
        with_block_width!(N, mlrta::<P, false>(self, packet, &mut best));
        best
    }

    fn occluded_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [bool; N] {
        let mut best = [None; N];
        with_block_width!(N, mlrta::<P, true>(self, packet, &mut best));
        best.map(|h| h.is_some())
    }
}

impl<P: PacketPrimitive> rt_geom::Accel for MlrtaKdTree<P> {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.tree.intersect(ray)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        self.tree.occluded(ray)
    }

    fn stats(&self) -> rt_geom::AccelStats {
        self.tree.stats()
    }

    fn validate(&self) -> Result<(), String> {
        self.tree.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{all_sizes, camera_tiles, conformance_rays, groups};
    use rt_accel_kd::KdParams;
    use rt_testkit::scenes;

    #[test]
    fn conformance_rays_in_packets_equal_single_rays() {
        for scene in scenes::conformance_triangle_scenes() {
            let rays = conformance_rays(&scene.prims, 60, 7);
            for params in [
                KdParams::sah(),
                KdParams::wald_havran(),
                KdParams::midpoint(),
            ] {
                let kd = KdTree::build(&scene.prims, params).unwrap();
                all_sizes(&kd, &rays, &scene.name);
                all_sizes(
                    &MlrtaKdTree::new(kd),
                    &rays,
                    &format!("{} mlrta", scene.name),
                );
            }
        }
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

    /// Packets through the small-leaf tree, single rays and incoherent groups through the
    /// single-ray one: the same answers either way, and both trees' bytes counted.
    #[test]
    fn packets_with_their_own_single_ray_tree() {
        use crate::WithSingleRays;
        use rt_geom::Accel;
        let tris = scenes::triangle_scene("torus").prims;
        let build = |params| KdTree::build(&tris, params).unwrap();
        let pair = WithSingleRays {
            packets: MlrtaKdTree::new(build(KdParams::wald_havran())),
            singles: build(KdParams::sah()),
        };
        let rays = conformance_rays(&tris, 60, 5);
        all_sizes(&pair, &rays, "torus pair");
        groups(&pair, &rays);
        let bytes = |kd: &KdTree<rt_geom::Triangle>| kd.stats().bytes;
        assert_eq!(
            pair.stats().bytes,
            bytes(pair.packets.tree()) + bytes(&pair.singles)
        );
        pair.validate().unwrap();
    }

    /// Blocks that search their own entry points give the single-ray answers too.
    #[cfg(feature = "research")]
    #[test]
    fn per_block_entry_points_equal_single_rays() {
        use rt_geom::Accel;
        fn check<const N: usize>(m: &MlrtaKdTree<rt_geom::Triangle>, rays: &[Ray], what: &str) {
            for (c, chunk) in rays.chunks(N).enumerate() {
                let mut p = RayPacket::<N>::new(chunk);
                let hits = m.intersect_packet_per_block(&mut p);
                p.recycle();
                for (k, r) in chunk.iter().enumerate() {
                    assert_eq!(
                        hits[k],
                        m.intersect(r),
                        "{what}, N = {N}, ray {}",
                        c * N + k
                    );
                }
            }
        }
        let mut sets = Vec::new();
        for scene in scenes::conformance_triangle_scenes() {
            let rays = conformance_rays(&scene.prims, 60, 7);
            sets.push((scene.name, scene.prims, rays));
        }
        let sphere = scenes::tessellated_sphere(5000, rt_geom::Vec3::splat(0.5), 0.4);
        let view = rt_testkit::View::front(&crate::check::bounds(&sphere));
        let camera = view.camera_rays(32, 32);
        let tiles: Vec<Ray> = crate::tiles(32, 32, 16, 16)
            .concat()
            .into_iter()
            .map(|i| camera[i])
            .collect();
        sets.push(("sphere camera".into(), sphere, tiles));
        for (name, prims, rays) in &sets {
            let m = MlrtaKdTree::new(KdTree::build(prims, KdParams::wald_havran()).unwrap());
            check::<4>(&m, rays, name);
            check::<16>(&m, rays, name);
            check::<64>(&m, rays, name);
            check::<256>(&m, rays, name);
        }
    }

    #[test]
    fn entry_points_go_deep_for_a_narrow_beam() {
        // A 4x4 beam aimed at a small part of a big sphere starts in a leaf well below the
        // root, with the far sides passed on the way down after it; a beam that misses
        // everything has no entry point.
        let tris = scenes::tessellated_sphere(20000, rt_geom::Vec3::ZERO, 1.0);
        let m = MlrtaKdTree::new(KdTree::build(&tris, KdParams::sah()).unwrap());
        let o = rt_geom::Vec3::new(0.0, 0.0, 3.0);
        let aim = |dx: f32, dy: f32| {
            let rays: Vec<Ray> = (0..16)
                .map(|i| {
                    let (x, y) = ((i % 4) as f32 * 1e-3, (i / 4) as f32 * 1e-3);
                    Ray::new(o, rt_geom::Vec3::new(dx + x, dy + y, -1.0))
                })
                .collect();
            Beam::new(&RayPacket::<16>::new(&rays), 0..16)
        };
        let beam = aim(0.1, 0.1);
        let e = m.entry_points(&beam);
        assert!(m.tree().nodes()[e[0].node].is_leaf());
        assert!(e[0].depth >= 8, "entry point at depth {}", e[0].depth);
        // The far sides: disjoint cells, each a leaf or a node whose both children the beam
        // may reach.
        assert!(e.len() >= 2, "{e:?}");
        for (i, a) in e.iter().enumerate() {
            for b in &e[i + 1..] {
                let overlap = a.cell.min.max(b.cell.min).cmplt(a.cell.max.min(b.cell.max));
                assert!(!overlap.all(), "{a:?} and {b:?} overlap");
            }
        }
        for f in &e[1..] {
            assert_eq!(m.one_sided(&beam, *f), Some(*f), "{f:?}");
        }
        assert!(m.entry_points(&aim(5.0, 5.0)).is_empty());
    }
}
