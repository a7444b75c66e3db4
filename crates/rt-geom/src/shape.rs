//! [`Shape`]: one primitive type for scenes that mix triangles, spheres and cones (NFF scenes,
//! rendered scenes). Every structure generic over [`Primitive`] builds over it unchanged.

use crate::{Aabb, Cone, PrimHit, Primitive, Ray, Sphere, Triangle};
use glam::Vec3;

/// A triangle, a sphere or an open cone/cylinder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A triangle.
    Triangle(Triangle),
    /// A sphere.
    Sphere(Sphere),
    /// An open cone or cylinder.
    Cone(Cone),
}

impl From<Triangle> for Shape {
    fn from(t: Triangle) -> Self {
        Shape::Triangle(t)
    }
}

impl From<Sphere> for Shape {
    fn from(s: Sphere) -> Self {
        Shape::Sphere(s)
    }
}

impl From<Cone> for Shape {
    fn from(c: Cone) -> Self {
        Shape::Cone(c)
    }
}

impl Shape {
    /// The triangle, if this shape is one.
    pub fn as_triangle(&self) -> Option<&Triangle> {
        match self {
            Shape::Triangle(t) => Some(t),
            _ => None,
        }
    }

    /// The unit geometric normal at point `p` of the surface: a triangle's by its winding, the
    /// outward normal of spheres and cones.
    pub fn normal_at(&self, p: Vec3) -> Vec3 {
        match self {
            Shape::Triangle(t) => t.normal(),
            Shape::Sphere(s) => s.normal_at(p),
            Shape::Cone(c) => c.normal_at(p),
        }
    }
}

/// Dispatches a `Primitive` method to the variant.
macro_rules! each {
    ($self:ident, $p:ident => $e:expr) => {
        match $self {
            Shape::Triangle($p) => $e,
            Shape::Sphere($p) => $e,
            Shape::Cone($p) => $e,
        }
    };
}

impl Primitive for Shape {
    #[inline]
    fn as_triangle(&self) -> Option<&Triangle> {
        match self {
            Shape::Triangle(t) => Primitive::as_triangle(t),
            _ => None,
        }
    }

    #[inline]
    fn bounds(&self) -> Aabb {
        each!(self, p => p.bounds())
    }

    fn normal(&self, ray: &Ray, h: &PrimHit) -> Option<Vec3> {
        each!(self, p => Primitive::normal(p, ray, h))
    }

    fn centroid(&self) -> Vec3 {
        match self {
            Shape::Triangle(t) => t.centroid(),
            Shape::Sphere(s) => s.center,
            Shape::Cone(c) => c.bounds().center(),
        }
    }

    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        each!(self, p => Primitive::intersect(p, ray))
    }

    fn clipped_bounds(&self, clip: &Aabb) -> Aabb {
        match self {
            Shape::Triangle(t) => t.clipped_bounds(clip),
            Shape::Sphere(s) => Primitive::clipped_bounds(s, clip),
            Shape::Cone(c) => c.bounds().intersection(*clip),
        }
    }

    fn extent_along(&self, n: Vec3) -> (f32, f32) {
        each!(self, p => Primitive::extent_along(p, n))
    }

    fn extent_along_from(&self, origin: Vec3, n: Vec3) -> (f32, f32) {
        each!(self, p => Primitive::extent_along_from(p, origin, n))
    }

    fn farthest_distance(&self, p: glam::DVec3) -> f32 {
        each!(self, s => Primitive::farthest_distance(s, p))
    }

    fn is_finite(&self) -> bool {
        each!(self, p => Primitive::is_finite(p))
    }

    fn plane(&self) -> Option<(Vec3, f32)> {
        match self {
            Shape::Triangle(t) => Primitive::plane(t),
            _ => None,
        }
    }
}

impl Primitive for Cone {
    #[inline]
    fn bounds(&self) -> Aabb {
        Cone::bounds(self)
    }

    fn normal(&self, ray: &Ray, h: &PrimHit) -> Option<Vec3> {
        Some(self.normal_at(ray.at(h.t)))
    }

    fn centroid(&self) -> Vec3 {
        Cone::bounds(self).center()
    }

    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        crate::counters::prims(1);
        Cone::intersect(self, ray)
    }

    fn clipped_bounds(&self, clip: &Aabb) -> Aabb {
        Cone::bounds(self).intersection(*clip)
    }

    fn extent_along(&self, n: Vec3) -> (f32, f32) {
        Cone::extent_along(self, n)
    }

    fn extent_along_from(&self, origin: Vec3, n: Vec3) -> (f32, f32) {
        Cone::extent_along_from(self, origin, n)
    }

    fn farthest_distance(&self, p: glam::DVec3) -> f32 {
        Cone::farthest_distance(self, p)
    }

    fn is_finite(&self) -> bool {
        Cone::is_finite(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_answer_like_their_variants() {
        let ray = Ray::new(Vec3::new(0.25, 0.25, -3.0), Vec3::Z);
        let tri = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
        let sph = Sphere::new(Vec3::new(0.25, 0.25, 1.0), 0.5);
        let cone = Cone::cylinder(Vec3::new(0.25, -1.0, 2.0), Vec3::new(0.25, 1.0, 2.0), 0.5);
        for (shape, expect) in [
            (Shape::from(tri), Primitive::intersect(&tri, &ray)),
            (Shape::from(sph), Primitive::intersect(&sph, &ray)),
            (Shape::from(cone), Primitive::intersect(&cone, &ray)),
        ] {
            assert!(expect.is_some());
            assert_eq!(Primitive::intersect(&shape, &ray), expect);
            assert_eq!(shape.bounds(), Primitive::bounds(&shape));
        }
        assert_eq!(Shape::from(tri).normal_at(Vec3::ZERO), Vec3::Z);
        assert_eq!(
            Shape::from(sph).normal_at(Vec3::new(0.25, 0.25, 0.5)),
            -Vec3::Z
        );
        assert_eq!(Shape::from(cone).plane(), None);
        assert!(Shape::from(tri).plane().is_some());
    }
}
