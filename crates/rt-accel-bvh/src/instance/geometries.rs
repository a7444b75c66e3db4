//! An instance scene whose objects are [`Geometries`]: a hit names the instance, the geometry
//! in its object and the primitive in that geometry, with the geometric normal in world space;
//! a query's mask meets a mask per geometry and one per instance.
//!
//! ```
//! use rt_accel_bvh::{BvhParams, Instance, InstanceBvh, Object, TriBvh8};
//! use rt_geom::glam::Affine3A;
//! use rt_geom::{Geometries, Ray, Triangle, Vec3};
//!
//! const CAMERA: u32 = 1;
//! const SHADOW: u32 = 2;
//! // One object: a floor tile (seen, casts shadows) and a sticker above it (seen only).
//! let mut object = Geometries::new();
//! object.add([Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)], CAMERA | SHADOW);
//! let sticker = Triangle::new(Vec3::Z * 0.5, Vec3::X + Vec3::Z * 0.5, Vec3::Y + Vec3::Z * 0.5);
//! object.add([sticker], CAMERA);
//! let built = Object::build(object.primitives(), TriBvh8::build_for_tracing).unwrap();
//! // Two copies, the second two units to the right.
//! let instances: Vec<Instance> = (0..2)
//!     .map(|i| Instance { object: 0, transform: Affine3A::from_translation(Vec3::X * 2.0 * i as f32) })
//!     .collect();
//! let scene = InstanceBvh::build(vec![built], &instances, BvhParams::balanced()).unwrap();
//! let geometries = [object];
//! let located = scene.with_geometries(&geometries, &[]).unwrap();
//! let down = Ray::new(Vec3::new(2.2, 0.2, 5.0), -Vec3::Z);
//! let hit = located.intersect(&down, CAMERA).unwrap();
//! assert_eq!((hit.instance, hit.hit.geometry, hit.hit.prim, hit.hit.t), (1, 1, 0, 4.5));
//! assert_eq!(hit.hit.normal, Some(Vec3::Z));
//! // Shadow rays see the tile, not the sticker.
//! assert_eq!(located.intersect(&down, SHADOW).unwrap().hit.geometry, 0);
//! ```

use super::InstanceBvh;
use rt_geom::{Accel, BuildError, FilteredAccel, Geometries, GeometryHit, Hit, HitFilter};
use rt_geom::{Primitive, Ray, Vec3};

/// A hit of [`InstancedGeometries`]: the instance, and the hit located in its object's
/// geometries (the normal in world space).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstanceGeometryHit {
    /// The instance hit.
    pub instance: u32,
    /// Where, on which geometry of the instance's object and which primitive of it.
    pub hit: GeometryHit,
}

/// An [`InstanceBvh`] whose object `o` was built over `geometries[o].primitives()`, with a
/// mask per instance: made by [`InstanceBvh::with_geometries`].
pub struct InstancedGeometries<'a, O, P> {
    scene: &'a InstanceBvh<O>,
    geometries: &'a [Geometries<P>],
    instance_masks: &'a [u32],
}

impl<O: Accel> InstanceBvh<O> {
    /// The scene read through its objects' geometries: object `o` must have been built over
    /// `geometries[o].primitives()`; `instance_masks[i]` is instance `i`'s mask (instances past
    /// the end are seen by every query). Fails when the counts of objects or of their
    /// primitives differ.
    pub fn with_geometries<'a, P: Primitive>(
        &'a self,
        geometries: &'a [Geometries<P>],
        instance_masks: &'a [u32],
    ) -> Result<InstancedGeometries<'a, O, P>, BuildError> {
        let mismatch = |value: String| BuildError::InvalidParameter {
            name: "geometries",
            value,
            expected: "one Geometries per object, over the object's primitives",
        };
        if geometries.len() != self.objects.len() {
            return Err(mismatch(format!(
                "{} for {} objects",
                geometries.len(),
                self.objects.len()
            )));
        }
        for (o, (g, object)) in geometries.iter().zip(&self.objects).enumerate() {
            if g.primitives().len() != object.primitives as usize {
                return Err(mismatch(format!(
                    "{} primitives for object {o} of {}",
                    g.primitives().len(),
                    object.primitives
                )));
            }
        }
        Ok(InstancedGeometries {
            scene: self,
            geometries,
            instance_masks,
        })
    }
}

impl<O: Accel, P: Primitive> InstancedGeometries<'_, O, P> {
    /// The closest hit among the geometries and instances whose masks share a bit with `mask`.
    pub fn intersect(&self, ray: &Ray, mask: u32) -> Option<InstanceGeometryHit> {
        let hit = self.scene.intersect_filtered(ray, &mut self.masked(mask))?;
        let instance = self.instance_of(hit.prim);
        let object = self.scene.instances[instance].object as usize;
        let to_object = &self.scene.to_object[instance];
        let local_ray = Ray::segment(
            to_object.transform_point3(ray.origin()),
            to_object.transform_vector3(ray.dir()),
            ray.tmin,
            ray.tmax,
        );
        let local = Hit {
            prim: hit.prim - self.scene.first_prim[instance],
            ..hit
        };
        let mut located = self.geometries[object].located(&local_ray, &local);
        // Normals go to world space by the inverse transpose of object-to-world, which is
        // the transpose of world-to-object.
        located.normal = located.normal.map(|n| {
            let world = to_object.matrix3.transpose() * rt_geom::glam::Vec3A::from(n);
            Vec3::from(world.normalize())
        });
        Some(InstanceGeometryHit {
            instance: instance as u32,
            hit: located,
        })
    }

    /// Whether the ray has a hit among the geometries and instances whose masks share a bit
    /// with `mask`.
    pub fn occluded(&self, ray: &Ray, mask: u32) -> bool {
        self.scene.occluded_filtered(ray, &mut self.masked(mask))
    }

    /// The instance global primitive `prim` belongs to.
    fn instance_of(&self, prim: u32) -> usize {
        let first = &self.scene.first_prim[..self.scene.instances.len()];
        first.partition_point(|&f| f <= prim) - 1
    }

    fn masked(&self, mask: u32) -> GeometryMasks<'_, O, P> {
        GeometryMasks { of: self, mask }
    }
}

/// The masks of the geometries (each primitive's, found through its instance's object) and
/// of the instances, against one query's.
struct GeometryMasks<'a, O, P> {
    of: &'a InstancedGeometries<'a, O, P>,
    mask: u32,
}

impl<O: Accel, P: Primitive> HitFilter for GeometryMasks<'_, O, P> {
    fn skips(&self, prim: u32) -> bool {
        let instance = self.of.instance_of(prim);
        let object = self.of.scene.instances[instance].object as usize;
        let local = prim - self.of.scene.first_prim[instance];
        self.of.geometries[object].prim_mask(local) & self.mask == 0
    }

    fn skips_instance(&self, instance: u32) -> bool {
        let masks = self.of.instance_masks;
        masks
            .get(instance as usize)
            .is_some_and(|m| m & self.mask == 0)
    }

    fn accepts(&mut self, _: &Hit) -> bool {
        true
    }
}
