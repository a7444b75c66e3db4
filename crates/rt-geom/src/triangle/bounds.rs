//! The error bounds that decide a lane of the lane kernel without the `f64` refinement:
//! a hit that surely lies before `tmin` ([`hits_before_tmin`]) and one that surely lies inside
//! the interval ([`proven_hit`]), from pbrt-v4's bounds on the watertight test.

use super::simd::{ShearedLanes, SimdLanes};
use crate::{PrimHit, Ray};

/// The lanes whose hit, if [`Triangle::refine`](super::Triangle::refine) found one, would certainly lie before `tmin`
/// (`tmin > 0`), so that it returns `None`: decided from the `f32` numbers with the error
/// bounds of Pharr, Jakob & Humphreys (pbrt-v4, `IntersectTriangle`, the bounds that keep
/// `t > 0`), each taken twice over.
///
/// - A lane qualifies only when every edge function exceeds its error bound `dE`: the exact
///   edge functions then agree in sign, `refine` takes its interpolating branch, and its `t`
///   is the exact `T / D` to `f64` rounding, `T = |U| za + |V| zb + |W| zc` and `D = |U| +
///   |V| + |W|` (the absolute values flip both by the common sign).
/// - The bounds: sheared `x`, `y` off by `dX = gamma(8) (max |x| + max |dz|)` and `dY` alike
///   (the subtraction, the shear product, the `f32` rounding of the shear constant, `|sx| <=
///   1`), the depths `z = dz sz` by `gamma(4) max |z|`, each edge function (two products, a
///   difference) by `dE = 4 (gamma(2) max|x| max|y| + dY max|x| + dX max|y|)`, `T` by
///   `dT = 3 max|z| ((gamma(3) + gamma(4)) max|e| + dE)`, `D` by `dD = 3 gamma(2) max|e| + 3 dE`.
/// - Culled when `T + 2 dT < tmin (D - 2 dD) (1 - 2^-20)`: the exact `T / D` lies below `tmin`
///   by more than the `f64` evaluation and its rounding to `f32` can move it.
///
/// NaN or infinite inputs fail the comparisons: such lanes are never culled. Out of line:
/// [`watertight_lanes`](super::watertight_lanes) asks only for rays with `tmin > 0` and lanes whose `f32` estimate
/// lies before `tmin`: inlined, or asked for every lane that passed the sign test, it cost
/// more than it saved. (Unfiltered any-hit leaf tests ask for every window with a candidate,
/// since the same pass proves their hits: [`proven_hit`] for all the lanes at once.)
#[inline(never)]
pub fn hits_before_tmin<L: SimdLanes>(t: &ShearedLanes<L>, tmin: f32) -> u32 {
    hits_outside(t, tmin, f32::INFINITY)
}

/// The lanes of `t` whose hit surely lies before `tmin` ([`hits_before_tmin`], asked only
/// for `tmin > 0`) or surely after `tmax` (asked only for a finite `tmax > 0`): the same
/// bounds mirrored, `T - 2 dT > tmax (D + 2 dD) (1 + 2^-20)`, as [`proven_hit`] proves a hit
/// after `tmin`. [`Triangle::finish_watertight`](super::Triangle::finish_watertight) rejects
/// every lane culled. Out of line, as [`hits_before_tmin`].
#[inline(never)]
pub fn hits_outside<L: SimdLanes>(t: &ShearedLanes<L>, tmin: f32, tmax: f32) -> u32 {
    outside_and_proven_lanes(t, tmin, tmax).0
}

/// [`outside_and_proven_lanes`] out of line, at the baseline.
#[inline(never)]
pub(crate) fn hits_outside_and_proven<L: SimdLanes>(
    t: &ShearedLanes<L>,
    tmin: f32,
    tmax: f32,
) -> (u32, u32) {
    outside_and_proven_lanes(t, tmin, tmax)
}

/// [`hits_outside`]'s lanes (its body, inlined at the AVX2 level), and beside them
/// the lanes whose hit [`proven_hit`] proves inside `[tmin, tmax]` (`tmin > 0`): the same
/// bounds, computed once for every lane. A lane is proven only where its inputs are all
/// finite (the lanes' `max` drops NaN where `f32::max` keeps the other operand, so the two
/// would differ there); `proven_hit` is this function on one lane.
#[inline(always)]
pub(crate) fn outside_and_proven_lanes<L: SimdLanes>(
    t: &ShearedLanes<L>,
    tmin: f32,
    tmax: f32,
) -> (u32, u32) {
    let b = EstimateBounds::of(t);
    // `T` and `D` moved by twice their bounds, toward and away from zero.
    let (num_lo, num_hi) = (t.num - b.dt2, t.num + b.dt2);
    let (den_lo, den_hi) = (t.den - b.dd2, t.den + b.dd2);
    let (below, above) = (L::splat(1.0 - ROUNDING), L::splat(1.0 + ROUNDING));
    let mut out = 0;
    if tmin > 0.0 {
        out |= L::less_bits(num_hi, L::splat(tmin) * below * den_lo);
    }
    if tmax > 0.0 && tmax < f32::INFINITY {
        out |= L::less_bits(L::splat(tmax) * above * den_hi, num_lo);
    }
    let sure_edges = L::less_bits(b.de, b.e_min);
    let after_tmin = L::less_bits(L::splat(tmin) * above * den_hi, num_lo);
    let before_tmax = L::less_bits(num_hi, L::splat(tmax) * below * den_lo);
    // Every input finite, read from `T` and `D` alone: an infinite or NaN factor makes its
    // product infinite or NaN (times zero), so an infinite or NaN sheared coordinate makes an
    // edge function that holds it so, and with it `D`; an infinite or NaN depth makes `T` so.
    let finite = L::less_bits(t.num.abs() + t.den, L::splat(f32::MAX));
    let proven = sure_edges & L::less_bits(b.dd2, t.den) & after_tmin & before_tmax & finite;
    (sure_edges & out, proven)
}

/// How far the `f32` numbers of the depth estimate may lie from the exact ones, in
/// [`refine`](Triangle::refine)'s relative rounding to `f32` (`2^-20`, generous).
const ROUNDING: f32 = 1.0 / (1 << 20) as f32;

/// The error bounds of [`hits_before_tmin`] for Woop's depth estimate `T / D` of sheared
/// triangles: each edge function's `dE`, the smallest `|e|`, and twice `dT` and `dD` (the
/// bounds are taken twice over).
struct EstimateBounds<L> {
    de: L,
    e_min: L,
    dt2: L,
    dd2: L,
}

impl<L: SimdLanes> EstimateBounds<L> {
    #[inline(always)]
    fn of(t: &ShearedLanes<L>) -> Self {
        use crate::aabb::gamma;
        let abs_max = |v: &[L; 3]| v[0].abs().max(v[1].abs()).max(v[2].abs());
        let (x_max, y_max) = (abs_max(&t.x), abs_max(&t.y));
        let (dz_max, z_max) = (abs_max(&t.dz), abs_max(&t.z));
        // `4 (gamma(2) x y + dY x + dX y)` expanded.
        let de = L::splat(4.0 * gamma(2) + 8.0 * gamma(8)) * x_max * y_max
            + L::splat(4.0 * gamma(8)) * dz_max * (x_max + y_max);
        let e = &t.edges;
        let e_max = e[0].max(e[1]).max(e[2]);
        let e_min = e[0].min(e[1]).min(e[2]);
        let de6 = L::splat(6.0) * de;
        let dt2 = z_max * (L::splat(6.0 * (gamma(3) + gamma(4))) * e_max + de6);
        let dd2 = L::splat(6.0 * gamma(2)) * e_max + de6;
        Self {
            de,
            e_min,
            dt2,
            dd2,
        }
    }
}

/// An any-hit query's shortcut for one triangle that passed the sign test: `Some` when the
/// error bounds of [`hits_before_tmin`], mirrored, prove that [`Triangle::finish_watertight`](super::Triangle::finish_watertight)
/// would report a hit inside `[tmin, tmax]` (`tmin > 0`), so that the query can stop without
/// the `f64` refinement. Every edge function exceeds its bound (the exact ones agree in sign,
/// so `refine` interpolates) and `T - 2 dT > tmin (D + 2 dD) (1 + 2^-20)`, `T + 2 dT < tmax
/// (D - 2 dD) (1 - 2^-20)`. The hit returned carries Woop's `f32` estimates of `t`, `u`, `v`
/// (an any-hit query answers only whether something is hit); `None` sends the caller to the
/// refinement.
///
/// Inputs as [`watertight_lanes`](super::watertight_lanes) computes them for the triangle's lane: the sheared `x`, `y`
/// and the unscaled depth `v[kz] - o[kz]` per vertex, and its edge functions ([`lane_edges`](super::lane_edges)).
#[inline]
pub fn proven_hit(
    x: [f32; 3],
    y: [f32; 3],
    dz: [f32; 3],
    (u, v, w): (f32, f32, f32),
    ray: &Ray,
) -> Option<PrimHit> {
    let (tmin, tmax) = (ray.tmin, ray.tmax);
    if !(tmin > 0.0) {
        return None;
    }
    let sz = ray.watertight_shear().z;
    let z = dz.map(|d| d * sz);
    let edges = [u.abs(), v.abs(), w.abs()];
    let num = edges[0] * z[0] + edges[1] * z[1] + edges[2] * z[2];
    let den = edges[0] + edges[1] + edges[2];
    let t = ShearedLanes {
        x,
        y,
        dz,
        z,
        edges,
        num,
        den,
    };
    let (_, proven) = outside_and_proven_lanes(&t, tmin, tmax);
    if proven == 0 {
        return None;
    }
    woop_hit(num, den, (u, v, w), ray)
}

/// The hit [`proven_hit`] reports once proven: Woop's `f32` estimates of `t` (`num / den`,
/// clamped to the ray's interval), `u`, `v`; `None` where the barycentrics are not finite.
#[inline(always)]
pub(crate) fn woop_hit(
    num: f32,
    den: f32,
    (u, v, w): (f32, f32, f32),
    ray: &Ray,
) -> Option<PrimHit> {
    let rcp = 1.0 / (u + v + w);
    let (bu, bv) = (v * rcp, w * rcp);
    (bu.is_finite() && bv.is_finite()).then(|| PrimHit {
        t: (num / den).clamp(ray.tmin, ray.tmax),
        u: bu,
        v: bv,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::triangle::{
        Triangle, TriangleLanes, lane_edges, watertight_lanes, watertight_rows_at,
    };

    use glam::Vec3;

    /// Eight triangles for lane tests (lane 0 a sliver in every fourth case), `1e-3`, 1 or
    /// `1e3` across (`case % 3`), centred at the origin, 10 or `1e4` away (`case / 3 % 3`),
    /// and a point of triangle `case % 8`: inside, on an edge (`case % 5 == 0`) or a vertex
    /// (`case % 5 == 1`).
    fn triangles_and_point(case: usize, rnd: &mut impl FnMut() -> f32) -> (Vec<Triangle>, Vec3) {
        let scale = [1e-3, 1.0, 1e3][case % 3];
        let centre = Vec3::new(rnd(), rnd(), rnd()) * [0.0, 10.0, 1e4][case / 3 % 3];
        let mut v = || centre + (Vec3::new(rnd(), rnd(), rnd()) - 0.5) * scale;
        let tris: Vec<Triangle> = (0..8)
            .map(|k| {
                let (a, b) = (v(), v());
                let c = if k == 0 && case % 4 == 0 {
                    a + (b - a) * 0.37 + Vec3::splat(1e-6 * scale)
                } else {
                    v()
                };
                Triangle::new(a, b, c)
            })
            .collect();
        let (mut u, mut w) = (rnd(), rnd());
        if u + w > 1.0 {
            (u, w) = (1.0 - u, 1.0 - w);
        }
        match case % 5 {
            0 => w = 0.0,
            1 => (u, w) = (0.0, 0.0),
            _ => {}
        }
        let point = tris[case % 8].point(u, w);
        (tris, point)
    }

    /// [`proven_hit`] proves only hits that [`Triangle::finish_watertight`] reports inside the
    /// interval: rays from near and far at points inside triangles, on their edges and
    /// vertices, grazing ones, slivers, coordinates far from the origin, intervals ending
    /// a hair before or after the hit; and it proves most clear hits.
    #[test]
    fn proves_only_hits_that_refine_keeps() {
        let mut uniform = crate::test_uniform(77);
        let mut rnd = move || uniform();
        let (mut clear, mut clear_proven, mut proven) = (0, 0, 0);
        for case in 0..40_000 {
            let scale = [1e-3, 1.0, 1e3][case % 3];
            let (tris, aim) = triangles_and_point(case, &mut rnd);
            let target = &tris[case % 8];
            let n = target.normal();
            let dir = match case % 4 {
                0 => (target.v[1] - target.v[0]).normalize_or_zero() + n * (rnd() - 0.5) * 1e-3,
                _ => Vec3::new(rnd(), rnd(), rnd()) - 0.5,
            };
            let dist = [1e-4, 1.0, 30.0][case / 9 % 3] * scale;
            let origin = aim - dir.normalize_or_zero() * dist;
            let t_aim = (aim - origin).length() / dir.length();
            let tmax = match case / 27 % 4 {
                0 => f32::INFINITY,
                1 => t_aim * 2.0,
                2 => t_aim * (1.0 + 1e-6),
                _ => t_aim * (1.0 - 1e-6),
            };
            // `tmin` far before the hit, or a hair before or after it.
            let tmin = match case / 108 % 3 {
                0 => [1e-7, 1e-5, 1e-3][case % 3] * t_aim,
                1 => t_aim * (1.0 - 1e-6),
                _ => t_aim * (1.0 + 1e-6),
            };
            let ray = Ray::segment(origin, dir, tmin, tmax);
            let w8: TriangleLanes<wide::f32x8> = std::array::from_fn(|j| {
                wide::f32x8::from(std::array::from_fn(|l| tris[l].v[j / 3][j % 3]))
            });
            let (mut lanes, sheared) = watertight_lanes(&w8, &ray);
            // The lanes' proof, all eight at once, as any-hit leaf tests ask it.
            let (lanes_too, proven_lanes, _) =
                watertight_rows_at(crate::isa::BaseLevel, |j| w8[j], &ray, true);
            assert_eq!(lanes, lanes_too, "case {case}");
            let [_, _, kz] = ray.watertight_axes();
            let oz = ray.origin().to_array()[kz];
            while lanes != 0 {
                let l = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                let edges = lane_edges(&sheared, l);
                let [ax, ay, bx, by, cx, cy] = &sheared;
                let dz = tris[l].v.map(|p| p.to_array()[kz] - oz);
                let got = proven_hit(
                    [ax[l], bx[l], cx[l]],
                    [ay[l], by[l], cy[l]],
                    dz,
                    edges,
                    &ray,
                );
                // The lane's bit says what `proven_hit` says, with the same hit.
                let by_lanes = (proven_lanes & (1 << l) != 0)
                    .then(|| {
                        let e = [edges.0.abs(), edges.1.abs(), edges.2.abs()];
                        let z = dz.map(|d| d * ray.watertight_shear().z);
                        let num = e[0] * z[0] + e[1] * z[1] + e[2] * z[2];
                        woop_hit(num, e[0] + e[1] + e[2], edges, &ray)
                    })
                    .flatten();
                assert_eq!(by_lanes, got, "case {case} lane {l}: {ray:?}");
                let refined = tris[l].finish_watertight(&ray, edges);
                if let Some(h) = got {
                    proven += 1;
                    let r = refined.unwrap_or_else(|| {
                        panic!("case {case} lane {l}: {h:?} proved, not refined: {ray:?}")
                    });
                    assert!((ray.tmin..=ray.tmax).contains(&h.t) && ray.in_range(r.t));
                }
                // A clear hit: inside, not grazing, well within the interval, coordinates
                // within 1e4 of the triangle's size.
                let near_origin = case / 3 % 3 < 2;
                let inside = case % 5 >= 2 && case % 4 != 0;
                let interval = case / 27 % 4 < 2 && case / 108 % 3 == 0;
                if l == case % 8 && inside && interval && near_origin {
                    clear += 1;
                    clear_proven += got.is_some() as u32;
                }
            }
        }
        assert!(
            clear > 1_000 && clear_proven * 100 > clear * 90,
            "clear hits proven {clear_proven} of {clear}"
        );
        assert!(proven > 3_000, "{proven}");
    }

    /// Every lane in `cut` is one that [`Triangle::finish_watertight`] rejects.
    fn assert_rejected(
        tris: &[Triangle],
        ray: &Ray,
        sheared: &[[f32; 8]; 6],
        mut cut: u32,
        case: usize,
    ) {
        while cut != 0 {
            let l = cut.trailing_zeros() as usize;
            cut &= cut - 1;
            let h = tris[l].finish_watertight(ray, lane_edges(sheared, l));
            assert!(
                h.is_none(),
                "case {case} lane {l}: {:?} {ray:?} -> {h:?}",
                tris[l]
            );
        }
    }

    /// [`hits_outside`] culls beyond `tmax` only lanes whose hit
    /// [`Triangle::finish_watertight`] rejects: `tmax` just before, at and just after each
    /// lane's own hit (and far before and after it), every scale; and it culls most lanes
    /// whose hit lies clearly beyond.
    #[test]
    fn culls_after_tmax_only_what_refine_rejects() {
        let mut uniform = crate::test_uniform(77);
        let mut rnd = move || uniform();
        let (mut beyond, mut beyond_culled) = (0, 0);
        for case in 0..20_000 {
            let scale = [1e-3, 1.0, 1e3][case % 3];
            let (tris, point) = triangles_and_point(case, &mut rnd);
            let t = &tris[case % 8];
            let n = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).normalize_or_zero();
            let dir = match case % 4 {
                0 => (t.v[1] - t.v[0]).normalize_or_zero() + n * (rnd() - 0.5) * 1e-3,
                _ => Vec3::new(rnd(), rnd(), rnd()) - 0.5,
            };
            let origin = point - dir * (scale * (0.5 + rnd()));
            let w8: TriangleLanes<wide::f32x8> = std::array::from_fn(|j| {
                wide::f32x8::from(std::array::from_fn(|l| tris[l].v[j / 3][j % 3]))
            });
            let open = Ray::segment(origin, dir, 0.0, f32::INFINITY);
            let (all, sheared) = watertight_lanes(&w8, &open);
            let Some(own) = tris[case % 8].finish_watertight(&open, lane_edges(&sheared, case % 8))
            else {
                continue;
            };
            let factor = [0.5, 1.0 - 1e-6, 1.0, 1.0 + 1e-6, 2.0, 1e-3][case % 6];
            let tmax = (own.t * factor).max(f32::MIN_POSITIVE);
            let ray = open.with_range(0.0, tmax);
            let (kept, _) = watertight_lanes(&w8, &ray);
            assert_eq!(kept & !all, 0);
            let cut = all & !kept;
            if factor <= 0.5 && all >> (case % 8) & 1 == 1 {
                beyond += 1;
                beyond_culled += cut >> (case % 8) & 1;
            }
            assert_rejected(&tris, &ray, &sheared, cut, case);
        }
        assert!(
            beyond > 3_000 && beyond_culled * 100 > beyond * 60,
            "{beyond_culled} of {beyond}"
        );
    }

    /// [`hits_before_tmin`] culls only lanes whose hit [`Triangle::finish_watertight`] rejects:
    /// rays leaving a triangle (origins inside it, on its edges and vertices, a hair off its
    /// plane), grazing and steep, slivers, far from the world origin, every scale of `tmin`;
    /// and it does cull most rays' own triangle.
    #[test]
    fn culls_before_tmin_only_what_refine_rejects() {
        let mut uniform = crate::test_uniform(2024);
        let mut rnd = move || uniform();
        let (mut own, mut own_culled, mut culled) = (0, 0, 0);
        for case in 0..20_000 {
            let scale = [1e-3, 1.0, 1e3][case % 3];
            let (tris, point) = triangles_and_point(case, &mut rnd);
            let t = &tris[case % 8];
            let n = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).normalize_or_zero();
            let off = [0.0, 1e-6, -1e-6][case % 3] * scale;
            let origin = point + n * off;
            let dir = match case % 4 {
                // Grazing: in the plane, tilted by a hair.
                0 => (t.v[1] - t.v[0]).normalize_or_zero() + n * (rnd() - 0.5) * 1e-3,
                _ => Vec3::new(rnd(), rnd(), rnd()) - 0.5,
            };
            let tmin = [1e-7, 1e-5, 1e-3, 1e-1][case % 4] * scale;
            let ray = Ray::segment(origin, dir, tmin, f32::INFINITY);
            let w8: TriangleLanes<wide::f32x8> = std::array::from_fn(|j| {
                wide::f32x8::from(std::array::from_fn(|l| tris[l].v[j / 3][j % 3]))
            });
            let (all, sheared) = watertight_lanes(&w8, &ray.with_range(0.0, f32::INFINITY));
            let (kept, _) = watertight_lanes(&w8, &ray);
            assert_eq!(kept & !all, 0);
            let cut = all & !kept;
            culled += cut.count_ones();
            // The usual case: an inside point, coordinates no larger than the triangle's
            // scale, `tmin` at least 1e-3 of it (shadow rays and bounces off a mesh start
            // `1e-4` of the way to the light, or `1e-5` of the scene's size, beyond their
            // triangle; the bounds cull from about 1e-3 of the triangle's size).
            let usual = case % 5 >= 2 && case / 3 % 3 < 2 && case % 4 >= 2;
            if usual && all >> (case % 8) & 1 == 1 {
                own += 1;
                own_culled += cut >> (case % 8) & 1;
            }
            assert_rejected(&tris, &ray, &sheared, cut, case);
        }
        assert!(
            own > 2_000 && own_culled * 100 > own * 95,
            "own triangle culled {own_culled} of {own}"
        );
        assert!(culled > 5_000, "{culled}");
    }
}
