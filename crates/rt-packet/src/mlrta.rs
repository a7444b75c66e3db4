//! Multi-level ray tracing (Reshetov, Soupikov & Hurley 2005, "Multi-Level Ray Tracing
//! Algorithm") over the kd-tree's packet walk: [`MlrtaKdTree`].
//!
//! Before the walk, the packet's rays are bounded as a beam ([`Beam`]), and the tree is searched
//! for the deepest node that is a valid *entry point*: every non-empty leaf that any of the rays
//! can reach lies below it. From the root down, a child is dropped when its subtree holds no
//! primitive or when the beam cannot enter its cell (inverse frustum culling against the split
//! planes); when both children stay, the near one is searched first and the far one is kept for
//! later. The lanes then start at the entry point, their intervals clipped to its cell, which skips
//! the top of the tree for the whole packet; the far sides kept follow, nearest the entry point
//! first, each taken down the levels where the beam reaches one child only and skipped by the whole
//! beam once every ray's closest hit lies before it. A beam whose search keeps more than a few far
//! sides (it straddles many planes) is subdivided into quarters, each with its own search.
//!
//! **Exactness.** Every answer equals the single-ray one: the leaf test keeps the closest hit
//! over all primitives tested, ties to the lower id ([`rt_geom::replaces`]), so a lane's
//! answer depends only on *which* leaves it tests; each lane tests every leaf its single-ray
//! walk would need (the same padded steps, and an entry-point cell that holds every non-empty
//! leaf the ray can reach, by conservative interval arithmetic).

use crate::api::{each_lane, each_lane_occluded};
use crate::beam::Beam;
use crate::kd::{KD_BLOCK, Stack, new_stack, trace_from, with_block_width};
use crate::lanes::{PacketPrimitive, block_width};
use crate::simd::{F8, PacketKernel, Query};
use crate::{PacketTraversal, RayPacket};
use rt_accel_kd::KdTree;
use rt_geom::{Aabb, Hit, Ray, Walk};

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
    /// the beam is not coherent (see [`MLRTA_MAX_CELLS`]). The quarters wait in a list, not
    /// in recursive calls, so that the walk inlines into each level's copy of the query
    /// ([`crate::simd`]).
    #[inline(always)]
    fn trace_range<V: F8, const N: usize, const W: usize, const ANY_HIT: bool>(
        &self,
        p: &mut RayPacket<'_, N>,
        best: &mut [Option<Hit>; N],
        range: std::ops::Range<usize>,
        stack: &mut Stack<V>,
    ) {
        let mut ranges = vec![range];
        while let Some(range) = ranges.pop() {
            if range.len() < MLRTA_MIN_BEAM {
                let root = (0, &self.tree.bounds());
                if !self.tree.nodes().is_empty() {
                    trace_from::<V, P, N, W, ANY_HIT>(&self.tree, p, best, range, root, stack);
                }
                continue;
            }
            let mut beam = Beam::new_on::<V, N>(p, range.clone());
            let entries = self.entry_points(&beam);
            let len = range.len();
            let incoherent = entries.len() > MLRTA_MAX_CELLS
                || entries
                    .first()
                    .is_some_and(|e| !self.tree.nodes()[e.node].is_leaf());
            if incoherent && len >= MLRTA_MIN_SPLIT && len % (4 * W) == 0 {
                // Last quarter first onto the list: the first is traced next.
                for q in (0..4).rev() {
                    ranges.push(range.start + q * len / 4..range.start + (q + 1) * len / 4);
                }
                continue;
            }
            for (k, e) in entries.iter().enumerate() {
                if k > 0 {
                    // Cells beyond every lane's closest hit so far are culled for the whole
                    // beam.
                    beam.limit_to_lanes_on::<V, N>(p, range.clone());
                    if !beam.may_enter(&e.cell.min.to_array(), &e.cell.max.to_array()) {
                        continue;
                    }
                }
                let (entry, lanes) = ((e.node, &e.cell), range.clone());
                trace_from::<V, P, N, W, ANY_HIT>(&self.tree, p, best, lanes, entry, stack);
            }
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
        with_block_width!(
            N,
            per_block::<wide::f32x8, P, false>(self, packet, &mut best)
        );
        best
    }
}

/// Every block of `p` from the entry points of its own beam.
#[cfg(feature = "research")]
fn per_block<V: F8, P: PacketPrimitive, const N: usize, const W: usize, const ANY_HIT: bool>(
    m: &MlrtaKdTree<P>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
) {
    use crate::kd::trace_block;
    use crate::lanes::active_mask;
    let stack = &mut new_stack();
    for base in (0..N).step_by(W) {
        if active_mask::<N, W>(p, base) == 0 {
            continue;
        }
        let beam = Beam::new(p, base..base + W);
        for e in m.entry_points(&beam) {
            let live = active_mask::<N, W>(p, base);
            if live != 0 {
                trace_block::<V, P, N, W, ANY_HIT>(
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
#[inline(always)]
fn mlrta<V: F8, P: PacketPrimitive, const N: usize, const W: usize, const ANY_HIT: bool>(
    m: &MlrtaKdTree<P>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
) {
    m.trace_range::<V, N, W, ANY_HIT>(p, best, 0..N, &mut new_stack());
}

impl<P: PacketPrimitive, const N: usize, const ANY_HIT: bool> PacketKernel
    for Query<'_, '_, MlrtaKdTree<P>, N, ANY_HIT>
{
    type Output = ();
    #[inline(always)]
    fn run<V: F8>(self) {
        let Query(m, p, best) = self;
        with_block_width!(N, mlrta::<V, P, ANY_HIT>(m, p, best));
    }
}

/// As the plain packet walk, lanes one by one for a tree whose planes lie in a frame.
impl<P: PacketPrimitive> PacketTraversal for MlrtaKdTree<P> {
    fn ray_by_ray(&self, lanes: usize) -> bool {
        self.tree.ray_by_ray(lanes)
    }

    fn intersect_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [Option<Hit>; N] {
        if !self.tree.frame().is_world() {
            return each_lane(&self.tree, packet);
        }
        let mut best = [None; N];
        crate::simd::run(
            self.tree.isa(),
            Query::<_, N, false>(self, packet, &mut best),
        );
        best
    }

    fn occluded_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [bool; N] {
        if !self.tree.frame().is_world() {
            return each_lane_occluded(&self.tree, packet);
        }
        let mut best = [None; N];
        crate::simd::run(
            self.tree.isa(),
            Query::<_, N, true>(self, packet, &mut best),
        );
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

    fn filtered(&self) -> Option<&dyn rt_geom::FilteredAccel> {
        Some(self)
    }
}

/// Single rays go through the kd-tree, filtered or not.
impl<P: PacketPrimitive> rt_geom::FilteredAccel for MlrtaKdTree<P> {
    fn intersect_filtered(&self, ray: &Ray, filter: &mut dyn rt_geom::HitFilter) -> Option<Hit> {
        self.tree.intersect_filtered(ray, filter)
    }

    fn occluded_filtered(&self, ray: &Ray, filter: &mut dyn rt_geom::HitFilter) -> bool {
        self.tree.occluded_filtered(ray, filter)
    }

    fn intersect_leaving(&self, ray: &Ray, prim: u32) -> Option<Hit> {
        self.tree.intersect_leaving(ray, prim)
    }

    fn occluded_leaving(&self, ray: &Ray, prim: u32) -> bool {
        self.tree.occluded_leaving(ray, prim)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{all_sizes, conformance_rays, groups};
    use rt_accel_kd::KdParams;
    use rt_testkit::scenes;

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
