//! [`Disc`]: user geometry written as a user would, with the two required methods of
//! [`Primitive`] only (`bounds` and `intersect`; the rest from the trait's defaults), and the
//! conformance scenes that take it through every structure.

use crate::rays::SamplePoints;
use crate::{Rng, Scene};
use rt_geom::aabb::{f32_at_or_above, f32_at_or_below};
use rt_geom::{Aabb, PrimHit, Primitive, Ray, Vec3};

/// A flat disc: centre, unit normal, radius.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Disc {
    /// Centre.
    pub center: Vec3,
    /// Unit normal.
    pub normal: Vec3,
    /// Radius.
    pub radius: f32,
}

impl Primitive for Disc {
    /// The exact box (`radius * sqrt(1 - n_a^2)` about the centre per axis, in `f64`),
    /// widened by a relative `1e-5` of the radius and the centre's magnitude: `intersect`
    /// accepts a rim hit by its own rounding, and such a hit must lie in the box.
    fn bounds(&self) -> Aabb {
        let (c, n, r) = (
            self.center.as_dvec3(),
            self.normal.as_dvec3(),
            self.radius as f64,
        );
        let margin = 1e-5 * (r + c.abs().max_element());
        let half = (1.0 - n * n).max(rt_geom::DVec3::ZERO).powf(0.5) * r + margin;
        let (lo, hi) = (c - half, c + half);
        Aabb::new(
            Vec3::from_array(lo.to_array().map(f32_at_or_below)),
            Vec3::from_array(hi.to_array().map(f32_at_or_above)),
        )
    }

    /// The plane's hit, kept when it lies within the radius; `u`, `v` the hit's offset from
    /// the centre over the radius along two fixed directions of the plane.
    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        let d = ray.dir().dot(self.normal);
        if d == 0.0 || self.radius <= 0.0 {
            return None;
        }
        let t = (self.center - ray.origin()).dot(self.normal) / d;
        // A depth beyond the floats (a far origin, a short direction) hits nothing.
        if !(t >= ray.tmin && t <= ray.tmax && t.is_finite()) {
            return None;
        }
        let offset = ray.origin() + t * ray.dir() - self.center;
        if !(offset.length_squared() <= self.radius * self.radius) {
            return None;
        }
        let (e1, e2) = self.normal.any_orthonormal_pair();
        Some(PrimHit {
            t,
            u: offset.dot(e1) / self.radius,
            v: offset.dot(e2) / self.radius,
        })
    }
}

impl SamplePoints for Disc {
    fn sample(&self, u: f32, v: f32) -> Vec3 {
        let (e1, e2) = self.normal.any_orthonormal_pair();
        let (r, phi) = (self.radius * u.sqrt(), std::f32::consts::TAU * v);
        self.center + r * (phi.cos() * e1 + phi.sin() * e2)
    }

    /// Points on the rim, where rays graze.
    fn feature_point(&self, rng: &mut Rng) -> Vec3 {
        self.sample(1.0, rng.f32())
    }
}

/// `n` discs in the unit cube: random normals and radii, a few axis-aligned (rays in their
/// plane), stacks of coplanar and duplicated discs, a few of radius 0 (never hit).
pub fn random_discs(n: usize, seed: u64) -> Vec<Disc> {
    let mut rng = Rng::new(seed);
    let mut discs = Vec::with_capacity(n);
    while discs.len() < n {
        let center = rng.point_in(Vec3::ZERO, Vec3::ONE);
        let normal = match rng.below(8) {
            0 => Vec3::AXES[rng.below(3)],
            _ => rng.unit_vector(),
        };
        let radius = match rng.below(40) {
            0 => 0.0,
            1 => rng.range(0.2, 0.4),
            _ => 0.01 + 0.06 * rng.f32(),
        };
        let disc = Disc {
            center,
            normal,
            radius,
        };
        discs.push(disc);
        match rng.below(12) {
            // A duplicate (ties at the same `t`), or a coplanar neighbour overlapping it.
            0 => discs.push(disc),
            1 => discs.push(Disc {
                center: center + 0.5 * radius * normal.any_orthonormal_vector(),
                ..disc
            }),
            _ => {}
        }
    }
    discs.truncate(n);
    discs
}

/// The disc scenes: `discs` (500 random ones), `one_disc`, `far_discs` (the same far from
/// the origin, as geographic coordinates come).
pub fn disc_scene(name: &str) -> Scene<Disc> {
    let discs = match name {
        "discs" => random_discs(500, 21),
        "one_disc" => random_discs(1, 4),
        "far_discs" => random_discs(300, 22)
            .into_iter()
            .map(|d| Disc {
                center: d.center * 100.0 + Vec3::new(4.0e5, -2.5e5, 6.0e5),
                radius: d.radius * 100.0,
                ..d
            })
            .collect(),
        _ => panic!("no disc scene named {name}"),
    };
    Scene::new(name, discs)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Hits on the rim lie in the box, and the derived methods hold the disc.
    #[test]
    fn hits_lie_in_the_box_and_defaults_hold_the_disc() {
        let mut rng = Rng::new(3);
        for d in random_discs(200, 5).into_iter().filter(|d| d.radius > 0.0) {
            let b = d.bounds();
            assert!(d.is_finite());
            assert!(b.contains_point(d.centroid()));
            for _ in 0..20 {
                let p = d.feature_point(&mut rng);
                let o = p + d.normal * 0.5 + rng.unit_vector() * 0.1;
                if let Some(h) = d.intersect(&Ray::new(o, p - o)) {
                    let at = o + h.t * (p - o);
                    assert!(b.contains_point(at), "{at} outside {b:?}");
                }
                let (lo, hi) = d.extent_along(Vec3::new(1.0, -2.0, 0.5));
                let k = p.dot(Vec3::new(1.0, -2.0, 0.5));
                assert!(lo <= k && k <= hi);
            }
        }
    }
}
