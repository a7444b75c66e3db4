//! Test helpers shared by the packet paths: every lane's answer against the structure's own
//! single-ray answer.

use crate::{PacketAccel, PacketTraversal, RayPacket};
use rt_geom::{FilteredAccel, Ray, SkipPrim, Triangle};
use rt_testkit::rays::SamplePoints;

/// The conformance suite's adversarial rays for `prims` (hits, misses, grazing, inside,
/// limited intervals, invalid rays), in file order.
pub fn conformance_rays<P: SamplePoints>(prims: &[P], per_family: usize, seed: u64) -> Vec<Ray> {
    let reference = rt_geom::BruteForce::build(prims).unwrap();
    rt_testkit::rays::conformance_rays(prims, &reference, per_family, seed)
        .into_iter()
        .map(|t| t.ray)
        .collect()
}

/// Every lane of packets of `N` equals the single-ray answer, closest and any hit; and with
/// every other ray leaving the primitive it hits first ([`RayPacket::leaving`]), the single
/// ray's filtered answer skipping it.
pub fn lanes_equal_single_rays<const N: usize, T: PacketTraversal + FilteredAccel>(
    accel: &T,
    rays: &[Ray],
    what: &str,
) {
    let hits = accel.intersect_rays::<N>(rays);
    let blocked = accel.occluded_rays::<N>(rays);
    for (k, r) in rays.iter().enumerate() {
        assert_eq!(
            hits[k],
            accel.intersect(r),
            "{what}, N = {N}, ray {k}: {r:?}"
        );
        assert_eq!(
            blocked[k],
            accel.occluded(r),
            "{what}, N = {N}, ray {k}: {r:?}"
        );
    }
    let leaving = leaving_every_other(&hits);
    for (chunk, leaves) in rays.chunks(N).zip(leaving.chunks(N)) {
        let mut p = RayPacket::<N>::leaving(chunk, leaves);
        let hits = accel.intersect_packet(&mut p);
        let mut p = RayPacket::<N>::leaving(chunk, leaves);
        let blocked = accel.occluded_packet(&mut p);
        for (k, (r, l)) in chunk.iter().zip(leaves).enumerate() {
            let skip = || SkipPrim(l.unwrap_or(u32::MAX));
            let want = accel.intersect_filtered(r, &mut skip());
            assert_eq!(hits[k], want, "{what}, N = {N}, leaving {l:?}: {r:?}");
            let want = accel.occluded_filtered(r, &mut skip());
            assert_eq!(blocked[k], want, "{what}, N = {N}, leaving {l:?}: {r:?}");
        }
    }
}

/// Every other ray leaves the primitive it hits first (so that skipping it changes the
/// answer), the rest leave none.
fn leaving_every_other(hits: &[Option<rt_geom::Hit>]) -> Vec<Option<u32>> {
    let leaves = |(k, h): (usize, &Option<rt_geom::Hit>)| h.filter(|_| k % 2 == 0).map(|h| h.prim);
    hits.iter().enumerate().map(leaves).collect()
}

/// [`lanes_equal_single_rays`] for packets of 4, 8, 16, 64 and 256.
pub fn all_sizes<T: PacketTraversal + FilteredAccel>(accel: &T, rays: &[Ray], what: &str) {
    lanes_equal_single_rays::<4, T>(accel, rays, what);
    lanes_equal_single_rays::<8, T>(accel, rays, what);
    lanes_equal_single_rays::<16, T>(accel, rays, what);
    lanes_equal_single_rays::<64, T>(accel, rays, what);
    lanes_equal_single_rays::<256, T>(accel, rays, what);
}

/// A front camera's rays over `tris`, cut into tiles of every [`crate::TILE_SIDES`] size.
pub fn camera_tiles<T: PacketTraversal + FilteredAccel>(accel: &T, tris: &[Triangle]) {
    view_tiles(accel, rt_testkit::View::front(&bounds(tris)));
}

/// A random soup inside a closed sphere, and a camera inside it: every ray of every tile hits
/// something, so a packet's closest hits so far bound it (what culls nodes behind them).
pub fn enclosed_tiles<T: PacketTraversal + FilteredAccel>(build: impl Fn(&[Triangle]) -> T) {
    let center = rt_geom::Vec3::splat(0.5);
    let mut tris = rt_testkit::scenes::tessellated_sphere(2000, center, 1.0);
    tris.extend(rt_testkit::scenes::random_soup(2000, 11));
    view_tiles(&build(&tris), rt_testkit::View::interior(&bounds(&tris)));
}

/// The box around `tris`.
pub fn bounds(tris: &[Triangle]) -> rt_geom::Aabb {
    tris.iter()
        .fold(rt_geom::Aabb::EMPTY, |b, t| b.union(t.bounds()))
}

/// `view`'s rays cut into tiles of every [`crate::TILE_SIDES`] size, in packets of every size.
fn view_tiles<T: PacketTraversal + FilteredAccel>(accel: &T, view: rt_testkit::View) {
    let (w, h) = (48, 40);
    let rays = view.camera_rays(w, h);
    for side in crate::TILE_SIDES {
        let tiled: Vec<Ray> = crate::tiles(w, h, side, side)
            .concat()
            .into_iter()
            .map(|i| rays[i])
            .collect();
        all_sizes(accel, &tiled, &format!("{side}x{side} tiles"));
    }
}

/// Groups of every size up to [`crate::MAX_GROUP`] through the trait object.
pub fn groups<T: PacketAccel + FilteredAccel>(accel: &T, rays: &[Ray]) {
    let dynamic: &dyn PacketAccel = accel;
    let leaving_groups = dynamic
        .leaving()
        .expect("rt's packet paths skip primitives");
    let first: Vec<_> = rays.iter().map(|r| accel.intersect(r)).collect();
    let leaving = leaving_every_other(&first);
    for size in [1, 3, 4, 5, 8, 16, 17, 50, 64, 65, 200, 256] {
        for group in rays.chunks(size) {
            let mut hits = vec![None; group.len()];
            let mut blocked = vec![false; group.len()];
            // Forced packets, and packets or single rays by coherence.
            dynamic.intersect_packet_group(group, &mut hits);
            dynamic.occluded_packet_group(group, &mut blocked);
            for (k, r) in group.iter().enumerate() {
                assert_eq!(hits[k], accel.intersect(r), "group of {size}");
                assert_eq!(blocked[k], accel.occluded(r), "group of {size}");
            }
            dynamic.intersect_group(group, &mut hits);
            dynamic.occluded_group(group, &mut blocked);
            for (k, r) in group.iter().enumerate() {
                assert_eq!(hits[k], accel.intersect(r), "group of {size}");
                assert_eq!(blocked[k], accel.occluded(r), "group of {size}");
            }
        }
        for (group, leaves) in rays.chunks(size).zip(leaving.chunks(size)) {
            let mut hits = vec![None; group.len()];
            let mut blocked = vec![false; group.len()];
            leaving_groups.intersect_group_leaving(group, leaves, &mut hits);
            leaving_groups.occluded_group_leaving(group, leaves, &mut blocked);
            for (k, (r, l)) in group.iter().zip(leaves).enumerate() {
                let skip = || SkipPrim(l.unwrap_or(u32::MAX));
                let want = accel.intersect_filtered(r, &mut skip());
                assert_eq!(hits[k], want, "group of {size} leaving {l:?}");
                let want = accel.occluded_filtered(r, &mut skip());
                assert_eq!(blocked[k], want, "group of {size} leaving {l:?}");
            }
        }
    }
}
