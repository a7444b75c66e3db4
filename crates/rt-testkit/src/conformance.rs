//! The conformance suite: one generic check that every structure, with every option that
//! matters, runs against [`BruteForce`] on the same scenes and rays.
//!
//! Checks per ray: the closest `t` equals the reference's (exactly, unless a [`Tolerance`] says
//! otherwise); the reported primitive really is hit at that `t`; `occluded` equals
//! `intersect().is_some()`. Per build: `validate()` passes and `stats()` is self-consistent.
//! A failure prints a reproducer: scene, ray (bit-exact), expected and got.

use crate::rays::{RayKind, SamplePoints, TestRay, conformance_rays};
use crate::scenes::Scene;
use rt_geom::{
    Aabb, Accel, BruteForce, BuildError, DVec3, FilteredAccel, Hit, HitFilter, Masked, PrimHit,
    Primitive, Ray, SkipPrim, Triangle, Vec3,
};
use std::any::TypeId;
use std::collections::HashMap;
use std::fmt;
use std::hash::{Hash, Hasher};
use std::sync::{Arc, Mutex, OnceLock};

/// How closely a structure must agree with the reference.
///
/// rt's own structures use [`Tolerance::EXACT`]: the same kernel, so the same closest `t` bit
/// for bit. Foreign code is held to what it can promise, and what it is excused is counted
/// (`Report::tolerated`), never hidden.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    /// `|dt| <= rel_t * max(1, |t|)` counts as agreement.
    pub rel_t: f32,
    /// Reference hits closer than this distance (`t * |dir|`) may be missed (obvhs's CWBVH
    /// drops hits below 1e-4).
    pub near_t: f32,
    /// Rays of the boundary families ([`RayKind::AxisParallel`], [`RayKind::PlaneParallel`],
    /// [`RayKind::Grazing`]) may miss a hit or report a farther one: for traversals whose box
    /// test is not watertight (no Ize padding, no care for rays lying in a box face).
    pub boundary_misses: bool,
    /// Rays whose interval starts behind the origin (`tmin < 0`) may disagree: for traversals
    /// that only walk forward from the origin (obvhs clamps the interval to `t >= 0`).
    pub behind_origin_misses: bool,
    /// Ties (two primitives hit at the same `t`) must go to the lower primitive id
    /// ([`rt_geom::replaces`]): rt's own structures, so that renders agree bit for bit.
    pub lowest_on_ties: bool,
    /// A disagreement (hit or miss, `t`, primitive) is excused where the hit either side
    /// reports lies within this barycentric distance of its triangle's boundary, or within
    /// `rel_t` of an end of the ray's interval: for geometry carried through transforms,
    /// whose rounding moves edges and distances (0 excuses nothing).
    pub edge_band: f32,
}

impl Tolerance {
    pub const EXACT: Tolerance = Tolerance {
        rel_t: 0.0,
        near_t: 0.0,
        boundary_misses: false,
        behind_origin_misses: false,
        lowest_on_ties: true,
        edge_band: 0.0,
    };

    /// Instanced scenes against their flattened form (world-space triangles): the ray is
    /// carried into each object's space by an `f32` inverse transform, and the flattened
    /// vertices by the forward one, so each side rounds differently. `t` agrees within
    /// `rel_t` (a few ulps of the origin's coordinates, amplified by the transform's
    /// condition number and by origins several scene sizes away from the hit), and hit or
    /// miss may differ only within `edge_band` of an edge (a few ulps of the coordinates
    /// again, over the height of a small triangle: 2e-3 of it), where the rounding of either
    /// transform moves a ray from one side of the edge to the other, or within `rel_t` of the
    /// interval's ends.
    pub const TRANSFORMED: Tolerance = Tolerance {
        rel_t: 1e-4,
        near_t: 0.0,
        boundary_misses: false,
        behind_origin_misses: false,
        lowest_on_ties: false,
        edge_band: 2e-3,
    };

    /// Whether `hit` lies within `edge_band` of its triangle's boundary or within `rel_t` of
    /// an end of `ray`'s interval (never with `edge_band == 0`).
    fn near_edge(&self, hit: Option<Hit>, ray: &Ray) -> bool {
        let near = |a: f32, b: f32| (a - b).abs() <= self.rel_t * a.abs().max(1.0);
        self.edge_band > 0.0
            && hit.is_some_and(|h| {
                h.u.min(h.v).min(1.0 - h.u - h.v) <= self.edge_band
                    || near(h.t, ray.tmin)
                    || near(h.t, ray.tmax)
            })
    }

    fn excuses(&self, test: &TestRay) -> bool {
        let boundary = matches!(
            test.kind,
            RayKind::AxisParallel | RayKind::PlaneParallel | RayKind::Grazing
        );
        (self.boundary_misses && boundary) || (self.behind_origin_misses && test.ray.tmin < 0.0)
    }
}

/// One disagreement, printable as a reproducer.
#[derive(Clone, Debug)]
pub struct Mismatch {
    pub scene: String,
    pub kind: RayKind,
    pub query: &'static str,
    pub ray: Ray,
    pub expected: Option<Hit>,
    pub got: Option<Hit>,
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (o, d) = (self.ray.origin(), self.ray.dir());
        write!(
            f,
            "scene {} {:?} ray {}: Ray::segment(Vec3::new({:?}, {:?}, {:?}), Vec3::new({:?}, {:?}, {:?}), {:?}, {:?}) expected {:?} got {:?}",
            self.scene,
            self.kind,
            self.query,
            o.x,
            o.y,
            o.z,
            d.x,
            d.y,
            d.z,
            self.ray.tmin,
            self.ray.tmax,
            self.expected,
            self.got
        )
    }
}

/// The outcome of comparing a structure with the reference over a ray set.
#[derive(Clone, Debug, Default)]
pub struct Report {
    pub scene: String,
    pub rays: usize,
    pub hits: usize,
    /// Number of disagreeing rays (only the first few are kept in `mismatches`).
    pub mismatch_count: usize,
    /// Disagreements the tolerance excuses (boundary rays of non-watertight traversals).
    pub tolerated: usize,
    /// `tolerated`, per ray family.
    pub tolerated_by_kind: std::collections::HashMap<RayKind, usize>,
    pub mismatches: Vec<Mismatch>,
    /// Largest `|t - t_reference|` over rays where both hit and agree.
    pub max_dt: f32,
}

impl Report {
    pub fn is_ok(&self) -> bool {
        self.mismatch_count == 0
    }

    /// Folds another report into this one (same scene).
    pub fn merge(&mut self, other: Report) {
        self.rays += other.rays;
        self.hits += other.hits;
        self.mismatch_count += other.mismatch_count;
        self.tolerated += other.tolerated;
        for (kind, n) in other.tolerated_by_kind {
            *self.tolerated_by_kind.entry(kind).or_default() += n;
        }
        self.max_dt = self.max_dt.max(other.max_dt);
        let room = KEEP.saturating_sub(self.mismatches.len());
        self.mismatches
            .extend(other.mismatches.into_iter().take(room));
    }
}

const KEEP: usize = 8;

/// Compares `subject` with `reference` ray by ray. `expected` may hold the reference's answers
/// already (one per ray); otherwise they are computed here.
pub fn compare<P: Primitive>(
    scene: &str,
    prims: &[P],
    rays: &[TestRay],
    reference: &dyn Accel,
    subject: &dyn Accel,
    tolerance: Tolerance,
) -> Report {
    let expected: Vec<Option<Hit>> = rays.iter().map(|r| reference.intersect(&r.ray)).collect();
    compare_with_expected(scene, prims, rays, &expected, subject, tolerance)
}

/// [`compare`] with the reference's answers given.
pub fn compare_with_expected<P: Primitive>(
    scene: &str,
    prims: &[P],
    rays: &[TestRay],
    expected: &[Option<Hit>],
    subject: &dyn Accel,
    tolerance: Tolerance,
) -> Report {
    let mut report = Report {
        scene: scene.to_string(),
        rays: rays.len(),
        ..Report::default()
    };
    for (test, expected) in rays.iter().zip(expected) {
        let ray = &test.ray;
        let got = subject.intersect(ray);
        let occluded = subject.occluded(ray);
        let mut bad = None;
        match (expected, got) {
            (None, None) => {}
            (Some(e), Some(g)) => {
                report.hits += 1;
                if !t_agrees(e.t, g.t, ray, tolerance) {
                    bad = Some("intersect t");
                } else if !prim_is_hit_at(prims, ray, &g, tolerance) {
                    bad = Some("intersect prim");
                } else if tolerance.lowest_on_ties && e.t == g.t && g.prim > e.prim {
                    // The reference hit `e.prim` at the same t: the lowest tied id is at most it.
                    bad = Some("intersect tie (not the lowest primitive id)");
                } else {
                    report.max_dt = report.max_dt.max((e.t - g.t).abs());
                }
            }
            (Some(e), None) => {
                if !may_drop(e.t, ray, tolerance) {
                    bad = Some("intersect miss");
                }
            }
            (None, Some(_)) => bad = Some("intersect false hit"),
        }
        if bad.is_none() && occluded != got.is_some() {
            bad = Some("occluded");
        }
        let near_edge = tolerance.near_edge(*expected, ray) || tolerance.near_edge(got, ray);
        if bad.is_some() && (tolerance.excuses(test) || near_edge) {
            report.tolerated += 1;
            *report.tolerated_by_kind.entry(test.kind).or_default() += 1;
            continue;
        }
        if let Some(query) = bad {
            report.mismatch_count += 1;
            if report.mismatches.len() < KEEP {
                report.mismatches.push(Mismatch {
                    scene: scene.to_string(),
                    kind: test.kind,
                    query,
                    ray: *ray,
                    expected: *expected,
                    got,
                });
            }
        }
    }
    report
}

fn t_agrees(expected: f32, got: f32, ray: &Ray, tolerance: Tolerance) -> bool {
    expected == got
        || (expected - got).abs() <= tolerance.rel_t * expected.abs().max(1.0)
        || may_drop(expected, ray, tolerance)
}

/// Whether the tolerance excuses missing a hit at `expected_t`: within `near_t` of the origin,
/// on either side (an interval may start behind the origin; a hit there is as binding as one
/// ahead, and `Tolerance::EXACT` excuses nothing).
fn may_drop(expected_t: f32, ray: &Ray, tolerance: Tolerance) -> bool {
    expected_t.abs() * ray.dir().length() < tolerance.near_t
}

fn prim_is_hit_at<P: Primitive>(prims: &[P], ray: &Ray, got: &Hit, tolerance: Tolerance) -> bool {
    let Some(p) = prims.get(got.prim as usize) else {
        return false;
    };
    match p.intersect(ray) {
        // The primitive's own nearest hit may be closer than `got` only on ties with equal t.
        Some(h) => t_agrees(h.t, got.t, ray, tolerance),
        None => false,
    }
}

/// Builds the structure, checks `validate()` and `stats()`, and compares it with brute force
/// on the scene's conformance rays.
pub fn check_scene<P, A, F>(
    scene: &Scene<P>,
    build: F,
    tolerance: Tolerance,
) -> Result<Report, String>
where
    P: SamplePoints,
    A: Accel,
    F: Fn(&[P]) -> Result<A, BuildError>,
{
    let subject =
        build(&scene.prims).map_err(|e| format!("build failed on {}: {e}", scene.name))?;
    check_built(scene, &subject, tolerance)
}

/// [`check_scene`] of a built structure (compiled once per primitive type, not per structure
/// and test).
fn check_built<P: SamplePoints>(
    scene: &Scene<P>,
    subject: &dyn Accel,
    tolerance: Tolerance,
) -> Result<Report, String> {
    subject
        .validate()
        .map_err(|e| format!("validate() failed on {}: {e}", scene.name))?;
    let stats = subject.stats();
    stats
        .check_consistency()
        .map_err(|e| format!("stats() inconsistent on {}: {e} ({stats})", scene.name))?;
    if stats.primitives != scene.prims.len() {
        return Err(format!(
            "stats().primitives = {} but the scene has {}",
            stats.primitives,
            scene.prims.len()
        ));
    }
    let reference = reference(scene)?;
    Ok(compare_with_expected(
        &scene.name,
        &scene.prims,
        &reference.rays,
        &reference.expected,
        subject,
        tolerance,
    ))
}

/// A scene's conformance rays and brute force's answers to them.
struct Reference {
    rays: Vec<TestRay>,
    expected: Vec<Option<Hit>>,
}

/// The brute-force [`Reference`] of `scene`, computed once per scene and process: every
/// structure a test binary checks on a scene is compared with the same rays and answers (the
/// reference's work is most of a conformance check). Scenes are told apart by name, primitive
/// type and the bits of every primitive's box.
fn reference<P: SamplePoints>(scene: &Scene<P>) -> Result<Arc<Reference>, String> {
    type Cache = Mutex<HashMap<(TypeId, String, u64), Arc<Reference>>>;
    static CACHE: OnceLock<Cache> = OnceLock::new();
    let key = scene_key(scene);
    let cache = CACHE.get_or_init(Default::default);
    if let Some(r) = cache.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
        return Ok(r.clone());
    }
    let brute = BruteForce::build(&scene.prims).map_err(|e| e.to_string())?;
    let rays = conformance_rays(&scene.prims, &brute, 400, 0x5eed ^ scene.prims.len() as u64);
    let expected = rays.iter().map(|r| brute.intersect(&r.ray)).collect();
    let r = Arc::new(Reference { rays, expected });
    cache
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .insert(key, r.clone());
    Ok(r)
}

/// A scene told apart by name, primitive type and the bits of every primitive's box.
fn scene_key<P: Primitive>(scene: &Scene<P>) -> (TypeId, String, u64) {
    let mut hash = std::hash::DefaultHasher::new();
    for p in &scene.prims {
        let b = p.bounds();
        for x in b.min.to_array().into_iter().chain(b.max.to_array()) {
            x.to_bits().hash(&mut hash);
        }
    }
    (TypeId::of::<P>(), scene.name.clone(), hash.finish())
}

/// [`check_scene`] with [`Tolerance::EXACT`], panicking with reproducers on any disagreement.
pub fn assert_conforms<P, A, F>(scene: &Scene<P>, build: F)
where
    P: SamplePoints,
    A: Accel,
    F: Fn(&[P]) -> Result<A, BuildError>,
{
    assert_conforms_within(scene, build, Tolerance::EXACT)
}

/// [`assert_conforms`] with a tolerance.
pub fn assert_conforms_within<P, A, F>(scene: &Scene<P>, build: F, tolerance: Tolerance)
where
    P: SamplePoints,
    A: Accel,
    F: Fn(&[P]) -> Result<A, BuildError>,
{
    let report = check_scene(scene, build, tolerance).unwrap_or_else(|e| panic!("{e}"));
    if !report.is_ok() {
        let lines: Vec<String> = report.mismatches.iter().map(|m| format!("  {m}")).collect();
        panic!(
            "{} of {} rays disagree with brute force on scene {}:\n{}",
            report.mismatch_count,
            report.rays,
            scene.name,
            lines.join("\n")
        );
    }
    assert!(report.rays > 0);
}

/// Builders must reject NaN and infinite coordinates with `BuildError::NonFinite` naming the
/// primitive, and must not panic.
pub fn assert_rejects_non_finite<P, A, F>(valid: &[P], poison: impl Fn(&mut P), build: F)
where
    P: Primitive,
    A: Accel,
    F: Fn(&[P]) -> Result<A, BuildError>,
{
    let mut prims = valid.to_vec();
    assert!(prims.len() > 2, "need a few primitives to poison");
    let at = prims.len() / 2;
    poison(&mut prims[at]);
    match build(&prims) {
        Err(BuildError::NonFinite { prim }) => assert_eq!(prim, at),
        Err(e) => panic!("expected NonFinite {{ prim: {at} }}, got {e}"),
        Ok(_) => panic!("a non-finite primitive was accepted"),
    }
}

/// The filters [`check_filters`] asks with, by name: whether each accepts `hit` for `ray`,
/// whose unfiltered closest hit (brute force's) is `closest`, in a scene of `n` primitives.
pub const FILTERS: [(&str, fn(&Hit, Option<Hit>, u32) -> bool); 4] = [
    // Alpha-test-like: a fixed pseudo-random third of the primitives is cut out.
    ("a hash of the id", |h, _, _| {
        (h.prim.wrapping_mul(0x9e37_79b9) >> 29) % 3 != 0
    }),
    // The nearest surface skipped (and everything at its `t`): the walk must go on past it.
    ("t beyond the unfiltered closest hit", |h, closest, _| {
        closest.is_none_or(|c| h.t > c.t)
    }),
    // The primitive a secondary ray leaves.
    ("skip primitive n / 2", |h, _, n| h.prim != n / 2),
    // Nothing accepted: every query misses.
    ("reject all", |_, _, _| false),
];

/// The query masks [`check_filters`] asks with, against primitive masks of one bit each
/// ([`test_masks`]): one bit, two bits, none (every primitive masked out).
pub const RAY_MASKS: [u32; 3] = [0b0001, 0b0110, 0];

/// Per primitive, a mask of one of four bits, by a hash of its id.
pub fn test_masks(n: u32) -> Vec<u32> {
    (0..n)
        .map(|p| 1 << (p.wrapping_mul(0x85eb_ca6b) >> 30))
        .collect()
}

/// Accepts everything, and notes whether it was offered a hit of a primitive it skips.
struct SkipWatch<'a> {
    masks: &'a [u32],
    ray: u32,
    offered_skipped: bool,
}

impl HitFilter for SkipWatch<'_> {
    fn skips(&self, prim: u32) -> bool {
        self.masks[prim as usize] & self.ray == 0
    }

    fn accepts(&mut self, hit: &Hit) -> bool {
        self.offered_skipped |= self.skips(hit.prim);
        true
    }
}

/// Every how many conformance rays [`check_filters`] asks its questions of: each eighth
/// (every family of rays is still asked, a few hundred rays per scene), or each ray with
/// `RT_LONG_TESTS=1` ([`crate::long_tests`]). The plain queries are checked on every ray; the
/// filtered ones cost twenty queries a ray, most of the conformance tests' time at full size.
pub fn filter_ray_stride() -> usize {
    if crate::long_tests() { 1 } else { 8 }
}

/// Filtered queries and every hit along a ray, against [`BruteForce`] asked the same on
/// the scene's conformance rays (every [`filter_ray_stride`]-th): for each of [`FILTERS`], and for ray masks ([`RAY_MASKS`] over
/// [`test_masks`]), `intersect_filtered` gives brute force's hit exactly (the same `t`, `u`,
/// `v` and primitive) and `occluded_filtered` its answer; a masked primitive is never
/// offered to the filter; and `for_each_hit` gives brute force's sorted
/// list of every primitive's hit (each once, even where a structure lists a primitive in
/// several cells). `Err` names the first disagreement with a reproducer.
pub fn check_filters<P, A, F>(scene: &Scene<P>, build: F) -> Result<usize, String>
where
    P: SamplePoints,
    A: FilteredAccel,
    F: Fn(&[P]) -> Result<A, BuildError>,
{
    let subject =
        build(&scene.prims).map_err(|e| format!("build failed on {}: {e}", scene.name))?;
    check_filters_built(scene, &subject)
}

/// [`check_filters`] of a built structure (compiled once per primitive type).
fn check_filters_built<P: SamplePoints>(
    scene: &Scene<P>,
    subject: &dyn FilteredAccel,
) -> Result<usize, String> {
    let reference = reference(scene)?;
    let expected = filtered_reference(scene, &reference)?;
    let n = scene.prims.len() as u32;
    let masks = test_masks(n);
    let mut checked = 0;
    for ((test, closest), want) in reference
        .rays
        .iter()
        .zip(&reference.expected)
        .step_by(filter_ray_stride())
        .zip(&*expected)
    {
        let ray = &test.ray;
        let at = |what: &str, expected: &dyn fmt::Debug, got: &dyn fmt::Debug| {
            format!(
                "{what} on scene {} ({:?} ray {ray:?}): expected {expected:?}, got {got:?}",
                scene.name, test.kind
            )
        };
        // The closest accepted hit and the any-hit answer of `filter`, against brute force's.
        let ask = |what: String, filter: &mut dyn HitFilter, closest: Option<Hit>, any: bool| {
            let got = subject.intersect_filtered(ray, filter);
            if !same_hits(got.as_slice(), closest.as_slice()) {
                return Err(at(&format!("intersect_filtered ({what})"), &closest, &got));
            }
            let got = subject.occluded_filtered(ray, filter);
            if got != any {
                return Err(at(&format!("occluded_filtered ({what})"), &any, &got));
            }
            Ok(())
        };
        for (k, (name, accept)) in FILTERS.into_iter().enumerate() {
            let mut filter = |h: &Hit| accept(h, *closest, n);
            ask(
                name.to_string(),
                &mut filter,
                want.closest[k],
                want.occluded[k],
            )?;
            checked += 1;
        }
        for (k, &mask) in RAY_MASKS.iter().enumerate() {
            let mut masked = Masked {
                prims: &masks,
                instances: &[],
                ray: mask,
                inner: |_: &Hit| true,
            };
            let (closest, any) = (want.masked[k], want.masked[k].is_some());
            ask(format!("mask {mask:#b}"), &mut masked, closest, any)?;
            let mut watch = SkipWatch {
                masks: &masks,
                ray: mask,
                offered_skipped: false,
            };
            subject.intersect_filtered(ray, &mut watch);
            if watch.offered_skipped {
                return Err(at(
                    &format!("a masked primitive tested (mask {mask:#b})"),
                    &"",
                    &"",
                ));
            }
        }
        // A ray leaving a primitive, through the queries without a filter to call.
        let left = left_prim(*closest, n);
        let got = subject.intersect_leaving(ray, left);
        if !same_hits(got.as_slice(), want.leaving.0.as_slice()) {
            return Err(at(
                &format!("intersect_leaving {left}"),
                &want.leaving.0,
                &got,
            ));
        }
        let got = subject.occluded_leaving(ray, left);
        if got != want.leaving.1 {
            return Err(at(
                &format!("occluded_leaving {left}"),
                &want.leaving.1,
                &got,
            ));
        }
        let got = all_hits(subject, ray);
        if !same_hits(&got, &want.all) {
            return Err(at("for_each_hit", &want.all, &got));
        }
        // Stopping after the first hit gives the closest.
        let mut first = None;
        subject.for_each_hit(ray, &mut |h| {
            first = Some(*h);
            std::ops::ControlFlow::Break(())
        });
        if !same_hits(first.as_slice(), closest.as_slice()) {
            return Err(at("for_each_hit, stopped at the first", closest, &first));
        }
    }
    Ok(checked)
}

/// The same hits bit for bit (a user primitive's `u`, `v` may be NaN).
fn same_hits(a: &[Hit], b: &[Hit]) -> bool {
    let key = |h: &Hit| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim);
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| key(x) == key(y))
}

/// Every hit `for_each_hit` hands over, in its order.
fn all_hits(a: &dyn FilteredAccel, ray: &Ray) -> Vec<Hit> {
    let mut hits = Vec::new();
    a.for_each_hit(ray, &mut |h| {
        hits.push(*h);
        std::ops::ControlFlow::Continue(())
    });
    hits
}

/// Brute force's answers to one ray's filtered questions ([`FILTERS`] in order, then the
/// closest hit under each of [`RAY_MASKS`]).
struct FilteredAnswers {
    closest: Vec<Option<Hit>>,
    occluded: Vec<bool>,
    masked: Vec<Option<Hit>>,
    all: Vec<Hit>,
    /// The closest hit and the any-hit answer of the ray leaving [`left_prim`].
    leaving: (Option<Hit>, bool),
}

/// The primitive a ray leaves in [`check_filters`]: the one it hits first (so that skipping
/// it changes the answer), else primitive `n / 2`.
fn left_prim(closest: Option<Hit>, n: u32) -> u32 {
    closest.map_or(n / 2, |h| h.prim)
}

/// Brute force's [`FilteredAnswers`] for the rays of `reference` that [`check_filters`] asks
/// (every [`filter_ray_stride`]-th), computed once per scene and process, as [`reference`] is.
fn filtered_reference<P: SamplePoints>(
    scene: &Scene<P>,
    reference: &Reference,
) -> Result<Arc<Vec<FilteredAnswers>>, String> {
    type Cache = Mutex<HashMap<(TypeId, String, u64), Arc<Vec<FilteredAnswers>>>>;
    static CACHE: OnceLock<Cache> = OnceLock::new();
    let key = scene_key(scene);
    let cache = CACHE.get_or_init(Default::default);
    if let Some(r) = cache.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
        return Ok(r.clone());
    }
    let brute = BruteForce::build(&scene.prims).map_err(|e| e.to_string())?;
    let n = scene.prims.len() as u32;
    let masks = test_masks(n);
    let answers: Vec<FilteredAnswers> = reference
        .rays
        .iter()
        .zip(&reference.expected)
        .step_by(filter_ray_stride())
        .map(|(test, closest)| {
            let ray = &test.ray;
            let mut answers = FilteredAnswers {
                closest: Vec::new(),
                occluded: Vec::new(),
                masked: Vec::new(),
                all: all_hits(&brute, ray),
                leaving: {
                    let mut skip = SkipPrim(left_prim(*closest, n));
                    let hit = brute.intersect_filtered(ray, &mut skip);
                    (hit, brute.occluded_filtered(ray, &mut skip))
                },
            };
            for mask in RAY_MASKS {
                let mut masked = Masked {
                    prims: &masks,
                    instances: &[],
                    ray: mask,
                    inner: |_: &Hit| true,
                };
                answers
                    .masked
                    .push(brute.intersect_filtered(ray, &mut masked));
            }
            for (_, accept) in FILTERS {
                let mut filter = |h: &Hit| accept(h, *closest, n);
                answers
                    .closest
                    .push(brute.intersect_filtered(ray, &mut filter));
                answers
                    .occluded
                    .push(brute.occluded_filtered(ray, &mut filter));
            }
            answers
        })
        .collect();
    let r = Arc::new(answers);
    cache
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .insert(key, r.clone());
    Ok(r)
}

/// [`check_filters`], panicking with the reproducer.
pub fn assert_filters_conform<P, A, F>(scene: &Scene<P>, build: F)
where
    P: SamplePoints,
    A: FilteredAccel,
    F: Fn(&[P]) -> Result<A, BuildError>,
{
    match check_filters(scene, build) {
        Ok(checked) => assert!(checked > 0 || scene.prims.is_empty()),
        Err(e) => panic!("{e}"),
    }
}

/// Stamps out the [`check_filters`] tests of a structure: triangle scenes with shared edges,
/// duplicates, coplanar and far-away triangles, and, where given, spheres and mixed shapes.
///
/// ```ignore
/// rt_testkit::filter_tests!(
///     triangles: |p: &[Triangle]| MyTree::build(p),
///     spheres: |p: &[Sphere]| MyTree::build(p),
/// );
/// ```
#[macro_export]
macro_rules! filter_tests {
    (triangles: $tri:expr $(, spheres: $sph:expr)? $(, shapes: $shp:expr)? $(,)?) => {
        #[test]
        fn filters_and_all_hits_on_triangles() {
            for scene in ["soup", "duplicates", "overlapping_fan", "far_soup", "empty"] {
                $crate::conformance::assert_filters_conform(
                    &$crate::scenes::triangle_scene(scene), $tri);
            }
        }
        $(
            #[test]
            fn filters_and_all_hits_on_spheres() {
                $crate::conformance::assert_filters_conform(
                    &$crate::scenes::sphere_scene("spheres"), $sph);
            }
        )?
        $(
            #[test]
            fn filters_and_all_hits_on_shapes() {
                $crate::conformance::assert_filters_conform(
                    &$crate::scenes::shape_scene("shapes"), $shp);
            }
        )?
    };
}

/// The triangle scenes every structure over triangles is checked on.
pub const TRIANGLE_SCENES: [&str; 19] = [
    "soup",
    "sphere_mesh",
    "torus",
    "planar_grid",
    "coplanar",
    "axis_slivers",
    "duplicates",
    "teapot_in_stadium",
    "overlapping_fan",
    "long_slivers",
    "huge_coords",
    "tiny_coords",
    "one_triangle",
    "empty",
    "far_soup",
    "far_sphere",
    "far_stadium",
    "far_dense",
    "far_slivers",
];

/// A triangle that brute force tests with Möller–Trumbore's kernel
/// ([`Triangle::intersect_moller_trumbore`]): the reference for structures whose leaves run
/// that kernel ([`conformance_tests!`](crate::conformance_tests)'s `moller_trumbore:` form).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MollerTrumbore(pub Triangle);

impl Primitive for MollerTrumbore {
    fn bounds(&self) -> Aabb {
        self.0.bounds()
    }

    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        self.0.intersect_moller_trumbore(ray)
    }

    fn centroid(&self) -> Vec3 {
        self.0.centroid()
    }

    fn clipped_bounds(&self, clip: &Aabb) -> Aabb {
        self.0.clipped_bounds(clip)
    }

    fn normal(&self, ray: &Ray, h: &PrimHit) -> Option<Vec3> {
        Primitive::normal(&self.0, ray, h)
    }

    fn extent_along(&self, n: Vec3) -> (f32, f32) {
        self.0.extent_along(n)
    }

    fn extent_along_from(&self, origin: Vec3, n: Vec3) -> (f32, f32) {
        self.0.extent_along_from(origin, n)
    }

    fn farthest_distance(&self, p: DVec3) -> f32 {
        self.0.farthest_distance(p)
    }

    fn is_finite(&self) -> bool {
        Primitive::is_finite(&self.0)
    }

    fn plane(&self) -> Option<(Vec3, f32)> {
        self.0.plane()
    }
}

impl SamplePoints for MollerTrumbore {
    fn sample(&self, u: f32, v: f32) -> Vec3 {
        self.0.sample(u, v)
    }

    fn feature_point(&self, rng: &mut crate::Rng) -> Vec3 {
        self.0.feature_point(rng)
    }
}

/// Triangle scene `name` ([`crate::scenes::triangle_scene`]) as [`MollerTrumbore`]
/// triangles.
pub fn moller_trumbore_scene(name: &str) -> Scene<MollerTrumbore> {
    let scene = crate::scenes::triangle_scene(name);
    Scene::new(
        scene.name,
        scene.prims.into_iter().map(MollerTrumbore).collect(),
    )
}

/// Stamps out the conformance tests of a structure: one `#[test]` per family of scenes
/// (triangles, spheres, mixed shapes) walking every scene of it, and the refusal of
/// non-finite primitives.
///
/// ```ignore
/// mod conformance {
///     use rt_geom::{BruteForce, Sphere, Triangle};
///     rt_testkit::conformance_tests!(
///         triangles: |p: &[Triangle]| BruteForce::build(p),
///         spheres: |p: &[Sphere]| BruteForce::build(p),
///     );
/// }
/// ```
/// An optional `tolerance: expr` first argument replaces [`Tolerance::EXACT`].
#[macro_export]
macro_rules! conformance_tests {
    (triangles: $tri:expr $(,)?) => {
        $crate::conformance_tests!(tolerance: $crate::conformance::Tolerance::EXACT, triangles: $tri);
    };
    (triangles: $tri:expr, spheres: $sph:expr $(,)?) => {
        $crate::conformance_tests!(
            tolerance: $crate::conformance::Tolerance::EXACT, triangles: $tri, spheres: $sph
        );
    };
    (tolerance: $tol:expr, triangles: $tri:expr $(,)?) => {
        $crate::conformance_tests!(@tri $tol, $tri);
        #[test]
        fn rejects_non_finite_triangles() {
            let valid = $crate::scenes::random_soup(10, 1);
            $crate::conformance::assert_rejects_non_finite(
                &valid, |t| t.v[1].y = f32::NAN, built_triangles);
            $crate::conformance::assert_rejects_non_finite(
                &valid, |t| t.v[0].x = f32::INFINITY, built_triangles);
        }
    };
    (tolerance: $tol:expr, triangles: $tri:expr, spheres: $sph:expr $(,)?) => {
        $crate::conformance_tests!(tolerance: $tol, triangles: $tri);
        $crate::conformance_tests!(@sph $tol, $sph; spheres, one_sphere, empty_spheres, far_spheres);
        #[test]
        fn rejects_non_finite_spheres() {
            let valid = $crate::scenes::random_spheres(10, 1);
            $crate::conformance::assert_rejects_non_finite(
                &valid, |s| s.radius = f32::NAN, built_spheres);
        }
    };
    (tolerance: $tol:expr, triangles: $tri:expr, spheres: $sph:expr, shapes: $shp:expr $(,)?) => {
        $crate::conformance_tests!(tolerance: $tol, triangles: $tri, spheres: $sph);
        $crate::conformance_tests!(@shp $tol, $shp; shapes, cones, posts);
        #[test]
        fn rejects_non_finite_shapes() {
            let valid = $crate::scenes::mixed_shapes(12, 1);
            $crate::conformance::assert_rejects_non_finite(&valid, |s| {
                if let $crate::rt_geom::Shape::Cone(c) = s { c.apex.z = f32::NAN }
                else { *s = $crate::rt_geom::Cone::new(
                    $crate::rt_geom::Vec3::ZERO, f32::INFINITY, $crate::rt_geom::Vec3::Z, 1.0).into() }
            }, built_shapes);
        }
    };
    (triangles: $tri:expr, spheres: $sph:expr, shapes: $shp:expr $(,)?) => {
        $crate::conformance_tests!(
            tolerance: $crate::conformance::Tolerance::EXACT, triangles: $tri, spheres: $sph,
            shapes: $shp
        );
    };
    (@shp $tol:expr, $build:expr; $($scene:ident),*) => {
        /// The structure under test, built over shapes, as a boxed `Accel` (the check is then
        /// compiled once per primitive type).
        fn built_shapes(
            p: &[$crate::rt_geom::Shape],
        ) -> Result<Box<dyn $crate::rt_geom::Accel>, $crate::rt_geom::BuildError> {
            ($build)(p).map(|a| Box::new(a) as Box<dyn $crate::rt_geom::Accel>)
        }
        /// Every scene of the family (one test: the scene's name is in every failure).
        #[test]
        fn shape_scenes() {
            for scene in [$(stringify!($scene)),*] {
                $crate::conformance::assert_conforms_within(
                    &$crate::scenes::shape_scene(scene), built_shapes, $tol);
            }
        }
    };
    (moller_trumbore: $build:expr $(,)?) => {
        /// The structure under test, its leaves on Möller–Trumbore's kernel, built over a
        /// scene's triangles, as a boxed `Accel`.
        fn built_moller_trumbore(
            p: &[$crate::conformance::MollerTrumbore],
        ) -> Result<Box<dyn $crate::rt_geom::Accel>, $crate::rt_geom::BuildError> {
            let tris: Vec<$crate::rt_geom::Triangle> = p.iter().map(|m| m.0).collect();
            ($build)(&tris[..]).map(|a| Box::new(a) as Box<dyn $crate::rt_geom::Accel>)
        }
        /// Every triangle scene, against brute force with Möller–Trumbore's kernel.
        #[test]
        fn moller_trumbore_scenes() {
            for scene in $crate::conformance::TRIANGLE_SCENES {
                $crate::conformance::assert_conforms(
                    &$crate::conformance::moller_trumbore_scene(scene), built_moller_trumbore);
            }
        }
    };
    (@tri $tol:expr, $build:expr) => {
        /// The structure under test, built over triangles, as a boxed `Accel` (the check is then
        /// compiled once per primitive type).
        fn built_triangles(
            p: &[$crate::rt_geom::Triangle],
        ) -> Result<Box<dyn $crate::rt_geom::Accel>, $crate::rt_geom::BuildError> {
            ($build)(p).map(|a| Box::new(a) as Box<dyn $crate::rt_geom::Accel>)
        }
        /// Every scene of the family (one test: the scene's name is in every failure).
        #[test]
        fn triangle_scenes() {
            for scene in $crate::conformance::TRIANGLE_SCENES {
                $crate::conformance::assert_conforms_within(
                    &$crate::scenes::triangle_scene(scene), built_triangles, $tol);
            }
        }
    };
    (@sph $tol:expr, $build:expr; $($scene:ident),*) => {
        /// The structure under test, built over spheres, as a boxed `Accel` (the check is then
        /// compiled once per primitive type).
        fn built_spheres(
            p: &[$crate::rt_geom::Sphere],
        ) -> Result<Box<dyn $crate::rt_geom::Accel>, $crate::rt_geom::BuildError> {
            ($build)(p).map(|a| Box::new(a) as Box<dyn $crate::rt_geom::Accel>)
        }
        /// Every scene of the family (one test: the scene's name is in every failure).
        #[test]
        fn sphere_scenes() {
            for scene in [$(stringify!($scene)),*] {
                $crate::conformance::assert_conforms_within(
                    &$crate::scenes::sphere_scene(scene), built_spheres, $tol);
            }
        }
    };
}

/// Stamps out the conformance tests of a structure over [`Disc`](crate::Disc)s, user
/// geometry that implements only `bounds` and `intersect`: the disc scenes against brute
/// force, and the filters on them.
///
/// ```ignore
/// rt_testkit::disc_tests!(|p: &[rt_testkit::Disc]| MyTree::build(p));
/// ```
#[macro_export]
macro_rules! disc_tests {
    ($build:expr) => {
        #[test]
        fn user_geometry_discs() {
            for scene in ["discs", "one_disc", "far_discs"] {
                $crate::conformance::assert_conforms(&$crate::disc::disc_scene(scene), $build);
            }
            $crate::conformance::assert_filters_conform(&$crate::disc::disc_scene("discs"), $build);
        }
    };
}

/// One module of [`conformance_tests!`] per named parameter set of a builder that takes
/// `(prims, params)`, over triangles, spheres and mixed shapes:
///
/// ```ignore
/// rt_testkit::conformance_per_params!(KdTree::build {
///     sah: KdParams::sah(),
///     midpoint: KdParams::midpoint(),
/// });
/// ```
#[macro_export]
macro_rules! conformance_per_params {
    ($ty:ident :: $build:ident { $($name:ident: $params:expr),* $(,)? }) => {$(
        mod $name {
            use super::*;
            $crate::conformance_tests!(
                triangles: |p: &[$crate::rt_geom::Triangle]| $ty::$build(p, $params),
                spheres: |p: &[$crate::rt_geom::Sphere]| $ty::$build(p, $params),
                shapes: |p: &[$crate::rt_geom::Shape]| $ty::$build(p, $params),
            );
            $crate::filter_tests!(
                triangles: |p: &[$crate::rt_geom::Triangle]| $ty::$build(p, $params),
                spheres: |p: &[$crate::rt_geom::Sphere]| $ty::$build(p, $params),
                shapes: |p: &[$crate::rt_geom::Shape]| $ty::$build(p, $params),
            );
            $crate::disc_tests!(|p: &[$crate::Disc]| $ty::$build(p, $params));
        }
    )*};
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_geom::{AccelStats, Triangle};

    mod brute_force {
        use rt_geom::{BruteForce, Sphere, Triangle};
        crate::conformance_tests!(
            triangles: |p: &[Triangle]| BruteForce::build(p),
            spheres: |p: &[Sphere]| BruteForce::build(p),
            shapes: |p: &[rt_geom::Shape]| BruteForce::build(p),
        );
        crate::disc_tests!(|p: &[crate::Disc]| BruteForce::build(p));
    }

    /// Filtered queries written the wrong ways must fail [`check_filters`]: the filter
    /// ignored, and the filter asked only of the unfiltered closest hit (a rejected nearest
    /// surface then hides everything behind it).
    #[test]
    fn filter_check_catches_wrong_filtering() {
        struct PostHoc(BruteForce<Triangle>, bool);
        impl Accel for PostHoc {
            fn intersect(&self, ray: &Ray) -> Option<Hit> {
                self.0.intersect(ray)
            }
            fn occluded(&self, ray: &Ray) -> bool {
                self.0.occluded(ray)
            }
            fn stats(&self) -> AccelStats {
                self.0.stats()
            }
            fn validate(&self) -> Result<(), String> {
                self.0.validate()
            }
        }
        impl FilteredAccel for PostHoc {
            fn intersect_filtered(
                &self,
                ray: &Ray,
                filter: &mut dyn rt_geom::HitFilter,
            ) -> Option<Hit> {
                let ignore = self.1;
                self.0
                    .intersect(ray)
                    .filter(|h| ignore || filter.accepts(h))
            }
            fn occluded_filtered(&self, ray: &Ray, filter: &mut dyn rt_geom::HitFilter) -> bool {
                self.intersect_filtered(ray, filter).is_some()
            }
        }
        let scene = crate::scenes::triangle_scene("duplicates");
        for ignore in [true, false] {
            let err = check_filters(&scene, |p| Ok(PostHoc(BruteForce::build(p)?, ignore)));
            assert!(err.is_err(), "ignore = {ignore}: the check passed");
        }
        assert!(check_filters(&scene, BruteForce::build).is_ok());
    }

    /// A deliberately broken structure: it forgets every other primitive.
    struct Forgetful(BruteForce<Triangle>);

    impl Accel for Forgetful {
        fn intersect(&self, ray: &Ray) -> Option<Hit> {
            self.0.intersect(ray).filter(|h| h.prim % 2 == 0)
        }
        fn occluded(&self, ray: &Ray) -> bool {
            self.intersect(ray).is_some()
        }
        fn stats(&self) -> AccelStats {
            self.0.stats()
        }
        fn validate(&self) -> Result<(), String> {
            Ok(())
        }
    }

    #[test]
    fn the_suite_catches_a_broken_structure() {
        let scene = crate::scenes::triangle_scene("soup");
        let report = check_scene(
            &scene,
            |p: &[Triangle]| BruteForce::build(p).map(Forgetful),
            Tolerance::EXACT,
        )
        .unwrap();
        assert!(report.mismatch_count > 100, "{}", report.mismatch_count);
        let text = report.mismatches[0].to_string();
        assert!(
            text.contains("Ray::segment(Vec3::new(") && text.contains("scene soup"),
            "{text}"
        );
    }

    /// Reports the last of equal-t hits instead of the first.
    struct HighestOnTies(Vec<Triangle>, BruteForce<Triangle>);

    impl Accel for HighestOnTies {
        fn intersect(&self, ray: &Ray) -> Option<Hit> {
            let mut best: Option<Hit> = None;
            for (i, t) in self.0.iter().enumerate() {
                if let Some(h) = t.intersect_watertight(ray) {
                    if best.is_none_or(|b| h.t <= b.t) {
                        best = Some(Hit::new(h, i as u32));
                    }
                }
            }
            best
        }
        fn occluded(&self, ray: &Ray) -> bool {
            self.intersect(ray).is_some()
        }
        fn stats(&self) -> AccelStats {
            self.1.stats()
        }
        fn validate(&self) -> Result<(), String> {
            Ok(())
        }
    }

    #[test]
    fn ties_must_go_to_the_lowest_primitive_id() {
        let scene = crate::scenes::triangle_scene("duplicates");
        let report = check_scene(
            &scene,
            |p: &[Triangle]| BruteForce::build(p).map(|b| HighestOnTies(p.to_vec(), b)),
            Tolerance::EXACT,
        )
        .unwrap();
        assert!(report.mismatch_count > 10, "{}", report.mismatch_count);
        assert!(
            report.mismatches[0].query.contains("tie"),
            "{}",
            report.mismatches[0]
        );
        let lenient = Tolerance {
            lowest_on_ties: false,
            ..Tolerance::EXACT
        };
        let report = check_scene(
            &scene,
            |p: &[Triangle]| BruteForce::build(p).map(|b| HighestOnTies(p.to_vec(), b)),
            lenient,
        )
        .unwrap();
        assert_eq!(report.mismatch_count, 0);
    }

    #[test]
    fn loose_tolerance_lets_near_hits_drop() {
        let tol = Tolerance {
            rel_t: 1e-6,
            near_t: 1e-4,
            boundary_misses: true,
            behind_origin_misses: true,
            lowest_on_ties: false,
            edge_band: 0.0,
        };
        let ray = Ray::new(rt_geom::Vec3::ZERO, rt_geom::Vec3::X * 2.0);
        assert!(may_drop(2e-5, &ray, tol) && may_drop(-2e-5, &ray, tol));
        assert!(!may_drop(2e-4, &ray, tol) && !may_drop(-2e-4, &ray, tol));
        assert!(!may_drop(2e-5, &ray, Tolerance::EXACT));
        // A hit behind the origin binds an exact structure like one ahead.
        assert!(!may_drop(-3.0, &ray, Tolerance::EXACT));
        assert!(!t_agrees(-3.0, 1.0, &ray, Tolerance::EXACT));
        let test = |kind, ray| TestRay { ray, kind };
        let behind = ray.with_range(-1.0, f32::INFINITY);
        assert!(tol.excuses(&test(RayKind::Grazing, ray)));
        assert!(!tol.excuses(&test(RayKind::Aimed, ray)));
        assert!(tol.excuses(&test(RayKind::Limited, behind)));
        assert!(!Tolerance::EXACT.excuses(&test(RayKind::Grazing, ray)));
        assert!(!Tolerance::EXACT.excuses(&test(RayKind::Behind, behind)));
        assert!(t_agrees(1000.0, 1000.0005, &ray, tol));
        assert!(!t_agrees(1.0, 1.001, &ray, tol));
    }
}
