//! Packet traversal of the wide BVHs ([`WideBvh`]: `Bvh4`, `Bvh8`), the same first-active-ray
//! descent as [`crate::bvh`] over a wide node's children: each child gets its own range of
//! entering lanes (the parent's range narrowed by the first and last lanes that enter the
//! child's box, the beam culling a child no lane can enter), and the children entered are
//! visited nearest first by the entry of their first lane. Leaves are tested a block of lanes
//! at a time, as in the binary tree, with the same tie rule: every lane's answer equals the
//! wide BVH's single-ray answer.

use crate::api::{each_lane, each_lane_occluded};
use crate::bvh::{Culling, lane_entry, narrow_range, test_leaf};
use crate::lanes::{PacketPrimitive, pad};
use crate::simd::{F8, PacketKernel, Query};
use crate::{PacketTraversal, RayPacket};
use rt_accel_bvh::{NodeLayout, WideBvh, WideNode};
use rt_geom::Hit;

/// A pending child: `(parent node, child slot, first lane, last lane)`, the lanes those in the
/// parent's range that entered the child's box when it was pushed.
type Pending = (u32, u32, u32, u32);

/// The box of child `c` of a wide node, as arrays.
#[inline(always)]
fn child_box<const K: usize>(node: &WideNode<K>, c: usize) -> ([f32; 3], [f32; 3]) {
    (
        [node.min[0][c], node.min[1][c], node.min[2][c]],
        [node.max[0][c], node.max[1][c], node.max[2][c]],
    )
}

/// Lane `i`'s [`lane_entry`] into every child box of `node` at once (up to 8 children, one
/// SIMD lane each): the children it enters, and the entries.
#[inline(always)]
fn lane_entries<V: F8, const K: usize, const N: usize>(
    node: &WideNode<K>,
    p: &RayPacket<'_, N>,
    i: usize,
) -> (u32, [f32; 8]) {
    const { assert!(K <= 8, "wide nodes of at most 8 children") };
    // A function, not a closure: see `rt_geom::isa`.
    #[inline(always)]
    fn row<V: F8, const K: usize>(v: &[f32; K], empty: f32) -> V {
        if K == 8 {
            return V::load(v);
        }
        let mut a = [empty; 8];
        a[..K].copy_from_slice(v);
        V::new(a)
    }
    let mut t0 = V::splat(p.tmin[i]);
    let mut t1 = V::splat(p.tmax[i]);
    for a in 0..3 {
        let (inv_lo, inv_hi) = (p.inv_lo[a][i], p.inv_hi[a][i]);
        let o = V::splat(p.origin[a][i]);
        let t_lo = (row::<V, K>(&node.min[a], f32::INFINITY) - o) * V::splat(inv_lo);
        let t_hi = (row::<V, K>(&node.max[a], f32::NEG_INFINITY) - o) * V::splat(inv_hi);
        let (tn, tf) = if inv_lo.is_sign_negative() {
            (t_hi, t_lo)
        } else {
            (t_lo, t_hi)
        };
        t0 = tn.gt(t0).select(tn, t0);
        t1 = tf.lt(t1).select(tf, t1);
    }
    if p.pad_after {
        (t0, t1) = (pad(t0, false), pad(t1, true));
    }
    let enters = t0.le(t1).bits() & ((1u32 << K) - 1);
    (enters, t0.to_array())
}

/// Pushes the children of node `index` that some lane in `[from, to]` enters, far to near
/// by the entry of their first lane (so the nearest is visited next).
#[inline(always)]
fn expand<V: F8, const K: usize, const N: usize, const W: usize>(
    nodes: &[WideNode<K>],
    index: u32,
    p: &RayPacket<'_, N>,
    culling: &mut Culling,
    (from, to): (usize, usize),
    stack: &mut Vec<Pending>,
) {
    let node = &nodes[index as usize];
    let mut entered = [(0.0f32, (0u32, 0u32, 0u32, 0u32)); K];
    let mut n = 0;
    // The first and the last active lanes against every child at once; the other lanes only
    // where they miss (`entering_range` with those two tests done).
    let Some(first) = (from..=to).find(|&i| p.active[i]) else {
        return;
    };
    let last = (first..=to).rev().find(|&i| p.active[i]).unwrap_or(first);
    let (first_in, first_entry) = lane_entries::<V, K, N>(node, p, first);
    let last_in = lane_entries::<V, K, N>(node, p, last).0;
    for c in (0..K).filter(|&c| node.is_used(c)) {
        let (min, max) = child_box(node, c);
        let b = (&min, &max);
        let first_entry = (first_in >> c & 1 == 1).then_some(first_entry[c]);
        let range = (first, last, to);
        let last_enters = || last_in >> c & 1 == 1;
        let Some((lo, hi, entry)) =
            narrow_range::<V, N, W>(b, p, culling, range, first_entry, last_enters)
        else {
            continue;
        };
        let entry = entry
            .or_else(|| lane_entry(b, p, lo))
            .unwrap_or(f32::INFINITY);
        entered[n] = (entry, (index, c as u32, lo as u32, hi as u32));
        n += 1;
    }
    entered[..n].sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
    stack.extend(entered[..n].iter().map(|e| e.1));
}

/// The one traversal behind both queries, over blocks of `W` lanes, for `K`-wide nodes.
#[inline(always)]
fn traverse<
    V: F8,
    P: PacketPrimitive,
    const K: usize,
    const N: usize,
    const W: usize,
    const ANY_HIT: bool,
>(
    bvh: &WideBvh<P, K>,
    p: &mut RayPacket<'_, N>,
    best: &mut [Option<Hit>; N],
) {
    let tree = bvh.tree();
    let prims = (bvh.prims(), bvh.ids());
    let Some(first) = (0..N).find(|&i| p.active[i]) else {
        return;
    };
    let last = (first..N).rev().find(|&i| p.active[i]).unwrap_or(first);
    if let Some(root) = tree.root_leaf() {
        let b = tree.root_bounds();
        let (min, max) = (b.min.to_array(), b.max.to_array());
        test_leaf::<V, P, N, W, ANY_HIT>(prims, root, (&min, &max), p, best, (first, last));
        return;
    }
    let nodes = tree.nodes();
    if nodes.is_empty() {
        return;
    }
    let mut culling = Culling::new();
    // At most K - 1 pending siblings per level, plus the children of the deepest node.
    let mut stack: Vec<Pending> = Vec::with_capacity((K - 1) * (tree.depth() + 1) + K);
    expand::<V, K, N, W>(nodes, 0, p, &mut culling, (first, last), &mut stack);
    while let Some((parent, c, lo, hi)) = stack.pop() {
        let node = &nodes[parent as usize];
        let c = c as usize;
        let lanes = (lo as usize, hi as usize);
        if node.count[c] > 0 {
            let (min, max) = child_box(node, c);
            let range = (node.child[c], node.count[c]);
            if test_leaf::<V, P, N, W, ANY_HIT>(prims, range, (&min, &max), p, best, lanes) {
                culling.lanes_hit();
            }
        } else {
            expand::<V, K, N, W>(nodes, node.child[c], p, &mut culling, lanes, &mut stack);
        }
    }
}

/// Packets of at most this many lanes go through a wide BVH ray by ray: a wide node's single-ray
/// test already fills the SIMD lanes with its children, and four lanes do not share enough
/// of the packet's per-node work.
pub const WIDE_RAY_BY_RAY: usize = 4;

impl<P: PacketPrimitive, const K: usize> PacketTraversal for WideBvh<P, K> {
    fn ray_by_ray(&self, lanes: usize) -> bool {
        lanes <= WIDE_RAY_BY_RAY
    }

    fn intersect_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [Option<Hit>; N] {
        if N <= WIDE_RAY_BY_RAY {
            return each_lane(self, packet);
        }
        let mut best = [None; N];
        let query = Query::<_, N, false>(self, packet, &mut best);
        crate::simd::run(self.tree().isa(), query);
        best
    }

    fn occluded_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [bool; N] {
        if N <= WIDE_RAY_BY_RAY {
            return each_lane_occluded(self, packet);
        }
        let mut best = [None; N];
        let query = Query::<_, N, true>(self, packet, &mut best);
        crate::simd::run(self.tree().isa(), query);
        best.map(|h| h.is_some())
    }
}

impl<P: PacketPrimitive, const K: usize, const N: usize, const ANY_HIT: bool> PacketKernel
    for Query<'_, '_, WideBvh<P, K>, N, ANY_HIT>
{
    type Output = ();
    #[inline(always)]
    fn run<V: F8>(self) {
        let Query(bvh, p, best) = self;
        by_block_width!(N, W => traverse::<V, P, K, N, W, ANY_HIT>(bvh, p, best));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{all_sizes, camera_tiles, conformance_rays, groups};
    use rt_accel_bvh::{Bvh4, Bvh8, BvhParams};
    use rt_testkit::scenes;

    #[test]
    fn conformance_rays_in_packets_equal_single_rays() {
        // On every instruction set this CPU runs (each level's vectors, `crate::simd`).
        for isa in rt_geom::Isa::available() {
            for scene in scenes::conformance_triangle_scenes() {
                let rays = conformance_rays(&scene.prims, 60, 7);
                let bvh8 = Bvh8::build(&scene.prims, BvhParams::balanced()).unwrap();
                all_sizes(
                    &bvh8.with_isa(isa),
                    &rays,
                    &format!("{} bvh8 {isa}", scene.name),
                );
                let bvh4 = Bvh4::build(&scene.prims, BvhParams::spatial()).unwrap();
                all_sizes(
                    &bvh4.with_isa(isa),
                    &rays,
                    &format!("{} bvh4 {isa}", scene.name),
                );
            }
        }
    }

    #[test]
    fn camera_tiles_groups_shapes_and_empty_equal_single_rays() {
        let tris = scenes::tessellated_sphere(5000, rt_geom::Vec3::splat(0.5), 0.4);
        let bvh8 = Bvh8::build(&tris, BvhParams::balanced()).unwrap();
        camera_tiles(&bvh8, &tris);
        crate::check::enclosed_tiles(|t| Bvh8::build(t, BvhParams::balanced()).unwrap());
        let soup = scenes::random_soup(3000, 9);
        groups(
            &Bvh8::build(&soup, BvhParams::fast()).unwrap(),
            &conformance_rays(&soup, 40, 5),
        );
        let scene = scenes::shape_scene("shapes");
        let rays = conformance_rays(&scene.prims, 60, 3);
        all_sizes(
            &Bvh8::build(&scene.prims, BvhParams::balanced()).unwrap(),
            &rays,
            "shapes",
        );
        // One leaf at the root, and nothing at all.
        let one = Bvh8::build(&tris[..3], BvhParams::balanced()).unwrap();
        all_sizes(&one, &conformance_rays(&tris[..3], 30, 1), "root leaf");
        let empty = Bvh8::<rt_geom::Triangle>::build(&[], BvhParams::balanced()).unwrap();
        assert_eq!(empty.intersect_rays::<4>(&rays[..3]), vec![None; 3]);
    }
}
