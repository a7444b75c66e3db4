//! What each fuzz target checks, as functions of the input bytes: `Err` is a broken property
//! (a wrong answer), a panic is a crash. The fuzz targets (`fuzz/`) call these; the ordinary
//! test suite runs them on every seed and on every input that once failed
//! (`fuzz/regressions/<target>/`), so a fixed crash stays fixed without a nightly toolchain.

use crate::rayfile::{HitRecord, encode_hits, encode_rays, parse_hits, parse_rays};
use crate::registry::{AccelEntry, REGISTRY};
use crate::verify::packet_report;
use rt_geom::{Accel, BruteForce, Cone, Hit, Ray, Shape, Sphere, Triangle, Vec3, parse_obj};
use rt_shade::{Scene, ShadeOptions, parse_nff_bytes, parse_obj_scene};
use rt_testkit::conformance::{Report, Tolerance, compare_with_expected};
use rt_testkit::rays::{RayKind, SamplePoints, TestRay, conformance_rays};
use std::path::Path;

/// The fuzz targets, by name: each is `fuzz/fuzz_targets/<name>.rs`.
pub const TARGETS: [(&str, fn(&[u8]) -> Result<(), String>); 6] = [
    ("obj", obj),
    ("obj_scene", obj_scene),
    ("nff", nff),
    ("rays", rays),
    ("build_trace", build_trace),
    ("load_bvh", load_bvh),
];

/// The check of the target `name`.
pub fn target(name: &str) -> Option<fn(&[u8]) -> Result<(), String>> {
    TARGETS.iter().find(|(n, _)| *n == name).map(|(_, f)| *f)
}

/// Scenes larger than this are parsed but not traced (the fuzzer's time goes to parsing).
const TRACE_MAX_PRIMS: usize = 256;

/// The OBJ mesh reader: any bytes give a mesh or an error; a mesh's triangles, in a BVH8,
/// answer rays as brute force does.
pub fn obj(bytes: &[u8]) -> Result<(), String> {
    let Ok(mesh) = parse_obj(bytes, Path::new("fuzz.obj")) else {
        return Ok(());
    };
    let tris = mesh.triangles();
    if tris.iter().any(|t| !t.bounds().is_finite()) {
        return Err("parse_obj returned a non-finite vertex".into());
    }
    if tris.len() <= TRACE_MAX_PRIMS {
        let bvh8 = crate::registry::find("bvh8-tri").ok_or("no bvh8-tri entry")?;
        check_entry(bvh8, &tris, &exact_domain(&tris, &scene_rays(&tris, 8)))?;
    }
    Ok(())
}

/// The OBJ scene reader (rt-shade): the bytes before the first NUL are the OBJ file, the bytes
/// after it the text of every MTL file it names. A scene that loads renders (4x4 pixels) to the
/// same image with a BVH as with brute force.
pub fn obj_scene(bytes: &[u8]) -> Result<(), String> {
    let (obj, mtl) = match bytes.iter().position(|&b| b == 0) {
        Some(i) => (&bytes[..i], Some(&bytes[i + 1..])),
        None => (bytes, None),
    };
    let read_mtl = |_: &Path| match mtl {
        Some(m) => Ok(String::from_utf8_lossy(m).into_owned()),
        None => Err(std::io::Error::from(std::io::ErrorKind::NotFound)),
    };
    match parse_obj_scene(obj, Path::new("fuzz.obj"), &read_mtl) {
        Ok(scene) => render_agrees(&scene),
        Err(_) => Ok(()),
    }
}

/// The NFF reader: any bytes give a scene or an error; a scene renders as [`obj_scene`]'s.
pub fn nff(bytes: &[u8]) -> Result<(), String> {
    match parse_nff_bytes(bytes, Path::new("fuzz.nff"), "fuzz") {
        Ok(scene) => render_agrees(&scene),
        Err(_) => Ok(()),
    }
}

/// The `.rays` and `.hits` readers: any bytes give rays or an error; rays written back read
/// the same; every ray (NaN, infinite, zero direction, reversed interval) is answered by
/// the structures as brute force answers it, on a small sphere of triangles.
pub fn rays(bytes: &[u8]) -> Result<(), String> {
    if let Ok(hits) = parse_hits(bytes) {
        let again = encode_hits(&hits);
        if again != bytes {
            return Err("hits written back differ from the bytes read".into());
        }
        let _: Vec<bool> = hits.iter().map(HitRecord::is_hit).collect();
    }
    let Ok(rays) = parse_rays(bytes) else {
        return Ok(());
    };
    // Writing back gives the bytes read, up to the direction components `Ray` flushes to
    // zero (below its resolution): reading what was written changes nothing more.
    let written = encode_rays(&rays);
    if written.len() != bytes.len() {
        return Err("rays written back differ in number from the rays read".into());
    }
    if parse_rays(&written).map(|again| encode_rays(&again)) != Ok(written) {
        return Err("rays read back from what was written differ".into());
    }
    let tris = rt_testkit::scenes::tessellated_sphere(6, Vec3::ZERO, 1.0);
    let tests: Vec<TestRay> = rays
        .iter()
        .take(64)
        .map(|&ray| TestRay {
            ray,
            kind: RayKind::Random,
        })
        .collect();
    let tests = exact_domain(&tris, &tests);
    for name in ["bvh8-tri", "kd", "grid2", "octree", "bvh"] {
        let entry = crate::registry::find(name).ok_or(format!("no {name} entry"))?;
        check_entry(entry, &tris, &tests)?;
    }
    Ok(())
}

/// The triangles saved structures are loaded over in [`load_bvh`] (and its seeds built over).
pub fn load_bvh_triangles() -> Vec<Triangle> {
    rt_testkit::scenes::tessellated_sphere(40, Vec3::ZERO, 1.0)
}

/// The one object the saved two-level scenes of [`load_bvh`] are loaded over: the triangles
/// under a `TriBvh8`.
pub fn load_bvh_object(tris: &[Triangle]) -> rt_accel_bvh::Object<rt_accel_bvh::TriBvh8> {
    rt_accel_bvh::Object::build(tris, rt_accel_bvh::TriBvh8::build_for_tracing)
        .expect("the fuzz triangles build")
}

/// The saved-structure loaders (`TriBvh::from_bytes`, `KdTree::from_bytes`): any bytes are
/// refused with an error or load a structure that answers rays exactly as brute force does,
/// and saves back to the same bytes. Tried as each layout (`TriBvh8`, `TriBvh4`,
/// `CompressedTriBvh8`, `Bvh8` and the binary `Bvh` over the triangles as primitives, the
/// kd-tree, the octree, the grids, and a two-level scene over the triangles as one object).
pub fn load_bvh(bytes: &[u8]) -> Result<(), String> {
    use rt_accel_bvh::{Bvh, Bvh8, CompressedTriBvh8, TriBvh4, TriBvh8};
    let tris = load_bvh_triangles();
    let brute = rt_geom::BruteForce::build(&tris).map_err(|e| e.to_string())?;
    let loaded: Vec<(Box<dyn Accel>, Vec<u8>)> = [
        TriBvh8::from_bytes(bytes, &tris).map(|b| (b.to_bytes(), Box::new(b) as Box<dyn Accel>)),
        TriBvh4::from_bytes(bytes, &tris).map(|b| (b.to_bytes(), Box::new(b) as Box<dyn Accel>)),
        CompressedTriBvh8::from_bytes(bytes, &tris)
            .map(|b| (b.to_bytes(), Box::new(b) as Box<dyn Accel>)),
        Bvh8::from_bytes(bytes, &tris).map(|b| (b.to_bytes(), Box::new(b) as Box<dyn Accel>)),
        Bvh::from_bytes(bytes, &tris).map(|b| (b.to_bytes(), Box::new(b) as Box<dyn Accel>)),
        rt_accel_kd::KdTree::from_bytes(bytes, &tris)
            .map(|b| (b.to_bytes(), Box::new(b) as Box<dyn Accel>)),
        rt_accel_octree::Octree::from_bytes(bytes, &tris)
            .map(|b| (b.to_bytes(), Box::new(b) as Box<dyn Accel>)),
        rt_accel_grid::Grid::from_bytes(bytes, &tris)
            .map(|b| (b.to_bytes(), Box::new(b) as Box<dyn Accel>)),
        rt_accel_bvh::InstanceBvh::from_bytes(bytes, vec![load_bvh_object(&tris)])
            .map(|b| (b.to_bytes(), Box::new(b) as Box<dyn Accel>)),
    ]
    .into_iter()
    .filter_map(Result::ok)
    .map(|(saved, a)| (a, saved))
    .collect();
    if loaded.len() > 1 {
        return Err("the bytes load as two layouts".into());
    }
    let Some((accel, saved)) = loaded.into_iter().next() else {
        return Ok(());
    };
    if saved != bytes {
        return Err("a loaded structure saves to other bytes".into());
    }
    let mut rng = rt_testkit::Rng::new(3);
    for _ in 0..200 {
        let o = rng.point_in(Vec3::splat(-2.0), Vec3::splat(2.0));
        let ray = Ray::new(o, rng.point_in(Vec3::splat(-0.5), Vec3::splat(0.5)) - o);
        let (want, got) = (brute.intersect(&ray), accel.intersect(&ray));
        if want != got || brute.occluded(&ray) != accel.occluded(&ray) {
            return Err(format!(
                "loaded structure answers {got:?}, brute force {want:?} ({ray:?})"
            ));
        }
    }
    Ok(())
}

/// Arbitrary bytes as a scene of up to 48 triangles (or triangles, spheres and cones) and rays
/// ([`Decoder`]): every rt structure in the registry (not the external peers) builds it or
/// rejects it as brute force does, passes `validate()`, and answers every ray exactly as brute
/// force does; packet paths answer as their single rays. The first byte's bits 1-2 move the
/// scene and its rays by 3e5, 5e6 or 1e7 (each coordinate rounded to `f32` once) for a second
/// check far from the origin.
pub fn build_trace(bytes: &[u8]) -> Result<(), String> {
    let mut d = Decoder::new(bytes);
    let first = d.byte();
    let mixed = first & 1 == 1;
    // Bits 1-2: the scene is also checked moved far from the origin (as GIS and CAD scenes
    // come), every coordinate rounded to `f32` once.
    let offset = [0.0, 3.0e5, 5.0e6, 1.0e7][((first >> 1) & 3) as usize];
    let count = d.byte() as usize % 49;
    let shapes: Vec<Shape> = (0..count)
        .map(|_| match (mixed, d.byte() % 3) {
            (true, 1) => Sphere::new(d.vec3(), d.value()).into(),
            (true, 2) => Cone::new(d.vec3(), d.value(), d.vec3(), d.value()).into(),
            _ => Triangle::new(d.vec3(), d.vec3(), d.vec3()).into(),
        })
        .collect();
    let mut extra = Vec::new();
    while !d.is_empty() {
        let (o, dir) = (d.vec3(), d.vec3());
        let ray = match d.byte() % 4 {
            0 => Ray::new(o, dir),
            1 => Ray::segment(o, dir, d.value(), d.value()),
            2 => Ray::segment(o, dir, 0.0, d.value()),
            _ => Ray::segment(o, dir, d.value(), f32::INFINITY),
        };
        extra.push(TestRay {
            ray,
            kind: RayKind::Random,
        });
    }
    check_scene(&shapes, &extra)?;
    if offset != 0.0 {
        let by = rt_geom::glam::DVec3::new(offset, -offset, offset);
        let moved: Vec<Shape> = shapes.iter().map(|s| moved_shape(s, by)).collect();
        let extra: Vec<TestRay> = extra
            .iter()
            .map(|t| TestRay {
                ray: Ray::segment(
                    (t.ray.origin().as_dvec3() + by).as_vec3(),
                    t.ray.dir(),
                    t.ray.tmin,
                    t.ray.tmax,
                ),
                kind: t.kind,
            })
            .collect();
        check_scene(&moved, &extra).map_err(|e| format!("moved by {by}: {e}"))?;
    }
    Ok(())
}

/// `s` moved by `by`, every coordinate rounded to `f32` once.
fn moved_shape(s: &Shape, by: rt_geom::glam::DVec3) -> Shape {
    let at = |p: Vec3| (p.as_dvec3() + by).as_vec3();
    match s {
        Shape::Triangle(t) => Triangle { v: t.v.map(at) }.into(),
        Shape::Sphere(sp) => Sphere::new(at(sp.center), sp.radius).into(),
        Shape::Cone(c) => Cone::new(at(c.base), c.base_radius, at(c.apex), c.apex_radius).into(),
    }
}

/// Every rt structure on `shapes` with its conformance rays and `extra`.
fn check_scene(shapes: &[Shape], extra: &[TestRay]) -> Result<(), String> {
    let entries = REGISTRY.iter().filter(|e| !e.external);
    match shapes
        .iter()
        .map(|s| s.as_triangle().copied())
        .collect::<Option<Vec<Triangle>>>()
    {
        Some(tris) => {
            let mut rays = scene_rays(&tris, 4);
            rays.extend_from_slice(extra);
            let rays = exact_domain(&tris, &rays);
            for e in entries {
                check_entry(e, &tris, &rays)?;
            }
        }
        None => {
            let mut rays = scene_rays(shapes, 4);
            rays.extend_from_slice(extra);
            let rays = exact_domain(shapes, &rays);
            for e in entries.filter(|e| e.build_shapes.is_some()) {
                check_shapes(e, shapes, &rays)?;
            }
        }
    }
    Ok(())
}

/// Rays for a small scene: the conformance families (`per_kind` each), or none when brute
/// force rejects the scene.
fn scene_rays<P: SamplePoints>(prims: &[P], per_kind: usize) -> Vec<TestRay> {
    match BruteForce::build(prims) {
        Ok(brute) => conformance_rays(prims, &brute, per_kind, 0xf022 ^ prims.len() as u64),
        Err(_) => Vec::new(),
    }
}

/// The rays whose answers rt promises exactly (ARCHITECTURE.md, robustness): not those with
/// a subnormal origin or direction component, or whose closest hit lies at a subnormal
/// distance (`0 < |t| < f32::MIN_POSITIVE`) or at a subnormal offset along an axis
/// (`0 < |t * d| < f32::MIN_POSITIVE`), where the box and cell tests' relative padding
/// rounds away, nor those whose hit (or the primitive hit) lies farther from the ray's
/// origin, or in a scene wider, than [`FAR_HIT`] times the narrowest extent of the primitive
/// hit: there points computed in `f32` along the ray (a grid's or octree's entry point in its
/// frame, a box test's or an edge test's rounding) are off by more than that primitive.
/// Where the scene lies does not matter.
fn exact_domain<P: rt_geom::Primitive>(prims: &[P], rays: &[TestRay]) -> Vec<TestRay> {
    let Ok(brute) = BruteForce::build(prims) else {
        return rays.to_vec();
    };
    let extent = scene_extent(prims);
    rays.iter()
        .filter(|r| in_exact_domain(prims, extent, &r.ray, brute.intersect(&r.ray)))
        .copied()
        .collect()
}

/// The largest extent of the scene's box: how far apart two of its points can lie.
fn scene_extent<P: rt_geom::Primitive>(prims: &[P]) -> f64 {
    let b = rt_geom::Aabb::around(prims);
    if b.is_empty() {
        0.0
    } else {
        (b.max.as_dvec3() - b.min.as_dvec3()).max_element()
    }
}

/// Whether `ray`, whose closest hit in `prims` (a scene `extent` wide) is `hit` (brute
/// force's), lies in the exactness domain (see [`exact_domain`]).
fn in_exact_domain<P: rt_geom::Primitive>(
    prims: &[P],
    extent: f64,
    ray: &Ray,
    hit: Option<Hit>,
) -> bool {
    let subnormal = |v: Vec3| v.to_array().iter().any(|x| x.is_subnormal());
    if subnormal(ray.origin()) || subnormal(ray.dir()) {
        return false;
    }
    match hit {
        None => true,
        Some(h) => {
            let e = prims[h.prim as usize].bounds().extent().to_array();
            let narrowest = e
                .into_iter()
                .filter(|&x| x > 0.0)
                .fold(f32::INFINITY, f32::min);
            let (o, d) = (ray.origin().as_dvec3(), ray.dir().as_dvec3());
            let b = prims[h.prim as usize].bounds();
            // How far the hit lies from the ray's origin (and the origin from the primitive:
            // the kernel's own rounding can put a hit next to an origin far from it), and how
            // wide the scene is: the cell walks compute in their own frame (`rt_geom::Frame`),
            // so where the scene lies does not matter, only its size.
            let gap = (o - o.clamp(b.min.as_dvec3(), b.max.as_dvec3()))
                .abs()
                .max_element();
            let reach = (d * h.t as f64).length().max(gap).max(extent);
            // The hit's offset from the origin along each axis the ray moves on is a normal
            // `f32`: where `t * d` underflows, the kernel sees the ray on a vertex or edge
            // that the exact box test finds the ray already past.
            let offsets_normal = (0..3)
                .all(|a| d[a] == 0.0 || (d[a] * h.t as f64).abs() >= f32::MIN_POSITIVE as f64);
            // A hit at `t = 0` (a ray starting on a surface) has no offset; it is exact only
            // where its origin lies near the primitive (`reach`), as any other hit.
            let t_normal = h.t == 0.0 || (h.t.abs() >= f32::MIN_POSITIVE && offsets_normal);
            t_normal && reach <= FAR_HIT * narrowest as f64
        }
    }
}

/// How far from a ray's origin, and in how wide a scene, in narrowest extents of the
/// primitive hit, a hit is exact: 2^20, a sixteenth of where the first structure (the uniform
/// grid's `f32` cell walk) was seen to miss a hit (2^24 from the ray's origin).
pub const FAR_HIT: f64 = (1u64 << 20) as f64;

/// One entry on a triangle scene: the single-ray structure and its packet path.
fn check_entry(entry: &AccelEntry, tris: &[Triangle], rays: &[TestRay]) -> Result<(), String> {
    let built = (entry.build)(tris).map_err(|e| e.to_string());
    if entry.kernel == rt_geom::TriangleKernel::MollerTrumbore {
        // Against brute force with the entry's kernel.
        let mt: Vec<_> = tris
            .iter()
            .copied()
            .map(rt_testkit::conformance::MollerTrumbore)
            .collect();
        agrees(entry.name, &mt, built, rays)?;
    } else {
        agrees(entry.name, tris, built, rays)?;
    }
    if entry.packets.is_some() && BruteForce::build(tris).is_ok() {
        let report = packet_report("fuzz", tris, rays, entry)
            .map_err(|e| format!("{} packets: {e}", entry.name))?;
        mismatches(&format!("{} packets", entry.name), &report)?;
    }
    Ok(())
}

/// One entry that takes any shape, on a scene of mixed shapes.
fn check_shapes(entry: &AccelEntry, shapes: &[Shape], rays: &[TestRay]) -> Result<(), String> {
    let build = entry.build_shapes.ok_or("no shape builder")?;
    agrees(
        entry.name,
        shapes,
        build(shapes).map_err(|e| e.to_string()),
        rays,
    )
}

/// A build result against brute force's: both rejected, or both built and agreeing on every
/// ray, the structure valid and its stats consistent.
fn agrees<P: rt_geom::Primitive>(
    name: &str,
    prims: &[P],
    built: Result<Box<dyn Accel>, String>,
    rays: &[TestRay],
) -> Result<(), String> {
    let reference = BruteForce::build(prims);
    let accel = match (reference.is_ok(), built) {
        (false, Err(_)) => return Ok(()),
        (false, Ok(_)) => return Err(format!("{name} built a scene brute force rejects")),
        (true, Err(e)) => return Err(format!("{name} rejected a valid scene: {e}")),
        (true, Ok(a)) => a,
    };
    let reference = reference.map_err(|e| e.to_string())?;
    accel
        .validate()
        .map_err(|e| format!("{name}: validate() failed: {e}"))?;
    let stats = accel.stats();
    stats
        .check_consistency()
        .map_err(|e| format!("{name}: stats() inconsistent: {e}"))?;
    if stats.primitives != prims.len() {
        return Err(format!(
            "{name}: stats().primitives = {} for {} primitives",
            stats.primitives,
            prims.len()
        ));
    }
    let expected: Vec<Option<Hit>> = rays.iter().map(|r| reference.intersect(&r.ray)).collect();
    if let Some((r, h)) = rays.iter().zip(&expected).find_map(|(r, h)| {
        h.filter(|h| !(h.u.is_finite() && h.v.is_finite()))
            .map(|h| (r, h))
    }) {
        return Err(format!("non-finite barycentrics {h:?} for {:?}", r.ray));
    }
    let report = compare_with_expected("fuzz", prims, rays, &expected, &accel, Tolerance::EXACT);
    mismatches(name, &report)
}

fn mismatches(name: &str, report: &Report) -> Result<(), String> {
    match report.mismatches.first() {
        None => Ok(()),
        Some(m) => Err(format!(
            "{name}: {} of {} rays disagree with brute force, first: {m}",
            report.mismatch_count, report.rays
        )),
    }
}

/// A parsed scene shades the same with a BVH as with brute force, bit for bit, pixel by
/// pixel (4x4 eye rays at depth 3, through every secondary ray they spawn), on scenes of up to
/// [`TRACE_MAX_PRIMS`] shapes. A pixel any of whose rays leaves the exactness domain
/// ([`exact_domain`]: judged from brute force's hit of each ray) is left out; every other
/// pixel is compared.
fn render_agrees(scene: &Scene) -> Result<(), String> {
    if scene.shapes.len() > TRACE_MAX_PRIMS {
        return Ok(());
    }
    let brute = BruteForce::build(&scene.shapes);
    let bvh = rt_accel_bvh::Bvh::build(&scene.shapes, rt_accel_bvh::BvhParams::balanced());
    let (brute, bvh) = match (brute, bvh) {
        (Ok(a), Ok(b)) => (a, b),
        (Err(_), Err(_)) => return Ok(()),
        (a, b) => {
            return Err(format!(
                "brute force and BVH disagree on building the scene: {:?} / {:?}",
                a.err(),
                b.err()
            ));
        }
    };
    if scene.check().is_err() {
        return Ok(());
    }
    let shade = ShadeOptions {
        max_depth: 3,
        ..ShadeOptions::default()
    };
    let (w, h) = (4, 4);
    let frame = scene.camera.frame(w, h);
    for y in 0..h {
        for x in 0..w {
            let eye = frame.ray(x as f32 + 0.5, y as f32 + 0.5, (0.5, 0.5));
            let colour = |accel: &dyn Accel| {
                let watched = DomainWatch::new(accel, &brute, &scene.shapes);
                let whitted = rt_shade::Whitted::new(scene, &watched, shade);
                let c = whitted.eye(&eye, &mut rt_shade::RayStats::default());
                (c, watched.left_domain())
            };
            let ((want, out_a), (got, out_b)) = (colour(&brute), colour(&bvh));
            if !out_a
                && !out_b
                && want.to_array().map(f32::to_bits) != got.to_array().map(f32::to_bits)
            {
                return Err(format!(
                    "pixel ({x}, {y}): the BVH shades {got:?}, brute force {want:?} (eye ray {eye:?})"
                ));
            }
        }
    }
    Ok(())
}

/// A structure whose queries note whether any ray asked lies outside the exactness domain.
struct DomainWatch<'a> {
    accel: &'a dyn Accel,
    brute: &'a BruteForce<Shape>,
    shapes: &'a [Shape],
    extent: f64,
    outside: std::sync::atomic::AtomicBool,
}

impl<'a> DomainWatch<'a> {
    fn new(accel: &'a dyn Accel, brute: &'a BruteForce<Shape>, shapes: &'a [Shape]) -> Self {
        Self {
            accel,
            brute,
            shapes,
            extent: scene_extent(shapes),
            outside: false.into(),
        }
    }

    fn watch(&self, ray: &Ray) {
        if !in_exact_domain(self.shapes, self.extent, ray, self.brute.intersect(ray)) {
            self.outside
                .store(true, std::sync::atomic::Ordering::Relaxed);
        }
    }

    /// Whether a ray asked so far left the domain.
    fn left_domain(&self) -> bool {
        self.outside.load(std::sync::atomic::Ordering::Relaxed)
    }
}

impl Accel for DomainWatch<'_> {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.watch(ray);
        self.accel.intersect(ray)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        self.watch(ray);
        self.accel.occluded(ray)
    }

    fn stats(&self) -> rt_geom::AccelStats {
        self.accel.stats()
    }

    fn validate(&self) -> Result<(), String> {
        self.accel.validate()
    }
}

/// Reads a fuzzer's bytes as values that make hard scenes likely: most bytes are points of a
/// coarse lattice (coincident vertices, axis-aligned and degenerate triangles, rays through
/// vertices and edges), some are special values (signed zeros, subnormals, near the largest
/// and smallest normal floats, NaN, infinities), some start a raw `f32`. Past the end, zeros.
pub struct Decoder<'a> {
    bytes: &'a [u8],
}

/// The special values of [`Decoder::value`]: signed zeros, near the smallest and largest
/// floats, a subnormal, NaN and infinities.
pub const SPECIAL: [f32; 16] = [
    0.0,
    -0.0,
    1e-38,
    -1e-38,
    1e-45,
    1e38,
    -1e38,
    f32::MAX,
    1e-7,
    1e7,
    0.1,
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    1e-20,
    1e20,
];

impl<'a> Decoder<'a> {
    /// A decoder over `bytes`.
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes }
    }

    /// Whether every byte is read.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// The next byte (0 past the end).
    pub fn byte(&mut self) -> u8 {
        match self.bytes.split_first() {
            Some((&b, rest)) => {
                self.bytes = rest;
                b
            }
            None => 0,
        }
    }

    /// The next value: bytes 0-223 a lattice point in quarters from -28 to 27.75, 224-239 a
    /// [`SPECIAL`] value, 240-255 the raw `f32` of the next four bytes.
    pub fn value(&mut self) -> f32 {
        match self.byte() {
            b @ 0..=223 => (b as i32 - 112) as f32 * 0.25,
            b @ 224..=239 => SPECIAL[(b - 224) as usize],
            _ => f32::from_le_bytes([self.byte(), self.byte(), self.byte(), self.byte()]),
        }
    }

    /// Three values.
    pub fn vec3(&mut self) -> Vec3 {
        Vec3::new(self.value(), self.value(), self.value())
    }
}
