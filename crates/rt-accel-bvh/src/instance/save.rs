//! Saved two-level scenes: an [`InstanceBvh`]'s instances and top level as bytes and back
//! (the format at [`InstanceBvh::to_bytes`]), its objects saved as their own structures.

use super::{Instance, InstanceBvh, Object};
use crate::Bvh;
use rt_geom::Accel;
use rt_geom::glam::{Affine3A, Mat3A, Vec3A};
use rt_geom::saved::{LoadError, Reader, Writer, words_hash};

const MAGIC: &[u8; 8] = b"rt-inst\n";
const VERSION: u32 = 1;

impl<O: Accel> InstanceBvh<O> {
    /// The instances and the top level as bytes; the objects are saved apart, as their own
    /// structures (each structure's `to_bytes`). A plain little-endian layout, versioned:
    ///
    /// ```text
    /// magic      8 bytes  "rt-inst\n"
    /// version    u32      1
    /// objects    u64 count, each object's primitive count (u32)
    /// instances  u64 count, each: object u32, transform 12 f32 (the columns of the linear
    ///            part, then the translation); then u64: the 64-bit FNV-1a hash of those words
    /// top        u64 byte count, then the top level's bytes (`Bvh::to_bytes` over the
    ///            instances' world boxes)
    /// ```
    ///
    /// [`Self::from_bytes`] takes the objects again (loaded from their own bytes, or built),
    /// checks them against the primitive counts, the instances against their hash and as
    /// [`InstanceBvh::build`] checks them, and the top level as `Bvh::from_bytes` does, over
    /// the world boxes that the objects and the instances give (a hash of them is in its
    /// bytes: objects of other extents are refused).
    ///
    /// ```
    /// use rt_accel_bvh::{BvhParams, Instance, InstanceBvh, Object, TriBvh8};
    /// use rt_geom::glam::Affine3A;
    /// use rt_geom::{Accel, Ray, Triangle, Vec3};
    ///
    /// let triangle = [Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)];
    /// let object = || Object::build(&triangle, TriBvh8::build_for_tracing).unwrap();
    /// let instances: Vec<Instance> = (0..3)
    ///     .map(|i| Instance { object: 0, transform: Affine3A::from_translation(-Vec3::Z * i as f32) })
    ///     .collect();
    /// let scene = InstanceBvh::build(vec![object()], &instances, BvhParams::balanced()).unwrap();
    /// let bytes = scene.to_bytes();
    /// let loaded = InstanceBvh::from_bytes(&bytes, vec![object()]).unwrap();
    /// let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z);
    /// assert_eq!(loaded.intersect(&ray), scene.intersect(&ray));
    /// assert!(InstanceBvh::from_bytes(&bytes[..bytes.len() - 1], vec![object()]).is_err());
    /// ```
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Writer::default();
        out.header(MAGIC, VERSION);
        out.u64(self.objects.len() as u64);
        self.objects.iter().for_each(|o| out.u32(o.primitives));
        out.u64(self.instances.len() as u64);
        let words: Vec<u32> = self.instances.iter().flat_map(instance_words).collect();
        words.iter().for_each(|&w| out.u32(w));
        out.u64(words_hash(words));
        let top = self.top.to_bytes();
        out.u64(top.len() as u64);
        out.0.extend_from_slice(&top);
        out.0
    }

    /// The scene [`Self::to_bytes`] saved, over `objects` (the same as it was built over):
    /// the same answers, bit for bit. Other objects, or any other bytes, give a
    /// [`LoadError`].
    pub fn from_bytes(bytes: &[u8], objects: Vec<Object<O>>) -> Result<Self, LoadError> {
        let mut r = Reader(bytes);
        r.header(MAGIC, VERSION)?;
        let count = r.count(4)?;
        let counts = (0..count).map(|_| r.u32()).collect::<Result<Vec<_>, _>>()?;
        let count = r.count(52)?;
        let mut instances = Vec::with_capacity(count);
        for _ in 0..count {
            let object = r.u32()?;
            let mut c = [Vec3A::ZERO; 4];
            for column in &mut c {
                *column = Vec3A::new(r.f32()?, r.f32()?, r.f32()?);
            }
            let transform = Affine3A {
                matrix3: Mat3A::from_cols(c[0], c[1], c[2]),
                translation: c[3],
            };
            instances.push(Instance { object, transform });
        }
        // A changed transform can leave every world box as it was (a low bit of a factor):
        // the words' hash tells.
        if r.u64()? != words_hash(instances.iter().flat_map(instance_words)) {
            return Err(LoadError::Corrupt(
                "the instances do not match their hash".into(),
            ));
        }
        let count = r.count(1)?;
        let (top, rest) = r.0.split_at(count);
        if !rest.is_empty() {
            return Err(LoadError::TrailingBytes);
        }
        if !counts
            .iter()
            .copied()
            .eq(objects.iter().map(|o| o.primitives))
        {
            return Err(LoadError::OtherPrimitives);
        }
        Self::over(objects, &instances, |boxes| Bvh::from_bytes(top, boxes))
    }
}

/// An instance as the words the format stores: its object, then its transform's columns.
fn instance_words(inst: &Instance) -> impl Iterator<Item = u32> {
    let t = inst.transform;
    let columns = [
        t.matrix3.x_axis,
        t.matrix3.y_axis,
        t.matrix3.z_axis,
        t.translation,
    ];
    let floats = columns
        .into_iter()
        .flat_map(|c| c.to_array())
        .map(f32::to_bits);
    std::iter::once(inst.object).chain(floats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{BvhParams, TriBvh8};
    use rt_geom::{BruteForce, Triangle, Vec3};
    use rt_testkit::scenes;

    /// Objects of a scene (a sphere and a soup) placed five times, and the same scene
    /// flattened, for brute force.
    fn scene() -> (Vec<Vec<Triangle>>, Vec<Instance>) {
        let objects = vec![
            scenes::tessellated_sphere(200, Vec3::ZERO, 0.3),
            scenes::random_soup(150, 4),
        ];
        let instances = (0..5)
            .map(|i| Instance {
                object: i % 2,
                transform: Affine3A::from_scale_rotation_translation(
                    Vec3::splat(0.5 + 0.1 * i as f32),
                    rt_geom::glam::Quat::from_rotation_y(0.7 * i as f32),
                    Vec3::new(i as f32 * 0.4 - 1.0, 0.1 * i as f32, 0.0),
                ),
            })
            .collect();
        (objects, instances)
    }

    fn objects(meshes: &[Vec<Triangle>]) -> Vec<Object<TriBvh8>> {
        meshes
            .iter()
            .map(|m| Object::build(m, TriBvh8::build_for_tracing).unwrap())
            .collect()
    }

    /// A saved scene loads back over the same objects with the same answers and the same
    /// bytes (rays that meet it: checked against the flattened scene's brute force); damaged
    /// bytes are refused or answer as the saved scene did; other objects are refused.
    #[test]
    fn round_trips_and_refuses_damage_and_other_objects() {
        let (meshes, instances) = scene();
        let built =
            InstanceBvh::build(objects(&meshes), &instances, BvhParams::balanced()).unwrap();
        let rays = rt_testkit::rays::rays_through_unit_cube(1500);
        let load = |b: &[u8]| InstanceBvh::from_bytes(b, objects(&meshes));
        rt_testkit::assert_round_trip(&built, InstanceBvh::to_bytes, load, &rays);
        let flat: Vec<Triangle> = instances
            .iter()
            .flat_map(|inst| {
                let t = inst.transform;
                meshes[inst.object as usize].iter().map(move |tri| {
                    Triangle::new(
                        t.transform_point3(tri.v[0]),
                        t.transform_point3(tri.v[1]),
                        t.transform_point3(tri.v[2]),
                    )
                })
            })
            .collect();
        let brute = BruteForce::build(&flat).unwrap();
        let hits = rays.iter().filter(|r| brute.intersect(r).is_some()).count();
        assert!(hits > 100, "{hits} hits: the rays must meet the scene");
        let bytes = built.to_bytes();
        rt_testkit::assert_damage_refused(&bytes, load, &built, &rays[..300]);
        let mut other = meshes.clone();
        other[1].pop();
        assert_eq!(
            InstanceBvh::from_bytes(&bytes, objects(&other)).err(),
            Some(LoadError::OtherPrimitives)
        );
        let mut moved = meshes.clone();
        for t in &mut moved[0] {
            t.v = t.v.map(|p| p * 1.5);
        }
        assert!(InstanceBvh::from_bytes(&bytes, objects(&moved)).is_err());
    }
}
