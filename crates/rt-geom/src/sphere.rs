//! Analytic spheres.

use crate::aabb::{f32_at_or_above, f32_at_or_below};
use crate::{Aabb, PrimHit, Ray};
use glam::{DVec3, Vec3};
use std::f32::consts::PI;

/// A sphere primitive. A radius of zero or less gives a sphere that is never hit.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3,
    /// Radius.
    pub radius: f32,
}

impl Sphere {
    /// The sphere around `center`.
    #[inline]
    pub const fn new(center: Vec3, radius: f32) -> Self {
        Self { center, radius }
    }

    /// The box around the sphere, rounded outwards (`center +- radius` in `f32` may round
    /// into the sphere, and a hit on the box face would then lie outside the box).
    #[inline]
    pub fn bounds(&self) -> Aabb {
        if self.radius > 0.0 {
            let (c, r) = (self.center.as_dvec3(), self.radius as f64);
            let (lo, hi) = (c - r, c + r);
            let [lo, hi] = [
                lo.to_array().map(f32_at_or_below),
                hi.to_array().map(f32_at_or_above),
            ];
            Aabb::new(Vec3::from_array(lo), Vec3::from_array(hi))
        } else {
            Aabb::new(self.center, self.center)
        }
    }

    /// Outward unit normal at a point on the surface.
    #[inline]
    pub fn normal_at(&self, p: Vec3) -> Vec3 {
        (p - self.center).normalize_or_zero()
    }

    /// The nearest of the two roots of the ray/sphere quadratic (solved in `f64`, stable form)
    /// that lies in `[tmin, tmax]`.
    /// `(u, v)` are spherical coordinates of the hit point, each in `[0, 1]`.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        let (t0, t1) = sphere_roots(self.center, self.radius, ray)?;
        let (t0, t1) = (t0 as f32, t1 as f32);
        let t = if ray.in_range(t0) {
            t0
        } else if ray.in_range(t1) {
            t1
        } else {
            return None;
        };
        if !self.bounds().holds_hit(ray, t) {
            return None;
        }
        let n = self.normal_at(ray.at(t));
        let u = 0.5 + n.z.atan2(n.x) / (2.0 * PI);
        let v = n.y.clamp(-1.0, 1.0).acos() / PI;
        Some(PrimHit { t, u, v })
    }
}

/// Both roots `t0 <= t1` of the ray/sphere quadratic, unclipped, in `f64`, or `None` when the
/// ray's line misses the sphere (or the ray is invalid, or the radius is not positive).
///
/// The quadratic is solved in the numerically stable form of Haines et al. ("Precision
/// Improvements for Ray/Sphere Intersection", Ray Tracing Gems, 2019): the discriminant is taken
/// from the distance between the centre and the ray's line, and the second root comes from the
/// first by Vieta's formula, so that neither cancels catastrophically. `f64` keeps the
/// discriminant of rays that graze the sphere (and so, bounding spheres conservative).
#[inline]
pub(crate) fn sphere_roots(center: Vec3, radius: f32, ray: &Ray) -> Option<(f64, f64)> {
    if !ray.is_valid() || !(radius > 0.0) {
        return None;
    }
    let f = ray.origin().as_dvec3() - center.as_dvec3();
    roots_from(f, ray.dir().as_dvec3(), radius as f64)
}

/// [`sphere_roots`] from the ray's origin relative to the centre (`f`), its direction and the
/// radius, all in `f64`.
#[inline]
pub(crate) fn roots_from(f: DVec3, d: DVec3, radius: f64) -> Option<(f64, f64)> {
    let a = d.dot(d);
    let b = -f.dot(d);
    let l = f + d * (b / a);
    let r2 = radius * radius;
    let disc = r2 - l.dot(l);
    if !(disc >= 0.0) {
        return None;
    }
    let c = f.dot(f) - r2;
    let q = b + (a * disc).sqrt().copysign(b);
    let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q / a) };
    Some((t0.min(t1), t0.max(t1)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn outside_inside_and_behind() {
        let s = Sphere::new(Vec3::ZERO, 1.0);
        let h = s
            .intersect(&Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z))
            .unwrap();
        assert_relative_eq!(h.t, 4.0);
        let h = s
            .intersect(&Ray::new(Vec3::ZERO, Vec3::new(0.0, 2.0, 0.0)))
            .unwrap();
        assert_relative_eq!(h.t, 0.5);
        assert!(
            s.intersect(&Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::Z))
                .is_none()
        );
        assert!(
            s.intersect(&Ray::new(Vec3::new(0.0, 2.0, -5.0), Vec3::Z))
                .is_none()
        );
        // tmin skips the near root and finds the far one.
        let r = Ray::segment(Vec3::new(0.0, 0.0, -5.0), Vec3::Z, 4.5, 100.0);
        assert_relative_eq!(s.intersect(&r).unwrap().t, 6.0);
    }

    #[test]
    fn far_away_small_sphere_is_precise() {
        // The naive quadratic loses all precision here; the stable form does not.
        let s = Sphere::new(Vec3::new(0.0, 0.0, 1.0e4), 1.0e-2);
        let h = s.intersect(&Ray::new(Vec3::ZERO, Vec3::Z)).unwrap();
        assert_relative_eq!(h.t, 1.0e4 - 1.0e-2, max_relative = 1e-6);
    }

    #[test]
    fn degenerate_spheres_never_hit() {
        let r = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
        assert!(Sphere::new(Vec3::ZERO, 0.0).intersect(&r).is_none());
        assert!(Sphere::new(Vec3::ZERO, -1.0).intersect(&r).is_none());
        assert!(Sphere::new(Vec3::ZERO, f32::NAN).intersect(&r).is_none());
    }
}
