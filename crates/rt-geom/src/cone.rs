//! Analytic open cones and cylinders (the `c` primitive of NFF): a frustum of a cone between a
//! base circle and an apex circle, without end caps. Equal radii make a cylinder.

use crate::{Aabb, PrimHit, Ray};
use glam::{DVec3, Vec3};
use std::f64::consts::TAU;

/// An open cone frustum (or cylinder) around the segment `base -> apex`, with radius
/// `base_radius` at `base` and `apex_radius` at `apex`, varying linearly between them.
///
/// A cone with a negative or non-finite radius, both radii zero, or `base == apex` is never hit
/// (NFF's negative radii, "inside only", are not supported; the SPD files do not use them).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Cone {
    /// Centre of the base circle.
    pub base: Vec3,
    /// Radius at the base.
    pub base_radius: f32,
    /// Centre of the apex circle.
    pub apex: Vec3,
    /// Radius at the apex (equal to `base_radius` for a cylinder).
    pub apex_radius: f32,
}

/// The cone in `f64`, with its axis frame: what the kernel and the bounds work from.
struct Frame {
    base: DVec3,
    /// Unit axis, `base -> apex`.
    axis: DVec3,
    height: f64,
    base_radius: f64,
    /// Radius change per unit of height.
    slope: f64,
}

impl Cone {
    /// An open cone from `base` to `apex` with the given radii.
    #[inline]
    pub const fn new(base: Vec3, base_radius: f32, apex: Vec3, apex_radius: f32) -> Self {
        Self {
            base,
            base_radius,
            apex,
            apex_radius,
        }
    }

    /// A cylinder of radius `radius` around `a -> b`.
    #[inline]
    pub const fn cylinder(a: Vec3, b: Vec3, radius: f32) -> Self {
        Self::new(a, radius, b, radius)
    }

    /// Whether the cone has a surface a ray can hit (see the type's documentation).
    pub fn is_valid(&self) -> bool {
        self.frame().is_some()
    }

    fn frame(&self) -> Option<Frame> {
        let (rb, ra) = (self.base_radius as f64, self.apex_radius as f64);
        let usable = |r: f64| r >= 0.0 && r.is_finite();
        if !usable(rb) || !usable(ra) || rb + ra == 0.0 {
            return None;
        }
        let base = self.base.as_dvec3();
        let d = self.apex.as_dvec3() - base;
        let height = d.length();
        if !(height > 0.0) || !height.is_finite() {
            return None;
        }
        Some(Frame {
            base,
            axis: d / height,
            height,
            base_radius: rb,
            slope: (ra - rb) / height,
        })
    }

    /// The two rims as `(centre, radius)`.
    fn rims(&self) -> [(DVec3, f64); 2] {
        [
            (self.base.as_dvec3(), self.base_radius.max(0.0) as f64),
            (self.apex.as_dvec3(), self.apex_radius.max(0.0) as f64),
        ]
    }

    /// Unit axis (`base -> apex`) in `f64`; zero for a degenerate cone.
    fn axis(&self) -> DVec3 {
        (self.apex.as_dvec3() - self.base.as_dvec3()).normalize_or_zero()
    }

    /// Bounds of the two rims (a rim of radius `r` around unit axis `a` spans
    /// `r * sqrt(1 - a_i^2)` along axis `i`), rounded outwards to `f32`.
    pub fn bounds(&self) -> Aabb {
        let a = self.axis();
        let spread = (DVec3::ONE - a * a).max(DVec3::ZERO).map(f64::sqrt);
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for (c, r) in self.rims() {
            lo = lo.min(c - spread * r);
            hi = hi.max(c + spread * r);
        }
        Aabb::new(round_down(lo), round_up(hi))
    }

    /// `(min, max)` of `n . p` over the cone's points.
    pub fn extent_along(&self, n: Vec3) -> (f32, f32) {
        self.extent_along_from(Vec3::ZERO, n)
    }

    /// `(min, max)` of `n . (p - origin)` over the cone's points (in `f64`, rounded outward).
    pub fn extent_along_from(&self, origin: Vec3, n: Vec3) -> (f32, f32) {
        let (n, a, o) = (n.as_dvec3(), self.axis(), origin.as_dvec3());
        let spread = (n.length_squared() - n.dot(a).powi(2)).max(0.0).sqrt();
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (c, r) in self.rims() {
            let d = (c - o).dot(n);
            lo = lo.min(d - spread * r);
            hi = hi.max(d + spread * r);
        }
        ((lo as f32).next_down(), (hi as f32).next_up())
    }

    /// The largest distance from `p` to a point of the cone (attained on a rim).
    pub fn farthest_distance(&self, p: glam::DVec3) -> f32 {
        let a = self.axis();
        let far = self
            .rims()
            .into_iter()
            .map(|(c, r)| {
                let q = p - c;
                let along = q.dot(a);
                let across = (q - a * along).length();
                (along * along + (across + r).powi(2)).sqrt()
            })
            .fold(0.0, f64::max);
        (far as f32).next_up()
    }

    /// Whether every number is finite.
    pub fn is_finite(&self) -> bool {
        self.base.is_finite()
            && self.apex.is_finite()
            && self.base_radius.is_finite()
            && self.apex_radius.is_finite()
    }

    /// Outward unit normal at a point on the surface (the gradient of `|w| - r(s)`, where `s` is
    /// the height above the base and `w` the offset from the axis).
    pub fn normal_at(&self, p: Vec3) -> Vec3 {
        let Some(f) = self.frame() else {
            return Vec3::ZERO;
        };
        let q = p.as_dvec3() - f.base;
        let w = q - f.axis * q.dot(f.axis);
        let n = w.normalize_or_zero() - f.axis * f.slope;
        n.normalize_or(f.axis).as_vec3()
    }

    /// Nearest hit with `t` in `[tmin, tmax]`, solved in `f64`. `u` is the angle around the axis
    /// (in turns, `[0, 1)`), `v` the height above the base as a fraction of the length.
    pub fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        if !ray.is_valid() {
            return None;
        }
        let f = self.frame()?;
        let o = ray.origin().as_dvec3() - f.base;
        let d = ray.dir().as_dvec3();
        let (oa, da) = (o.dot(f.axis), d.dot(f.axis));
        let (o_perp, d_perp) = (o - f.axis * oa, d - f.axis * da);
        // |o_perp + t d_perp| = r0 + t dr, squared: A t^2 + 2 B t + C = 0.
        let r0 = f.base_radius + f.slope * oa;
        let dr = f.slope * da;
        let a = d_perp.dot(d_perp) - dr * dr;
        let b = o_perp.dot(d_perp) - r0 * dr;
        let c = o_perp.dot(o_perp) - r0 * r0;
        let roots = if a == 0.0 {
            // The ray runs parallel to a line of the surface: at most one crossing.
            if b == 0.0 {
                return None;
            }
            let t = -c / (2.0 * b);
            [t, t]
        } else {
            let disc = b * b - a * c;
            if !(disc >= 0.0) {
                return None;
            }
            // Stable roots: q = -(B + sign(B) sqrt(disc)); t = q / A and C / q.
            let q = -(b + disc.sqrt().copysign(b));
            let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (q / a, c / q) };
            [t0.min(t1), t0.max(t1)]
        };
        for t in roots {
            let t32 = t as f32;
            if !ray.in_range(t32) {
                continue;
            }
            // On this cone's frustum (not beyond a rim, not on the mirrored nappe).
            let s = oa + t * da;
            if !(0.0..=f.height).contains(&s) || f.base_radius + f.slope * s < 0.0 {
                continue;
            }
            if !self.bounds().holds_hit(ray, t32) {
                continue;
            }
            let w = o_perp + d_perp * t;
            let (e1, e2) = f.axis.any_orthonormal_pair();
            let turn = w.dot(e2).atan2(w.dot(e1)) / TAU;
            let u = if turn < 0.0 { turn + 1.0 } else { turn };
            return Some(PrimHit {
                t: t32,
                u: (u as f32).min(1.0f32.next_down()),
                v: (s / f.height) as f32,
            });
        }
        None
    }
}

fn round_down(v: DVec3) -> Vec3 {
    Vec3::new(
        (v.x as f32).next_down(),
        (v.y as f32).next_down(),
        (v.z as f32).next_down(),
    )
}

fn round_up(v: DVec3) -> Vec3 {
    Vec3::new(
        (v.x as f32).next_up(),
        (v.y as f32).next_up(),
        (v.z as f32).next_up(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// From 4.5e16 away the `f64` roots put this ray's crossing on the cone, 0.6 beside its box
    /// on an axis the ray does not move along (found by fuzzing the NFF reader): no hit.
    #[test]
    fn far_hits_outside_the_box_are_dropped() {
        let c = Cone::new(
            Vec3::new(-0.753191, 2.3684, 0.489453),
            0.07412,
            Vec3::new(-2.22045e-16, 3.10258, 0.791951),
            0.07412,
        );
        let r = Ray::new(
            Vec3::new(0.6817568, -1.6404778e16, 4.2062676e16),
            Vec3::new(0.0, 1.6404778e16, -4.2062676e16),
        );
        assert_eq!(c.intersect(&r), None);
    }
    use approx::assert_relative_eq;

    #[test]
    fn cylinder_from_outside_and_inside() {
        let c = Cone::cylinder(Vec3::ZERO, Vec3::new(0.0, 0.0, 2.0), 1.0);
        let h = c
            .intersect(&Ray::new(Vec3::new(-5.0, 0.0, 1.0), Vec3::X))
            .unwrap();
        assert_relative_eq!(h.t, 4.0);
        assert_relative_eq!(h.v, 0.5);
        // From inside: the far wall (no caps).
        let h = c
            .intersect(&Ray::new(Vec3::new(0.0, 0.0, 1.0), Vec3::X))
            .unwrap();
        assert_relative_eq!(h.t, 1.0);
        // Above the top rim, and along the axis: no hit.
        assert!(
            c.intersect(&Ray::new(Vec3::new(-5.0, 0.0, 2.5), Vec3::X))
                .is_none()
        );
        assert!(
            c.intersect(&Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z))
                .is_none()
        );
        // Through the open end, hitting the inside wall.
        let h = c
            .intersect(&Ray::new(
                Vec3::new(0.0, 0.0, 3.0),
                Vec3::new(1.0, 0.0, -1.0),
            ))
            .unwrap();
        assert_relative_eq!(h.t, 1.0, max_relative = 1e-6);
        assert!(
            c.normal_at(Vec3::new(1.0, 0.0, 2.0))
                .abs_diff_eq(Vec3::X, 1e-6)
        );
    }

    #[test]
    fn cone_to_a_point() {
        // Radius 1 at z = 0 down to 0 at z = 1: the surface at height z has radius 1 - z.
        let c = Cone::new(Vec3::ZERO, 1.0, Vec3::Z, 0.0);
        let h = c
            .intersect(&Ray::new(Vec3::new(-3.0, 0.0, 0.5), Vec3::X))
            .unwrap();
        assert_relative_eq!(h.t, 2.5, max_relative = 1e-6);
        // The mirrored nappe above the apex is not part of the cone.
        assert!(
            c.intersect(&Ray::new(Vec3::new(-3.0, 0.0, 1.5), Vec3::X))
                .is_none()
        );
        let n = c.normal_at(Vec3::new(0.5, 0.0, 0.5));
        assert!(
            n.abs_diff_eq(Vec3::new(1.0, 0.0, 1.0).normalize(), 1e-6),
            "{n}"
        );
    }

    #[test]
    fn bounds_and_extents_contain_the_surface() {
        let c = Cone::new(
            Vec3::new(1.0, 2.0, 3.0),
            0.5,
            Vec3::new(2.0, -1.0, 4.0),
            0.2,
        );
        let b = c.bounds();
        let n = Vec3::new(0.3, -0.7, 0.2);
        let (lo, hi) = c.extent_along(n);
        let p = Vec3::new(-1.0, 0.5, 2.0);
        let far = c.farthest_distance(p.as_dvec3());
        let mut rng = 12345u32;
        let mut next = || {
            rng = rng.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (rng >> 8) as f32 / (1 << 24) as f32
        };
        for _ in 0..2000 {
            // Rays from outside towards random points of the axis find the surface.
            let target = c.base.lerp(c.apex, next());
            let from = target + (Vec3::new(next(), next(), next()) - 0.5) * 8.0;
            if let Some(h) = c.intersect(&Ray::new(from, target - from)) {
                let q = from + (target - from) * h.t;
                assert!(b.min.cmple(q + 1e-5).all() && b.max.cmpge(q - 1e-5).all());
                assert!(q.dot(n) >= lo - 1e-5 && q.dot(n) <= hi + 1e-5);
                assert!(q.distance(p) <= far + 1e-5);
                assert!((0.0..1.0).contains(&h.u) && (0.0..=1.0).contains(&h.v));
            }
        }
    }

    #[test]
    fn degenerate_cones_never_hit() {
        let r = Ray::new(Vec3::new(-5.0, 0.0, 0.5), Vec3::X);
        for c in [
            Cone::new(Vec3::ZERO, 0.0, Vec3::Z, 0.0),
            Cone::new(Vec3::ZERO, 1.0, Vec3::ZERO, 1.0),
            Cone::new(Vec3::ZERO, -1.0, Vec3::Z, 1.0),
            Cone::new(Vec3::ZERO, f32::NAN, Vec3::Z, 1.0),
        ] {
            assert!(!c.is_valid());
            assert!(c.intersect(&r).is_none(), "{c:?}");
        }
        assert!(
            Cone::cylinder(Vec3::ZERO, Vec3::Z, 1.0)
                .intersect(&Ray::new(Vec3::ZERO, Vec3::ZERO))
                .is_none()
        );
    }
}
