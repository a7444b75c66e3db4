//! The packet queries: [`PacketTraversal`] (packets of a size known at compile time) and
//! [`PacketAccel`] (groups of any size up to [`MAX_GROUP`], behind a trait object).

use crate::RayPacket;
use rt_geom::{Accel, Hit, Ray};

/// Packet queries on a BVH. Results are per lane, in the packet's order; inactive lanes miss.
pub trait PacketTraversal {
    /// Closest hit of every lane.
    fn intersect_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [Option<Hit>; N];
    /// Whether each lane is blocked (lanes stop as soon as they are).
    fn occluded_packet<const N: usize>(&self, packet: &mut RayPacket<'_, N>) -> [bool; N];

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
/// The structure answers single rays too ([`Accel`]), with the same answers lane by lane.
pub trait PacketAccel: Accel + Send + Sync {
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

/// Every structure with packet traversal is a packet path: a group is traced as one packet of
/// the smallest size that holds it.
impl<T: PacketTraversal + Accel + Send + Sync> PacketAccel for T {
    fn intersect_group(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        as_one_packet!(rays, out, |p| self.intersect_packet(p))
    }

    fn occluded_group(&self, rays: &[Ray], out: &mut [bool]) {
        as_one_packet!(rays, out, |p| self.occluded_packet(p))
    }
}
