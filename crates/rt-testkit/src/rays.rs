//! Seeded rays: the adversarial sets of the conformance suite, and the standard camera, shadow
//! and diffuse sets that `verify` and `bench` trace through the shared meshes.

use crate::Rng;
use rt_geom::{Aabb, Accel, Cone, Hit, Primitive, Ray, Shape, Sphere, Triangle, Vec3};

/// Points on a primitive that rays are aimed at.
pub trait SamplePoints: Primitive {
    /// A point on the primitive from two uniform numbers.
    fn sample(&self, u: f32, v: f32) -> Vec3;
    /// Points where rays graze: vertices and points on edges (silhouette points for spheres).
    fn feature_point(&self, rng: &mut Rng) -> Vec3;
}

impl SamplePoints for Triangle {
    fn sample(&self, u: f32, v: f32) -> Vec3 {
        let (u, v) = if u + v > 1.0 {
            (1.0 - u, 1.0 - v)
        } else {
            (u, v)
        };
        self.point(u, v)
    }

    fn feature_point(&self, rng: &mut Rng) -> Vec3 {
        let i = rng.below(3);
        if rng.chance(0.5) {
            self.v[i]
        } else {
            let s = rng.f32();
            self.v[i] * (1.0 - s) + self.v[(i + 1) % 3] * s
        }
    }
}

impl SamplePoints for Sphere {
    fn sample(&self, u: f32, v: f32) -> Vec3 {
        let z = 2.0 * u - 1.0;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = std::f32::consts::TAU * v;
        self.center + self.radius.max(0.0) * Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    fn feature_point(&self, rng: &mut Rng) -> Vec3 {
        self.sample(rng.f32(), rng.f32())
    }
}

impl SamplePoints for Cone {
    fn sample(&self, u: f32, v: f32) -> Vec3 {
        let axis = self.apex - self.base;
        let (e1, e2) = axis.normalize_or(Vec3::Z).any_orthonormal_pair();
        let r = self.base_radius + (self.apex_radius - self.base_radius) * v;
        let phi = std::f32::consts::TAU * u;
        self.base + axis * v + r.max(0.0) * (e1 * phi.cos() + e2 * phi.sin())
    }

    /// Points on the rims, where rays graze the open ends.
    fn feature_point(&self, rng: &mut Rng) -> Vec3 {
        let rim = if rng.chance(0.5) { 0.0 } else { 1.0 };
        self.sample(rng.f32(), rim)
    }
}

impl SamplePoints for Shape {
    fn sample(&self, u: f32, v: f32) -> Vec3 {
        match self {
            Shape::Triangle(t) => t.sample(u, v),
            Shape::Sphere(s) => s.sample(u, v),
            Shape::Cone(c) => c.sample(u, v),
        }
    }

    fn feature_point(&self, rng: &mut Rng) -> Vec3 {
        match self {
            Shape::Triangle(t) => t.feature_point(rng),
            Shape::Sphere(s) => s.feature_point(rng),
            Shape::Cone(c) => c.feature_point(rng),
        }
    }
}

/// A family of conformance rays, so that a failure says what kind of ray failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RayKind {
    /// Random origin around the scene, random direction.
    Random,
    /// Origin inside the scene's box.
    Inside,
    /// Aimed at a random point of a random primitive.
    Aimed,
    /// Aimed exactly at vertices and edges.
    Grazing,
    /// Direction along an axis (two zero components), origin on vertex coordinates, so rays run
    /// in the planes of axis-aligned faces and edges.
    AxisParallel,
    /// One zero direction component.
    PlaneParallel,
    /// `tmin`/`tmax` placed on, just before and just after the closest hit; intervals ending
    /// in signed zeros from vertex and edge points.
    Limited,
    /// Origin inside the scene's box, the interval starting far behind it (`tmin < 0`): the
    /// ray crosses behind its origin the planes and cells it heads away from.
    Behind,
    /// The shortest valid directions (largest component [`rt_geom::MIN_DIRECTION`]) from
    /// origins as far from the world's origin as a valid origin lies: the slab tests'
    /// offsets (origin over direction) overflow on every axis.
    Faint,
    /// Zero, NaN or infinite directions and origins, NaN intervals: must miss.
    Invalid,
    /// Primary rays of the standard camera (mesh verification).
    Camera,
    /// Shadow rays toward the standard light.
    Shadow,
    /// Diffuse bounces from camera hits.
    Diffuse,
}

/// A conformance ray with its family.
#[derive(Clone, Copy, Debug)]
pub struct TestRay {
    pub ray: Ray,
    pub kind: RayKind,
}

/// The conformance rays for a scene: `per_kind` of each family (fewer for `Invalid`).
/// `reference` supplies closest hits for the `Limited` family.
pub fn conformance_rays<P: SamplePoints>(
    prims: &[P],
    reference: &dyn Accel,
    per_kind: usize,
    seed: u64,
) -> Vec<TestRay> {
    let mut rng = Rng::new(seed);
    let bounds = Aabb::around(prims);
    let (lo, hi) = if bounds.is_empty() {
        (Vec3::splat(-1.0), Vec3::splat(1.0))
    } else {
        let pad = bounds
            .extent()
            .max_element()
            .max(bounds.min.abs().max_element() * 1e-6);
        (bounds.min - pad * 0.5, bounds.max + pad * 0.5)
    };
    let mut out = Vec::new();
    let mut push = |ray: Ray, kind| out.push(TestRay { ray, kind });
    let target = |rng: &mut Rng, feature: bool| {
        if prims.is_empty() {
            return rng.point_in(lo, hi);
        }
        let p = &prims[rng.below(prims.len())];
        if feature {
            p.feature_point(rng)
        } else {
            p.sample(rng.f32(), rng.f32())
        }
    };
    for _ in 0..per_kind {
        push(
            Ray::new(rng.point_in(lo, hi), rng.unit_vector()),
            RayKind::Random,
        );
        if !bounds.is_empty() {
            let o = rng.point_in(bounds.min, bounds.max);
            push(Ray::new(o, rng.unit_vector()), RayKind::Inside);
            let o = rng.point_in(bounds.min, bounds.max);
            let t = target(&mut rng, false);
            let back = -2.0 * (hi - lo).length() / (t - o).length().max(1e-30);
            let far = if rng.chance(0.5) { f32::INFINITY } else { 0.5 };
            push(Ray::segment(o, t - o, back, far), RayKind::Behind);
        }
        let o = rng.point_in(lo, hi);
        let t = target(&mut rng, false);
        push(Ray::new(o, t - o), RayKind::Aimed);
        let o = rng.point_in(lo, hi);
        let t = target(&mut rng, true);
        push(Ray::new(o, t - o), RayKind::Grazing);

        // Axis-parallel: origin copies the coordinates of a feature point except along the axis.
        let axis = rng.below(3);
        let f = target(&mut rng, true);
        let mut o = f;
        o[axis] = if rng.chance(0.5) { lo[axis] } else { hi[axis] };
        let mut d = Vec3::ZERO;
        d[axis] = if o[axis] <= f[axis] { 1.0 } else { -1.0 };
        if rng.chance(0.1) {
            d[axis] *= 1e-3; // short direction vectors: t is not a distance
        }
        push(Ray::new(o, d), RayKind::AxisParallel);

        let feature = rng.chance(0.5);
        let f = target(&mut rng, feature);
        let o = rng.point_in(lo, hi);
        let mut d = f - o;
        let zero = rng.below(3);
        d[zero] = if rng.chance(0.5) { 0.0 } else { -0.0 };
        let mut o2 = o;
        o2[zero] = f[zero];
        push(Ray::new(o2, d), RayKind::PlaneParallel);
    }
    // Limited: around the closest hit of aimed rays.
    let mut limited = 0;
    let mut tries = 0;
    while limited < per_kind && tries < 4 * per_kind && !prims.is_empty() {
        tries += 1;
        let o = rng.point_in(lo, hi);
        let t = target(&mut rng, false);
        let ray = Ray::new(o, t - o);
        let Some(hit) = reference.intersect(&ray) else {
            continue;
        };
        let t = hit.t;
        for (a, b) in [
            (0.0, t),
            (0.0, t.next_down()),
            (t, f32::INFINITY),
            (t.next_up(), f32::INFINITY),
            (t, t),
            (t * 0.5, t * 0.75),
            (-1.0, f32::INFINITY),
        ] {
            push(ray.with_range(a, b), RayKind::Limited);
        }
        // Signed zeros at the ends of the interval, from a vertex or edge point (hits at 0).
        let from = Ray::new(target(&mut rng, true), ray.dir());
        for (a, b) in [(-0.0, -0.0), (0.0, -0.0), (-0.0, f32::INFINITY)] {
            push(from.with_range(a, b), RayKind::Limited);
        }
        limited += 10;
    }
    let far = rt_geom::MAX_COORDINATE / 2.0;
    for corner in [
        Vec3::splat(far),
        Vec3::new(far, -far, far),
        Vec3::splat(-far),
    ] {
        let to_scene = (lo + hi) * 0.5 - corner;
        let d = to_scene / to_scene.abs().max_element() * rt_geom::MIN_DIRECTION;
        for d in [d, -d, Vec3::new(d.x, -d.y, 0.0)] {
            push(Ray::new(corner, d), RayKind::Faint);
        }
    }
    let o = rng.point_in(lo, hi);
    let inf = f32::INFINITY;
    for (o, d, tmin, tmax) in [
        (o, Vec3::ZERO, 0.0, inf),
        (o, Vec3::new(f32::NAN, 1.0, 0.0), 0.0, inf),
        (o, Vec3::new(inf, 1.0, 0.0), 0.0, inf),
        (Vec3::new(f32::NAN, 0.5, 0.5), Vec3::X, 0.0, inf),
        (Vec3::new(-inf, 0.5, 0.5), Vec3::X, 0.0, inf),
        (o, Vec3::X, f32::NAN, inf),
        (o, Vec3::X, 0.0, f32::NAN),
        (o, Vec3::X, 5.0, 1.0),
    ] {
        push(Ray::segment(o, d, tmin, tmax), RayKind::Invalid);
    }
    out
}

/// `n` rays from points around the unit cube (`-0.5..1.5` on each axis) towards points in it:
/// most cross the random soups of [`crate::scenes`], some start inside them (the saved
/// structures' round-trip tests).
pub fn rays_through_unit_cube(n: usize) -> Vec<Ray> {
    let mut rng = Rng::new(17);
    (0..n)
        .map(|_| {
            let o = rng.point_in(Vec3::splat(-0.5), Vec3::splat(1.5));
            Ray::new(o, rng.point_in(Vec3::ZERO, Vec3::ONE) - o)
        })
        .collect()
}

/// A pinhole camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    /// Vertical field of view, degrees.
    pub fov_y: f32,
}

impl View {
    /// Looks at the box from the front (+z), a little from above, from twice the radius of its
    /// bounding sphere: the object fills most of the frame, as in the usual benchmark views.
    pub fn front(bounds: &Aabb) -> Self {
        let c = bounds.center();
        let radius = 0.5 * bounds.extent().length().max(f32::MIN_POSITIVE);
        let fov_y: f32 = 45.0;
        let dist = 2.0 * radius;
        let dir = Vec3::new(0.25, 0.3, 1.0).normalize();
        Self {
            eye: c + dir * dist,
            target: c,
            up: Vec3::Y,
            fov_y,
        }
    }

    /// Standing inside the box, looking along its longest horizontal axis (interiors).
    pub fn interior(bounds: &Aabb) -> Self {
        let c = bounds.center();
        let e = bounds.extent();
        let along = if e.x >= e.z { Vec3::X } else { Vec3::Z };
        let eye = c - along * (0.4 * e.dot(along)) - Vec3::Y * (0.25 * e.y);
        Self {
            eye,
            target: eye + along + Vec3::Y * 0.15,
            up: Vec3::Y,
            fov_y: 65.0,
        }
    }

    /// The standard view of a named scene: interiors (sponza) from inside, objects from outside.
    pub fn standard(scene: &str, bounds: &Aabb) -> Self {
        if scene.contains("sponza") {
            Self::interior(bounds)
        } else {
            Self::front(bounds)
        }
    }

    /// Primary rays through pixel centres, row-major from the top-left.
    pub fn camera_rays(&self, width: usize, height: usize) -> Vec<Ray> {
        let forward = (self.target - self.eye).normalize();
        let right = forward.cross(self.up).normalize();
        let up = right.cross(forward);
        let h = (self.fov_y.to_radians() * 0.5).tan();
        let w = h * width as f32 / height as f32;
        let mut rays = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                let sx = (2.0 * (x as f32 + 0.5) / width as f32 - 1.0) * w;
                let sy = (1.0 - 2.0 * (y as f32 + 0.5) / height as f32) * h;
                rays.push(Ray::new(self.eye, forward + right * sx + up * sy));
            }
        }
        rays
    }
}

/// The three standard ray sets of a mesh: primary, shadow toward a point light, diffuse bounce.
#[derive(Clone, Debug, Default)]
pub struct RaySets {
    pub primary: Vec<Ray>,
    pub shadow: Vec<Ray>,
    pub diffuse: Vec<Ray>,
    /// The primary ray (pixel) each shadow and diffuse ray starts from: `shadow[k]` and
    /// `diffuse[k]` leave the hit of `primary[from_pixel[k]]`.
    pub from_pixel: Vec<usize>,
}

impl RaySets {
    /// Primary rays of the standard view at `width x height`; shadow and diffuse rays from their
    /// hits (found with `reference`), one each per hit.
    pub fn generate(
        scene: &str,
        tris: &[Triangle],
        reference: &dyn Accel,
        width: usize,
        height: usize,
        seed: u64,
    ) -> Self {
        let bounds = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(t.bounds()));
        let view = View::standard(scene, &bounds);
        let primary = view.camera_rays(width, height);
        let light = light_position(scene, &bounds);
        let eps = bounds.extent().max_element() * 1e-5;
        let mut rng = Rng::new(seed);
        let mut shadow = Vec::new();
        let mut diffuse = Vec::new();
        let mut from_pixel = Vec::new();
        for (pixel, ray) in primary.iter().enumerate() {
            let Some(hit) = reference.intersect(ray) else {
                continue;
            };
            from_pixel.push(pixel);
            let (p, n) = surface(ray, &hit, tris);
            shadow.push(Ray::segment(p, light - p, 1e-4, 1.0));
            let d = rng.cosine_hemisphere(n);
            diffuse.push(Ray::segment(p, d, eps, f32::INFINITY));
        }
        Self {
            primary,
            shadow,
            diffuse,
            from_pixel,
        }
    }

    pub fn by_name(&self, name: &str) -> Option<&[Ray]> {
        match name {
            "primary" => Some(&self.primary),
            "shadow" => Some(&self.shadow),
            "diffuse" => Some(&self.diffuse),
            _ => None,
        }
    }

    pub const NAMES: [&'static str; 3] = ["primary", "shadow", "diffuse"];

    /// Single-thread speed of each structure on each set (shadow rays as occlusion queries):
    /// `rates[set][structure]` in Mrays/s, the median of `reps` runs in which the structures
    /// take turns, so that a change of machine speed touches all alike. What the examples
    /// that compare parameters (`kd_costs`, `grid_params`, `oct_stats`) print.
    pub fn race(&self, accels: &[&dyn Accel], reps: usize) -> [Vec<f64>; 3] {
        let reps = reps.max(1);
        Self::NAMES.map(|name| {
            let rays = self.by_name(name).unwrap_or_default();
            let mut times = vec![Vec::with_capacity(reps); accels.len()];
            for _ in 0..reps {
                for (accel, times) in accels.iter().zip(&mut times) {
                    let start = std::time::Instant::now();
                    let n = if name == "shadow" {
                        rays.iter().filter(|r| accel.occluded(r)).count()
                    } else {
                        rays.iter().filter(|r| accel.intersect(r).is_some()).count()
                    };
                    std::hint::black_box(n);
                    times.push(start.elapsed().as_secs_f64());
                }
            }
            times
                .into_iter()
                .map(|mut t| {
                    t.sort_by(f64::total_cmp);
                    rays.len() as f64 / t[reps / 2] / 1e6
                })
                .collect()
        })
    }

    /// [`RaySets::race`], printed: one line per set and structure, `labels` naming them.
    pub fn print_race(&self, accels: &[&dyn Accel], labels: &[String], reps: usize) {
        let rates = self.race(accels, reps);
        for (name, rates) in Self::NAMES.iter().zip(&rates) {
            for (label, rate) in labels.iter().zip(rates) {
                println!("{label:<24} {name:<8} {rate:7.2} Mrays/s");
            }
        }
    }

    /// The `main` of the examples that compare build parameters (`kd_costs`, `grid_params`):
    /// arguments `MESH CONFIG... [SIDE]`, MESH as [`crate::scenes::mesh_or_sphere`] reads it,
    /// each CONFIG as `parse` reads it (the others are skipped), SIDE the camera resolution
    /// (default 512). Builds every configuration, printing its build time and `stats()`, then
    /// races them on the mesh's standard rays ([`RaySets::print_race`], 5 runs each).
    pub fn race_configs<C, A: Accel>(
        usage: &str,
        parse: impl Fn(&str) -> Option<C>,
        build: impl Fn(&[Triangle], &C) -> Result<A, rt_geom::BuildError>,
    ) {
        let args: Vec<String> = std::env::args().skip(1).collect();
        let fail = |message: &str, code| -> ! {
            eprintln!("{message}");
            std::process::exit(code)
        };
        let Some(path) = args.first() else {
            fail(usage, 2)
        };
        let side = args
            .last()
            .and_then(|s| s.parse::<usize>().ok())
            .unwrap_or(512);
        let configs: Vec<(&String, C)> = args[1..]
            .iter()
            .filter_map(|s| Some((s, parse(s)?)))
            .collect();
        if configs.is_empty() {
            fail(usage, 2);
        }
        let tris = crate::scenes::mesh_or_sphere(path).unwrap_or_else(|e| fail(&e, 1));
        let mut built = Vec::new();
        for (label, config) in &configs {
            let start = std::time::Instant::now();
            match build(&tris, config) {
                Ok(accel) => {
                    let ms = start.elapsed().as_secs_f64() * 1e3;
                    println!("{label}: {ms:7.1} ms  {}", accel.stats());
                    built.push(accel);
                }
                Err(e) => fail(&format!("{label}: {e}"), 1),
            }
        }
        let scene = std::path::Path::new(path)
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("");
        let sets = RaySets::generate(scene, &tris, &built[0], side, side, 7);
        let accels: Vec<&dyn Accel> = built.iter().map(|a| a as &dyn Accel).collect();
        let labels: Vec<String> = configs.iter().map(|(l, _)| l.to_string()).collect();
        sets.print_race(&accels, &labels, 5);
    }

    /// Groups of pixel indices (image tiles, say) as groups of the shadow (or diffuse) rays
    /// leaving those pixels; pixels whose primary ray missed have none, empty groups are left
    /// out.
    pub fn secondary_groups(&self, pixel_groups: &[Vec<usize>]) -> Vec<Vec<usize>> {
        let mut of_pixel = vec![usize::MAX; self.primary.len()];
        for (k, &p) in self.from_pixel.iter().enumerate() {
            of_pixel[p] = k;
        }
        pixel_groups
            .iter()
            .map(|g| {
                g.iter()
                    .map(|&p| of_pixel[p])
                    .filter(|&k| k != usize::MAX)
                    .collect::<Vec<_>>()
            })
            .filter(|g| !g.is_empty())
            .collect()
    }

    /// All rays, tagged with their set, for the conformance comparison.
    pub fn tagged(&self) -> Vec<TestRay> {
        let mut out = Vec::new();
        for (rays, kind) in [
            (&self.primary, RayKind::Camera),
            (&self.shadow, RayKind::Shadow),
            (&self.diffuse, RayKind::Diffuse),
        ] {
            out.extend(rays.iter().map(|&ray| TestRay { ray, kind }));
        }
        out
    }
}

/// Hit point and the geometric normal facing the ray.
fn surface(ray: &Ray, hit: &Hit, tris: &[Triangle]) -> (Vec3, Vec3) {
    let tri = &tris[hit.prim as usize];
    let p = tri.point(hit.u, hit.v);
    let mut n = tri.normal();
    if n.dot(ray.dir()) > 0.0 {
        n = -n;
    }
    (p, n)
}

/// Where the standard point light of a scene is.
pub fn light_position(scene: &str, bounds: &Aabb) -> Vec3 {
    let c = bounds.center();
    let e = bounds.extent();
    if scene.contains("sponza") {
        c + Vec3::new(0.1 * e.x, 0.35 * e.y, 0.0)
    } else {
        c + Vec3::new(-0.6, 1.2, 0.9) * e.length()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn secondary_rays_group_by_the_pixels_they_leave() {
        let tris = crate::scenes::tessellated_sphere(2000, Vec3::ZERO, 1.0);
        let reference = rt_geom::BruteForce::build(&tris).unwrap();
        let sets = RaySets::generate("sphere", &tris, &reference, 16, 16, 1);
        assert_eq!(sets.from_pixel.len(), sets.shadow.len());
        assert_eq!(sets.from_pixel.len(), sets.diffuse.len());
        // Each shadow ray leaves the hit of its pixel's primary ray.
        for (k, &pixel) in sets.from_pixel.iter().enumerate() {
            let hit = reference
                .intersect(&sets.primary[pixel])
                .expect("a hit pixel");
            let p = sets.primary[pixel].at(hit.t);
            assert!((sets.shadow[k].origin() - p).length() < 1e-3, "ray {k}");
        }
        // Tiles of pixels become groups of the shadow rays of their hit pixels, in order; tiles
        // that miss everything give no group.
        let tiles: Vec<Vec<usize>> = (0..4)
            .map(|t| (t * 64..(t + 1) * 64).collect())
            .chain([vec![0]])
            .collect();
        let groups = sets.secondary_groups(&tiles);
        let all: Vec<usize> = groups.concat();
        assert_eq!(all, (0..sets.shadow.len()).collect::<Vec<_>>());
        assert!(groups.iter().all(|g| !g.is_empty()));
    }
}
