//! [`Frame`]: the coordinates a cell structure computes in, relative to its own box, so that a
//! scene far from the origin (projected GIS or CAD coordinates, x = 3e5, y = 5e6) keeps the
//! precision it has at the origin.
//!
//! A grid's or octree's cell walls, and a point along a ray, computed in world `f32`
//! coordinates at 5e6 snap to a lattice of 0.5: walls collapse onto each other and points
//! land in the wrong cell. Relative to an anchor near the box they are as fine as at the
//! origin. Nothing here touches the primitives or the kernel: hits are still computed in
//! world coordinates, exactly as brute force computes them; the frame only decides which
//! cells a primitive is listed in and which cells a ray visits.
//!
//! Exactness rests on rounding in the safe direction: boxes move between the frames rounded
//! outward ([`Frame::to_local`], [`Frame::to_world`]), so a primitive is listed in every cell
//! whose world box it touches; a ray's origin moves to the nearest `f32` of its exact local
//! position ([`Frame::local_point`]), off by half an ulp of a coordinate the size of the
//! box, the rounding a structure at the origin has in every coordinate anyway.

use crate::aabb::{f32_at_or_above, f32_at_or_below};
use crate::{Aabb, Primitive};
use glam::Vec3;

/// An anchor point: local coordinates are world coordinates minus the anchor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The anchor, in world coordinates (an `f32` point, so that a world `f32` minus it is
    /// exact in `f64`).
    pub anchor: Vec3,
}

impl Frame {
    /// The world frame (anchor at the origin): local and world coordinates are the same.
    pub const WORLD: Frame = Frame { anchor: Vec3::ZERO };

    /// The frame of a structure over `bounds`: per axis, the box's centre snapped to a
    /// multiple of the smallest power of two at least twice the box's largest extent. A box
    /// whose centre lies within half that of the origin keeps the world frame (its cells and
    /// walls are bit for bit what they were without one); a box far away gets local
    /// coordinates no larger than about twice its extent.
    pub fn of(bounds: &Aabb) -> Frame {
        if bounds.is_empty() {
            return Frame::WORLD;
        }
        let extent = bounds.extent().max_element() as f64;
        let step = if extent > 0.0 {
            (2.0 * extent).log2().ceil().exp2()
        } else {
            1.0
        };
        let c = (bounds.min.as_dvec3() + bounds.max.as_dvec3()) * 0.5;
        let snap = |x: f64| ((x / step).round() * step) as f32;
        Frame {
            anchor: Vec3::new(snap(c.x), snap(c.y), snap(c.z)),
        }
    }

    /// Whether this is the world frame.
    pub fn is_world(&self) -> bool {
        self.anchor == Vec3::ZERO
    }

    /// `b` in local coordinates, rounded outward (it holds every local point of `b`).
    pub fn to_local(&self, b: &Aabb) -> Aabb {
        self.moved(b, -self.anchor.as_dvec3())
    }

    /// `b` (local) in world coordinates, rounded outward (it holds every world point of `b`).
    pub fn to_world(&self, b: &Aabb) -> Aabb {
        self.moved(b, self.anchor.as_dvec3())
    }

    fn moved(&self, b: &Aabb, by: glam::DVec3) -> Aabb {
        if self.is_world() || b.is_empty() {
            return *b;
        }
        let (lo, hi) = (b.min.as_dvec3() + by, b.max.as_dvec3() + by);
        Aabb::new(
            Vec3::new(
                f32_at_or_below(lo.x),
                f32_at_or_below(lo.y),
                f32_at_or_below(lo.z),
            ),
            Vec3::new(
                f32_at_or_above(hi.x),
                f32_at_or_above(hi.y),
                f32_at_or_above(hi.z),
            ),
        )
    }

    /// The box of the part of `p` inside the local box `cell`, in local coordinates:
    /// `p` clipped to the cell's world box, both moves rounded outward (it holds the
    /// exact answer; what a cell structure lists a primitive by).
    pub fn clipped_bounds<P: Primitive>(&self, p: &P, cell: &Aabb) -> Aabb {
        self.to_local(&p.clipped_bounds(&self.to_world(cell)))
    }

    /// A world point in local coordinates: the exact difference (in `f64`) rounded to the
    /// nearest `f32`.
    #[inline]
    pub fn local_point(&self, p: Vec3) -> [f32; 3] {
        if self.is_world() {
            return p.to_array();
        }
        (p.as_dvec3() - self.anchor.as_dvec3()).as_vec3().to_array()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boxes_near_the_origin_keep_the_world_frame() {
        let unit = Aabb::new(Vec3::ZERO, Vec3::ONE);
        assert!(Frame::of(&unit).is_world());
        let wide = Aabb::new(Vec3::splat(-1e3), Vec3::splat(3e3));
        assert!(Frame::of(&wide).is_world());
        assert_eq!(Frame::of(&unit).to_local(&unit), unit);
    }

    #[test]
    fn far_boxes_get_small_local_coordinates_rounded_outward() {
        let b = Aabb::new(
            Vec3::new(3.0e5, 5.0e6, -2.0e4),
            Vec3::new(3.0e5 + 1.5, 5.0e6 + 0.5, -2.0e4 + 1.0),
        );
        let f = Frame::of(&b);
        assert!(!f.is_world());
        let local = f.to_local(&b);
        assert!(local.min.abs().max_element() <= 4.0 && local.max.abs().max_element() <= 4.0);
        let back = f.to_world(&local);
        assert!(back.contains(&b), "{back:?} holds {b:?}");
        // A point's local coordinates are the exact difference where it is representable.
        let p = Vec3::new(3.0e5 + 0.25, 5.0e6, -2.0e4 + 0.5);
        let l = f.local_point(p);
        for a in 0..3 {
            assert_eq!(l[a] as f64, p[a] as f64 - f.anchor[a] as f64);
        }
    }
}
