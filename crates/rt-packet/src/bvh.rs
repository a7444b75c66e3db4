//! Packet traversal of [`Bvh`] (Wald, Boulos & Shirley 2007, "Ray Tracing Deformable Scenes
//! Using Dynamic Bounding Volume Hierarchies"): the packet descends together, each node is
//! entered when some active lane hits its box, and the *first active ray* is tracked: lanes
//! before the first one that hits a node cannot hit its children, so the search in a subtree
//! starts there (and, symmetrically, the last one: lanes after it are never tried below).
//! Children are visited near first by that ray's direction on the split axis. When the first
//! active ray misses a node, packets of 64 lanes and more first try their [`Beam`] (interval
//! arithmetic over the whole packet), which culls the node at once when no lane can enter it.
//!
//! Per lane, the box test is the single-ray traversal's (padded slab test against the lane's
//! current closest hit), the primitive kernel is the same and ties go to the lower id
//! ([`rt_geom::replaces`]), so every lane's answer equals `Bvh::intersect` of its ray. At a
//! leaf, the lanes are taken a block of 8 at a time: one slab test for the block, then each
//! primitive against the block's entering lanes ([`PacketPrimitive`]: for triangles, the
//! watertight edge functions of all lanes at once).

use crate::beam::Beam;
use crate::lanes::{PacketPrimitive, enter_mask, test_block};
use crate::simd::{F8, PacketKernel, Query};
use crate::{PacketTraversal, RayPacket};
use rt_accel_bvh::{Bvh, MAX_DEPTH};
use rt_geom::aabb::{pad_down, pad_up};
use rt_geom::{Hit, Walk};

/// Whether lane `i` of `p` enters `node`'s box within its `[tmin, tmax]` (the single-ray
/// traversal's padded slab test, [`rt_geom::aabb::SlabRay::entry`], with the packet's folded
/// reciprocals; NaN from an origin on a slab plane leaves the interval as is).
#[inline(always)]
pub(crate) fn lane_enters<const N: usize>(b: Bounds<'_>, p: &RayPacket<'_, N>, i: usize) -> bool {
    lane_entry(b, p, i).is_some()
}

/// A box as `(min, max)` arrays.
pub(crate) type Bounds<'a> = (&'a [f32; 3], &'a [f32; 3]);

/// Lane `i`'s padded entry into the box `b` when it enters (the single-ray slab test, see
/// [`lane_enters`]).
#[inline(always)]
pub(crate) fn lane_entry<const N: usize>(
    (min, max): Bounds<'_>,
    p: &RayPacket<'_, N>,
    i: usize,
) -> Option<f32> {
    let mut t0 = p.tmin[i];
    let mut t1 = p.tmax[i];
    for a in 0..3 {
        let (inv_lo, inv_hi) = (p.inv_lo[a][i], p.inv_hi[a][i]);
        let (near, far) = if inv_lo.is_sign_negative() {
            ((max[a], inv_hi), (min[a], inv_lo))
        } else {
            ((min[a], inv_lo), (max[a], inv_hi))
        };
        let tn = (near.0 - p.origin[a][i]) * near.1;
        let tf = (far.0 - p.origin[a][i]) * far.1;
        t0 = if tn > t0 { tn } else { t0 };
        t1 = if tf < t1 { tf } else { t1 };
    }
    if p.pad_after {
        (pad_down(t0) <= pad_up(t1)).then_some(pad_down(t0))
    } else {
        (t0 <= t1).then_some(t0)
    }
}

/// A packet's [`Beam`] for culling whole nodes, made when first needed (interval culling pays
/// off for packets of 64 lanes and more only) and ended at the lanes' closest hits so far each
/// time it is asked after lanes hit something: a node behind the surface the packet has hit
/// is culled by one test, not by a slab test of every block of lanes.
pub(crate) struct Culling {
    beam: Option<Beam>,
    /// Lanes hit something since the beam was last limited: their `tmax` shrank.
    stale: bool,
}

impl Culling {
    pub(crate) fn new() -> Self {
        Self {
            beam: None,
            stale: false,
        }
    }

    /// Some lanes' closest hits came nearer (or any-hit lanes are done).
    #[inline(always)]
    pub(crate) fn lanes_hit(&mut self) {
        self.stale = true;
    }

    /// False only when no active lane of `p` can enter the box `node`.
    #[inline(always)]
    fn may_enter<V: F8, const N: usize>(&mut self, node: Bounds<'_>, p: &RayPacket<'_, N>) -> bool {
        if N < 64 {
            return true;
        }
        let beam = match &mut self.beam {
            Some(beam) => {
                if self.stale {
                    beam.limit_to_lanes_on::<V, N>(p, 0..N);
                }
                beam
            }
            none => none.insert(Beam::new_on::<V, N>(p, 0..N)),
        };
        self.stale = false;
        beam.may_enter(node.0, node.1)
    }
}

/// The first and the last active lane in `lanes` (inclusive) that enter `node`, if any: the
/// first active ray is tried alone, and when it misses, the beam may cull the node for the
/// whole packet before the following lanes are tried a block at a time; the last lane is
/// found the same way from the other end.
#[inline(always)]
pub(crate) fn entering_range<V: F8, const N: usize, const W: usize>(
    node: Bounds<'_>,
    p: &RayPacket<'_, N>,
    culling: &mut Culling,
    (from, to): (usize, usize),
) -> Option<(usize, usize)> {
    let first = (from..=to).find(|&i| p.active[i])?;
    let last = (first..=to).rev().find(|&i| p.active[i])?;
    let first_entry = lane_entry(node, p, first);
    let range = narrow_range::<V, N, W>(
        node,
        p,
        culling,
        (first, last, to),
        first_entry,
        #[inline(always)]
        || lane_enters(node, p, last),
    );
    range.map(|(lo, hi, _)| (lo, hi))
}

/// [`entering_range`] from the first and the last active lanes `first`, `last` of a range
/// ending at `to`, once the first lane's entry into `node` (`None`: it misses) is known and
/// the last lane can be asked: the first lane that enters (with its entry when it is
/// `first`) and the last.
#[inline(always)]
pub(crate) fn narrow_range<V: F8, const N: usize, const W: usize>(
    node: Bounds<'_>,
    p: &RayPacket<'_, N>,
    culling: &mut Culling,
    (first, last, to): (usize, usize, usize),
    first_entry: Option<f32>,
    last_enters: impl FnOnce() -> bool,
) -> Option<(usize, usize, Option<f32>)> {
    let lo = match first_entry {
        Some(_) => first,
        None => {
            if !culling.may_enter::<V, N>(node, p) {
                return None;
            }
            scan::<V, N, W>(node, p, first + 1..=to, false)?
        }
    };
    if last == lo || last_enters() {
        return Some((lo, last, first_entry));
    }
    Some((
        lo,
        scan::<V, N, W>(node, p, lo..=last - 1, true)?,
        first_entry,
    ))
}

/// Tests the primitives `first..first + count` (leaf order, with their ids) against the lanes
/// in `[lo, hi]` that enter the box `b`, a block at a time. Returns whether some lane hit
/// (its `tmax` changed).
#[inline(always)]
pub(crate) fn test_leaf<
    V: F8,
    P: PacketPrimitive,
    const N: usize,
    const W: usize,
    const ANY_HIT: bool,
>(
    (prims, ids): (&[P], &[u32]),
    (first, count): (u32, u32),
    b: Bounds<'_>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
    (lo, hi): (usize, usize),
) -> bool {
    let range = first as usize..(first + count) as usize;
    let mut changed = false;
    for base in (lo / W..=hi / W).map(|k| k * W) {
        let lanes = enter_mask::<V, N, W>(b.0, b.1, p, base);
        let leaf = prims[range.clone()]
            .iter()
            .zip(ids[range.clone()].iter().copied());
        changed |= test_block::<V, P, N, W, ANY_HIT>(leaf, p, best, base, lanes) != 0;
    }
    changed
}

/// The first (or with `backwards`, the last) lane in `lanes` that enters `node`, testing a
/// block of lanes at a time.
#[inline(always)]
fn scan<V: F8, const N: usize, const W: usize>(
    (min, max): Bounds<'_>,
    p: &RayPacket<'_, N>,
    lanes: std::ops::RangeInclusive<usize>,
    backwards: bool,
) -> Option<usize> {
    let (lo, hi) = (*lanes.start(), *lanes.end());
    if lo > hi {
        return None;
    }
    // The lanes of the block at `base` that enter, among those inside `lanes` (`base <= hi`
    // for every block). A function, not a closure: see `rt_geom::isa`.
    #[inline(always)]
    fn mask<V: F8, const N: usize, const W: usize>(
        (min, max): Bounds<'_>,
        p: &RayPacket<'_, N>,
        (lo, hi): (usize, usize),
        base: usize,
    ) -> u32 {
        let (from, to) = (lo.saturating_sub(base), (hi - base).min(W - 1));
        let inside = (u32::MAX >> (31 - to)) & (u32::MAX << from);
        enter_mask::<V, N, W>(min, max, p, base) & inside
    }
    let (first_block, last_block) = (lo / W, hi / W);
    if backwards {
        for b in (first_block..=last_block).rev() {
            let m = mask::<V, N, W>((min, max), p, (lo, hi), b * W);
            if m != 0 {
                return Some(b * W + 31 - m.leading_zeros() as usize);
            }
        }
    } else {
        for b in first_block..=last_block {
            let m = mask::<V, N, W>((min, max), p, (lo, hi), b * W);
            if m != 0 {
                return Some(b * W + m.trailing_zeros() as usize);
            }
        }
    }
    None
}

impl<P: PacketPrimitive> PacketTraversal for Bvh<P> {
    fn intersect_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [Option<Hit>; N] {
        let mut best: [Option<Hit>; N] = [None; N];
        let query = Query::<_, N, false>(self, packet, &mut best);
        crate::simd::run(self.isa(), query);
        best
    }

    fn occluded_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [bool; N] {
        let mut best: [Option<Hit>; N] = [None; N];
        let query = Query::<_, N, true>(self, packet, &mut best);
        crate::simd::run(self.isa(), query);
        best.map(|h| h.is_some())
    }
}

impl<P: PacketPrimitive, const N: usize, const ANY_HIT: bool> PacketKernel
    for Query<'_, '_, Bvh<P>, N, ANY_HIT>
{
    type Output = ();
    #[inline(always)]
    fn run<V: F8>(self) {
        let Query(bvh, p, best) = self;
        by_block_width!(N, W => traverse::<V, P, N, W, ANY_HIT>(bvh, p, best));
    }
}

/// The one traversal behind both queries, over blocks of `W` lanes. With `ANY_HIT`, a lane
/// that hits anything is done (made inactive) at once.
#[inline(always)]
fn traverse<V: F8, P: PacketPrimitive, const N: usize, const W: usize, const ANY_HIT: bool>(
    bvh: &Bvh<P>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
) {
    let nodes = bvh.nodes();
    if nodes.is_empty() {
        return;
    }
    let (prims, ids) = (bvh.prims(), bvh.ids());
    let mut culling = Culling::new();
    // Pending far children with the first and last lanes that entered their parent.
    let mut stack = [(0u32, 0u32, 0u32); MAX_DEPTH + 1];
    let mut sp = 0;
    let mut next = Some((0usize, 0usize, N - 1));
    while let Some((index, from, to)) = next.take().or_else(|| {
        (sp > 0).then(|| {
            sp -= 1;
            let (n, a, b) = stack[sp];
            (n as usize, a as usize, b as usize)
        })
    }) {
        let node = &nodes[index];
        let Some((first, last)) =
            entering_range::<V, N, W>((&node.min, &node.max), p, &mut culling, (from, to))
        else {
            continue;
        };
        if node.is_leaf() {
            let leaf = (node.offset, node.count());
            let b = (&node.min, &node.max);
            if test_leaf::<V, P, N, W, ANY_HIT>((prims, ids), leaf, b, p, best, (first, last)) {
                culling.lanes_hit();
            }
            continue;
        }
        // Near child first, by the first entering lane's direction on the split axis.
        let (a, b) = (index + 1, node.offset as usize);
        let (near, far) = if p.inv_dir[node.axis()][first].is_sign_negative() {
            (b, a)
        } else {
            (a, b)
        };
        stack[sp] = (far as u32, first as u32, last as u32);
        sp += 1;
        next = Some((near, first, last));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{all_sizes, conformance_rays};
    use rt_accel_bvh::BvhParams;
    use rt_testkit::scenes;

    #[test]
    fn conformance_rays_in_packets_equal_single_rays() {
        // The adversarial ray families, in file order: packets of mixed directions, rays
        // starting inside boxes, tmin/tmax limits, invalid rays, partial last packets.
        // On every instruction set this CPU runs (each level's vectors, `crate::simd`).
        for isa in rt_geom::Isa::available() {
            for scene in scenes::conformance_triangle_scenes() {
                let bvh = Bvh::build(&scene.prims, BvhParams::balanced()).unwrap();
                let name = format!("{} {isa}", scene.name);
                all_sizes(
                    &bvh.with_isa(isa),
                    &conformance_rays(&scene.prims, 60, 7),
                    &name,
                );
            }
        }
    }

    #[test]
    fn camera_tiles_equal_single_rays() {
        let tris = scenes::tessellated_sphere(5000, rt_geom::Vec3::splat(0.5), 0.4);
        for isa in rt_geom::Isa::available() {
            let bvh = Bvh::build(&tris, BvhParams::balanced()).unwrap();
            crate::check::camera_tiles(&bvh.with_isa(isa), &tris);
            let build = |t: &[rt_geom::Triangle]| Bvh::build(t, BvhParams::balanced()).unwrap();
            crate::check::enclosed_tiles(|t| build(t).with_isa(isa));
        }
    }

    #[test]
    fn groups_of_any_size_equal_single_rays() {
        let tris = scenes::random_soup(3000, 9);
        let bvh = Bvh::build(&tris, BvhParams::balanced()).unwrap();
        crate::check::groups(&bvh, &conformance_rays(&tris, 40, 5));
    }

    #[test]
    fn mixed_shapes_and_empty() {
        let scene = scenes::shape_scene("shapes");
        let bvh = Bvh::build(&scene.prims, BvhParams::balanced()).unwrap();
        all_sizes(&bvh, &conformance_rays(&scene.prims, 60, 3), "shapes");
        let empty = Bvh::<rt_geom::Triangle>::build(&[], BvhParams::balanced()).unwrap();
        let rays = conformance_rays(&scene.prims, 2, 3);
        assert_eq!(empty.intersect_rays::<4>(&rays[..3]), vec![None; 3]);
    }
}
