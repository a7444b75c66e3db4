//! Filtered queries and all hits along a ray: what a renderer asks on top of the closest and
//! any hit (alpha-tested leaves, the triangle a secondary ray leaves, transparency, volumes).
//!
//! A filter sees each candidate hit as the query would report it (`t`, `u`, `v` exact, the
//! primitive as the caller's id; an instance scene's global id) and accepts or rejects it. A
//! rejected hit neither shortens the ray nor ends an any-hit query. The answer is brute
//! force's asked the same question: the closest accepted hit (ties by [`replaces`]), or
//! whether some hit is accepted. Each primitive offers one candidate, its nearest hit within
//! the ray's interval (the hit [`Primitive::intersect`](crate::Primitive::intersect) gives);
//! a filter may see the same candidate more than once (structures that list a primitive in
//! several cells) and must answer the same each time.
//!
//! Every structure writes its leaf tests against [`Keep`], which `Option<Hit>` implements
//! without a filter (today's queries, the same code) and [`Filtered`] with one.
//!
//! ```
//! use rt_geom::{Accel, BruteForce, FilteredAccel, Hit, Ray, Triangle, Vec3};
//!
//! // Two triangles, one behind the other.
//! let tris = [
//!     Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y),
//!     Triangle::new(-Vec3::Z, Vec3::X - Vec3::Z, Vec3::Y - Vec3::Z),
//! ];
//! let scene = BruteForce::build(&tris).unwrap();
//! let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z);
//! assert_eq!(scene.intersect(&ray).unwrap().prim, 0);
//! // Triangle 0 is cut out (an alpha test, or the triangle a ray leaves): the ray goes on.
//! let hit = scene.intersect_filtered(&ray, &mut |h: &Hit| h.prim != 0).unwrap();
//! assert_eq!((hit.prim, hit.t), (1, 2.0));
//! assert!(!scene.occluded_filtered(&ray, &mut |_: &Hit| false));
//! // Every hit along the ray, in order of `t`.
//! let mut seen = Vec::new();
//! scene.for_each_hit(&ray, &mut |h| {
//!     seen.push(h.prim);
//!     std::ops::ControlFlow::Continue(())
//! });
//! assert_eq!(seen, [0, 1]);
//! ```

use crate::{Accel, Hit, PrimHit, replaces};
use std::ops::ControlFlow;

/// What a filtered query asks: which primitives (and instances) to leave untested, as ray
/// masks do, and which candidate hits to accept. Any `FnMut(&Hit) -> bool` is a filter that
/// tests everything; [`Masked`] adds masks to one.
pub trait HitFilter {
    /// Whether primitive `prim` (the caller's id; an instance scene's global id) is left
    /// untested. None is, by default.
    #[inline(always)]
    fn skips(&self, prim: u32) -> bool {
        let _ = prim;
        false
    }

    /// Whether instance `instance` of an instance scene is left untested, its whole object.
    /// None is, by default.
    #[inline(always)]
    fn skips_instance(&self, instance: u32) -> bool {
        let _ = instance;
        false
    }

    /// Whether the candidate `hit` is accepted.
    fn accepts(&mut self, hit: &Hit) -> bool;
}

impl<F: FnMut(&Hit) -> bool> HitFilter for F {
    #[inline(always)]
    fn accepts(&mut self, hit: &Hit) -> bool {
        self(hit)
    }
}

/// Ray masks (as Embree's and OptiX's): a 32-bit mask per primitive (of its geometry, as
/// [`crate::Geometries`] lays them out) and per instance, and one per query; a primitive or
/// instance whose mask shares no bit with the query's is not tested. Candidates of the rest
/// go to `inner`.
pub struct Masked<'a, F> {
    /// Per primitive (the caller's ids), its mask; primitives past the end are tested.
    pub prims: &'a [u32],
    /// Per instance, its mask; instances past the end are tested.
    pub instances: &'a [u32],
    /// The query's mask.
    pub ray: u32,
    /// The filter of the primitives tested.
    pub inner: F,
}

impl<F: HitFilter> HitFilter for Masked<'_, F> {
    #[inline(always)]
    fn skips(&self, prim: u32) -> bool {
        self.prims
            .get(prim as usize)
            .is_some_and(|m| m & self.ray == 0)
            || self.inner.skips(prim)
    }

    #[inline(always)]
    fn skips_instance(&self, instance: u32) -> bool {
        self.instances
            .get(instance as usize)
            .is_some_and(|m| m & self.ray == 0)
            || self.inner.skips_instance(instance)
    }

    #[inline(always)]
    fn accepts(&mut self, hit: &Hit) -> bool {
        self.inner.accepts(hit)
    }
}

/// Leaves one primitive untested and accepts every other hit: the filter of a ray that
/// leaves a planar primitive (a triangle), which it cannot meet again, so the ray starts on
/// the surface with no offset and still never hits its own origin.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SkipPrim(pub u32);

impl HitFilter for SkipPrim {
    #[inline(always)]
    fn skips(&self, prim: u32) -> bool {
        prim == self.0
    }

    #[inline(always)]
    fn accepts(&mut self, _: &Hit) -> bool {
        true
    }
}

/// What a query keeps of the hits its leaf tests find: the closest (or any) hit, through a
/// filter or not. `Option<Hit>` is the unfiltered keeper every structure's plain queries use;
/// [`Filtered`] asks a filter first.
pub trait Keep {
    /// Whether candidates go through a filter: they must then carry their exact `t`, `u`,
    /// `v` (an any-hit query may otherwise end on a hit proven in `f32`, not refined).
    const FILTERED: bool;

    /// Whether leaf tests ask [`Self::skips`] before testing a primitive: where a filter is
    /// asked, and for [`Skipping`].
    const SKIPS: bool = Self::FILTERED;

    /// Whether an any-hit query reads the `t`, `u`, `v` of the hit it ends on. Where it only
    /// asks whether there is one ([`Occlusion`]), a leaf test may end it on a hit it has proven
    /// to lie in the ray's interval without working them out.
    const ANY_HIT_VALUES: bool = true;

    /// The hit kept so far.
    fn best(&self) -> Option<Hit>;

    /// Whether the filter accepts `hit` (true without a filter).
    fn accepts(&mut self, hit: &Hit) -> bool;

    /// Whether primitive `prim` is left untested ([`HitFilter::skips`]; false without a
    /// filter). Leaf tests ask it before testing, where `SKIPS`.
    fn skips(&self, prim: u32) -> bool;

    /// Records hit `h` of primitive `prim`, already accepted, as [`crate::keep_hit`] does:
    /// with `ANY_HIT` the search is over (true); else it replaces the best hit when
    /// [`replaces`] says so, and `tmax` shrinks to it.
    fn record<const ANY_HIT: bool>(&mut self, h: PrimHit, prim: u32, tmax: &mut f32) -> bool;

    /// Offers the candidate hit `h` of primitive `prim`: the filter is asked only for a
    /// candidate that would be kept (any hit, or one that [`replaces`] the best so far), and
    /// an accepted one is [recorded](Self::record). True when the search is over.
    #[inline(always)]
    fn keep<const ANY_HIT: bool>(&mut self, h: PrimHit, prim: u32, tmax: &mut f32) -> bool {
        if Self::FILTERED {
            if !ANY_HIT && !replaces(h.t, prim, self.best().as_ref().map(Hit::key)) {
                return false;
            }
            if !self.accepts(&Hit::new(h, prim)) {
                return false;
            }
        }
        self.record::<ANY_HIT>(h, prim, tmax)
    }
}

impl Keep for Option<Hit> {
    const FILTERED: bool = false;

    #[inline(always)]
    fn best(&self) -> Option<Hit> {
        *self
    }

    #[inline(always)]
    fn accepts(&mut self, _: &Hit) -> bool {
        true
    }

    #[inline(always)]
    fn skips(&self, _: u32) -> bool {
        false
    }

    #[inline(always)]
    fn record<const ANY_HIT: bool>(&mut self, h: PrimHit, prim: u32, tmax: &mut f32) -> bool {
        crate::keep_hit::<ANY_HIT>(h, prim, tmax, self)
    }
}

/// The best hit a filter accepted so far, and the filter.
pub struct Filtered<'a, F: ?Sized> {
    hit: Option<Hit>,
    filter: &'a mut F,
}

impl<'a, F: HitFilter + ?Sized> Filtered<'a, F> {
    /// No hit yet.
    #[inline(always)]
    pub fn new(filter: &'a mut F) -> Self {
        Self { hit: None, filter }
    }
}

impl<F: HitFilter + ?Sized> Keep for Filtered<'_, F> {
    const FILTERED: bool = true;

    #[inline(always)]
    fn best(&self) -> Option<Hit> {
        self.hit
    }

    #[inline(always)]
    fn accepts(&mut self, hit: &Hit) -> bool {
        self.filter.accepts(hit)
    }

    #[inline(always)]
    fn skips(&self, prim: u32) -> bool {
        self.filter.skips(prim)
    }

    #[inline(always)]
    fn record<const ANY_HIT: bool>(&mut self, h: PrimHit, prim: u32, tmax: &mut f32) -> bool {
        crate::keep_hit::<ANY_HIT>(h, prim, tmax, &mut self.hit)
    }
}

/// The closest (or any) hit of a ray that skips one primitive, the one it leaves: the answer
/// of a [`SkipPrim`] filter, kept as plain queries keep hits (no filter to ask, so an
/// any-hit query may end on a hit proven in `f32`).
pub struct Skipping {
    hit: Option<Hit>,
    prim: u32,
}

impl Skipping {
    /// No hit yet; primitive `prim` is skipped.
    #[inline(always)]
    pub fn new(prim: u32) -> Self {
        Self { hit: None, prim }
    }
}

impl Keep for Skipping {
    const FILTERED: bool = false;
    const SKIPS: bool = true;

    #[inline(always)]
    fn best(&self) -> Option<Hit> {
        self.hit
    }

    #[inline(always)]
    fn accepts(&mut self, _: &Hit) -> bool {
        true
    }

    #[inline(always)]
    fn skips(&self, prim: u32) -> bool {
        prim == self.prim
    }

    #[inline(always)]
    fn record<const ANY_HIT: bool>(&mut self, h: PrimHit, prim: u32, tmax: &mut f32) -> bool {
        crate::keep_hit::<ANY_HIT>(h, prim, tmax, &mut self.hit)
    }
}

/// What an occlusion query keeps: the hits of keeper `K`, of which it asks only whether there
/// is one. An any-hit leaf test may end it on a hit proven to lie in the ray's interval
/// without working out that hit's `t`, `u`, `v` ([`Keep::ANY_HIT_VALUES`]): the [`Hit`] it
/// reports then carries the primitive, `t = tmin` and `u = v = 0`.
pub struct Occlusion<K>(pub K);

impl<K: Keep> Keep for Occlusion<K> {
    const FILTERED: bool = K::FILTERED;
    const SKIPS: bool = K::SKIPS;
    const ANY_HIT_VALUES: bool = K::FILTERED;

    #[inline(always)]
    fn best(&self) -> Option<Hit> {
        self.0.best()
    }

    #[inline(always)]
    fn accepts(&mut self, hit: &Hit) -> bool {
        self.0.accepts(hit)
    }

    #[inline(always)]
    fn skips(&self, prim: u32) -> bool {
        self.0.skips(prim)
    }

    #[inline(always)]
    fn record<const ANY_HIT: bool>(&mut self, h: PrimHit, prim: u32, tmax: &mut f32) -> bool {
        self.0.record::<ANY_HIT>(h, prim, tmax)
    }
}

/// Queries with a filter on each candidate hit, and every hit along a ray. Every rt structure
/// implements it (through [`crate::queries_from_walk!`]); see the [module](self) for the
/// contract.
pub trait FilteredAccel: Accel {
    /// The closest hit in `[ray.tmin, ray.tmax]` that `filter` accepts, among the primitives
    /// it does not skip.
    fn intersect_filtered(&self, ray: &crate::Ray, filter: &mut dyn HitFilter) -> Option<Hit>;

    /// Whether some hit in `[ray.tmin, ray.tmax]` of a primitive `filter` does not skip is
    /// accepted by it (which may stop being asked at the first it accepts).
    fn occluded_filtered(&self, ray: &crate::Ray, filter: &mut dyn HitFilter) -> bool;

    /// The closest hit of a ray that leaves primitive `prim` and skips it: the answer of
    /// [`Self::intersect_filtered`] with [`SkipPrim`], without a filter to call (rt's
    /// structures walk it as their plain queries, with the one primitive skipped).
    fn intersect_leaving(&self, ray: &crate::Ray, prim: u32) -> Option<Hit> {
        self.intersect_filtered(ray, &mut SkipPrim(prim))
    }

    /// Whether a ray that leaves primitive `prim` and skips it is blocked: the answer of
    /// [`Self::occluded_filtered`] with [`SkipPrim`].
    fn occluded_leaving(&self, ray: &crate::Ray, prim: u32) -> bool {
        self.occluded_filtered(ray, &mut SkipPrim(prim))
    }

    /// Hands every hit in `[ray.tmin, ray.tmax]` to `visit` in order of `t` (ties by
    /// primitive id), each primitive once (its nearest hit in the interval), until `visit`
    /// breaks. The order is known only once the ray's whole interval is walked: the hits are
    /// gathered first (a filter that rejects every candidate), then sorted.
    fn for_each_hit(&self, ray: &crate::Ray, visit: &mut dyn FnMut(&Hit) -> ControlFlow<()>) {
        let mut hits = Vec::new();
        self.intersect_filtered(ray, &mut |h: &Hit| {
            hits.push(*h);
            false
        });
        for h in sorted_hits(hits) {
            if visit(&h).is_break() {
                return;
            }
        }
    }
}

/// `hits` in order of `(t, prim)`, each primitive once: the list [`FilteredAccel::for_each_hit`]
/// visits, from candidates a structure may have offered more than once (the same hit each
/// time).
pub fn sorted_hits(mut hits: Vec<Hit>) -> Vec<Hit> {
    hits.sort_by(|a, b| a.t.total_cmp(&b.t).then(a.prim.cmp(&b.prim)));
    let mut seen = std::collections::HashSet::with_capacity(hits.len());
    hits.retain(|h| seen.insert(h.prim));
    hits
}

/// Boxed and shared structures answer as the structure they hold.
macro_rules! forward_filtered {
    ($($ptr:ident)::+) => {
        impl<A: FilteredAccel + ?Sized> FilteredAccel for $($ptr)::+<A> {
            #[inline]
            fn intersect_filtered(
                &self,
                ray: &crate::Ray,
                filter: &mut dyn HitFilter,
            ) -> Option<Hit> {
                (**self).intersect_filtered(ray, filter)
            }
            #[inline]
            fn occluded_filtered(&self, ray: &crate::Ray, filter: &mut dyn HitFilter) -> bool {
                (**self).occluded_filtered(ray, filter)
            }
            #[inline]
            fn intersect_leaving(&self, ray: &crate::Ray, prim: u32) -> Option<Hit> {
                (**self).intersect_leaving(ray, prim)
            }
            #[inline]
            fn occluded_leaving(&self, ray: &crate::Ray, prim: u32) -> bool {
                (**self).occluded_leaving(ray, prim)
            }
        }
    };
}

forward_filtered!(Box);
forward_filtered!(std::sync::Arc);
