//! The O(n) baseline: test every primitive. The reference every structure is checked against.

use crate::accel::check_primitives;
use crate::{Accel, AccelStats, BuildError, Filtered, FilteredAccel, Hit, Keep, Primitive, Ray};

/// Tests every primitive against every ray.
#[derive(Clone, Debug)]
pub struct BruteForce<P> {
    prims: Vec<P>,
}

impl<P: Primitive> BruteForce<P> {
    /// Copies the primitives. Fails on non-finite coordinates or more than `u32::MAX - 1`
    /// primitives (`u32::MAX` is the miss marker of hit files).
    pub fn build(prims: &[P]) -> Result<Self, BuildError> {
        check_primitives(prims, u32::MAX as usize - 1)?;
        Ok(Self {
            prims: prims.to_vec(),
        })
    }

    /// The primitives, in the caller's order.
    pub fn primitives(&self) -> &[P] {
        &self.prims
    }
}

impl<P: Primitive> BruteForce<P> {
    /// Every primitive in index order, each hit offered to `best`: in index order,
    /// [`crate::replaces`] keeps the first of equal-`t` hits.
    fn query<const ANY_HIT: bool>(&self, ray: &Ray, mut best: impl Keep) -> Option<Hit> {
        if !ray.is_valid() {
            return None;
        }
        let mut r = *ray;
        for (i, p) in self.prims.iter().enumerate() {
            if best.skips(i as u32) {
                continue;
            }
            // Any-hit queries ask each primitive over the whole interval, as the structures'
            // any-hit walks (whose `tmax` never shrinks) do.
            if let Some(h) = p.intersect(&r) {
                if best.keep::<ANY_HIT>(h, i as u32, &mut r.tmax) {
                    break;
                }
            }
        }
        best.best()
    }
}

impl<P: Primitive> Accel for BruteForce<P> {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.query::<false>(ray, None)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        ray.is_valid() && self.prims.iter().any(|p| p.intersect(ray).is_some())
    }

    fn stats(&self) -> AccelStats {
        AccelStats {
            primitives: self.prims.len(),
            nodes: 1,
            leaves: 1,
            references: self.prims.len(),
            max_depth: 0,
            bytes: std::mem::size_of_val(self.prims.as_slice()),
            sah_cost: None,
        }
    }

    fn validate(&self) -> Result<(), String> {
        match self.prims.iter().position(|p| !p.is_finite()) {
            Some(i) => Err(format!("primitive {i} is not finite")),
            None => Ok(()),
        }
    }

    fn filtered(&self) -> Option<&dyn FilteredAccel> {
        Some(self)
    }
}

/// The reference of filtered queries: the closest accepted hit, or whether one is accepted.
impl<P: Primitive> FilteredAccel for BruteForce<P> {
    fn intersect_filtered(&self, ray: &Ray, filter: &mut dyn crate::HitFilter) -> Option<Hit> {
        self.query::<false>(ray, Filtered::new(filter))
    }

    fn occluded_filtered(&self, ray: &Ray, filter: &mut dyn crate::HitFilter) -> bool {
        self.query::<true>(ray, Filtered::new(filter)).is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Sphere, Triangle};
    use glam::Vec3;

    #[test]
    fn closest_hit_and_occlusion() {
        let tris = [
            Triangle::new(
                Vec3::new(-1.0, -1.0, 2.0),
                Vec3::new(1.0, -1.0, 2.0),
                Vec3::new(0.0, 1.0, 2.0),
            ),
            Triangle::new(
                Vec3::new(-1.0, -1.0, 1.0),
                Vec3::new(1.0, -1.0, 1.0),
                Vec3::new(0.0, 1.0, 1.0),
            ),
        ];
        let b = BruteForce::build(&tris).unwrap();
        let r = Ray::new(Vec3::ZERO, Vec3::Z);
        let h = b.intersect(&r).unwrap();
        assert_eq!((h.t, h.prim), (1.0, 1));
        assert!(b.occluded(&r));
        assert!(!b.occluded(&r.with_range(0.0, 0.5)));
        assert_eq!(b.intersect(&r.with_range(1.5, 9.0)).unwrap().prim, 0);
        assert!(b.stats().check_consistency().is_ok());
        b.validate().unwrap();
    }

    #[test]
    fn bad_input() {
        let empty = BruteForce::<Sphere>::build(&[]).unwrap();
        assert!(empty.intersect(&Ray::new(Vec3::ZERO, Vec3::X)).is_none());
        let nan = [
            Sphere::new(Vec3::ZERO, 1.0),
            Sphere::new(Vec3::new(f32::NAN, 0.0, 0.0), 1.0),
        ];
        assert_eq!(
            BruteForce::build(&nan).unwrap_err(),
            BuildError::NonFinite { prim: 1 }
        );
        let b = BruteForce::build(&nan[..1]).unwrap();
        assert!(
            b.intersect(&Ray::new(Vec3::splat(-3.0), Vec3::ZERO))
                .is_none()
        );
        assert!(!b.occluded(&Ray::new(Vec3::splat(-3.0), Vec3::ZERO)));
    }
}
