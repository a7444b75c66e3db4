//! The lane kernel: the watertight test's edge functions and sign test for four or eight
//! triangles at once, with exactly the scalar kernel's numbers, and the batched leaf test.

use super::simd::{ShearedLanes, SimdLanes, TriangleLanes};
use super::{Triangle, watertight_edges};
use crate::isa::{BaseLevel, Level};
use crate::{Keep, Ray};
use wide::f32x4;

/// [`watertight_edges`] of lane `l` of [`watertight_lanes`]' sheared coordinates. Reads the
/// six values in place (`sheared.map(|x| x[l])` copied all the lanes into a call that was not
/// inlined).
#[inline(always)]
pub fn lane_edges<A: std::ops::Index<usize, Output = f32>>(
    sheared: &[A; 6],
    l: usize,
) -> (f32, f32, f32) {
    let [ax, ay, bx, by, cx, cy] = sheared;
    watertight_edges([ax[l], ay[l], bx[l], by[l], cx[l], cy[l]])
}

/// The watertight test's edge functions for four (or eight) triangles at once
/// ([`TriangleLanes`]), with the scalar kernel's numbers (vertex minus origin, sheared by the
/// ray's [`Ray::watertight_shear`] along its [`Ray::watertight_axes`]), and their sign test.
/// Returns the lanes the sign test cannot reject (signs that agree, or an edge function
/// exactly zero, which [`watertight_edges`] recomputes in `f64`) and that
/// [`hits_outside`](super::hits_outside) does not prove to lie outside `[tmin, tmax]`, as bits, and the sheared
/// coordinates `[ax, ay, bx, by, cx, cy]` of every lane: for such a lane `l`,
/// `tri.finish_watertight(ray, lane_edges(&sheared, l))` is exactly what
/// [`Triangle::intersect_watertight`] returns, and for every other lane that is `None`.
#[inline(always)]
pub fn watertight_lanes<L: SimdLanes>(tris: &TriangleLanes<L>, ray: &Ray) -> (u32, [L::Array; 6]) {
    watertight_rows(
        #[inline(always)]
        |j| tris[j],
        ray,
    )
}

/// [`watertight_lanes`] with coordinate row `j` of the lanes (as in [`TriangleLanes`]) from
/// `row(j)`: a leaf test loads the rows the ray's axes pick straight from its leaf's memory,
/// instead of first storing all nine in an array that the axes index.
#[inline(always)]
pub fn watertight_rows<L: SimdLanes>(row: impl Fn(usize) -> L, ray: &Ray) -> (u32, [L::Array; 6]) {
    let (may_hit, _, lanes) = watertight_rows_at(BaseLevel, row, ray, false);
    (may_hit, lanes)
}

/// [`watertight_rows`] at `level`, whose copy of the out-of-line bounds it calls. With
/// `prove` (any-hit queries with `tmin > 0`), also the lanes among those that may hit whose
/// edge functions agree in sign, none zero, and whose hit [`proven_hit`](super::proven_hit)
/// proves inside the ray's interval (the middle value; 0 without `prove`).
#[inline(always)]
pub(crate) fn watertight_rows_at<L: SimdLanes, V: Level>(
    level: V,
    row: impl Fn(usize) -> L,
    ray: &Ray,
    prove: bool,
) -> (u32, u32, [L::Array; 6]) {
    // The lanes hold one coordinate per row, so the ray's axes pick rows (loads at a
    // run-time offset) and the shear takes two products per vertex, not the six of the dot
    // products with the shear rows that the scalar kernel computes: the same numbers, since
    // the rows' other terms are exact zeros (up to the sign of a zero, which no comparison
    // or later step sees).
    let [kx, ky, kz] = ray.watertight_axes();
    let o = ray.origin().to_array();
    let (ox, oy, oz) = (L::splat(o[kx]), L::splat(o[ky]), L::splat(o[kz]));
    let s = ray.watertight_shear();
    let (sx, sy) = (L::splat(s.x), L::splat(s.y));
    // Written out rather than through closures or `array::from_fn`: a closure that does not
    // inline is a function of its own, compiled for the baseline instruction set inside the
    // AVX2 walks ([`crate::isa`]). `row` inlines (the callers mark it).
    let dz = [row(kz) - oz, row(3 + kz) - oz, row(6 + kz) - oz];
    let (ax, bx, cx) = (
        row(kx) - ox - sx * dz[0],
        row(3 + kx) - ox - sx * dz[1],
        row(6 + kx) - ox - sx * dz[2],
    );
    let (ay, by, cy) = (
        row(ky) - oy - sy * dz[0],
        row(3 + ky) - oy - sy * dz[1],
        row(6 + ky) - oy - sy * dz[2],
    );
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let (neg, pos, on_edge) = L::sign_bits(u, v, w);
    let mut may_hit = (!(neg & pos) | on_edge) & ((1 << L::WIDTH) - 1);
    let mut proven = 0;
    // Rays that leave a surface (shadow rays, bounces, `tmin > 0`) pierce the triangle they
    // start on at `t` near 0, and once a closest hit is found (`tmax` finite) the triangles
    // the ray meets beyond it need no `f64` refinement either: both rejected here in SIMD
    // rather than one by one in `f64`.
    let (tmin, tmax) = (ray.tmin, ray.tmax);
    let (cut_before, cut_after) = (tmin > 0.0, tmax > 0.0 && tmax < f32::INFINITY);
    if may_hit != 0 && (cut_before || cut_after) {
        // Woop's depth estimate `T / D` first (a few operations): only lanes it puts before
        // `tmin` or after `tmax` are worth the rigorous bounds; real hits skip them.
        let sz = L::splat(s.z);
        let z = [dz[0] * sz, dz[1] * sz, dz[2] * sz];
        let e = [u.abs(), v.abs(), w.abs()];
        let num = e[0] * z[0] + e[1] * z[1] + e[2] * z[2];
        let den = e[0] + e[1] + e[2];
        let before = if cut_before {
            L::less_bits(num, L::splat(tmin) * den)
        } else {
            0
        };
        let after = if cut_after {
            L::less_bits(L::splat(tmax) * den, num)
        } else {
            0
        };
        let prove = prove && cut_before;
        if prove || (before | after) & may_hit != 0 {
            let sheared = ShearedLanes {
                x: [ax, bx, cx],
                y: [ay, by, cy],
                dz,
                z,
                edges: e,
                num,
                den,
            };
            let (outside, sure) = level.outside(&sheared, tmin, tmax);
            may_hit &= !outside;
            if prove {
                proven = sure & may_hit & !(neg & pos) & !on_edge;
            }
        }
    }
    // Spelled out: `.map(L::to_lanes)` compiled to a call that copies every lane.
    let lanes = [
        ax.to_lanes(),
        ay.to_lanes(),
        bx.to_lanes(),
        by.to_lanes(),
        cx.to_lanes(),
        cy.to_lanes(),
    ];
    (may_hit, proven, lanes)
}

/// The leaf test of [`crate::test_primitives`] for triangles: the ids that `skip` lets
/// through, four at a time (gathered into [`TriangleLanes`], edge functions and sign test in
/// SIMD lanes, the scalar kernel's own steps for the lanes that pass), the last one to three
/// one by one. Same answers, same order, same `ray.tmax` updates as testing each in turn.
///
/// Lists of fewer than four ids (the leaves of kd-trees, mostly) take the scalar loop inline;
/// longer ones the batched loop, out of line, so that it does not weigh on the callers'
/// traversal loops.
#[inline(always)]
pub(crate) fn test_triangles<const ANY_HIT: bool>(
    tris: &[Triangle],
    ids: &[u32],
    ray: &mut Ray,
    best: &mut impl Keep,
    skip: impl FnMut(u32) -> bool,
) -> bool {
    if ids.len() < 4 {
        crate::ray::test_each::<Triangle, ANY_HIT>(tris, ids, ray, best, skip)
    } else {
        test_in_batches::<ANY_HIT>(tris, ids, ray, best, skip)
    }
}

/// [`test_triangles`] four at a time.
#[inline(never)]
fn test_in_batches<const ANY_HIT: bool>(
    tris: &[Triangle],
    ids: &[u32],
    ray: &mut Ray,
    best: &mut impl Keep,
    mut skip: impl FnMut(u32) -> bool,
) -> bool {
    if !ray.is_valid() {
        return false;
    }
    let mut batch = [0u32; 4];
    let mut n = 0;
    for &p in ids {
        if skip(p) || best.skips(p) {
            continue;
        }
        batch[n] = p;
        n += 1;
        if n == 4 {
            n = 0;
            crate::counters::prims(4);
            let lanes: [&Triangle; 4] = batch.map(|p| &tris[p as usize]);
            let w: TriangleLanes =
                std::array::from_fn(|j| f32x4::from(lanes.map(|t| t.v[j / 3][j % 3])));
            let (mut may_hit, sheared) = watertight_lanes(&w, ray);
            while may_hit != 0 {
                let l = may_hit.trailing_zeros() as usize;
                may_hit &= may_hit - 1;
                let edges = lane_edges(&sheared, l);
                if let Some(h) = lanes[l].finish_watertight(ray, edges) {
                    if best.keep::<ANY_HIT>(h, batch[l], &mut ray.tmax) {
                        return true;
                    }
                }
            }
        }
    }
    crate::counters::prims(n as u32);
    for &p in &batch[..n] {
        if let Some(h) = tris[p as usize].intersect_watertight(ray) {
            if best.keep::<ANY_HIT>(h, p, &mut ray.tmax) {
                return true;
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// The four-lane leaf test against the scalar one: same hit, same `tmax`, same any-hit
    /// answer, on a grid of triangles sharing edges and vertices (rays through them), with
    /// degenerate and duplicated triangles, skipped ids, and every batch remainder.
    #[test]
    fn lanes_test_equals_one_at_a_time() {
        let mut tris = Vec::new();
        for i in 0..6 {
            for j in 0..6 {
                let p = Vec3::new(i as f32, j as f32, 0.25 * ((i + j) % 3) as f32);
                let (px, py) = (p + Vec3::X, p + Vec3::Y);
                tris.push(Triangle::new(p, px, py));
                tris.push(Triangle::new(px, px + Vec3::Y, py));
            }
        }
        tris.push(Triangle::new(Vec3::ONE, Vec3::ONE, Vec3::ONE)); // a point
        tris.push(Triangle::new(Vec3::ZERO, Vec3::X, Vec3::X * 2.0)); // a segment
        tris.push(tris[7]); // a duplicate
        let mut seed = 7u64;
        let mut rnd = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut hits = 0;
        for case in 0..4000 {
            // Origins on a lattice (rays through shared vertices and edges) or anywhere.
            let o = if case % 3 == 0 {
                Vec3::new((rnd() * 6.0).floor(), (rnd() * 6.0).floor(), 2.0)
            } else {
                Vec3::new(rnd() * 7.0 - 0.5, rnd() * 7.0 - 0.5, rnd() * 4.0 - 1.0)
            };
            let d = Vec3::new(rnd() - 0.5, rnd() - 0.5, -rnd());
            let d = if case % 5 == 0 { -Vec3::Z } else { d };
            let mut ray = Ray::new(o, d);
            if case % 7 == 0 {
                ray.tmax = rnd() * 3.0;
            }
            let n = case % (tris.len() + 1);
            let ids: Vec<u32> = (0..n as u32).rev().collect();
            let skip = |p: u32| case % 4 == 0 && p % 5 == 1;
            let (mut r1, mut r2) = (ray, ray);
            let (mut b1, mut b2) = (None, None);
            let a1 = test_triangles::<false>(&tris, &ids, &mut r1, &mut b1, skip);
            let a2 = crate::ray::test_each::<Triangle, false>(&tris, &ids, &mut r2, &mut b2, skip);
            assert_eq!((a1, b1, r1.tmax), (a2, b2, r2.tmax), "case {case}");
            hits += b1.is_some() as usize;
            let (mut r1, mut r2) = (ray, ray);
            let (mut b1, mut b2) = (None, None);
            let a1 = test_triangles::<true>(&tris, &ids, &mut r1, &mut b1, skip);
            let a2 = crate::ray::test_each::<Triangle, true>(&tris, &ids, &mut r2, &mut b2, skip);
            assert_eq!((a1, b1), (a2, b2), "case {case} (any hit)");
        }
        assert!(hits > 500, "{hits} hits: the rays must meet the triangles");
    }
}
