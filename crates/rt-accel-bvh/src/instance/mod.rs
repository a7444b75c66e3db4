//! Two-level ray tracing: objects, each with its own structure, placed by instances (affine
//! transforms) under a top-level binary BVH over the instances' world boxes, as Embree, OptiX
//! and pbrt build scenes. An object is stored once however many instances use it.
//!
//! A ray is walked through the top level in world space; at each instance it enters, it is
//! carried into the object's space (origin and direction by the inverse transform, the
//! direction not normalised, so `t` is the same parameter in both spaces) and asked of the
//! object's structure. Hits name the primitive globally, as the scene flattened instance by
//! instance would (instance `i`'s primitives follow those of instances `0..i`), so an
//! [`InstanceBvh`] is an [`Accel`] like any other; [`InstanceBvh::intersect_instance`] gives
//! the instance and the object's own primitive id.
//!
//! Objects built over [`rt_geom::Geometries`] answer which geometry and primitive of which
//! instance a ray hits, with the normal in world space ([`InstanceBvh::with_geometries`]).
//!
//! Moving things: [`InstanceBvh::set_transforms`] moves instances and
//! [`InstanceBvh::refit_object`] deforms an object (its structure refit); either then refits
//! or rebuilds the top level only ([`TopUpdate`]).
//!
//! ```
//! use rt_accel_bvh::{BvhParams, Instance, InstanceBvh, Object, TriBvh8};
//! use rt_geom::glam::Affine3A;
//! use rt_geom::{Accel, Ray, Triangle, Vec3};
//!
//! let triangle = [Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)];
//! let object = Object::build(&triangle, TriBvh8::build_for_tracing).unwrap();
//! // Three copies, one behind the other.
//! let instances: Vec<Instance> = (0..3)
//!     .map(|i| Instance { object: 0, transform: Affine3A::from_translation(-Vec3::Z * i as f32) })
//!     .collect();
//! let scene = InstanceBvh::build(vec![object], &instances, BvhParams::balanced()).unwrap();
//! let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z);
//! let hit = scene.intersect_instance(&ray).unwrap();
//! assert_eq!((hit.instance, hit.hit.prim, hit.hit.t), (0, 0, 1.0));
//! // As an `Accel`, the primitive id is the flattened scene's: instance 2's triangle is 2.
//! let behind = Ray::segment(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z, 2.5, 10.0);
//! assert_eq!(scene.intersect(&behind).unwrap().prim, 2);
//! ```

mod geometries;
mod save;

pub use geometries::{InstanceGeometryHit, InstancedGeometries};

use crate::refit::{Refit, check_moved};
use crate::{Bvh, BvhParams};
use rt_geom::glam::Affine3A;
use rt_geom::{
    Aabb, Accel, AccelStats, BuildError, FilteredAccel, Hit, HitFilter, Keep, PrimHit, Primitive,
    Ray, Vec3, check_primitives,
};
use std::fmt;
use std::sync::Arc;

/// A structure over an object's primitives (in the object's own space), its box and its
/// primitive count.
#[derive(Clone)]
pub struct Object<O = Arc<dyn FilteredAccel>> {
    accel: O,
    bounds: Aabb,
    primitives: u32,
}

impl<O: Accel> Object<O> {
    /// Builds `build(prims)` as an object over `prims`.
    pub fn build<P: Primitive>(
        prims: &[P],
        build: impl FnOnce(&[P]) -> Result<O, BuildError>,
    ) -> Result<Self, BuildError> {
        check_primitives(prims, u32::MAX as usize - 1)?;
        Self::new(prims, build(prims)?)
    }

    /// The object over `prims` whose structure `accel` (built over them) is.
    pub fn new<P: Primitive>(prims: &[P], accel: O) -> Result<Self, BuildError> {
        check_primitives(prims, u32::MAX as usize - 1)?;
        Ok(Self {
            accel,
            bounds: Aabb::around(prims),
            primitives: prims.len() as u32,
        })
    }

    /// The object's structure.
    pub fn accel(&self) -> &O {
        &self.accel
    }

    /// The box of the object's primitives, in its own space.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The object's primitive count.
    pub fn primitives(&self) -> usize {
        self.primitives as usize
    }
}

impl<A: FilteredAccel + 'static> Object<A> {
    /// The same object behind a shared, type-erased structure, so that objects of different
    /// structure types can sit in one scene.
    pub fn shared(self) -> Object {
        Object {
            accel: Arc::new(self.accel),
            bounds: self.bounds,
            primitives: self.primitives,
        }
    }
}

/// An object placed in the world: `transform` maps the object's space to the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// Index of the object in the scene's object list.
    pub object: u32,
    /// Object space to world space.
    pub transform: Affine3A,
}

/// How the top level follows moved instances or objects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TopUpdate {
    /// Recompute the top level's boxes, keep its tree (fast; degrades as instances travel).
    Refit,
    /// Build the top level again over the new boxes.
    Rebuild,
}

/// The closest hit of an [`InstanceBvh`] with the instance that was hit: `hit.prim` is the
/// object's own primitive id.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstanceHit {
    /// The hit, `prim` numbered within the object.
    pub hit: Hit,
    /// The instance hit.
    pub instance: u32,
}

/// A two-level BVH over instances of objects (see the module documentation).
#[derive(Clone)]
pub struct InstanceBvh<O = Arc<dyn FilteredAccel>> {
    objects: Vec<Object<O>>,
    instances: Vec<Instance>,
    /// World space to object space, per instance.
    to_object: Vec<Affine3A>,
    /// The global id of each instance's first primitive, and the total at the end.
    first_prim: Vec<u32>,
    top: Bvh<WorldBox>,
    params: BvhParams,
}

impl<O: Accel> InstanceBvh<O> {
    /// Builds the top level (a binary BVH with `params`) over `instances` of `objects`. Fails
    /// on an object whose structure has no filtered queries ([`Accel::filtered`]: every rt
    /// structure has them; the scene's filtered queries go through its objects'), an instance
    /// of an object that does not exist, a transform that is not finite or not invertible,
    /// world boxes beyond [`rt_geom::MAX_COORDINATE`], or more primitives in all than a `u32`
    /// numbers.
    pub fn build(
        objects: Vec<Object<O>>,
        instances: &[Instance],
        params: BvhParams,
    ) -> Result<Self, BuildError> {
        params.validate()?;
        Self::over(objects, instances, |boxes| Bvh::build(boxes, params))
    }

    /// The scene of `instances` of `objects` (checked as [`Self::build`] says) whose top
    /// level `top` makes over the instances' world boxes: built, or loaded.
    pub(crate) fn over<E: From<BuildError>>(
        objects: Vec<Object<O>>,
        instances: &[Instance],
        top: impl FnOnce(&[WorldBox]) -> Result<Bvh<WorldBox>, E>,
    ) -> Result<Self, E> {
        if let Some(i) = objects.iter().position(|o| o.accel.filtered().is_none()) {
            return Err(BuildError::InvalidParameter {
                name: "Object::accel",
                value: format!("object {i}, a structure without filtered queries"),
                expected: "a structure whose `Accel::filtered` answers (every rt structure)",
            }
            .into());
        }
        let mut first_prim = Vec::with_capacity(instances.len() + 1);
        let mut total = 0u64;
        for (i, inst) in instances.iter().enumerate() {
            let object =
                objects
                    .get(inst.object as usize)
                    .ok_or_else(|| BuildError::InvalidParameter {
                        name: "Instance::object",
                        value: format!("{} (instance {i})", inst.object),
                        expected: "the index of an object of the scene",
                    })?;
            first_prim.push(total as u32);
            total += object.primitives as u64;
            if total > u32::MAX as u64 - 1 {
                return Err(BuildError::TooManyPrimitives {
                    count: total as usize,
                    max: u32::MAX as usize - 1,
                }
                .into());
            }
        }
        first_prim.push(total as u32);
        let to_object = inverses(instances)?;
        let boxes = world_boxes(&objects, instances);
        let top = top(&boxes)?;
        Ok(Self {
            objects,
            instances: instances.to_vec(),
            to_object,
            first_prim,
            params: top.params,
            top,
        })
    }

    /// The objects.
    pub fn objects(&self) -> &[Object<O>] {
        &self.objects
    }

    /// The instances.
    pub fn instances(&self) -> &[Instance] {
        &self.instances
    }

    /// The top level: a binary BVH whose leaves list instances.
    pub fn top(&self) -> &Bvh<WorldBox> {
        &self.top
    }

    /// The global id (as in [`Accel::intersect`]) of instance `instance`'s first primitive.
    pub fn first_primitive(&self, instance: u32) -> u32 {
        self.first_prim[instance as usize]
    }

    /// Moves every instance to its new transform (same count, same order) and refits or
    /// rebuilds the top level; objects are untouched. Fails, leaving the scene unchanged, on
    /// a count mismatch or a transform that is not finite or not invertible.
    pub fn set_transforms(
        &mut self,
        transforms: &[Affine3A],
        update: TopUpdate,
    ) -> Result<(), BuildError> {
        if transforms.len() != self.instances.len() {
            return Err(BuildError::InvalidParameter {
                name: "transforms.len()",
                value: transforms.len().to_string(),
                expected: "one transform per instance",
            });
        }
        let mut instances = self.instances.clone();
        for (inst, &t) in instances.iter_mut().zip(transforms) {
            inst.transform = t;
        }
        let to_object = inverses(&instances)?;
        self.update_top(world_boxes(&self.objects, &instances), update)?;
        self.instances = instances;
        self.to_object = to_object;
        Ok(())
    }

    /// Refits object `object`'s structure to its moved primitives `prims` (same count, same
    /// order), then refits or rebuilds the top level over its instances' new boxes. Fails,
    /// leaving the scene unchanged, on a bad object index, a count mismatch or non-finite
    /// primitives.
    pub fn refit_object<P: Primitive>(
        &mut self,
        object: u32,
        prims: &[P],
        update: TopUpdate,
    ) -> Result<(), BuildError>
    where
        O: Refit<P>,
    {
        let o =
            self.objects
                .get_mut(object as usize)
                .ok_or_else(|| BuildError::InvalidParameter {
                    name: "object",
                    value: object.to_string(),
                    expected: "the index of an object of the scene",
                })?;
        check_moved(prims, o.primitives as usize)?;
        let bounds = Aabb::around(prims);
        let old = o.bounds;
        o.bounds = bounds;
        if let Err(e) = self.update_top(world_boxes(&self.objects, &self.instances), update) {
            self.objects[object as usize].bounds = old;
            return Err(e);
        }
        self.objects[object as usize].accel.refit(prims)
    }

    /// Refits or rebuilds the top level over the instances' world boxes `boxes`.
    fn update_top(&mut self, boxes: Vec<WorldBox>, update: TopUpdate) -> Result<(), BuildError> {
        match update {
            TopUpdate::Refit => self.top.refit(&boxes),
            TopUpdate::Rebuild => {
                self.top = Bvh::build(&boxes, self.params)?;
                Ok(())
            }
        }
    }

    /// The closest hit with the instance hit and the object's own primitive id.
    pub fn intersect_instance(&self, ray: &Ray) -> Option<InstanceHit> {
        let hit = self.traverse::<false>(ray)?;
        let instance =
            self.first_prim[..self.instances.len()].partition_point(|&f| f <= hit.prim) - 1;
        Some(InstanceHit {
            hit: Hit {
                prim: hit.prim - self.first_prim[instance],
                ..hit
            },
            instance: instance as u32,
        })
    }

    /// The top-level walk; at each instance, the ray in object space (same `t`) handed to
    /// `ask(object, local ray, instance, best, world ray)`, which asks the object and offers
    /// its hit (global id: the instance's first plus the object's) to `best`; it returns true
    /// to stop (any-hit queries).
    #[inline]
    fn walk<const ANY_HIT: bool, K: Keep>(
        &self,
        ray: &Ray,
        best: impl FnOnce() -> K,
        mut ask: impl FnMut(&O, &Ray, u32, &mut K, &mut Ray) -> bool,
    ) -> Option<Hit> {
        self.top
            .walk_ray::<ANY_HIT, K>(ray, best, |first, count, r, best| {
                let first = first as usize;
                for &i in &self.top.ids[first..first + count as usize] {
                    let i = i as usize;
                    let to_object = &self.to_object[i];
                    let local = Ray::segment(
                        to_object.transform_point3(r.origin()),
                        to_object.transform_vector3(r.dir()),
                        r.tmin,
                        r.tmax,
                    );
                    let accel = &self.objects[self.instances[i].object as usize].accel;
                    if ask(accel, &local, i as u32, best, r) {
                        return true;
                    }
                }
                false
            })
    }

    /// [`Self::walk`] asking each object its own query: any hit ends the walk (with the
    /// ray's `tmin` as `t`: an any-hit query answers only whether), a closest hit is kept by
    /// [`rt_geom::replaces`].
    #[inline]
    fn traverse<const ANY_HIT: bool>(&self, ray: &Ray) -> Option<Hit> {
        self.walk::<ANY_HIT, _>(
            ray,
            || None,
            |accel, local, i, best, r| {
                let first = self.first_prim[i as usize];
                if ANY_HIT {
                    accel.occluded(local) && best.record::<true>(any_hit(r), first, &mut r.tmax)
                } else {
                    if let Some(h) = accel.intersect(local) {
                        best.record::<false>(prim_hit(&h), first + h.prim, &mut r.tmax);
                    }
                    false
                }
            },
        )
    }
}

/// What an any-hit query through an object records: the ray's `tmin` as `t` (it answers only
/// whether).
fn any_hit(r: &Ray) -> PrimHit {
    PrimHit {
        t: r.tmin,
        u: 0.0,
        v: 0.0,
    }
}

/// The `t`, `u`, `v` of a hit.
fn prim_hit(h: &Hit) -> PrimHit {
    PrimHit {
        t: h.t,
        u: h.u,
        v: h.v,
    }
}

/// The user's filter as an object's query sees it: primitive ids made global.
struct Global<'a, 'f> {
    filter: &'a mut &'f mut dyn HitFilter,
    first: u32,
}

impl HitFilter for Global<'_, '_> {
    fn skips(&self, prim: u32) -> bool {
        self.filter.skips(self.first + prim)
    }

    fn accepts(&mut self, hit: &Hit) -> bool {
        let global = Hit {
            prim: self.first + hit.prim,
            ..*hit
        };
        self.filter.accepts(&global)
    }
}

/// Filtered queries through the objects' own ([`Accel::filtered`], which [`InstanceBvh::build`]
/// checks every object has): the filter sees each object's candidates with their global ids;
/// an instance it skips is not asked.
impl<O: Accel> FilteredAccel for InstanceBvh<O> {
    fn intersect_filtered(&self, ray: &Ray, filter: &mut dyn HitFilter) -> Option<Hit> {
        self.walk_filtered::<false>(ray, filter)
    }

    fn occluded_filtered(&self, ray: &Ray, filter: &mut dyn HitFilter) -> bool {
        self.walk_filtered::<true>(ray, filter).is_some()
    }
}

impl<O: Accel> InstanceBvh<O> {
    /// [`Self::walk`] asking each object its filtered query, as [`Self::traverse`] asks the
    /// plain one.
    fn walk_filtered<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        mut filter: &mut dyn HitFilter,
    ) -> Option<Hit> {
        self.walk::<ANY_HIT, _>(
            ray,
            || None,
            |accel, local, i, best, r| {
                // Every object has filtered queries (checked when built).
                let Some(accel) = accel.filtered().filter(|_| !filter.skips_instance(i)) else {
                    return false;
                };
                let first = self.first_prim[i as usize];
                let mut global = Global {
                    filter: &mut filter,
                    first,
                };
                if ANY_HIT {
                    accel.occluded_filtered(local, &mut global)
                        && best.record::<true>(any_hit(r), first, &mut r.tmax)
                } else {
                    if let Some(h) = accel.intersect_filtered(local, &mut global) {
                        best.record::<false>(prim_hit(&h), first + h.prim, &mut r.tmax);
                    }
                    false
                }
            },
        )
    }
}

impl<O: Accel> fmt::Debug for Object<O> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Object")
            .field("bounds", &self.bounds)
            .field("primitives", &self.primitives)
            .field("stats", &self.accel.stats())
            .finish()
    }
}

impl<O: Accel> fmt::Debug for InstanceBvh<O> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("InstanceBvh")
            .field("objects", &self.objects)
            .field("instances", &self.instances)
            .field("top", &self.top.stats())
            .finish()
    }
}

impl<O: Accel> Accel for InstanceBvh<O> {
    // `prim` of a hit is the global id (see the module documentation).
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.traverse::<false>(ray)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        self.traverse::<true>(ray).is_some()
    }

    fn filtered(&self) -> Option<&dyn FilteredAccel> {
        Some(self)
    }

    /// `primitives` counts every instance's primitives; nodes, leaves, references and bytes
    /// count the top level, the instances, and each object once.
    fn stats(&self) -> AccelStats {
        let top = self.top.stats();
        let mut s = AccelStats {
            primitives: *self.first_prim.last().unwrap_or(&0) as usize,
            bytes: top.bytes
                + std::mem::size_of_val(self.instances.as_slice())
                + std::mem::size_of_val(self.to_object.as_slice())
                + std::mem::size_of_val(self.first_prim.as_slice()),
            ..top
        };
        s.sah_cost = None;
        let mut deepest = 0;
        for o in &self.objects {
            let os = o.accel.stats();
            s.nodes += os.nodes;
            s.leaves += os.leaves;
            s.references += os.references;
            s.bytes += os.bytes;
            deepest = deepest.max(os.max_depth + 1);
        }
        s.max_depth += deepest;
        s
    }

    /// The top level holds every instance's current world box, every object is valid, every
    /// instance names an object.
    fn validate(&self) -> Result<(), String> {
        self.top.validate()?;
        for (i, inst) in self.instances.iter().enumerate() {
            if inst.object as usize >= self.objects.len() {
                return Err(format!("instance {i} names object {}", inst.object));
            }
        }
        for (k, o) in self.objects.iter().enumerate() {
            o.accel.validate().map_err(|e| format!("object {k}: {e}"))?;
        }
        // The top level's boxes are the instances' world boxes as they stand.
        let now = world_boxes(&self.objects, &self.instances);
        for (placed, &i) in self.top.prims.iter().zip(&self.top.ids) {
            if !placed.0.contains(&now[i as usize].0) {
                return Err(format!("instance {i}'s world box is stale"));
            }
        }
        Ok(())
    }
}

/// The inverse of every instance's transform; fails on a transform that is not finite or not
/// invertible.
fn inverses(instances: &[Instance]) -> Result<Vec<Affine3A>, BuildError> {
    instances
        .iter()
        .enumerate()
        .map(|(i, inst)| {
            let t = inst.transform;
            let det = t.matrix3.determinant();
            let inv = t.inverse();
            if t.is_finite() && det != 0.0 && det.is_finite() && inv.is_finite() {
                Ok(inv)
            } else {
                Err(BuildError::InvalidParameter {
                    name: "Instance::transform",
                    value: format!("instance {i}: determinant {det}, {t:?}"),
                    expected: "a finite, invertible affine transform",
                })
            }
        })
        .collect()
}

/// The world box of each instance: its object's box corners transformed, widened by a few
/// units in the last place of its largest coordinate (the rounding of the transform), so that
/// every point the object's structure can hit lies inside it.
fn world_boxes<O>(objects: &[Object<O>], instances: &[Instance]) -> Vec<WorldBox> {
    instances
        .iter()
        .map(|inst| {
            let b = objects[inst.object as usize].bounds;
            if b.is_empty() {
                // An object without primitives: a point where it stands (never hit).
                let at = inst.transform.translation.into();
                return WorldBox(Aabb::new(at, at));
            }
            let corner = |k: usize| {
                let pick = |bit: usize, a: usize| {
                    if k >> bit & 1 == 0 {
                        b.min[a]
                    } else {
                        b.max[a]
                    }
                };
                inst.transform
                    .transform_point3(Vec3::new(pick(0, 0), pick(1, 1), pick(2, 2)))
            };
            let w = (0..8).fold(Aabb::EMPTY, |w, k| w.grow(corner(k)));
            let pad = w.min.abs().max(w.max.abs()).max_element() * 4.0 * f32::EPSILON;
            WorldBox(Aabb::new(
                w.min - Vec3::splat(pad),
                w.max + Vec3::splat(pad),
            ))
        })
        .collect()
}

/// An instance's world box: what the top-level BVH is built over (its leaves list instances;
/// the walk asks the objects, never this box's own test).
#[derive(Clone, Copy, Debug)]
pub struct WorldBox(Aabb);

impl Primitive for WorldBox {
    fn bounds(&self) -> Aabb {
        self.0
    }
    fn centroid(&self) -> Vec3 {
        self.0.center()
    }
    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        let (t, _) = self.0.clip_ray(ray)?;
        Some(PrimHit { t, u: 0.0, v: 0.0 })
    }
    fn clipped_bounds(&self, clip: &Aabb) -> Aabb {
        self.0.intersection(*clip)
    }
    fn extent_along(&self, n: Vec3) -> (f32, f32) {
        let lo = (self.0.min * n).min(self.0.max * n).element_sum();
        let hi = (self.0.min * n).max(self.0.max * n).element_sum();
        (lo, hi)
    }
    fn farthest_distance(&self, p: rt_geom::DVec3) -> f32 {
        let (lo, hi) = (self.0.min.as_dvec3() - p, self.0.max.as_dvec3() - p);
        rt_geom::aabb::f32_at_or_above(lo.abs().max(hi.abs()).length())
    }
    fn is_finite(&self) -> bool {
        self.0.min.is_finite() && self.0.max.is_finite()
    }
}
