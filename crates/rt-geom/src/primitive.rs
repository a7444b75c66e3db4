//! The `Primitive` trait: what every acceleration structure needs to know about its elements.

use crate::aabb::{f32_at_or_above, f32_at_or_below};
use crate::{Aabb, PrimHit, Ray, Sphere, Triangle};
use glam::{DVec3, Vec3};

/// Something a ray can hit. Structures are generic over it; triangles, spheres, cones and
/// [`crate::Shape`] implement it, and so can a user's own geometry with two methods:
/// [`bounds`](Self::bounds) and [`intersect`](Self::intersect). The rest is derived from the
/// box by default (conservative: a primitive is never culled where it could be hit), and a
/// primitive that knows more (triangles clipped to a cell, a sphere's extent along a normal)
/// overrides it for tighter kd-tree cells and bounding volumes.
///
/// The contract every structure relies on to answer exactly what [`crate::BruteForce`]
/// answers: `intersect` is a function of the primitive and the ray (the same answer each time
/// it is asked), and every hit it reports lies in `bounds()`, rounding of the hit included.
///
/// ```
/// use rt_geom::{Aabb, Accel, BruteForce, PrimHit, Primitive, Ray, Vec3};
///
/// /// A square of side 2 at height `z`, facing up: user geometry in two methods.
/// #[derive(Clone)]
/// struct Square {
///     z: f32,
/// }
///
/// impl Primitive for Square {
///     fn bounds(&self) -> Aabb {
///         Aabb::new(Vec3::new(-1.0, -1.0, self.z), Vec3::new(1.0, 1.0, self.z))
///     }
///     fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
///         let t = (self.z - ray.origin().z) / ray.dir().z;
///         let p = ray.origin() + t * ray.dir();
///         let inside = p.x.abs() <= 1.0 && p.y.abs() <= 1.0;
///         (inside && t >= ray.tmin && t <= ray.tmax).then_some(PrimHit { t, u: p.x, v: p.y })
///     }
/// }
///
/// let squares = [Square { z: 0.0 }, Square { z: -1.0 }];
/// let scene = BruteForce::build(&squares).unwrap();
/// let hit = scene.intersect(&Ray::new(Vec3::new(0.5, 0.5, 2.0), -Vec3::Z)).unwrap();
/// assert_eq!((hit.prim, hit.t), (0, 2.0));
/// ```
pub trait Primitive: Clone + Send + Sync + 'static {
    /// Axis-aligned bounds holding every hit [`Self::intersect`] reports (as tight as that
    /// allows: structures cull by it).
    fn bounds(&self) -> Aabb;

    /// Nearest hit with `t` in `[ray.tmin, ray.tmax]`.
    fn intersect(&self, ray: &Ray) -> Option<PrimHit>;

    /// The point builders sort by. The box's centre by default.
    fn centroid(&self) -> Vec3 {
        self.bounds().center()
    }

    /// Bounds of the part of the primitive inside `clip` (empty if none). May be larger than the
    /// exact answer, never smaller: kd-trees with perfect splits rely on it. The box's part
    /// inside `clip` by default.
    fn clipped_bounds(&self, clip: &Aabb) -> Aabb {
        self.bounds().intersection(*clip)
    }

    /// `(min, max)` of `n . p` over the points `p` of the primitive: the slab the primitive
    /// occupies along `n` (k-DOPs are built from it). The box's slab by default, rounded
    /// outward.
    fn extent_along(&self, n: Vec3) -> (f32, f32) {
        let b = self.bounds();
        let (mut lo, mut hi) = (0.0f64, 0.0f64);
        for a in 0..3 {
            let k = n[a] as f64;
            let (p, q) = (k * b.min[a] as f64, k * b.max[a] as f64);
            lo += p.min(q);
            hi += p.max(q);
        }
        (f32_at_or_below(lo), f32_at_or_above(hi))
    }

    /// `(min, max)` of `n . (p - origin)` over the points `p` of the primitive, rounded
    /// outward: [`Self::extent_along`] measured from `origin`, as precise as the result's own
    /// size allows rather than the world coordinates' (BSP planes in a frame of their own,
    /// [`crate::Frame`], far from the world's origin). The default widens `extent_along` by
    /// its rounding; triangles, spheres and cones compute it in `f64`.
    fn extent_along_from(&self, origin: Vec3, n: Vec3) -> (f32, f32) {
        let (lo, hi) = self.extent_along(n);
        let o = n.as_dvec3().dot(origin.as_dvec3());
        let scale = lo.abs().max(hi.abs()) as f64
            + (n.abs().element_sum() * origin.abs().max_element()) as f64;
        let err = scale * f64::from(f32::EPSILON) * 4.0;
        (
            f32_at_or_below(lo as f64 - o - err),
            f32_at_or_above(hi as f64 - o + err),
        )
    }

    /// The largest distance from `p` to a point of the primitive, rounded up (bounding
    /// spheres). The point is in `f64` so that a centre near a scene far from the origin keeps
    /// the precision of the scene's own size. The box's farthest corner by default.
    fn farthest_distance(&self, p: DVec3) -> f32 {
        let b = self.bounds();
        let (lo, hi) = (b.min.as_dvec3() - p, b.max.as_dvec3() - p);
        f32_at_or_above(lo.abs().max(hi.abs()).length())
    }

    /// All coordinates finite (builders reject the rest with `BuildError::NonFinite`). The
    /// box's corners by default.
    fn is_finite(&self) -> bool {
        let b = self.bounds();
        b.min.is_finite() && b.max.is_finite()
    }

    /// The unit geometric normal at the hit `h` of `ray` (a triangle's by its winding, the
    /// outward normal of spheres and cones); `None` where the primitive gives none, the
    /// default ([`crate::Geometries`] reports it in its hits).
    fn normal(&self, ray: &Ray, h: &PrimHit) -> Option<Vec3> {
        let _ = (ray, h);
        None
    }

    /// The plane a flat primitive lies in, as `(unit normal n, d)` with `n . p = d` for its
    /// points; `None` for primitives that are not flat (or have no area). BSP trees take
    /// their candidate planes from it.
    fn plane(&self) -> Option<(Vec3, f32)> {
        None
    }

    /// This primitive as a triangle whose [`Primitive::intersect`] is the triangle's own
    /// watertight kernel: layouts that test triangles four at a time ([`crate::LeafPrims`])
    /// store such primitives as SoA. `None` by default.
    #[inline]
    fn as_triangle(&self) -> Option<&Triangle> {
        None
    }

    /// [`crate::test_primitives`]: tests `prims[id]` for the `ids` that `skip` lets through,
    /// in order, keeping the closest hit in `best` (ties by [`crate::replaces`]) and lowering
    /// `ray.tmax` to it; with `ANY_HIT`, stops at the first hit and returns true. One at a
    /// time by default ([`crate::ray::test_each`]); primitives with a SIMD kernel override it
    /// with the same answers.
    #[inline(always)]
    fn test_all<const ANY_HIT: bool>(
        prims: &[Self],
        ids: &[u32],
        ray: &mut Ray,
        best: &mut impl crate::Keep,
        skip: impl FnMut(u32) -> bool,
    ) -> bool {
        crate::ray::test_each::<Self, ANY_HIT>(prims, ids, ray, best, skip)
    }
}

impl Primitive for Triangle {
    #[inline]
    fn as_triangle(&self) -> Option<&Triangle> {
        Some(self)
    }

    /// Four triangles at a time in SIMD lanes ([`crate::triangle::watertight_lanes`]).
    #[inline(always)]
    fn test_all<const ANY_HIT: bool>(
        prims: &[Self],
        ids: &[u32],
        ray: &mut Ray,
        best: &mut impl crate::Keep,
        skip: impl FnMut(u32) -> bool,
    ) -> bool {
        crate::triangle::test_triangles::<ANY_HIT>(prims, ids, ray, best, skip)
    }

    #[inline]
    fn bounds(&self) -> Aabb {
        Triangle::bounds(self)
    }

    #[inline]
    fn centroid(&self) -> Vec3 {
        Triangle::centroid(self)
    }

    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        crate::counters::prims(1);
        self.intersect_watertight(ray)
    }

    fn clipped_bounds(&self, clip: &Aabb) -> Aabb {
        Triangle::clipped_bounds(self, clip)
    }

    fn normal(&self, _: &Ray, _: &PrimHit) -> Option<Vec3> {
        Some(Triangle::normal(self))
    }

    fn extent_along(&self, n: Vec3) -> (f32, f32) {
        let d = self.v.map(|p| p.dot(n));
        (d[0].min(d[1]).min(d[2]), d[0].max(d[1]).max(d[2]))
    }

    fn extent_along_from(&self, origin: Vec3, n: Vec3) -> (f32, f32) {
        let (o, n) = (origin.as_dvec3(), n.as_dvec3());
        let d = self.v.map(|p| (p.as_dvec3() - o).dot(n));
        (
            f32_at_or_below(d[0].min(d[1]).min(d[2])),
            f32_at_or_above(d[0].max(d[1]).max(d[2])),
        )
    }

    fn farthest_distance(&self, p: DVec3) -> f32 {
        let far = self
            .v
            .iter()
            .map(|v| v.as_dvec3().distance(p))
            .fold(0.0, f64::max);
        f32_at_or_above(far)
    }

    fn is_finite(&self) -> bool {
        self.v.iter().all(|p| p.is_finite())
    }

    fn plane(&self) -> Option<(Vec3, f32)> {
        // In f64: the cross product of tiny (1e-6) edges underflows in f32.
        let [a, b, c] = self.v.map(|p| p.as_dvec3());
        let n = (b - a).cross(c - a).try_normalize()?;
        Some((n.as_vec3(), n.dot((a + b + c) / 3.0) as f32))
    }
}

impl Primitive for Sphere {
    #[inline]
    fn bounds(&self) -> Aabb {
        Sphere::bounds(self)
    }

    #[inline]
    fn centroid(&self) -> Vec3 {
        self.center
    }

    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        crate::counters::prims(1);
        Sphere::intersect(self, ray)
    }

    fn clipped_bounds(&self, clip: &Aabb) -> Aabb {
        self.bounds().intersection(*clip)
    }

    fn normal(&self, ray: &Ray, h: &PrimHit) -> Option<Vec3> {
        Some(self.normal_at(ray.at(h.t)))
    }

    fn extent_along(&self, n: Vec3) -> (f32, f32) {
        let c = self.center.dot(n);
        let r = self.radius.max(0.0) * n.length();
        (c - r, c + r)
    }

    fn extent_along_from(&self, origin: Vec3, n: Vec3) -> (f32, f32) {
        let n = n.as_dvec3();
        let c = (self.center.as_dvec3() - origin.as_dvec3()).dot(n);
        let r = self.radius.max(0.0) as f64 * n.length();
        (f32_at_or_below(c - r), f32_at_or_above(c + r))
    }

    fn farthest_distance(&self, p: DVec3) -> f32 {
        f32_at_or_above(self.center.as_dvec3().distance(p) + self.radius.max(0.0) as f64)
    }

    fn is_finite(&self) -> bool {
        self.center.is_finite() && self.radius.is_finite()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Far from the origin, `extent_along` in `f32` rounds `n . p` to a unit; measured from
    /// a nearby origin the slab keeps the primitive's own precision, and holds it.
    #[test]
    fn extents_from_a_nearby_origin_keep_their_precision() {
        let far = Vec3::new(3.0e5, 5.0e6, 1.0e7);
        let t = Triangle::new(
            far + Vec3::new(0.25, 0.0, 0.0),
            far + Vec3::new(0.0, 0.5, 0.0),
            far + Vec3::new(0.0, 0.0, 1.0),
        );
        let n = Vec3::new(1.0, 2.0, 2.0) / 3.0;
        let exact: Vec<f64> = [[0.25, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 1.0]]
            .iter()
            .map(|p| p[0] * n.x as f64 + p[1] * n.y as f64 + p[2] * n.z as f64)
            .collect();
        let (lo, hi) = Primitive::extent_along_from(&t, far, n);
        let (min, max) = (
            exact[0].min(exact[1]).min(exact[2]),
            exact[0].max(exact[1]).max(exact[2]),
        );
        assert!(lo as f64 <= min && min - (lo as f64) < 1e-6, "{lo} {min}");
        assert!(hi as f64 >= max && (hi as f64) - max < 1e-6, "{hi} {max}");
        let s = Sphere::new(far, 0.5);
        let (lo, hi) = Primitive::extent_along_from(&s, far, n);
        assert!(
            (-0.5001..=-0.5).contains(&lo) && (0.5..0.5001).contains(&hi),
            "{lo} {hi}"
        );
    }
}
