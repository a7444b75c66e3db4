//! Several geometries (meshes, shape sets) in one structure: each a range of the primitive
//! list any structure is built over, with a 32-bit mask; a hit names its geometry, the
//! primitive in it and the geometric normal, without the caller keeping offset tables.
//!
//! ```
//! use rt_geom::{BruteForce, Geometries, Ray, Triangle, Vec3};
//!
//! let floor = [Triangle::new(Vec3::new(-9.0, -9.0, 0.0), Vec3::new(9.0, -9.0, 0.0), Vec3::new(0.0, 9.0, 0.0))];
//! let bulb = [Triangle::new(Vec3::new(-1.0, -1.0, 2.0), Vec3::new(1.0, -1.0, 2.0), Vec3::new(0.0, 1.0, 2.0))];
//! const CAMERA: u32 = 1;
//! const SHADOW: u32 = 2;
//! let mut scene = Geometries::new();
//! let floor_id = scene.add(floor, CAMERA | SHADOW);
//! let bulb_id = scene.add(bulb, CAMERA); // seen, casts no shadow
//! let accel = BruteForce::build(scene.primitives()).unwrap();
//! let down = Ray::new(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z);
//! let hit = scene.intersect(&accel, &down, CAMERA).unwrap();
//! assert_eq!((hit.geometry, hit.prim, hit.t), (bulb_id, 0, 3.0));
//! assert_eq!(hit.normal, Some(Vec3::Z));
//! // A shadow ray passes the bulb and meets the floor.
//! let hit = scene.intersect(&accel, &down, SHADOW).unwrap();
//! assert_eq!((hit.geometry, hit.t), (floor_id, 5.0));
//! ```

use crate::{FilteredAccel, Hit, HitFilter, Masked, PrimHit, Primitive, Ray, Vec3};

/// A hit in [`Geometries`]: where along the ray, on which geometry and primitive in it, and
/// the primitive's geometric normal there ([`Primitive::normal`]; unit length, facing where
/// the primitive defines; `None` where the primitive gives none).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GeometryHit {
    /// Distance along the ray, in units of its direction.
    pub t: f32,
    /// First barycentric coordinate (or surface parameter).
    pub u: f32,
    /// Second barycentric coordinate (or surface parameter).
    pub v: f32,
    /// The geometry, as [`Geometries::add`] numbered it.
    pub geometry: u32,
    /// The primitive's index in its geometry.
    pub prim: u32,
    /// The geometric normal at the hit.
    pub normal: Option<Vec3>,
}

/// Several geometries as one primitive list (build any structure over
/// [`Geometries::primitives`]), each with a ray mask; queries take the structure and a mask.
#[derive(Clone, Debug)]
pub struct Geometries<P> {
    prims: Vec<P>,
    /// The first primitive of each geometry, and the total at the end.
    first: Vec<u32>,
    /// Per geometry, its mask.
    masks: Vec<u32>,
    /// Per primitive, its geometry's mask (what [`Masked`] reads in the leaves).
    prim_masks: Vec<u32>,
}

impl<P> Default for Geometries<P> {
    fn default() -> Self {
        Self {
            prims: Vec::new(),
            first: vec![0],
            masks: Vec::new(),
            prim_masks: Vec::new(),
        }
    }
}

impl<P: Primitive> Geometries<P> {
    /// No geometry yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends a geometry with its mask; returns its id (0, 1, ... in the order added).
    pub fn add(&mut self, prims: impl IntoIterator<Item = P>, mask: u32) -> u32 {
        let before = self.prims.len();
        self.prims.extend(prims);
        let added = self.prims.len() - before;
        self.prim_masks.extend(std::iter::repeat_n(mask, added));
        self.masks.push(mask);
        self.first.push(self.prims.len() as u32);
        (self.masks.len() - 1) as u32
    }

    /// Every geometry's primitives, geometry after geometry: what a structure is built over.
    pub fn primitives(&self) -> &[P] {
        &self.prims
    }

    /// Number of geometries.
    pub fn len(&self) -> usize {
        self.masks.len()
    }

    /// Whether no geometry was added.
    pub fn is_empty(&self) -> bool {
        self.masks.is_empty()
    }

    /// The mask of `geometry`.
    pub fn mask(&self, geometry: u32) -> u32 {
        self.masks[geometry as usize]
    }

    /// Changes the mask of `geometry` (the structure stays as built).
    pub fn set_mask(&mut self, geometry: u32, mask: u32) {
        let g = geometry as usize;
        self.masks[g] = mask;
        let (a, b) = (self.first[g] as usize, self.first[g + 1] as usize);
        self.prim_masks[a..b].fill(mask);
    }

    /// The mask of the geometry primitive `prim` of [`Self::primitives`] belongs to.
    pub fn prim_mask(&self, prim: u32) -> u32 {
        self.prim_masks[prim as usize]
    }

    /// `(geometry, primitive in it)` of primitive `prim` of [`Self::primitives`].
    pub fn locate(&self, prim: u32) -> (u32, u32) {
        let g = self.first.partition_point(|&f| f <= prim) - 1;
        (g as u32, prim - self.first[g])
    }

    /// The closest hit of `accel` (built over [`Self::primitives`]) among the geometries whose
    /// mask shares a bit with `mask`.
    pub fn intersect(
        &self,
        accel: &dyn FilteredAccel,
        ray: &Ray,
        mask: u32,
    ) -> Option<GeometryHit> {
        if self.masks.iter().all(|m| m & mask != 0) {
            return accel.intersect(ray).map(|h| self.located(ray, &h));
        }
        self.intersect_filtered(accel, ray, mask, &mut |_| true)
    }

    /// Whether `accel` has a hit among the geometries whose mask shares a bit with `mask`.
    pub fn occluded(&self, accel: &dyn FilteredAccel, ray: &Ray, mask: u32) -> bool {
        if self.masks.iter().all(|m| m & mask != 0) {
            return accel.occluded(ray);
        }
        accel.occluded_filtered(ray, &mut self.masked(mask, |_: &Hit| true))
    }

    /// [`Self::intersect`] keeping only the hits `filter` accepts.
    pub fn intersect_filtered(
        &self,
        accel: &dyn FilteredAccel,
        ray: &Ray,
        mask: u32,
        filter: &mut dyn FnMut(&GeometryHit) -> bool,
    ) -> Option<GeometryHit> {
        let mut masked = self.masked(mask, |h: &Hit| filter(&self.located(ray, h)));
        accel
            .intersect_filtered(ray, &mut masked)
            .map(|h| self.located(ray, &h))
    }

    /// [`Self::occluded`] counting only the hits `filter` accepts.
    pub fn occluded_filtered(
        &self,
        accel: &dyn FilteredAccel,
        ray: &Ray,
        mask: u32,
        filter: &mut dyn FnMut(&GeometryHit) -> bool,
    ) -> bool {
        let mut masked = self.masked(mask, |h: &Hit| filter(&self.located(ray, h)));
        accel.occluded_filtered(ray, &mut masked)
    }

    /// The masks of the geometries over `inner`.
    fn masked<F: HitFilter>(&self, mask: u32, inner: F) -> Masked<'_, F> {
        Masked {
            prims: &self.prim_masks,
            instances: &[],
            ray: mask,
            inner,
        }
    }

    /// `h`, a hit of `ray` on [`Self::primitives`], located in its geometry, with the normal.
    pub fn located(&self, ray: &Ray, h: &Hit) -> GeometryHit {
        let (geometry, prim) = self.locate(h.prim);
        let ph = PrimHit {
            t: h.t,
            u: h.u,
            v: h.v,
        };
        GeometryHit {
            t: h.t,
            u: h.u,
            v: h.v,
            geometry,
            prim,
            normal: self.prims[h.prim as usize].normal(ray, &ph),
        }
    }
}
