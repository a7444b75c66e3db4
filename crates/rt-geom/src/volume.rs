//! Bounding volumes (Kay & Kajiya 1986): sphere, axis-aligned box and a k-DOP of
//! seven slabs, each with a conservative ray test that returns the entry distance.

use crate::aabb::{gamma, pad_down, pad_up};
use crate::sphere::sphere_roots;
use crate::{Aabb, Primitive, Ray};
use glam::Vec3;

/// A volume around a set of primitives that a ray can be tested against.
///
/// Every implementation is conservative: a ray that hits a primitive inside the volume (with `t`
/// in `[tmin, tmax]`) also enters the volume at some `t <= ` that hit.
pub trait BoundingVolume: Clone + Send + Sync + std::fmt::Debug + 'static {
    /// Short name (`"sphere"`, `"box"`, `"kdop7"`).
    const NAME: &'static str;

    /// A volume around all of `prims` (empty when `prims` is).
    fn enclosing<P: Primitive>(prims: &[P]) -> Self;

    /// A volume around both volumes (volumes of volumes).
    fn merge(&self, other: &Self) -> Self;

    /// What [`Self::entry_from`] needs of a ray beyond the ray itself (the reciprocal
    /// direction for boxes), made once per ray by [`Self::ray_data`] for all the volumes it
    /// meets.
    type RayData;
    /// The per-ray data for all the volumes the ray meets.
    fn ray_data(ray: &Ray) -> Self::RayData;

    /// [`Self::entry_distance`] with the ray's [`Self::RayData`].
    fn entry_from(&self, ray: &Ray, data: &Self::RayData) -> Option<f32>;

    /// Where the ray enters the volume, clamped to `ray.tmin`; `None` if it misses it within
    /// `[tmin, tmax]`.
    #[inline]
    fn entry_distance(&self, ray: &Ray) -> Option<f32> {
        self.entry_from(ray, &Self::ray_data(ray))
    }
}

impl BoundingVolume for Aabb {
    const NAME: &'static str = "box";

    fn enclosing<P: Primitive>(prims: &[P]) -> Self {
        prims.iter().fold(Aabb::EMPTY, |b, p| b.union(p.bounds()))
    }

    fn merge(&self, other: &Self) -> Self {
        self.union(*other)
    }

    /// The reciprocal direction ([`Ray::inv_dir`]).
    type RayData = [f32; 3];

    #[inline]
    fn ray_data(ray: &Ray) -> [f32; 3] {
        ray.inv_dir().to_array()
    }

    /// [`Aabb::hit_distance`], the same numbers.
    #[inline]
    fn entry_from(&self, ray: &Ray, inv: &[f32; 3]) -> Option<f32> {
        self.clip_ray_with_inv(ray, inv).map(|(t0, _)| t0)
    }
}

/// A bounding sphere. The centre is the centre of the primitives' box and the radius the largest
/// distance to any of them, enlarged by a few ulps to absorb rounding.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundingSphere {
    /// Centre.
    pub center: Vec3,
    /// Negative for the empty volume.
    pub radius: f32,
}

impl BoundingVolume for BoundingSphere {
    const NAME: &'static str = "sphere";

    fn enclosing<P: Primitive>(prims: &[P]) -> Self {
        if prims.is_empty() {
            return Self {
                center: Vec3::ZERO,
                radius: -1.0,
            };
        }
        let center = Aabb::enclosing(prims).center();
        let r = prims
            .iter()
            .map(|p| p.farthest_distance(center))
            .fold(0.0, f32::max);
        Self {
            center,
            radius: pad_radius(r, center),
        }
    }

    fn merge(&self, o: &Self) -> Self {
        if self.radius < 0.0 {
            return *o;
        }
        if o.radius < 0.0 {
            return *self;
        }
        let d = o.center - self.center;
        let dist = d.length();
        if dist + o.radius <= self.radius {
            return *self;
        }
        if dist + self.radius <= o.radius {
            return *o;
        }
        let radius = 0.5 * (dist + self.radius + o.radius);
        let center = self.center + d * ((radius - self.radius) / dist);
        Self {
            center,
            radius: pad_radius(radius, center),
        }
    }

    type RayData = ();

    #[inline]
    fn ray_data(_: &Ray) {}

    #[inline]
    fn entry_from(&self, ray: &Ray, _: &()) -> Option<f32> {
        if self.radius == 0.0 {
            // A point: pad_radius keeps radius > 0 for anything but a point at the origin.
            return Aabb::new(self.center, self.center).hit_distance(ray);
        }
        if !(self.radius <= f32::MAX) && ray.is_valid() {
            // Distances between vertices near the largest floats overflow to an infinite (or,
            // once merged, NaN) radius: such a sphere holds everything.
            return clip_interval(ray.tmin, ray.tmax, ray);
        }
        // Roots in f64 (for rays that graze the sphere an f32 discriminant loses so much that
        // the padded radius would not cover it), rounded outwards.
        let (t0, t1) = sphere_roots(self.center, self.radius, ray)?;
        let (t0, t1) = ((t0 as f32).next_down(), (t1 as f32).next_up());
        clip_interval(pad_down(t0), pad_up(t1), ray)
    }
}

/// Enlarge a radius by the rounding of the distance computations around `center`.
fn pad_radius(r: f32, center: Vec3) -> f32 {
    let scale = r + center.abs().max_element();
    r + gamma(8) * scale
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

/// A discrete oriented polytope of seven slabs: `near[i] <= n_i . p <= far[i]` for every point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kdop7 {
    /// Per slab normal, the lowest projection.
    pub near: [f32; 7],
    /// Per slab normal, the highest projection.
    pub far: [f32; 7],
}

impl Kdop7 {
    /// The empty polytope: the identity of merging.
    pub const EMPTY: Kdop7 = Kdop7 {
        near: [f32::INFINITY; 7],
        far: [f32::NEG_INFINITY; 7],
    };
}

impl BoundingVolume for Kdop7 {
    const NAME: &'static str = "kdop7";

    fn enclosing<P: Primitive>(prims: &[P]) -> Self {
        let mut k = Self::EMPTY;
        for p in prims {
            for (i, n) in KDOP7_NORMALS.iter().enumerate() {
                let (lo, hi) = p.extent_along(*n);
                k.near[i] = k.near[i].min(lo);
                k.far[i] = k.far[i].max(hi);
            }
        }
        if prims.is_empty() {
            return k;
        }
        // Pad each slab by the rounding error of `n . p` for points inside the primitives' box.
        let b = Aabb::enclosing(prims);
        let mag = b.min.abs().max(b.max.abs());
        for (i, n) in KDOP7_NORMALS.iter().enumerate() {
            let pad = gamma(4) * n.abs().dot(mag);
            k.near[i] -= pad;
            k.far[i] += pad;
        }
        k
    }

    fn merge(&self, o: &Self) -> Self {
        let mut k = *self;
        for i in 0..7 {
            k.near[i] = k.near[i].min(o.near[i]);
            k.far[i] = k.far[i].max(o.far[i]);
        }
        k
    }

    type RayData = ();

    #[inline]
    fn ray_data(_: &Ray) {}

    #[inline]
    fn entry_from(&self, ray: &Ray, _: &()) -> Option<f32> {
        if !ray.is_valid() {
            return None;
        }
        let (o, d) = (ray.origin(), ray.dir());
        let mut t0 = ray.tmin;
        let mut t1 = ray.tmax;
        for (i, n) in KDOP7_NORMALS.iter().enumerate() {
            let on = n.dot(o);
            let dn = n.dot(d);
            // Rounding of `n . o` as an extra margin on the slab.
            let err = gamma(3) * n.abs().dot(o.abs());
            let (near, far) = (self.near[i] - err, self.far[i] + err);
            if !(near <= far) {
                return None; // the empty volume
            }
            if dn == 0.0 {
                if on < near || on > far {
                    return None;
                }
                continue;
            }
            let (mut ta, mut tb) = ((near - on) / dn, (far - on) / dn);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(pad_down(ta));
            t1 = t1.min(pad_up(tb));
            if t0 > t1 {
                return None;
            }
        }
        Some(t0)
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
        let v = V::enclosing(&tris);
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
                let e = v.entry_distance(&r);
                assert!(e.is_some_and(|e| e <= t), "{} missed a hit: {r:?}", V::NAME);
            }
        }
        assert!(hits > 1000);
        let empty = V::enclosing::<Triangle>(&[]);
        assert!(
            empty
                .entry_distance(&Ray::new(Vec3::splat(-1.0), Vec3::ONE))
                .is_none()
        );
        let merged = empty.merge(&v);
        assert!(
            merged
                .entry_distance(&Ray::new(Vec3::splat(-1.0), Vec3::ONE))
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
        let t = Triangle::new(Vec3::ZERO, Vec3::ONE, Vec3::new(1.0, 1.0, 0.9));
        let k = Kdop7::enclosing(&[t]);
        // Passes through the box's corner region but far from the diagonal.
        let r = Ray::new(Vec3::new(0.9, 0.1, -1.0), Vec3::Z);
        assert!(Aabb::enclosing(&[t]).entry_distance(&r).is_some());
        assert!(k.entry_distance(&r).is_none());
    }

    #[test]
    fn sphere_volume_of_spheres() {
        let s = [
            Sphere::new(Vec3::ZERO, 1.0),
            Sphere::new(Vec3::new(4.0, 0.0, 0.0), 1.0),
        ];
        let b = BoundingSphere::enclosing(&s);
        assert!(b.radius >= 3.0 && b.radius < 3.001);
        let m = BoundingSphere::enclosing(&s[..1]).merge(&BoundingSphere::enclosing(&s[1..]));
        assert!((m.radius - 3.0).abs() < 1e-3 && (m.center.x - 2.0).abs() < 1e-3);
    }
}
