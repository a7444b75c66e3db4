//! `cargo xtask far`: every structure on one mesh placed far from the origin, as scenes in
//! projected coordinates come from GIS and CAD tools (x = 3e5, y = 5e6 metres), against the
//! same mesh at the origin: build and trace time, and the rays whose answers differ from
//! brute force's.
//!
//! A placement scales the mesh to a largest extent (`size`) about its centre and moves that
//! centre to `(d, d, d)`, each vertex rounded to `f32` once, as a file in such coordinates
//! holds it: at 5e6 vertices snap to a lattice of 0.5. Its twin at the origin is the same
//! placed mesh moved back by `-d` (exact: the differences are small multiples of that
//! lattice), so both hold the same triangles and differ only in where they lie. The rays
//! are the standard front view's camera rays and a diffuse bounce from each hit, made at the
//! origin, moved out the same way (the eye and the bounce origins rounded once) and back.

use crate::registry::AccelEntry;
use crate::run::{pool, trace_into};
use rayon::prelude::*;
use rt_geom::glam::DVec3;
use rt_geom::{Aabb, Accel, BruteForce, Ray, Triangle, Vec3};
use rt_testkit::rayfile::HitRecord;
use rt_testkit::rays::RaySets;
use std::time::Instant;

/// What `far` runs.
pub struct FarOptions {
    /// Largest extents to scale the mesh to.
    pub sizes: Vec<f64>,
    /// Offsets of the mesh's centre along every axis (each measured against its twin at the
    /// origin).
    pub offsets: Vec<f64>,
    /// Camera resolution (side x side primary rays).
    pub side: usize,
    /// Threads for the traces.
    pub threads: usize,
    /// Trace repetitions; the median is kept.
    pub repeat: usize,
}

/// One structure on one placement (at the origin or far away).
#[derive(Clone, Debug)]
pub struct FarRun {
    pub build_seconds: f64,
    /// Median time to trace every ray once (closest hits).
    pub trace_seconds: f64,
    /// Rays whose closest hit or occlusion differs from brute force's.
    pub differ: usize,
    /// The build's error, if it rejected the placement.
    pub error: Option<String>,
}

/// One structure at one size and offset: at the origin and far away.
#[derive(Clone, Debug)]
pub struct FarRow {
    pub accel: &'static str,
    pub size: f64,
    pub offset: f64,
    pub rays: usize,
    pub origin: FarRun,
    pub far: FarRun,
}

/// A placed mesh, its rays and brute force's answers.
struct Placement {
    tris: Vec<Triangle>,
    rays: Vec<Ray>,
    expected: Vec<HitRecord>,
    blocked: Vec<bool>,
}

impl Placement {
    fn new(tris: Vec<Triangle>, rays: Vec<Ray>) -> Result<Self, String> {
        let brute = BruteForce::build(&tris).map_err(|e| format!("the placed mesh: {e}"))?;
        let expected: Vec<HitRecord> = rays
            .par_iter()
            .map(|r| HitRecord::from_hit(brute.intersect(r)))
            .collect();
        // Brute force's any-hit answer is whether it has a closest hit.
        let blocked = expected.iter().map(HitRecord::is_hit).collect();
        Ok(Self {
            tris,
            rays,
            expected,
            blocked,
        })
    }
}

/// `p + by`, rounded to `f32` once.
fn moved(p: Vec3, by: f64) -> Vec3 {
    (p.as_dvec3() + DVec3::splat(by)).as_vec3()
}

/// The mesh scaled to `size` about its centre and moved to `offset`, and its twin at the
/// origin (the placed mesh moved back), with their rays.
fn place(
    mesh: &[Triangle],
    size: f64,
    offset: f64,
    side: usize,
) -> Result<(Placement, Placement), String> {
    let bounds = mesh.iter().fold(Aabb::EMPTY, |b, t| b.union(t.bounds()));
    let (c, s) = (
        bounds.center().as_dvec3(),
        size / bounds.extent().max_element().max(f32::MIN_POSITIVE) as f64,
    );
    let scaled: Vec<Triangle> = mesh
        .iter()
        .map(|t| Triangle {
            v: t.v.map(|p| ((p.as_dvec3() - c) * s).as_vec3()),
        })
        .collect();
    // The rays from a BVH's hits (the same as brute force's, faster on a large mesh).
    let bvh = rt_accel_bvh::TriBvh8::build_for_tracing(&scaled)
        .map_err(|e| format!("the mesh at size {size}: {e}"))?;
    let sets = RaySets::generate("far", &scaled, &bvh, side, side, 7);
    let rays: Vec<Ray> = sets.primary.into_iter().chain(sets.diffuse).collect();
    let out = |t: &Triangle| Triangle {
        v: t.v.map(|p| moved(p, offset)),
    };
    let back = |t: &Triangle| Triangle {
        v: t.v.map(|p| moved(p, -offset)),
    };
    let far_tris: Vec<Triangle> = scaled.iter().map(out).collect();
    let origin_tris: Vec<Triangle> = far_tris.iter().map(back).collect();
    let ray_at = |r: &Ray, o: Vec3| Ray::segment(o, r.dir(), r.tmin, r.tmax);
    let far_rays: Vec<Ray> = rays
        .iter()
        .map(|r| ray_at(r, moved(r.origin(), offset)))
        .collect();
    let origin_rays: Vec<Ray> = far_rays
        .iter()
        .map(|r| ray_at(r, moved(r.origin(), -offset)))
        .collect();
    Ok((
        Placement::new(origin_tris, origin_rays)?,
        Placement::new(far_tris, far_rays)?,
    ))
}

/// Builds and traces `entry` on `p`.
fn measure(entry: &AccelEntry, p: &Placement, repeat: usize, pool: &rayon::ThreadPool) -> FarRun {
    let start = Instant::now();
    let built = (entry.build)(&p.tris);
    let mut run = FarRun {
        build_seconds: start.elapsed().as_secs_f64(),
        trace_seconds: f64::NAN,
        differ: 0,
        error: None,
    };
    match built {
        Err(e) => run.error = Some(e.to_string()),
        Ok(accel) => {
            let mut out = vec![HitRecord::MISS; p.rays.len()];
            let mut times: Vec<f64> = (0..repeat.max(1))
                .map(|_| {
                    trace_into(accel.as_ref(), &p.rays, false, 1, pool, &mut out).as_secs_f64()
                })
                .collect();
            times.sort_by(f64::total_cmp);
            run.trace_seconds = times[times.len() / 2];
            run.differ = differing(accel.as_ref(), p, &out, pool);
        }
    }
    run
}

/// Builds and traces every entry at every size and offset and at the origin; `progress`
/// hears what runs.
pub fn run(
    mesh: &[Triangle],
    entries: &[&AccelEntry],
    options: &FarOptions,
    progress: &dyn Fn(&str),
) -> Result<Vec<FarRow>, String> {
    let pool = pool(options.threads)?;
    let mut rows = Vec::new();
    for &size in &options.sizes {
        for &offset in &options.offsets {
            progress(&format!("size {size}, offset {offset:e}: brute force"));
            let (origin, far) = pool.install(|| place(mesh, size, offset, options.side))?;
            for entry in entries {
                progress(&format!("size {size}, offset {offset:e}: {}", entry.name));
                rows.push(FarRow {
                    accel: entry.name,
                    size,
                    offset,
                    rays: far.rays.len(),
                    origin: measure(entry, &origin, options.repeat, &pool),
                    far: measure(entry, &far, options.repeat, &pool),
                });
            }
        }
    }
    Ok(rows)
}

/// Rays whose closest hit (`hits`, already traced) or occlusion differs from brute force's.
fn differing(
    accel: &dyn Accel,
    p: &Placement,
    hits: &[HitRecord],
    pool: &rayon::ThreadPool,
) -> usize {
    pool.install(|| {
        (0..p.rays.len())
            .into_par_iter()
            .filter(|&k| {
                let (a, b) = (hits[k], p.expected[k]);
                a.t.to_bits() != b.t.to_bits()
                    || a.prim != b.prim
                    || accel.occluded(&p.rays[k]) != p.blocked[k]
            })
            .count()
    })
}

/// The rows as a Markdown table: per structure, size and offset, the build and trace time at
/// the origin, the far placement's as a multiple of them, and the differing rays of each.
pub fn markdown(rows: &[FarRow]) -> String {
    let mut out = String::from(
        "| structure | size | offset | rays | origin build ms | origin trace ms | far build / origin | far trace / origin | differ at origin | differ far |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let (o, f) = (&r.origin, &r.far);
        let (build, trace) = match (&o.error, &f.error) {
            (None, None) => (
                format!("{:.2}", f.build_seconds / o.build_seconds),
                format!("{:.2}", f.trace_seconds / o.trace_seconds),
            ),
            _ => ("rejected".into(), "rejected".into()),
        };
        out.push_str(&format!(
            "| {} | {} | {:e} | {} | {:.1} | {:.1} | {build} | {trace} | {} | {} |\n",
            r.accel,
            r.size,
            r.offset,
            r.rays,
            o.build_seconds * 1e3,
            o.trace_seconds * 1e3,
            o.differ,
            f.differ
        ));
    }
    out
}
