//! Procedural and adversarial scenes. None needs a file; every one is fixed by its parameters.

use crate::Rng;
use rt_geom::{Aabb, Cone, Primitive, Shape, Sphere, Triangle, Vec3};
use std::f32::consts::{PI, TAU};

/// A named list of primitives.
#[derive(Clone, Debug)]
pub struct Scene<P> {
    pub name: String,
    pub prims: Vec<P>,
}

impl<P: Primitive> Scene<P> {
    pub fn new(name: impl Into<String>, prims: Vec<P>) -> Self {
        Self {
            name: name.into(),
            prims,
        }
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::around(&self.prims)
    }
}

/// Random triangles of random sizes in the unit cube; 5% of them have zero area (two equal
/// vertices, or three collinear ones), as in the dragon mesh.
pub fn random_soup(n: usize, seed: u64) -> Vec<Triangle> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            let c = rng.point_in(Vec3::ZERO, Vec3::ONE);
            let size = 0.2 * rng.f32().powi(2) + 0.002;
            let a = c + rng.unit_vector() * size;
            let b = c + rng.unit_vector() * size;
            match rng.below(40) {
                0 => Triangle::new(c, a, a),
                1 => Triangle::new(c, a, c + (a - c) * 0.5),
                _ => Triangle::new(c, a, b),
            }
        })
        .collect()
}

/// A UV sphere of about `n` triangles (at least 8): watertight, shared edges and vertices.
pub fn tessellated_sphere(n: usize, center: Vec3, radius: f32) -> Vec<Triangle> {
    let rings = ((n as f32 / 2.0).sqrt().round() as usize).max(2);
    let segments = (n / (2 * rings)).max(4);
    let p = |i: usize, j: usize| {
        let theta = PI * i as f32 / rings as f32;
        let phi = TAU * (j % segments) as f32 / segments as f32;
        center
            + radius
                * Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                )
    };
    let mut tris = Vec::with_capacity(2 * rings * segments);
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            if i != 0 {
                tris.push(Triangle::new(a, b, d));
            }
            if i != rings - 1 {
                tris.push(Triangle::new(b, c, d));
            }
        }
    }
    tris
}

/// A torus of about `n` triangles around the y axis.
pub fn torus(n: usize, major: f32, minor: f32) -> Vec<Triangle> {
    let nu = ((n as f32 / 2.0 * 3.0).sqrt().round() as usize).max(3);
    let nv = (n / (2 * nu)).max(3);
    let p = |i: usize, j: usize| {
        let u = TAU * (i % nu) as f32 / nu as f32;
        let v = TAU * (j % nv) as f32 / nv as f32;
        let r = major + minor * v.cos();
        Vec3::new(r * u.cos(), minor * v.sin(), r * u.sin())
    };
    let mut tris = Vec::with_capacity(2 * nu * nv);
    for i in 0..nu {
        for j in 0..nv {
            tris.push(Triangle::new(p(i, j), p(i + 1, j), p(i + 1, j + 1)));
            tris.push(Triangle::new(p(i, j), p(i + 1, j + 1), p(i, j + 1)));
        }
    }
    tris
}

/// A regular grid of `n x n` quads (two triangles each) in the plane `y = 0`: every box in any
/// structure is flat, edges are axis-aligned and shared.
pub fn planar_grid(n: usize) -> Vec<Triangle> {
    let mut tris = Vec::with_capacity(2 * n * n);
    let s = 1.0 / n as f32;
    for i in 0..n {
        for k in 0..n {
            let p = |a: usize, b: usize| Vec3::new(a as f32 * s, 0.0, b as f32 * s);
            tris.push(Triangle::new(p(i, k), p(i + 1, k), p(i + 1, k + 1)));
            tris.push(Triangle::new(p(i, k), p(i + 1, k + 1), p(i, k + 1)));
        }
    }
    tris
}

/// Random triangles all in the plane `z = 0.5`.
pub fn coplanar(n: usize, seed: u64) -> Vec<Triangle> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            let mut v = || Vec3::new(rng.f32(), rng.f32(), 0.5);
            Triangle::new(v(), v(), v())
        })
        .collect()
}

/// `n` triangles that all share one vertex, the others a unit away in random directions:
/// every triangle overlaps the same point, so no plane separates them (the pathological
/// input for duplicating structures: kd-trees, grids, octrees).
pub fn overlapping_fan(n: usize, seed: u64) -> Vec<Triangle> {
    let mut rng = Rng::new(seed);
    let p = Vec3::splat(0.5);
    (0..n)
        .map(|_| Triangle::new(p, p + rng.unit_vector(), p + rng.unit_vector()))
        .collect()
}

/// Slivers crossing the whole scene along x, y or z, a thousandth wide: every plane or cell
/// wall cuts a third of them.
pub fn long_slivers(n: usize, seed: u64) -> Vec<Triangle> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|i| {
            let axis = Vec3::AXES[i % 3];
            let a = rng.point_in(Vec3::ZERO, Vec3::splat(10.0));
            let a = a - axis * a.dot(axis);
            let b = a + axis * 10.0;
            Triangle::new(a, b, b + rng.unit_vector() * 1e-3)
        })
        .collect()
}

/// Slivers in two planes a hundredth apart (`z` = -0.04625 and -0.03625), each reaching from
/// near `x = 0` to near `x = 5.7e8` and 900 to 1,000 wide in `y`: rays that start between
/// the planes meet a sliver a few thousandths away, its vertices 1e8 away. There the `f64`
/// depth, interpolated between the vertices, loses the digits that place a hit near the
/// origin: the hit must still lie in the sliver's box, where every structure looks for it.
pub fn far_slivers(n: usize, seed: u64) -> Vec<Triangle> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|i| {
            let z = if i % 2 == 0 { -0.04625 } else { -0.03625 };
            let far = 569_315_840.0;
            let (xa, xb) = (rng.range(0.0, 1000.0), far - rng.range(0.0, 2000.0));
            let xc = if rng.chance(0.5) {
                rng.range(0.0, 1000.0)
            } else {
                far - rng.range(0.0, 2000.0)
            };
            let (ya, yb, yc) = (
                rng.range(0.0, 50.0),
                rng.range(0.0, 1000.0),
                rng.range(950.0, 1000.0),
            );
            let v = [
                Vec3::new(xa, ya, z),
                Vec3::new(xb, yb, z),
                Vec3::new(xc, yc, z),
            ];
            // Either vertex order, so that both sides face the rays.
            if rng.chance(0.5) {
                Triangle::new(v[0], v[1], v[2])
            } else {
                Triangle::new(v[0], v[2], v[1])
            }
        })
        .collect()
}

/// Long, thin triangles aligned with the axes (boxes that are flat in one or two dimensions).
pub fn axis_slivers(n: usize, seed: u64) -> Vec<Triangle> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|i| {
            let a = rng.point_in(Vec3::ZERO, Vec3::ONE);
            let axis = i % 3;
            let across = (axis + 1 + rng.below(2)) % 3;
            let mut b = a;
            b[axis] += rng.range(0.2, 1.0);
            let mut c = b;
            c[across] += 1e-4 * rng.f32() + 1e-6;
            Triangle::new(a, b, c)
        })
        .collect()
}

/// Every triangle three times, and many sharing vertices (ties in `t`).
pub fn duplicates(n: usize, seed: u64) -> Vec<Triangle> {
    let base = random_soup(n.div_ceil(3), seed);
    let mut tris: Vec<Triangle> = base.iter().flat_map(|t| [*t, *t, *t]).collect();
    tris.truncate(n);
    tris
}

/// Teapot in a stadium: a dense small sphere mesh (`n` triangles, radius 0.01) in the middle of
/// a huge, nearly empty box (a floor and four walls of 1000 units).
pub fn teapot_in_stadium(n: usize) -> Vec<Triangle> {
    let mut tris = tessellated_sphere(n, Vec3::new(0.0, 0.02, 0.0), 0.01);
    let s = 500.0;
    let quad =
        |a: Vec3, b: Vec3, c: Vec3, d: Vec3| [Triangle::new(a, b, c), Triangle::new(a, c, d)];
    let p = |x: f32, y: f32, z: f32| Vec3::new(x * s, y * s, z * s);
    tris.extend(quad(
        p(-1., 0., -1.),
        p(1., 0., -1.),
        p(1., 0., 1.),
        p(-1., 0., 1.),
    ));
    tris.extend(quad(
        p(-1., 0., -1.),
        p(-1., 1., -1.),
        p(1., 1., -1.),
        p(1., 0., -1.),
    ));
    tris.extend(quad(
        p(-1., 0., 1.),
        p(1., 0., 1.),
        p(1., 1., 1.),
        p(-1., 1., 1.),
    ));
    tris.extend(quad(
        p(-1., 0., -1.),
        p(-1., 0., 1.),
        p(-1., 1., 1.),
        p(-1., 1., -1.),
    ));
    tris.extend(quad(
        p(1., 0., -1.),
        p(1., 1., -1.),
        p(1., 1., 1.),
        p(1., 0., 1.),
    ));
    tris
}

/// A scene moved to `offset` and scaled by `scale` (coordinates near 1e6 or near 1e-6).
pub fn transformed(tris: &[Triangle], scale: f32, offset: Vec3) -> Vec<Triangle> {
    tris.iter()
        .map(|t| Triangle {
            v: t.v.map(|p| p * scale + offset),
        })
        .collect()
}

/// A scene scaled by `scale` and moved to `offset`, each coordinate computed in `f64` and
/// rounded to `f32` once, as a file in projected coordinates (GIS, CAD) holds it: far from the
/// origin, vertices snap to the coarse `f32` lattice there (0.5 at 5e6, 1 at 1e7).
pub fn placed(tris: &[Triangle], scale: f64, offset: [f64; 3]) -> Vec<Triangle> {
    let at = |p: Vec3| {
        let o = rt_geom::glam::DVec3::from_array(offset);
        (p.as_dvec3() * scale + o).as_vec3()
    };
    tris.iter().map(|t| Triangle { v: t.v.map(at) }).collect()
}

/// Random spheres: most small, a few large, some overlapping, a few of zero radius.
pub fn random_spheres(n: usize, seed: u64) -> Vec<Sphere> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            let c = rng.point_in(Vec3::ZERO, Vec3::ONE);
            let r = match rng.below(50) {
                0 => 0.0,
                1 => rng.range(0.2, 0.5),
                _ => 0.003 + 0.04 * rng.f32().powi(2),
            };
            Sphere::new(c, r)
        })
        .collect()
}

/// Open cones and cylinders of random sizes and directions in the unit cube; a few point-like,
/// a few axis-aligned (rays run along their walls), a few degenerate (never hit).
pub fn random_cones(n: usize, seed: u64) -> Vec<Cone> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            let base = rng.point_in(Vec3::ZERO, Vec3::ONE);
            let len = 0.02 + 0.2 * rng.f32().powi(2);
            let dir = match rng.below(10) {
                0 => Vec3::AXES[rng.below(3)],
                _ => rng.unit_vector(),
            };
            let rb = 0.002 + 0.04 * rng.f32();
            let ra = match rng.below(4) {
                0 => rb,
                1 => 0.0,
                _ => 0.002 + 0.04 * rng.f32(),
            };
            match rng.below(40) {
                0 => Cone::new(base, 0.0, base + dir * len, 0.0),
                1 => Cone::cylinder(base, base, rb),
                _ => Cone::new(base, rb, base + dir * len, ra),
            }
        })
        .collect()
}

/// Triangles, spheres and cones mixed in one scene (what NFF files hold).
pub fn mixed_shapes(n: usize, seed: u64) -> Vec<Shape> {
    let third = n / 3;
    let mut out: Vec<Shape> = Vec::with_capacity(n);
    let tris = random_soup(third, seed);
    let spheres = random_spheres(third, seed + 1);
    let cones = random_cones(n - 2 * third, seed + 2);
    // Interleaved, so that primitive ids of each kind are spread over the scene.
    for (i, cone) in cones.into_iter().enumerate() {
        if let Some(t) = tris.get(i) {
            out.push((*t).into());
        }
        if let Some(s) = spheres.get(i) {
            out.push((*s).into());
        }
        out.push(cone.into());
    }
    out
}

/// The triangle scenes every structure must agree with brute force on.
pub fn conformance_triangle_scenes() -> Vec<Scene<Triangle>> {
    let soup = random_soup(2000, 1);
    vec![
        Scene::new("soup", soup.clone()),
        Scene::new(
            "sphere_mesh",
            tessellated_sphere(3000, Vec3::splat(0.5), 0.5),
        ),
        Scene::new("torus", torus(2000, 1.0, 0.3)),
        Scene::new("planar_grid", planar_grid(30)),
        Scene::new("coplanar", coplanar(800, 2)),
        Scene::new("axis_slivers", axis_slivers(1000, 3)),
        Scene::new("duplicates", duplicates(1500, 4)),
        Scene::new("teapot_in_stadium", teapot_in_stadium(2000)),
        Scene::new("overlapping_fan", overlapping_fan(1500, 5)),
        Scene::new("long_slivers", long_slivers(1500, 6)),
        Scene::new(
            "huge_coords",
            transformed(&soup[..1000], 1.0e3, Vec3::splat(1.0e6)),
        ),
        Scene::new(
            "tiny_coords",
            transformed(&soup[..1000], 1.0e-6, Vec3::splat(1.0e-6)),
        ),
        Scene::new(
            "one_triangle",
            vec![Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)],
        ),
        Scene::new("empty", vec![]),
        // Far from the origin, as GIS and CAD scenes come (UTM coordinates, metres): small
        // triangles on the 0.5 lattice at 5e6 (many snap flat), a sphere at 1e7, the
        // teapot in a stadium at 5e6.
        Scene::new(
            "far_soup",
            placed(&soup[..1000], 20.0, [3.0e5, 5.0e6, 250.0]),
        ),
        Scene::new(
            "far_sphere",
            placed(
                &tessellated_sphere(1500, Vec3::ZERO, 1.0),
                60.0,
                [1.0e7, -1.0e7, 1.0e7],
            ),
        ),
        Scene::new(
            "far_stadium",
            placed(&teapot_in_stadium(1500), 50.0, [-3.0e5, 2.0e3, 5.0e6]),
        ),
        // A torus a few lattice steps wide at 5e6 (f32 steps by 0.5 there): cells finer
        // than the lattice (world-coordinate grids lost hits here).
        Scene::new(
            "far_dense",
            placed(&torus(2000, 1.0, 0.3), 1.5, [5.0e6, 3.5e6, -5.0e6]),
        ),
        // Slivers 5.7e8 long, rays starting a hundredth from them.
        Scene::new("far_slivers", far_slivers(200, 9)),
    ]
}

/// The sphere scenes every structure generic over `Primitive` must agree on.
pub fn conformance_sphere_scenes() -> Vec<Scene<Sphere>> {
    vec![
        Scene::new("spheres", random_spheres(1500, 5)),
        Scene::new("one_sphere", vec![Sphere::new(Vec3::splat(0.5), 0.25)]),
        Scene::new("empty_spheres", vec![]),
        Scene::new(
            "far_spheres",
            random_spheres(1000, 6)
                .into_iter()
                .map(|s| {
                    let c = s.center.as_dvec3() * 40.0
                        + rt_geom::glam::DVec3::new(3.0e5, 5.0e6, -4.0e3);
                    Sphere::new(c.as_vec3(), s.radius * 40.0)
                })
                .collect(),
        ),
    ]
}

/// The mixed-shape scenes (triangles, spheres, cones) every structure generic over
/// `Primitive` must agree on.
pub fn conformance_shape_scenes() -> Vec<Scene<Shape>> {
    let ground = [
        Triangle::new(
            Vec3::ZERO,
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 1.0),
        ),
        Triangle::new(
            Vec3::ZERO,
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, 1.0),
        ),
    ];
    // Cylinders standing on the ground, touching it and each other (as in SPD's rings).
    let mut posts: Vec<Shape> = ground.iter().map(|&t| t.into()).collect();
    for i in 0..5 {
        for j in 0..5 {
            let c = Vec3::new(0.1 + 0.2 * i as f32, 0.0, 0.1 + 0.2 * j as f32);
            posts.push(Cone::cylinder(c, c + Vec3::Y * 0.3, 0.1).into());
            posts.push(Sphere::new(c + Vec3::Y * 0.3, 0.1).into());
        }
    }
    vec![
        Scene::new("shapes", mixed_shapes(1500, 7)),
        Scene::new(
            "cones",
            random_cones(1000, 8).into_iter().map(Shape::from).collect(),
        ),
        Scene::new("posts", posts),
    ]
}

/// A conformance scene by name (shapes).
pub fn shape_scene(name: &str) -> Scene<Shape> {
    conformance_shape_scenes()
        .into_iter()
        .find(|s| s.name == name)
        .unwrap_or_else(|| panic!("no conformance scene named {name}"))
}

/// A conformance scene by name (triangles).
pub fn triangle_scene(name: &str) -> Scene<Triangle> {
    conformance_triangle_scenes()
        .into_iter()
        .find(|s| s.name == name)
        .unwrap_or_else(|| panic!("no conformance scene named {name}"))
}

/// A conformance scene by name (spheres).
pub fn sphere_scene(name: &str) -> Scene<Sphere> {
    conformance_sphere_scenes()
        .into_iter()
        .find(|s| s.name == name)
        .unwrap_or_else(|| panic!("no conformance scene named {name}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenes_have_the_sizes_asked_for() {
        let s = tessellated_sphere(10_000, Vec3::ZERO, 1.0);
        assert!((8_000..12_000).contains(&s.len()), "{}", s.len());
        for t in &s {
            for v in t.v {
                assert!((v.length() - 1.0).abs() < 1e-5);
            }
        }
        let t = torus(5000, 1.0, 0.25);
        assert!((4000..6000).contains(&t.len()), "{}", t.len());
        assert_eq!(planar_grid(10).len(), 200);
        assert!(planar_grid(10).iter().all(|t| t.bounds().extent().y == 0.0));
        let soup = random_soup(4000, 9);
        let degenerate = soup.iter().filter(|t| t.is_degenerate()).count();
        assert!(degenerate > 50, "{degenerate}");
        for s in conformance_triangle_scenes() {
            assert!(s.prims.iter().all(|p| p.is_finite()), "{}", s.name);
        }
    }
}

/// A primitive with no data and no surface (a zero-sized type, never hit): a test can pass
/// more of them than an index type holds without the memory, to check `TooManyPrimitives`.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoGeometry;

impl rt_geom::Primitive for NoGeometry {
    fn bounds(&self) -> Aabb {
        Aabb::new(Vec3::ZERO, Vec3::ZERO)
    }
    fn centroid(&self) -> Vec3 {
        Vec3::ZERO
    }
    fn intersect(&self, _: &rt_geom::Ray) -> Option<rt_geom::PrimHit> {
        None
    }
    fn clipped_bounds(&self, clip: &Aabb) -> Aabb {
        self.bounds().intersection(*clip)
    }
    fn extent_along(&self, _: Vec3) -> (f32, f32) {
        (0.0, 0.0)
    }
    fn farthest_distance(&self, _: rt_geom::DVec3) -> f32 {
        0.0
    }
    fn is_finite(&self) -> bool {
        true
    }
}

/// The triangles a command-line argument names: `sphere:N` for a tessellated unit sphere of
/// about N triangles, `stadium:N` for [`teapot_in_stadium`], anything else an OBJ file (the
/// error names the file and line).
pub fn mesh_or_sphere(arg: &str) -> Result<Vec<Triangle>, String> {
    let count = |prefix: &str| arg.strip_prefix(prefix)?.parse::<usize>().ok();
    if let Some(n) = count("sphere:") {
        return Ok(tessellated_sphere(n, Vec3::ZERO, 1.0));
    }
    match count("stadium:") {
        Some(n) => Ok(teapot_in_stadium(n)),
        None => rt_geom::load_obj(arg)
            .map(|m| m.triangles())
            .map_err(|e| e.to_string()),
    }
}
