//! The packet queries: [`PacketTraversal`] (packets of a size known at compile time) and
//! [`PacketAccel`] (groups of any size up to [`MAX_GROUP`], behind a trait object).

use crate::RayPacket;
use rt_geom::{Accel, FilteredAccel, Hit, Ray};

/// Packet queries. Results are per lane, in the packet's order; inactive lanes miss.
pub trait PacketTraversal {
    /// Closest hit of every lane.
    fn intersect_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [Option<Hit>; N];
    /// Whether each lane is blocked (lanes stop as soon as they are).
    fn occluded_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [bool; N];

    /// Whether this structure traces packets of `lanes` lanes ray by ray (where the packet
    /// traversal would lose to single rays): groups that small then skip filling a packet.
    fn ray_by_ray(&self, lanes: usize) -> bool {
        let _ = lanes;
        false
    }

    /// `intersect` of every ray, traced as packets of `N` consecutive rays.
    fn intersect_rays<const N: usize>(&self, rays: &[Ray]) -> Vec<Option<Hit>> {
        let mut out = Vec::with_capacity(rays.len());
        for chunk in rays.chunks(N) {
            let mut p = RayPacket::<N>::new(chunk);
            let hits = self.intersect_packet(&mut p);
            p.recycle();
            out.extend_from_slice(&hits[..chunk.len()]);
        }
        out
    }

    /// `occluded` of every ray, traced as packets of `N` consecutive rays.
    fn occluded_rays<const N: usize>(&self, rays: &[Ray]) -> Vec<bool> {
        let mut out = Vec::with_capacity(rays.len());
        for chunk in rays.chunks(N) {
            let mut p = RayPacket::<N>::new(chunk);
            let blocked = self.occluded_packet(&mut p);
            p.recycle();
            out.extend_from_slice(&blocked[..chunk.len()]);
        }
        out
    }
}

/// Every active lane of `packet` traced on its own through `a` (closest hit), skipping the
/// primitive it leaves ([`RayPacket::leaving`]): for packets too small to share work, and for
/// walks that do not apply (a kd-tree whose planes lie in a frame of their own).
pub(crate) fn each_lane<const N: usize>(
    a: &impl FilteredAccel,
    packet: &RayPacket<'_, N>,
) -> [Option<Hit>; N] {
    std::array::from_fn(|i| match packet.active[i] {
        false => None,
        true if packet.skipping => a.intersect_leaving(&packet.ray(i), packet.skip[i]),
        true => a.intersect(&packet.ray(i)),
    })
}

/// [`each_lane`] for any hit.
pub(crate) fn each_lane_occluded<const N: usize>(
    a: &impl FilteredAccel,
    packet: &RayPacket<'_, N>,
) -> [bool; N] {
    std::array::from_fn(|i| match packet.active[i] {
        false => false,
        true if packet.skipping => a.occluded_leaving(&packet.ray(i), packet.skip[i]),
        true => a.occluded(&packet.ray(i)),
    })
}

/// Packet queries behind a trait object (the registry's packet paths): a group of up to 256
/// rays is traced as one packet of the smallest size that holds it (4, 16, 64 or 256 lanes),
/// unless it is incoherent ([`is_coherent`]): then ray by ray, so that incoherent rays (diffuse
/// bounces) lose nothing against single rays. The structure answers single rays too
/// ([`Accel`]), with the same answers lane by lane.
pub trait PacketAccel: Accel + Send + Sync {
    /// Closest hit of every ray of the group into `out` (same length, at most 256), as one
    /// packet whatever the directions (what `verify` checks), or ray by ray where the
    /// structure traces packets that small so ([`PacketTraversal::ray_by_ray`]).
    fn intersect_packet_group(&self, rays: &[Ray], out: &mut [Option<Hit>]);
    /// Whether each ray of the group is blocked, as [`Self::intersect_packet_group`] traces it.
    fn occluded_packet_group(&self, rays: &[Ray], out: &mut [bool]);

    /// Closest hit of every ray of the group: as one packet when the group is coherent, ray by
    /// ray otherwise.
    fn intersect_group(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        if is_coherent(rays) {
            self.intersect_packet_group(rays, out);
        } else {
            for (r, o) in rays.iter().zip(out) {
                *o = self.intersect(r);
            }
        }
    }

    /// Whether each ray of the group is blocked: as one packet when the group is coherent, ray
    /// by ray otherwise.
    fn occluded_group(&self, rays: &[Ray], out: &mut [bool]) {
        if is_coherent(rays) {
            self.occluded_packet_group(rays, out);
        } else {
            for (r, o) in rays.iter().zip(out) {
                *o = self.occluded(r);
            }
        }
    }

    /// The same groups for rays that each leave a primitive, which they skip, where this path
    /// can skip one (every rt structure; `None` by default, as for a peer's packets).
    fn leaving(&self) -> Option<&dyn LeavingGroups> {
        None
    }
}

/// Groups of rays that each leave a primitive (`leaving[i]` for ray `i`, `None` where it
/// leaves none), which each skips: the answers of the structure's
/// [`FilteredAccel::intersect_leaving`] and `occluded_leaving`, ray by ray, traced as
/// [`PacketAccel`] traces groups (one packet when coherent, [`RayPacket::leaving`]).
pub trait LeavingGroups: Sync {
    /// Closest hit of each ray into `out` (same length as `rays` and `leaving`).
    fn intersect_group_leaving(
        &self,
        rays: &[Ray],
        leaving: &[Option<u32>],
        out: &mut [Option<Hit>],
    );
    /// Whether each ray is blocked, into `out`.
    fn occluded_group_leaving(&self, rays: &[Ray], leaving: &[Option<u32>], out: &mut [bool]);
}

/// A packet path that answers single rays with a structure of its own: packets through
/// `packets`, single rays (queries, and the ray-by-ray fallback of incoherent groups) through
/// `singles`. For structures whose best build differs between the two, such as the kd-tree
/// (packets run faster on Wald & Havran's small leaves, single rays on larger ones): both
/// give the same answers, so the lanes still equal the single rays bit for bit. Holds both
/// (`stats().bytes` counts both).
#[derive(Clone, Debug)]
pub struct WithSingleRays<Pk, S> {
    /// The structure packets go through.
    pub packets: Pk,
    /// The structure single rays and incoherent groups go through.
    pub singles: S,
}

impl<Pk: Accel, S: Accel> Accel for WithSingleRays<Pk, S> {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.singles.intersect(ray)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        self.singles.occluded(ray)
    }

    fn stats(&self) -> rt_geom::AccelStats {
        let mut stats = self.packets.stats();
        stats.bytes += self.singles.stats().bytes;
        stats
    }

    fn validate(&self) -> Result<(), String> {
        self.packets.validate()?;
        self.singles.validate()
    }

    /// The single-ray structure's (filtered single rays go through it).
    fn filtered(&self) -> Option<&dyn FilteredAccel> {
        self.singles.filtered()
    }
}

/// Filtered single rays go through the single-ray structure.
impl<Pk: Accel, S: FilteredAccel> FilteredAccel for WithSingleRays<Pk, S> {
    fn intersect_filtered(&self, ray: &Ray, filter: &mut dyn rt_geom::HitFilter) -> Option<Hit> {
        self.singles.intersect_filtered(ray, filter)
    }

    fn occluded_filtered(&self, ray: &Ray, filter: &mut dyn rt_geom::HitFilter) -> bool {
        self.singles.occluded_filtered(ray, filter)
    }
    fn intersect_leaving(&self, ray: &Ray, prim: u32) -> Option<Hit> {
        self.singles.intersect_leaving(ray, prim)
    }

    fn occluded_leaving(&self, ray: &Ray, prim: u32) -> bool {
        self.singles.occluded_leaving(ray, prim)
    }
}

impl<Pk: PacketTraversal, S> PacketTraversal for WithSingleRays<Pk, S> {
    fn intersect_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [Option<Hit>; N] {
        self.packets.intersect_packet(packet)
    }

    fn occluded_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [bool; N] {
        self.packets.occluded_packet(packet)
    }

    fn ray_by_ray(&self, lanes: usize) -> bool {
        self.packets.ray_by_ray(lanes)
    }
}

/// Largest group [`PacketAccel`] traces as one packet.
pub const MAX_GROUP: usize = 256;

/// The lanes of the packet [`PacketAccel`] traces a group of `n` rays in (4, 16, 64 or 256).
fn packet_lanes(n: usize) -> usize {
    match n {
        0..=4 => 4,
        5..=16 => 16,
        17..=64 => 64,
        _ => 256,
    }
}

/// Traces `$rays` (at most 256; each leaving the primitive of `$leaving`, see
/// [`RayPacket::leaving`]) as one packet of the smallest size that holds them, binding
/// the packet to `$p` in `$query`, and copies the lanes' answers to `$out`.
macro_rules! as_one_packet {
    ($rays:expr, $leaving:expr, $out:expr, |$p:ident| $query:expr) => {{
        let (rays, leaving, out) = ($rays, $leaving, $out);
        assert!(rays.len() <= MAX_GROUP && rays.len() == out.len());
        let n = rays.len();
        macro_rules! trace {
            ($lanes:literal) => {{
                let mut packet = RayPacket::<$lanes>::leaving(rays, leaving);
                {
                    let $p = &mut packet;
                    out.copy_from_slice(&$query[..n]);
                }
                packet.recycle()
            }};
        }
        match packet_lanes(n) {
            4 => trace!(4),
            16 => trace!(16),
            64 => trace!(64),
            _ => trace!(256),
        }
    }};
}

/// Directions of a coherent group lie within this cosine of the first one's (about 26
/// degrees): a camera tile's spread is a fraction of a degree, shadow rays toward a light
/// from one tile's hit points a few degrees; small groups of diffuse bounces can share two
/// octants yet point anywhere.
pub const COHERENT_COS: f32 = 0.9;

/// Whether a group of rays is worth a packet: their directions fall in at most two octants
/// (a camera tile does, unless it straddles both of the image's centre lines; diffuse bounces
/// spread over all eight) and within [`COHERENT_COS`] of the first ray's. Invalid rays are
/// ignored. One pass, no square root.
pub fn is_coherent(rays: &[Ray]) -> bool {
    let mut valid = rays.iter().filter(|r| r.is_valid());
    let Some(first) = valid.next() else {
        return true;
    };
    let d0 = first.dir();
    let len0 = d0.length_squared();
    let octant = |d: rt_geom::Vec3| {
        1u8 << ((d.x < 0.0) as u8 | ((d.y < 0.0) as u8) << 1 | ((d.z < 0.0) as u8) << 2)
    };
    let mut seen = octant(d0);
    for r in valid {
        let d = r.dir();
        seen |= octant(d);
        // cos(d, d0) >= COHERENT_COS, squared: both sides are non-negative.
        let dot = d.dot(d0);
        if !(dot > 0.0 && dot * dot >= COHERENT_COS * COHERENT_COS * d.length_squared() * len0) {
            return false;
        }
    }
    seen.count_ones() <= 2
}

/// Every structure with packet traversal is a packet path: a coherent group is traced as one
/// packet of the smallest size that holds it, an incoherent one ray by ray.
impl<T: PacketTraversal + FilteredAccel + Send + Sync> PacketAccel for T {
    fn intersect_packet_group(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.intersect_packets(rays, &[], out, false)
    }

    fn occluded_packet_group(&self, rays: &[Ray], out: &mut [bool]) {
        self.occluded_packets(rays, &[], out, false)
    }

    fn leaving(&self) -> Option<&dyn LeavingGroups> {
        Some(self)
    }
}

impl<T: PacketTraversal + FilteredAccel + Send + Sync> LeavingGroups for T {
    fn intersect_group_leaving(
        &self,
        rays: &[Ray],
        leaving: &[Option<u32>],
        out: &mut [Option<Hit>],
    ) {
        self.intersect_packets(rays, leaving, out, !is_coherent(rays))
    }

    fn occluded_group_leaving(&self, rays: &[Ray], leaving: &[Option<u32>], out: &mut [bool]) {
        self.occluded_packets(rays, leaving, out, !is_coherent(rays))
    }
}

/// A group through a packet path: as one packet, or ray by ray (`ray_by_ray`, or where the
/// structure traces packets that small so), each ray skipping the primitive it leaves.
trait Groups {
    fn intersect_packets(
        &self,
        rays: &[Ray],
        leaving: &[Option<u32>],
        out: &mut [Option<Hit>],
        ray_by_ray: bool,
    );
    fn occluded_packets(
        &self,
        rays: &[Ray],
        leaving: &[Option<u32>],
        out: &mut [bool],
        ray_by_ray: bool,
    );
}

/// The primitive ray `i` of a group leaves (`u32::MAX`, no primitive, for none).
fn skip_of(leaving: &[Option<u32>], i: usize) -> u32 {
    leaving.get(i).copied().flatten().unwrap_or(u32::MAX)
}

impl<T: PacketTraversal + FilteredAccel> Groups for T {
    fn intersect_packets(
        &self,
        rays: &[Ray],
        leaving: &[Option<u32>],
        out: &mut [Option<Hit>],
        ray_by_ray: bool,
    ) {
        if ray_by_ray || self.ray_by_ray(packet_lanes(rays.len())) {
            for (i, (r, o)) in rays.iter().zip(out).enumerate() {
                *o = match leaving.is_empty() {
                    true => self.intersect(r),
                    false => self.intersect_leaving(r, skip_of(leaving, i)),
                };
            }
            return;
        }
        as_one_packet!(rays, leaving, out, |p| self.intersect_packet(p))
    }

    fn occluded_packets(
        &self,
        rays: &[Ray],
        leaving: &[Option<u32>],
        out: &mut [bool],
        ray_by_ray: bool,
    ) {
        if ray_by_ray || self.ray_by_ray(packet_lanes(rays.len())) {
            for (i, (r, o)) in rays.iter().zip(out).enumerate() {
                *o = match leaving.is_empty() {
                    true => self.occluded(r),
                    false => self.occluded_leaving(r, skip_of(leaving, i)),
                };
            }
            return;
        }
        as_one_packet!(rays, leaving, out, |p| self.occluded_packet(p))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_geom::Vec3;

    #[test]
    fn coherence_counts_octants() {
        let ray = |x: f32, y: f32, z: f32| Ray::new(Vec3::ZERO, Vec3::new(x, y, z));
        let tile = [
            ray(0.1, 0.2, -1.0),
            ray(0.2, 0.2, -1.0),
            ray(-0.1, 0.2, -1.0),
        ];
        assert!(is_coherent(&tile));
        let spread: Vec<Ray> = (0..8)
            .map(|o| {
                let s = |b: u32| if o >> b & 1 == 1 { -1.0 } else { 1.0 };
                ray(s(0), s(1), s(2))
            })
            .collect();
        assert!(!is_coherent(&spread));
        // One octant, but 80 degrees apart: diffuse bounces, not a tile.
        assert!(!is_coherent(&[ray(1.0, 0.1, 0.1), ray(0.1, 1.0, 0.1)]));
        // Invalid rays do not count.
        let mut with_invalid = tile.to_vec();
        with_invalid.push(ray(0.0, 0.0, 0.0));
        with_invalid.push(Ray::new(Vec3::ZERO, Vec3::new(f32::NAN, 1.0, 1.0)));
        assert!(is_coherent(&with_invalid));
        assert!(is_coherent(&[]));
    }
}
