//! Packet traversal of [`Bvh`] (Wald, Boulos & Shirley 2007, "Ray Tracing Deformable Scenes
//! Using Dynamic Bounding Volume Hierarchies"): the packet descends together, each node is
//! entered when some active lane hits its box, and the *first active ray* is tracked: lanes
//! before the first one that hits a node cannot hit its children, so the search in a subtree
//! starts there. Children are visited near first by that ray's direction on the split axis.
//! When the first active ray misses a node, packets of 64 lanes and more first try an
//! interval-arithmetic test over the whole packet, which culls the node at once when no lane
//! can enter it.
//!
//! Per lane, the box test is the single-ray traversal's (padded slab test against the lane's
//! current closest hit), the primitive kernel is the same and ties go to the lower id
//! ([`rt_geom::replaces`]), so every lane's answer equals `Bvh::intersect` of its ray.

use crate::RayPacket;
use rt_accel_bvh::{Bvh, BvhNode, MAX_DEPTH};
use rt_geom::aabb::{pad_down, pad_up};
use rt_geom::{Hit, Primitive, Ray, replaces};

/// Whether lane `i` of `p` enters `node`'s box within its `[tmin, tmax]` (the single-ray
/// traversal's padded slab test; NaN from an origin on a slab plane leaves the interval as is).
#[inline(always)]
fn lane_enters<const N: usize>(node: &BvhNode, p: &RayPacket<N>, i: usize) -> bool {
    let mut t0 = p.tmin[i];
    let mut t1 = p.tmax[i];
    for a in 0..3 {
        let inv = p.inv_dir[a][i];
        let (near, far) = if inv.is_sign_negative() {
            (node.max[a], node.min[a])
        } else {
            (node.min[a], node.max[a])
        };
        let tn = (near - p.origin[a][i]) * inv;
        let tf = (far - p.origin[a][i]) * inv;
        t0 = if tn > t0 { tn } else { t0 };
        t1 = if tf < t1 { tf } else { t1 };
    }
    pad_down(t0) <= pad_up(t1)
}

/// Bounds of a packet's rays per axis, for interval-arithmetic culling (Wald, Boulos & Shirley
/// 2007): if even the loosest entry over all lanes lies beyond the tightest exit, no lane
/// enters the box.
struct PacketBounds {
    origin: [(f32, f32); 3],
    /// `(min, max)` of `1 / dir`; `None` when lanes' signs differ or a component is infinite
    /// (that axis then constrains nothing).
    inv: [Option<(f32, f32)>; 3],
    tmin: f32,
    tmax: f32,
}

impl PacketBounds {
    fn new<const N: usize>(p: &RayPacket<N>) -> Self {
        let lanes = || (0..N).filter(|&i| p.active[i]);
        let range = |v: &[f32; N]| {
            lanes().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), i| {
                (lo.min(v[i]), hi.max(v[i]))
            })
        };
        let inv = |a: usize| {
            let (lo, hi) = range(&p.inv_dir[a]);
            let one_sign = lanes().all(|i| p.inv_dir[a][i].is_sign_negative())
                || lanes().all(|i| !p.inv_dir[a][i].is_sign_negative());
            (one_sign && lo.is_finite() && hi.is_finite()).then_some((lo, hi))
        };
        Self {
            origin: [
                range(&p.origin[0]),
                range(&p.origin[1]),
                range(&p.origin[2]),
            ],
            inv: [inv(0), inv(1), inv(2)],
            tmin: range(&p.tmin).0,
            tmax: range(&p.tmax).1,
        }
    }

    /// False only when no lane can enter `node` (the lanes' own padded test would fail for all).
    fn may_enter(&self, node: &BvhNode) -> bool {
        let (mut t0, mut t1) = (self.tmin, self.tmax);
        for a in 0..3 {
            let Some((lo, hi)) = self.inv[a] else {
                continue;
            };
            let (near, far) = if hi < 0.0 || (hi == 0.0 && lo.is_sign_negative()) {
                (node.max[a], node.min[a])
            } else {
                (node.min[a], node.max[a])
            };
            let (o_lo, o_hi) = self.origin[a];
            // Products of the intervals [near - o] x [inv]: the extreme corners.
            let corners = |d_lo: f32, d_hi: f32| {
                let c = [d_lo * lo, d_lo * hi, d_hi * lo, d_hi * hi];
                (
                    c.iter().copied().fold(f32::INFINITY, f32::min),
                    c.iter().copied().fold(f32::NEG_INFINITY, f32::max),
                )
            };
            let (tn_lo, _) = corners(near - o_hi, near - o_lo);
            let (_, tf_hi) = corners(far - o_hi, far - o_lo);
            t0 = t0.max(tn_lo);
            t1 = t1.min(tf_hi);
        }
        // The differences `near - o` round; widen by the same relative pad as the lanes.
        pad_down(pad_down(t0)) <= pad_up(pad_up(t1))
    }
}

/// The first active lane at or after `from` that enters `node`, if any: the first active ray
/// is tried first; when it misses, the interval test may cull the node for the whole packet
/// before the other lanes are tried one by one.
#[inline(always)]
fn first_entering<const N: usize>(
    node: &BvhNode,
    p: &RayPacket<N>,
    bounds: Option<&PacketBounds>,
    from: usize,
) -> Option<usize> {
    let first = (from..N).find(|&i| p.active[i])?;
    if lane_enters(node, p, first) {
        return Some(first);
    }
    if bounds.is_some_and(|b| !b.may_enter(node)) {
        return None;
    }
    (first + 1..N).find(|&i| p.active[i] && lane_enters(node, p, i))
}

/// Packet queries on a BVH. Results are per lane, in the packet's order; inactive lanes miss.
pub trait PacketTraversal {
    /// Closest hit of every lane.
    fn intersect_packet<const N: usize>(&self, packet: &mut RayPacket<N>) -> [Option<Hit>; N];
    /// Whether each lane is blocked (lanes stop as soon as they are).
    fn occluded_packet<const N: usize>(&self, packet: &mut RayPacket<N>) -> [bool; N];

    /// `intersect` of every ray, traced as packets of `N` consecutive rays.
    fn intersect_rays<const N: usize>(&self, rays: &[Ray]) -> Vec<Option<Hit>> {
        let mut out = Vec::with_capacity(rays.len());
        for chunk in rays.chunks(N) {
            let hits = self.intersect_packet(&mut RayPacket::<N>::new(chunk));
            out.extend_from_slice(&hits[..chunk.len()]);
        }
        out
    }

    /// `occluded` of every ray, traced as packets of `N` consecutive rays.
    fn occluded_rays<const N: usize>(&self, rays: &[Ray]) -> Vec<bool> {
        let mut out = Vec::with_capacity(rays.len());
        for chunk in rays.chunks(N) {
            let blocked = self.occluded_packet(&mut RayPacket::<N>::new(chunk));
            out.extend_from_slice(&blocked[..chunk.len()]);
        }
        out
    }
}

/// Packet queries behind a trait object (the registry's packet paths): a group of up to 256
/// rays is traced as one packet of the smallest size that holds it (4, 16, 64 or 256 lanes).
pub trait PacketAccel: Send + Sync {
    /// Closest hit of every ray of the group into `out` (same length, at most 256).
    fn intersect_group(&self, rays: &[Ray], out: &mut [Option<Hit>]);
    /// Whether each ray of the group is blocked.
    fn occluded_group(&self, rays: &[Ray], out: &mut [bool]);
}

/// Largest group [`PacketAccel`] traces as one packet.
pub const MAX_GROUP: usize = 256;

/// Traces `$rays` (at most 256) as one packet of the smallest size that holds them, binding
/// the packet to `$p` in `$query`, and copies the lanes' answers to `$out`.
macro_rules! as_one_packet {
    ($rays:expr, $out:expr, |$p:ident| $query:expr) => {{
        let (rays, out) = ($rays, $out);
        assert!(rays.len() <= MAX_GROUP && rays.len() == out.len());
        let n = rays.len();
        match n {
            0..=4 => {
                let $p = &mut RayPacket::<4>::new(rays);
                out.copy_from_slice(&$query[..n])
            }
            5..=16 => {
                let $p = &mut RayPacket::<16>::new(rays);
                out.copy_from_slice(&$query[..n])
            }
            17..=64 => {
                let $p = &mut RayPacket::<64>::new(rays);
                out.copy_from_slice(&$query[..n])
            }
            _ => {
                let $p = &mut RayPacket::<256>::new(rays);
                out.copy_from_slice(&$query[..n])
            }
        }
    }};
}

impl<P: Primitive> PacketAccel for Bvh<P> {
    fn intersect_group(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        as_one_packet!(rays, out, |p| self.intersect_packet(p))
    }

    fn occluded_group(&self, rays: &[Ray], out: &mut [bool]) {
        as_one_packet!(rays, out, |p| self.occluded_packet(p))
    }
}

impl<P: Primitive> PacketTraversal for Bvh<P> {
    fn intersect_packet<const N: usize>(&self, packet: &mut RayPacket<N>) -> [Option<Hit>; N] {
        let mut best: [Option<Hit>; N] = [None; N];
        traverse::<P, N, false>(self, packet, &mut best);
        best
    }

    fn occluded_packet<const N: usize>(&self, packet: &mut RayPacket<N>) -> [bool; N] {
        let mut best: [Option<Hit>; N] = [None; N];
        traverse::<P, N, true>(self, packet, &mut best);
        best.map(|h| h.is_some())
    }
}

/// The one traversal behind both queries. With `ANY_HIT`, a lane that hits anything is done
/// (made inactive) at once.
fn traverse<P: Primitive, const N: usize, const ANY_HIT: bool>(
    bvh: &Bvh<P>,
    p: &mut RayPacket<N>,
    best: &mut [Option<Hit>; N],
) {
    let nodes = bvh.nodes();
    if nodes.is_empty() {
        return;
    }
    let (prims, ids) = (bvh.prims(), bvh.ids());
    // Interval culling pays off for large packets only.
    let bounds = (N >= 64).then(|| PacketBounds::new(p));
    // Pending far children with the first active lane of their parent.
    let mut stack = [(0u32, 0u32); MAX_DEPTH + 1];
    let mut sp = 0;
    let mut next = Some((0usize, 0usize));
    while let Some((index, from)) = next.take().or_else(|| {
        (sp > 0).then(|| {
            sp -= 1;
            (stack[sp].0 as usize, stack[sp].1 as usize)
        })
    }) {
        let node = &nodes[index];
        let Some(first) = first_entering(node, p, bounds.as_ref(), from) else {
            continue;
        };
        if node.is_leaf() {
            let range = node.offset as usize..(node.offset + node.count()) as usize;
            #[allow(clippy::needless_range_loop)] // lanes index several arrays of the packet
            for lane in first..N {
                if !p.active[lane] || (lane > first && !lane_enters(node, p, lane)) {
                    continue;
                }
                let mut ray = p.rays[lane];
                ray.tmax = p.tmax[lane];
                for i in range.clone() {
                    let Some(h) = prims[i].intersect(&ray) else {
                        continue;
                    };
                    let id = ids[i];
                    if ANY_HIT {
                        best[lane] = Some(Hit::new(h, id));
                        p.active[lane] = false;
                        break;
                    }
                    if replaces(h.t, id, best[lane].as_ref().map(Hit::key)) {
                        best[lane] = Some(Hit::new(h, id));
                        ray.tmax = h.t;
                    }
                }
                p.tmax[lane] = ray.tmax;
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
        stack[sp] = (far as u32, first as u32);
        sp += 1;
        next = Some((near, first));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_accel_bvh::BvhParams;
    use rt_geom::Accel;
    use rt_testkit::scenes;

    /// Every lane of packets of `N` equals the single-ray answer, closest and any hit.
    fn lanes_equal_single_rays<const N: usize, P: Primitive>(
        bvh: &Bvh<P>,
        rays: &[Ray],
        what: &str,
    ) {
        let hits = bvh.intersect_rays::<N>(rays);
        let blocked = bvh.occluded_rays::<N>(rays);
        for (k, r) in rays.iter().enumerate() {
            assert_eq!(hits[k], bvh.intersect(r), "{what}, N = {N}, ray {k}: {r:?}");
            assert_eq!(
                blocked[k],
                bvh.occluded(r),
                "{what}, N = {N}, ray {k}: {r:?}"
            );
        }
    }

    fn all_sizes<P: Primitive>(bvh: &Bvh<P>, rays: &[Ray], what: &str) {
        lanes_equal_single_rays::<4, P>(bvh, rays, what);
        lanes_equal_single_rays::<16, P>(bvh, rays, what);
        lanes_equal_single_rays::<64, P>(bvh, rays, what);
        lanes_equal_single_rays::<256, P>(bvh, rays, what);
    }

    #[test]
    fn conformance_rays_in_packets_equal_single_rays() {
        // The adversarial ray families, in file order: packets of mixed directions, rays
        // starting inside boxes, tmin/tmax limits, invalid rays, partial last packets.
        for scene in scenes::conformance_triangle_scenes() {
            let bvh = Bvh::build(&scene.prims, BvhParams::balanced()).unwrap();
            let reference = rt_geom::BruteForce::build(&scene.prims).unwrap();
            let rays: Vec<Ray> =
                rt_testkit::rays::conformance_rays(&scene.prims, &reference, 60, 7)
                    .into_iter()
                    .map(|t| t.ray)
                    .collect();
            all_sizes(&bvh, &rays, &scene.name);
        }
    }

    #[test]
    fn camera_tiles_equal_single_rays() {
        let tris = scenes::tessellated_sphere(5000, rt_geom::Vec3::splat(0.5), 0.4);
        let bvh = Bvh::build(&tris, BvhParams::balanced()).unwrap();
        let bounds = tris
            .iter()
            .fold(rt_geom::Aabb::EMPTY, |b, t| b.union(t.bounds()));
        let view = rt_testkit::View::front(&bounds);
        let (w, h) = (48, 40);
        let rays = view.camera_rays(w, h);
        for side in crate::TILE_SIDES {
            let tiled: Vec<Ray> = crate::tiles(w, h, side, side)
                .concat()
                .into_iter()
                .map(|i| rays[i])
                .collect();
            all_sizes(&bvh, &tiled, &format!("{side}x{side} tiles"));
        }
    }

    #[test]
    fn groups_of_any_size_equal_single_rays() {
        let tris = scenes::random_soup(3000, 9);
        let bvh = Bvh::build(&tris, BvhParams::balanced()).unwrap();
        let reference = rt_geom::BruteForce::build(&tris).unwrap();
        let rays: Vec<Ray> = rt_testkit::rays::conformance_rays(&tris, &reference, 40, 5)
            .into_iter()
            .map(|t| t.ray)
            .collect();
        let accel: &dyn PacketAccel = &bvh;
        for size in [1, 3, 4, 5, 8, 16, 17, 50, 64, 65, 200, 256] {
            for group in rays.chunks(size) {
                let mut hits = vec![None; group.len()];
                let mut blocked = vec![false; group.len()];
                accel.intersect_group(group, &mut hits);
                accel.occluded_group(group, &mut blocked);
                for (k, r) in group.iter().enumerate() {
                    assert_eq!(hits[k], bvh.intersect(r), "group of {size}");
                    assert_eq!(blocked[k], bvh.occluded(r), "group of {size}");
                }
            }
        }
    }

    #[test]
    fn mixed_shapes_and_empty() {
        let scene = scenes::shape_scene("shapes");
        let bvh = Bvh::build(&scene.prims, BvhParams::balanced()).unwrap();
        let reference = rt_geom::BruteForce::build(&scene.prims).unwrap();
        let rays: Vec<Ray> = rt_testkit::rays::conformance_rays(&scene.prims, &reference, 60, 3)
            .into_iter()
            .map(|t| t.ray)
            .collect();
        all_sizes(&bvh, &rays, "shapes");
        let empty = Bvh::<rt_geom::Triangle>::build(&[], BvhParams::balanced()).unwrap();
        assert_eq!(empty.intersect_rays::<4>(&rays[..3]), vec![None; 3]);
    }
}
