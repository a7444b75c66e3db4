//! Bounding volumes (Kay & Kajiya 1986): sphere, axis-aligned box and a k-DOP of
//! seven slabs, each with a conservative ray test that returns the entry distance.
//!
//! Spheres and k-DOPs are kept in a [`Frame`] of the list they belong to, and their ray tests
//! run in `f64` from the ray's exact local origin: far from the world's origin (a scene at
//! 5e6, where world `f32` coordinates step by 0.5) a volume stays as tight as at the origin.
//! Boxes are values of the primitives' own coordinates and stay in world coordinates.

use crate::aabb::{f32_at_or_above, f32_at_or_below, gamma, pad_down, pad_up};
use crate::sphere::roots_from;
use crate::{Aabb, Frame, Primitive, Ray};
use glam::{DVec3, Vec3};

/// A volume around a set of primitives that a ray can be tested against.
///
/// Every implementation is conservative: a ray that hits a primitive inside the volume (with `t`
/// in `[tmin, tmax]`) also enters the volume at some `t <= ` that hit. A volume is built in a
/// [`Frame`] and tested with ray data made in the same frame.
pub trait BoundingVolume: Clone + Send + Sync + std::fmt::Debug + 'static {
    /// Short name (`"sphere"`, `"box"`, `"kdop7"`).
    const NAME: &'static str;

    /// A volume around all of `prims` (empty when `prims` is), in `frame`.
    fn enclosing<P: Primitive>(prims: &[P], frame: &Frame) -> Self;

    /// A volume around both volumes (volumes of volumes, of one frame).
    fn merge(&self, other: &Self) -> Self;

    /// What [`Self::entry_from`] needs of a ray beyond the ray itself (the reciprocal
    /// direction for boxes, the local origin for the others), made once per ray by
    /// [`Self::ray_data`] for all the volumes it meets.
    type RayData;
    /// The per-ray data for all the volumes of `frame` the ray meets.
    fn ray_data(ray: &Ray, frame: &Frame) -> Self::RayData;

    /// [`Self::entry_distance`] with the ray's [`Self::RayData`].
    fn entry_from(&self, ray: &Ray, data: &Self::RayData) -> Option<f32>;

    /// Where the ray enters the volume (built in `frame`), clamped to `ray.tmin`; `None` if it
    /// misses it within `[tmin, tmax]`.
    #[inline]
    fn entry_distance(&self, ray: &Ray, frame: &Frame) -> Option<f32> {
        self.entry_from(ray, &Self::ray_data(ray, frame))
    }
}

impl BoundingVolume for Aabb {
    const NAME: &'static str = "box";

    /// The primitives' world box (boxes need no frame: their faces are the primitives' own
    /// coordinates).
    fn enclosing<P: Primitive>(prims: &[P], _: &Frame) -> Self {
        Aabb::around(prims)
    }

    fn merge(&self, other: &Self) -> Self {
        self.union(*other)
    }

    /// The reciprocal direction ([`Ray::inv_dir`]).
    type RayData = [f32; 3];

    #[inline]
    fn ray_data(ray: &Ray, _: &Frame) -> [f32; 3] {
        ray.inv_dir().to_array()
    }

    /// [`Aabb::hit_distance`], the same numbers.
    #[inline]
    fn entry_from(&self, ray: &Ray, inv: &[f32; 3]) -> Option<f32> {
        self.clip_ray_with_inv(ray, inv).map(|(t0, _)| t0)
    }
}

/// The ray in a volume list's frame: its origin relative to the anchor (exact in `f64`) and
/// its direction.
#[derive(Clone, Copy, Debug)]
pub struct LocalRay {
    /// `origin - anchor`, exact.
    pub origin: DVec3,
    /// The direction.
    pub dir: DVec3,
    /// The anchor (for volumes that fall back to a box in world coordinates).
    anchor: Vec3,
}

impl LocalRay {
    fn new(ray: &Ray, frame: &Frame) -> Self {
        Self {
            origin: ray.origin().as_dvec3() - frame.anchor.as_dvec3(),
            dir: ray.dir().as_dvec3(),
            anchor: frame.anchor,
        }
    }
}

/// How far beside a volume, relative to the distance between the ray's origin and the
/// volume's points, a ray may pass and still hit a primitive inside: the triangle kernel
/// decides in `f32` (its edge functions round at that scale) and reports such a ray's hit at
/// the point nearest the triangle. Boxes allow it through the relative padding of their slab
/// test; spheres and k-DOPs grow by it. It also covers the few `f64` roundings of their tests.
const SLACK: f64 = gamma(8) as f64;

/// A bounding sphere in a list's frame. The centre (local) is the centre of the primitives'
/// box and the radius the largest distance to any of them, computed in `f64` and rounded up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundingSphere {
    /// Centre, relative to the frame's anchor.
    pub center: Vec3,
    /// Negative for the empty volume.
    pub radius: f32,
}

impl BoundingSphere {
    /// A sphere about the exact `f64` local centre `c` with radius `r`: the centre rounded to
    /// `f32` and the radius grown by the distance the rounding moved it.
    fn around(c: DVec3, r: f64) -> Self {
        let center = c.as_vec3();
        let moved = (center.as_dvec3() - c).length();
        Self {
            center,
            radius: pad_radius(f32_at_or_above(r + moved)),
        }
    }
}

impl BoundingVolume for BoundingSphere {
    const NAME: &'static str = "sphere";

    fn enclosing<P: Primitive>(prims: &[P], frame: &Frame) -> Self {
        if prims.is_empty() {
            return Self {
                center: Vec3::ZERO,
                radius: -1.0,
            };
        }
        let center = frame.to_local(&Aabb::around(prims)).center();
        let world = center.as_dvec3() + frame.anchor.as_dvec3();
        let r = prims
            .iter()
            .map(|p| p.farthest_distance(world))
            .fold(0.0, f32::max);
        Self {
            center,
            radius: pad_radius(r),
        }
    }

    fn merge(&self, o: &Self) -> Self {
        if self.radius < 0.0 {
            return *o;
        }
        if o.radius < 0.0 {
            return *self;
        }
        let (c0, c1) = (self.center.as_dvec3(), o.center.as_dvec3());
        let (r0, r1) = (self.radius as f64, o.radius as f64);
        let d = c1 - c0;
        let dist = d.length();
        if dist + r1 <= r0 {
            return *self;
        }
        if dist + r0 <= r1 {
            return *o;
        }
        let radius = 0.5 * (dist + r0 + r1);
        Self::around(c0 + d * ((radius - r0) / dist), radius)
    }

    type RayData = LocalRay;

    #[inline]
    fn ray_data(ray: &Ray, frame: &Frame) -> LocalRay {
        LocalRay::new(ray, frame)
    }

    #[inline]
    fn entry_from(&self, ray: &Ray, local: &LocalRay) -> Option<f32> {
        if !ray.is_valid() {
            return None;
        }
        if self.radius == 0.0 {
            // A point (the sphere of a point primitive): its box in world coordinates.
            let frame = Frame {
                anchor: local.anchor,
            };
            let point = Aabb::new(self.center, self.center);
            return frame.to_world(&point).hit_distance(ray);
        }
        if !(self.radius <= f32::MAX) {
            // Distances between vertices near the largest floats overflow to an infinite (or,
            // once merged, NaN) radius: such a sphere holds everything.
            return clip_interval(ray.tmin, ray.tmax, ray);
        }
        if !(self.radius > 0.0) {
            return None; // the empty volume
        }
        // Roots in f64 from the exact local origin (for rays that graze the sphere an f32
        // discriminant loses so much that the padded radius would not cover it), with the
        // radius grown by the slack, rounded outwards.
        let f = local.origin - self.center.as_dvec3();
        let r = self.radius as f64;
        let r = r + SLACK * (r + f.length());
        let (t0, t1) = roots_from(f, local.dir, r)?;
        let (t0, t1) = (f32_at_or_below(t0), f32_at_or_above(t1));
        clip_interval(pad_down(t0), pad_up(t1), ray)
    }
}

/// Enlarge a radius (already rounded up) by a few ulps.
fn pad_radius(r: f32) -> f32 {
    r + gamma(8) * r
}

/// `[t0, t1]` clipped to the ray's interval; the entry distance.
#[inline]
fn clip_interval(t0: f32, t1: f32, ray: &Ray) -> Option<f32> {
    let t0 = t0.max(ray.tmin);
    let t1 = t1.min(ray.tmax);
    (t0 <= t1).then_some(t0)
}

/// The seven slab normals of Kay & Kajiya: the three axes and the four diagonals of the cube.
/// They are not normalised; slab distances do not depend on the normal's length.
pub const KDOP7_NORMALS: [Vec3; 7] = [
    Vec3::X,
    Vec3::Y,
    Vec3::Z,
    Vec3::new(1.0, 1.0, 1.0),
    Vec3::new(1.0, 1.0, -1.0),
    Vec3::new(1.0, -1.0, 1.0),
    Vec3::new(-1.0, 1.0, 1.0),
];

/// A discrete oriented polytope of seven slabs in a list's frame: `near[i] <= n_i . (p -
/// anchor) <= far[i]` for every point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kdop7 {
    /// Per slab normal, the lowest projection.
    pub near: [f32; 7],
    /// Per slab normal, the highest projection.
    pub far: [f32; 7],
    /// The largest absolute local coordinate of the volume's points, from the axis slabs:
    /// the scale of the ray test's slack (kept with the slabs, not recomputed per ray).
    pub size: f32,
}

impl Kdop7 {
    /// The empty polytope: the identity of merging.
    pub const EMPTY: Kdop7 = Kdop7 {
        near: [f32::INFINITY; 7],
        far: [f32::NEG_INFINITY; 7],
        size: 0.0,
    };

    /// `size` from the axis slabs (0 for the empty polytope).
    fn with_size(mut self) -> Self {
        self.size = (0..3)
            .filter(|&a| self.near[a] <= self.far[a])
            .map(|a| self.near[a].abs().max(self.far[a].abs()))
            .fold(0.0, f32::max);
        self
    }
}

/// A ray against the seven slab normals: per normal, `n . (origin - anchor)` and `n . dir` in
/// `f64`, and the largest local coordinate of the origin (for the slack).
#[derive(Clone, Copy, Debug)]
pub struct SlabProjections {
    on: [f64; 7],
    dn: [f64; 7],
    inv_dn: [f64; 7],
    origin_size: f64,
}

/// `|n|_1` of each of [`KDOP7_NORMALS`]: how much `n . p` grows with `|p|_inf`.
const KDOP7_NORM1: [f64; 7] = [1.0, 1.0, 1.0, 3.0, 3.0, 3.0, 3.0];

impl BoundingVolume for Kdop7 {
    const NAME: &'static str = "kdop7";

    /// Each slab from [`Primitive::extent_along_from`] the anchor (rounded outward).
    fn enclosing<P: Primitive>(prims: &[P], frame: &Frame) -> Self {
        let mut k = Self::EMPTY;
        for p in prims {
            for (i, n) in KDOP7_NORMALS.iter().enumerate() {
                let (lo, hi) = p.extent_along_from(frame.anchor, *n);
                k.near[i] = k.near[i].min(lo);
                k.far[i] = k.far[i].max(hi);
            }
        }
        k.with_size()
    }

    fn merge(&self, o: &Self) -> Self {
        let mut k = *self;
        for i in 0..7 {
            k.near[i] = k.near[i].min(o.near[i]);
            k.far[i] = k.far[i].max(o.far[i]);
        }
        k.with_size()
    }

    type RayData = SlabProjections;

    #[inline]
    fn ray_data(ray: &Ray, frame: &Frame) -> SlabProjections {
        let l = LocalRay::new(ray, frame);
        let n = KDOP7_NORMALS.map(|n| n.as_dvec3());
        let dn = n.map(|n| n.dot(l.dir));
        SlabProjections {
            on: n.map(|n| n.dot(l.origin)),
            dn,
            inv_dn: dn.map(|d| 1.0 / d),
            origin_size: l.origin.abs().max_element(),
        }
    }

    #[inline]
    fn entry_from(&self, ray: &Ray, s: &SlabProjections) -> Option<f32> {
        if !ray.is_valid() {
            return None;
        }
        if !(self.near[0] <= self.far[0]) {
            return None; // the empty volume
        }
        // The slack, for the distance between the origin and the volume's points.
        let slack = SLACK * (s.origin_size + self.size as f64);
        let (mut t0, mut t1) = (ray.tmin as f64, ray.tmax as f64);
        for (i, norm1) in KDOP7_NORM1.iter().enumerate() {
            let (near, far) = (self.near[i] as f64, self.far[i] as f64);
            let err = slack * norm1;
            let (near, far, on, dn) = (near - err, far + err, s.on[i], s.dn[i]);
            if dn == 0.0 {
                if on < near || on > far {
                    return None;
                }
                continue;
            }
            let (ta, tb) = ((near - on) * s.inv_dn[i], (far - on) * s.inv_dn[i]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
            if t0 > t1 {
                return None;
            }
        }
        // Outward to f32, then the relative padding of the box test for the f64 roundings.
        let (t0, t1) = (pad_down(f32_at_or_below(t0)), pad_up(f32_at_or_above(t1)));
        clip_interval(t0, t1, ray)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Sphere, Triangle};

    fn check_conservative<V: BoundingVolume>() {
        let tris = [
            Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y),
            Triangle::new(
                Vec3::new(3.0, 1.0, 2.0),
                Vec3::new(2.0, 3.0, 1.0),
                Vec3::ONE,
            ),
        ];
        let v = V::enclosing(&tris, &Frame::WORLD);
        let mut state = 7u64;
        let mut rnd = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut hits = 0;
        for _ in 0..20_000 {
            let o = Vec3::new(rnd(), rnd(), rnd()) * 10.0 - 5.0;
            let target = Vec3::new(rnd(), rnd(), rnd()) * 3.5 - 0.25;
            let r = Ray::new(o, target - o);
            let prim_hit = tris
                .iter()
                .filter_map(|t| t.intersect_watertight(&r))
                .map(|h| h.t);
            if let Some(t) =
                prim_hit.fold(None, |a: Option<f32>, t| Some(a.map_or(t, |a| a.min(t))))
            {
                hits += 1;
                let e = v.entry_distance(&r, &Frame::WORLD);
                assert!(e.is_some_and(|e| e <= t), "{} missed a hit: {r:?}", V::NAME);
            }
        }
        assert!(hits > 1000);
        let empty = V::enclosing::<Triangle>(&[], &Frame::WORLD);
        assert!(
            empty
                .entry_distance(&Ray::new(Vec3::splat(-1.0), Vec3::ONE), &Frame::WORLD)
                .is_none()
        );
        let merged = empty.merge(&v);
        assert!(
            merged
                .entry_distance(&Ray::new(Vec3::splat(-1.0), Vec3::ONE), &Frame::WORLD)
                .is_some()
        );
    }

    #[test]
    fn volumes_are_conservative() {
        check_conservative::<Aabb>();
        check_conservative::<BoundingSphere>();
        check_conservative::<Kdop7>();
    }

    #[test]
    fn kdop_is_tighter_than_box_on_a_diagonal_sliver() {
        let w = Frame::WORLD;
        let t = Triangle::new(Vec3::ZERO, Vec3::ONE, Vec3::new(1.0, 1.0, 0.9));
        let k = Kdop7::enclosing(&[t], &w);
        // Passes through the box's corner region but far from the diagonal.
        let r = Ray::new(Vec3::new(0.9, 0.1, -1.0), Vec3::Z);
        assert!(Aabb::around(&[t]).entry_distance(&r, &w).is_some());
        assert!(k.entry_distance(&r, &w).is_none());
    }

    #[test]
    fn sphere_volume_of_spheres() {
        let w = Frame::WORLD;
        let s = [
            Sphere::new(Vec3::ZERO, 1.0),
            Sphere::new(Vec3::new(4.0, 0.0, 0.0), 1.0),
        ];
        let b = BoundingSphere::enclosing(&s, &w);
        assert!(b.radius >= 3.0 && b.radius < 3.001);
        let m =
            BoundingSphere::enclosing(&s[..1], &w).merge(&BoundingSphere::enclosing(&s[1..], &w));
        assert!((m.radius - 3.0).abs() < 1e-3 && (m.center.x - 2.0).abs() < 1e-3);
    }

    /// A small triangle at 5e6, where world `f32` coordinates step by 0.5: in the list's frame
    /// its sphere and k-DOP are as tight as at the origin, and hold every hit of rays from
    /// nearby and from the world's origin.
    fn check_far<V: BoundingVolume>() {
        let far = Vec3::new(3.0e5, 5.0e6, -2.0e4);
        let t = Triangle::new(
            far,
            far + Vec3::new(0.5, 0.0, 0.0),
            far + Vec3::new(0.0, 0.5, 0.5),
        );
        let frame = Frame::of(&t.bounds());
        let v = V::enclosing(&[t], &frame);
        // A ray passing 1.5 units beside the triangle misses the volume.
        let beside = Ray::new(far + Vec3::new(2.0, 0.0, -4.0), Vec3::Z);
        assert!(v.entry_distance(&beside, &frame).is_none(), "{}", V::NAME);
        let mut hits = 0;
        for i in 0..400 {
            let (a, b) = ((i % 20) as f32 / 19.0, (i / 20) as f32 / 19.0);
            let target = far + Vec3::new(0.5 * a * (1.0 - b), 0.5 * b, 0.5 * b);
            for o in [far + Vec3::new(1.0, -2.0, -3.0), Vec3::ZERO] {
                let r = Ray::new(o, target - o);
                if let Some(h) = t.intersect_watertight(&r) {
                    hits += 1;
                    let e = v.entry_distance(&r, &frame);
                    assert!(
                        e.is_some_and(|e| e <= h.t),
                        "{} missed a hit: {r:?}",
                        V::NAME
                    );
                }
            }
        }
        assert!(hits > 300, "{hits}");
    }

    #[test]
    fn far_volumes_are_tight_and_conservative() {
        check_far::<BoundingSphere>();
        check_far::<Kdop7>();
    }
}
