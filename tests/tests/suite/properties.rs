//! Generated scenes and rays for every registered rt structure (each registry entry is one of
//! its parameter presets): the closest hit, its primitive and `occluded` equal brute force's,
//! bit for bit, and `validate()` holds. Scenes are triangle soups on a coarse lattice (shared
//! vertices, axis-aligned and coincident triangles), with degenerate ones, or mixed triangles,
//! spheres and cones. A failure shrinks to a minimal scene and ray, printed as a reproducer.
//! Cases per property: 64, or `PROPTEST_CASES` for heavier runs.

use proptest::prelude::*;
use rt_geom::{
    Accel, BruteForce, Cone, Hit, Primitive, Ray, Shape, Sphere, Triangle, TriangleKernel, Vec3,
};
use rt_testkit::conformance::{MollerTrumbore, Tolerance, compare_with_expected};
use rt_testkit::props::config;
use rt_testkit::{RayKind, TestRay};
use xtask::registry::REGISTRY;

fn point() -> impl Strategy<Value = Vec3> {
    rt_testkit::props::point(4, 2.0)
}

fn triangle() -> impl Strategy<Value = Triangle> {
    prop_oneof![
        8 => (point(), point(), point()).prop_map(|(a, b, c)| Triangle::new(a, b, c)),
        1 => point().prop_map(|a| Triangle::new(a, a, a)),
        1 => (point(), point()).prop_map(|(a, b)| Triangle::new(a, b, b)),
    ]
}

fn shape() -> impl Strategy<Value = Shape> {
    prop_oneof![
        3 => triangle().prop_map(Shape::from),
        1 => (point(), 0.0f32..1.5).prop_map(|(c, r)| Sphere::new(c, r).into()),
        1 => (point(), 0.0f32..1.0, point(), 0.0f32..1.0)
            .prop_map(|(b, rb, a, ra)| Cone::new(b, rb, a, ra).into()),
    ]
}

/// Rays from lattice points: general, along an axis, aimed at a vertex of the scene, with
/// open, bounded and reversed intervals.
fn rays(vertices: Vec<Vec3>) -> impl Strategy<Value = Vec<Ray>> {
    let n = vertices.len().max(1);
    prop::collection::vec((point(), point(), 0u8..4, 0usize..n, 0u8..3), 1..24).prop_map(
        move |rays| {
            rays.into_iter()
                .map(|(o, d, kind, v, interval)| {
                    let o = o * 1.5 + Vec3::new(0.1, 0.2, 0.3) * (kind as f32);
                    let d = match kind {
                        0 => d,
                        1 => Vec3::AXES[v % 3] * if d.x < 0.0 { -1.0 } else { 1.0 },
                        _ => vertices.get(v).map_or(d, |&p| p - o),
                    };
                    let ray = Ray::new(o, d);
                    match interval {
                        1 => ray.with_range(0.25, 2.0),
                        2 => ray.with_range(-1.0, 1.0),
                        _ => ray,
                    }
                })
                .collect()
        },
    )
}

fn vertices<P: Primitive>(prims: &[P]) -> Vec<Vec3> {
    prims
        .iter()
        .flat_map(|p| {
            let b = p.bounds();
            [b.min, b.max, b.center()]
        })
        .collect()
}

/// Every entry's answers against brute force on `prims` and `rays`; a message per failure.
fn disagreements<P: Primitive>(
    prims: &[P],
    rays: &[Ray],
    build: impl Fn(&xtask::registry::AccelEntry) -> Option<Result<Box<dyn Accel>, String>>,
) -> Vec<String> {
    let brute = BruteForce::build(prims).expect("generated scenes are finite");
    let tests: Vec<TestRay> = rays
        .iter()
        .map(|&ray| TestRay {
            ray,
            kind: RayKind::Random,
        })
        .collect();
    let expected: Vec<Option<Hit>> = rays.iter().map(|r| brute.intersect(r)).collect();
    // Entries on Möller–Trumbore's kernel against brute force with it (triangle scenes).
    let mt: Option<Vec<MollerTrumbore>> = prims
        .iter()
        .map(|p| p.as_triangle().copied().map(MollerTrumbore))
        .collect();
    let expected_mt: Option<Vec<Option<Hit>>> = mt.as_ref().map(|mt| {
        let brute = BruteForce::build(mt).expect("generated scenes are finite");
        rays.iter().map(|r| brute.intersect(r)).collect()
    });
    let mut out = Vec::new();
    for entry in REGISTRY.iter().filter(|e| !e.external) {
        let Some(built) = build(entry) else { continue };
        let accel = match built {
            Ok(a) => a,
            Err(e) => {
                out.push(format!("{}: build failed: {e}", entry.name));
                continue;
            }
        };
        if let Err(e) = accel.validate() {
            out.push(format!("{}: validate: {e}", entry.name));
        }
        let report = match (&mt, &expected_mt) {
            (Some(mt), Some(expected_mt)) if entry.kernel == TriangleKernel::MollerTrumbore => {
                let t = Tolerance::EXACT;
                compare_with_expected("generated", mt, &tests, expected_mt, &accel, t)
            }
            _ => compare_with_expected(
                "generated",
                prims,
                &tests,
                &expected,
                &accel,
                Tolerance::EXACT,
            ),
        };
        if let Some(m) = report.mismatches.first() {
            out.push(format!("{}: {m}", entry.name));
        }
    }
    out
}

fn triangle_case() -> impl Strategy<Value = (Vec<Triangle>, Vec<Ray>)> {
    prop::collection::vec(triangle(), 1..32).prop_flat_map(|tris| {
        let v = vertices(&tris);
        (Just(tris), rays(v))
    })
}

fn shape_case() -> impl Strategy<Value = (Vec<Shape>, Vec<Ray>)> {
    prop::collection::vec(shape(), 1..24).prop_flat_map(|shapes| {
        let v = vertices(&shapes);
        (Just(shapes), rays(v))
    })
}

proptest! {
    #![proptest_config(config(64))]

    #[test]
    fn every_structure_answers_as_brute_force_on_triangles(case in triangle_case()) {
        let (tris, rays) = case;
        let bad = disagreements(&tris, &rays, |e| Some((e.build)(&tris).map_err(|e| e.to_string())));
        prop_assert!(bad.is_empty(), "{}", bad.join("\n"));
    }

    #[test]
    fn every_structure_answers_as_brute_force_on_mixed_shapes(case in shape_case()) {
        let (shapes, rays) = case;
        let bad = disagreements(&shapes, &rays, |e| {
            e.build_shapes.map(|b| b(&shapes).map_err(|e| e.to_string()))
        });
        prop_assert!(bad.is_empty(), "{}", bad.join("\n"));
    }
}
