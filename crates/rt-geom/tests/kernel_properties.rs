//! Generated properties of the kernels against straightforward `f64` references: ray/triangle
//! (watertight), ray/box, ray/sphere, ray/cone. Inputs include lattice points (coincident and
//! axis-aligned geometry), axis-parallel rays, zero and subnormal direction components, and
//! scenes scaled to huge and tiny coordinates. A failure shrinks to a minimal case, saved in
//! `kernel_properties.proptest-regressions` and replayed first on every later run.
//!
//! The reference decides only where it is well conditioned (a hit or miss by a margin); near
//! an edge, where `f32` and `f64` may honestly differ, the watertight property decides instead.
//! Cases per property: 1024, or `PROPTEST_CASES`.

use glam::DVec3;
use proptest::prelude::*;
use rt_geom::{Aabb, Cone, Primitive, Ray, Sphere, Triangle, Vec3};
use rt_testkit::props::config;

/// A point of the half-unit lattice within 4 (or any within 10), in `f64`.
fn point() -> impl Strategy<Value = DVec3> {
    rt_testkit::props::point(8, 10.0).prop_map(|p| p.as_dvec3())
}

/// Scene scales: ordinary, huge (coordinates up to `MAX_COORDINATE`, about 1e18) and tiny.
/// Exactness is promised for distances in the normal float range (ARCHITECTURE.md,
/// robustness): the tiny scale keeps coordinate differences normal; subnormal values enter
/// as direction components.
fn scale() -> impl Strategy<Value = f64> {
    prop_oneof![
        6 => Just(1.0),
        1 => Just(5e16),
        1 => Just(1e-18),
        1 => Just(1e-30),
    ]
}

fn f32s(p: DVec3) -> Vec3 {
    p.as_vec3()
}

/// A direction: general, along an axis, or with a zero or subnormal component.
fn direction_edit() -> impl Strategy<Value = u8> {
    prop_oneof![5 => Just(0u8), 1 => Just(1u8), 1 => Just(2u8), 1 => Just(3u8)]
}

fn edit_direction(d: Vec3, edit: u8, axis: usize) -> Vec3 {
    let mut a = d.to_array();
    match edit {
        1 => {
            let s = if a[axis] < 0.0 { -1.0 } else { 1.0 };
            a = [0.0; 3];
            a[axis] = s;
        }
        2 => a[(axis + 1) % 3] = 0.0,
        3 => a[(axis + 1) % 3] = 1e-40,
        _ => {}
    }
    Vec3::from_array(a)
}

/// Möller-Trumbore in `f64` on the `f32` inputs: `(t, barycentrics, |det| relative)`.
fn triangle_reference(t: &Triangle, o: Vec3, d: Vec3) -> Option<(f64, [f64; 3], f64)> {
    let [a, b, c] = t.v.map(|p| p.as_dvec3());
    let (o, d) = (o.as_dvec3(), d.as_dvec3());
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    let norm = d.length() * e1.length() * e2.length();
    if det == 0.0 || !(norm > 0.0) {
        return None;
    }
    let s = o - a;
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let v = d.dot(q) / det;
    let tt = e2.dot(q) / det;
    Some((tt, [1.0 - u - v, u, v], det.abs() / norm))
}

/// A triangle and a ray aimed at a point given by barycentrics (inside, on an edge, at a
/// vertex, outside), from an origin or along an axis, all scaled.
fn triangle_case() -> impl Strategy<Value = (Triangle, Ray)> {
    (
        point(),
        point(),
        point(),
        point(),
        (-0.3f64..1.3, -0.3f64..1.3),
        scale(),
        direction_edit(),
        0usize..3,
        prop_oneof![Just(0.0f32), Just(-1.0), Just(1e-3)],
        // Needles: one vertex pulled 1e9 times farther along an axis.
        prop_oneof![4 => Just(1.0f64), 1 => Just(1e9)],
    )
        .prop_map(|(a, b, c, o, (u, v), s, edit, axis, tmin, stretch)| {
            let mut c = c;
            c[axis] = c[axis] * stretch + (stretch - 1.0).signum();
            let tri = Triangle::new(f32s(a * s), f32s(b * s), f32s(c * s));
            let target = a * (1.0 - u - v) + b * u + c * v;
            let o = f32s(o * s + DVec3::splat(0.25 * s));
            let d = edit_direction(f32s(target * s) - o, edit, axis);
            (tri, Ray::segment(o, d, tmin, f32::INFINITY))
        })
}

proptest! {
    #![proptest_config(config(1024))]

    /// Where the `f64` reference is clear, the watertight kernel agrees: a hit well inside is
    /// found at the same distance, a point well outside is missed; every hit lies in the
    /// triangle's box as the box test sees it, with barycentrics in the triangle.
    #[test]
    fn triangle_kernel_agrees_with_f64(case in triangle_case()) {
        let (tri, ray) = case;
        // Directions shorter than `MIN_DIRECTION` make invalid rays (they miss); builders
        // reject vertices beyond `MAX_COORDINATE`.
        prop_assume!(ray.is_valid());
        prop_assume!(tri.v.iter().all(|p| p.abs().max_element() <= rt_geom::MAX_COORDINATE));
        let got = tri.intersect_watertight(&ray);
        if let Some(h) = got {
            prop_assert!(h.u >= 0.0 && h.v >= 0.0 && h.u + h.v <= 1.0 + 1e-5, "barycentrics {h:?}");
            let (t0, t1) = tri.bounds().clip_ray(&ray).expect("a hit outside the triangle's box");
            prop_assert!(t0 <= h.t && h.t <= t1, "hit {} outside the box interval {t0}..{t1}", h.t);
        }
        let Some((t, bary, cond)) = triangle_reference(&tri, ray.origin(), ray.dir()) else {
            return Ok(());
        };
        let margin = bary.iter().cloned().fold(f64::INFINITY, f64::min);
        let in_range = t > ray.tmin as f64 + 1e-6 * t.abs().max(1e-30);
        if cond > 1e-4 && margin > 1e-4 && in_range && !tri.is_degenerate() {
            let h = got.ok_or_else(|| TestCaseError::fail("missed a hit well inside the triangle"))?;
            prop_assert!(((h.t as f64) - t).abs() <= 1e-5 * t.abs(), "t {} against {t}", h.t);
        }
        if cond > 1e-4 && margin < -1e-4 {
            prop_assert!(got.is_none(), "hit a point well outside the triangle: {got:?}");
        }
    }

    /// Watertight: a ray aimed at the centre of a closed fan of six triangles, or at a point
    /// of one of its shared edges, hits at least one of them (never slips between).
    #[test]
    fn triangle_fans_are_watertight(
        q in point(), e1 in point(), e2 in point(), o in point(),
        spoke in 0usize..6, along in prop_oneof![Just(0.0f64), Just(0.5), 0.0f64..0.9],
        s in scale(), axis_parallel in any::<bool>(), axis in 0usize..3,
    ) {
        let (u, w) = (e1.normalize_or_zero(), e1.cross(e2).cross(e1).normalize_or_zero());
        prop_assume!(u != DVec3::ZERO && w != DVec3::ZERO);
        let ring: Vec<DVec3> = (0..6)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 6.0;
                q + (u * a.cos() + w * a.sin()) * 2.0
            })
            .collect();
        let fan: Vec<Triangle> = (0..6)
            .map(|k| Triangle::new(f32s(q * s), f32s(ring[k] * s), f32s(ring[(k + 1) % 6] * s)))
            .collect();
        let target = f32s((q + (ring[spoke] - q) * along) * s);
        let normal = u.cross(w);
        let (origin, dir) = if axis_parallel {
            let mut d = DVec3::ZERO;
            d[axis] = if normal[axis] < 0.0 { 1.0 } else { -1.0 };
            (f32s(target.as_dvec3() - d * 3.0 * s), f32s(d))
        } else {
            let o = f32s(o * s + normal * s);
            (o, target - o)
        };
        let ray = Ray::new(origin, dir);
        prop_assume!(ray.is_valid());
        // Not edge-on: the fan is seen as a disc.
        let dd = dir.as_dvec3();
        prop_assume!(dd.length() > 0.0 && (dd.normalize().dot(normal)).abs() > 1e-2);
        prop_assume!((target.as_dvec3() - origin.as_dvec3()).dot(dd) > 0.0);
        prop_assert!(fan.iter().any(|t| t.intersect_watertight(&ray).is_some()),
            "the ray slips through the fan");
    }

    /// The box test never misses an interval the exact slab test finds (it is padded to be
    /// conservative), and misses boxes that the ray passes by a margin.
    #[test]
    fn box_test_is_conservative(
        a in point(), b in point(), o in point(), d in point(),
        s in scale(), edit in direction_edit(), axis in 0usize..3,
        on_face in any::<bool>(),
    ) {
        let bounds = Aabb::new(f32s(a.min(b) * s), f32s(a.max(b) * s));
        let mut o = f32s(o * s);
        let d = edit_direction(f32s(d), edit, axis);
        if on_face {
            // The origin in a face plane, moving within it (a ray in the face).
            let mut oa = o.to_array();
            oa[axis] = bounds.min[axis];
            o = Vec3::from_array(oa);
        }
        let ray = Ray::new(o, d);
        prop_assume!(ray.is_valid());
        let (od, dd) = (o.as_dvec3(), d.as_dvec3());
        let (mut t0, mut t1) = (ray.tmin as f64, f64::INFINITY);
        let mut gap = 0.0f64;
        for k in 0..3 {
            let (lo, hi) = (bounds.min[k] as f64, bounds.max[k] as f64);
            if dd[k] == 0.0 {
                if od[k] < lo || od[k] > hi {
                    t1 = f64::NEG_INFINITY;
                    gap = f64::INFINITY;
                }
            } else {
                let (ta, tb) = ((lo - od[k]) / dd[k], (hi - od[k]) / dd[k]);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
        }
        if t0 <= t1 {
            let (g0, g1) = bounds.clip_ray(&ray).ok_or_else(|| TestCaseError::fail("missed a box the exact test enters"))?;
            prop_assert!(g0 as f64 <= t0 && g1 as f64 >= t1.min(f32::MAX as f64),
                "interval {g0}..{g1} inside the exact {t0}..{t1}");
        } else {
            gap = gap.max(t0 - t1);
            // A subnormal direction component has an infinite reciprocal: that axis counts as
            // parallel (the ray drifts off the plane by less than a float's resolution).
            if edit != 3 && gap > 1e-3 * t0.abs().max(t1.abs()).max(1e-30) {
                prop_assert!(bounds.clip_ray(&ray).is_none(), "entered a box it passes by");
            }
        }
    }

    /// Spheres: the nearest root in range of the `f64` quadratic, where well conditioned.
    #[test]
    fn sphere_kernel_agrees_with_f64(
        c in point(), r in 0.01f64..5.0, o in point(), aim in point(),
        s in scale(), edit in direction_edit(), axis in 0usize..3,
    ) {
        let sphere = Sphere::new(f32s(c * s), (r * s) as f32);
        prop_assume!(sphere.radius > 0.0 && sphere.radius.is_finite());
        let o32 = f32s(o * s);
        let d32 = edit_direction(f32s((c + aim * 0.2 * r) * s) - o32, edit, axis);
        let ray = Ray::new(o32, d32);
        prop_assume!(ray.is_valid());
        let got = Primitive::intersect(&sphere, &ray);
        let (od, dd) = (o32.as_dvec3() - sphere.center.as_dvec3(), d32.as_dvec3());
        let rr = sphere.radius as f64;
        let (qa, qb, qc) = (dd.dot(dd), 2.0 * od.dot(dd), od.dot(od) - rr * rr);
        let disc = qb * qb - 4.0 * qa * qc;
        let scale2 = qb * qb + (4.0 * qa * qc).abs();
        if disc < -1e-6 * scale2 {
            prop_assert!(got.is_none(), "hit a sphere the ray passes by: {got:?}");
        } else if disc > 1e-6 * scale2 {
            let sq = disc.sqrt();
            let roots = [(-qb - sq) / (2.0 * qa), (-qb + sq) / (2.0 * qa)];
            let near = rr / dd.length();
            match roots.iter().find(|&&t| t >= 0.0) {
                Some(&t) if t > 1e-4 * near => {
                    let h = got.ok_or_else(|| TestCaseError::fail("missed a sphere the ray enters"))?;
                    prop_assert!(((h.t as f64) - t).abs() <= 1e-4 * (t.abs() + near),
                        "t {} against {t}", h.t);
                }
                None => prop_assert!(got.is_none(), "hit a sphere behind the ray"),
                _ => {}
            }
        }
    }

    /// Open cones and cylinders: the nearest crossing of the surface in range, found by the
    /// `f64` quadratic in the cone's own frame, away from the rims and from tangency.
    #[test]
    fn cone_kernel_agrees_with_f64(
        b in point(), axis_dir in point(), h in 0.5f64..6.0, r0 in 0.0f64..3.0, r1 in 0.0f64..3.0,
        o in point(), aim in 0.05f64..0.95, s in scale(), edit in direction_edit(), k in 0usize..3,
    ) {
        let w = axis_dir.normalize_or_zero();
        prop_assume!(w != DVec3::ZERO && r0 + r1 > 0.1);
        let cone = Cone::new(f32s(b * s), (r0 * s) as f32, f32s((b + w * h) * s), (r1 * s) as f32);
        prop_assume!(cone.is_valid());
        let o32 = f32s(o * s);
        let d32 = edit_direction(f32s((b + w * (h * aim)) * s) - o32, edit, k);
        let ray = Ray::new(o32, d32);
        prop_assume!(ray.is_valid());
        let got = Primitive::intersect(&cone, &ray);
        // The frame of the f32 cone.
        let (base, apex) = (cone.base.as_dvec3(), cone.apex.as_dvec3());
        let height = (apex - base).length();
        let axis = (apex - base) / height;
        let (ra, rb) = (cone.base_radius as f64, cone.apex_radius as f64);
        let slope = (rb - ra) / height;
        let (e1, e2) = axis.any_orthonormal_pair();
        let local = |p: DVec3| DVec3::new(p.dot(e1), p.dot(e2), p.dot(axis));
        let (ol, dl) = (local(o32.as_dvec3() - base), local(d32.as_dvec3()));
        // x^2 + y^2 = (ra + slope z)^2 along o + t d.
        let qa = dl.x * dl.x + dl.y * dl.y - slope * slope * dl.z * dl.z;
        let qb = 2.0 * (ol.x * dl.x + ol.y * dl.y - (ra + slope * ol.z) * slope * dl.z);
        let qc = ol.x * ol.x + ol.y * ol.y - (ra + slope * ol.z).powi(2);
        let disc = qb * qb - 4.0 * qa * qc;
        let scale2 = qb * qb + (4.0 * qa * qc).abs();
        prop_assume!(qa.abs() > 1e-6 * dl.length_squared() && disc.abs() > 1e-6 * scale2);
        let mut roots = if disc > 0.0 {
            let sq = disc.sqrt();
            vec![(-qb - sq) / (2.0 * qa), (-qb + sq) / (2.0 * qa)]
        } else {
            vec![]
        };
        roots.sort_by(f64::total_cmp);
        let unit = height / dl.length();
        // Crossings on the frustum, each with its distance to a rim or to t = 0.
        let crossings: Vec<(f64, f64)> = roots
            .into_iter()
            .map(|t| {
                let z = ol.z + t * dl.z;
                let rim = z.min(height - z) / height;
                let radius = (ra + slope * z) / (ra.max(rb));
                (t, if rim < 0.0 || radius < 0.0 { -rim.abs().min(radius.abs()) } else { rim.min(radius) }
                    .min(t / unit))
            })
            .collect();
        // The first crossing that counts, if every earlier one is clearly off the frustum.
        for (t, clearance) in crossings {
            if clearance.abs() < 1e-4 {
                return Ok(());
            }
            if clearance > 0.0 {
                let hit = got.ok_or_else(|| TestCaseError::fail("missed the cone"))?;
                prop_assert!(((hit.t as f64) - t).abs() <= 1e-4 * (t.abs() + unit),
                    "t {} against {t}", hit.t);
                return Ok(());
            }
        }
        prop_assert!(got.is_none(), "hit a cone the ray misses: {got:?}");
    }
}
