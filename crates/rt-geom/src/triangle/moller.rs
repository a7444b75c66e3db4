//! The Möller–Trumbore kernel ([`TriangleKernel::MollerTrumbore`](super::TriangleKernel)):
//! one arithmetic for a single triangle and for lanes of them, so that a leaf test of eight
//! triangles at once answers bit for bit what [`Triangle::intersect_moller_trumbore`] does,
//! and the depth it reports held in the triangle's box, so that every structure that culls by
//! box finds the hits brute force finds.

use super::Triangle;
use super::simd::SimdLanes;
use crate::{PrimHit, Ray};
use glam::DVec3;

/// The Möller–Trumbore test (Möller & Trumbore 1997, no epsilon; in the form Embree's
/// kernel takes, the determinant and the depth from the triangle's normal) of the triangles
/// whose coordinate row `j` of `[v0.x, v0.y, v0.z, v1.x, .., v2.z]` is `row(j)` (one
/// triangle per lane), against `ray`'s line: the bits of the lanes whose barycentrics it
/// accepts (their numerators of the determinant's sign, or zero, and their sum no larger than
/// it, a nonzero determinant; false wherever a value is NaN) and per lane the numbers that
/// give `[t, u, v]` in `f32` ([`MollerLanes::values`]). Every lane's numbers are the same
/// sequence of IEEE operations whatever the lanes' width (a single `f32` included). The depth
/// `t` is not checked against the ray's interval here: the depth a hit reports is `t` only
/// where the triangle's box holds it ([`Triangle::moller_trumbore_hit`]).
#[inline(always)]
pub(crate) fn moller_trumbore_rows<L: SimdLanes>(
    row: impl Fn(usize) -> L,
    ray: &Ray,
) -> (u32, MollerLanes<L>) {
    #[inline(always)]
    fn cross<L: SimdLanes>(a: &[L; 3], b: &[L; 3]) -> [L; 3] {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }
    #[inline(always)]
    fn dot<L: SimdLanes>(a: &[L; 3], b: &[L; 3]) -> L {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }
    let (o, d) = (ray.origin().to_array(), ray.dir().to_array());
    let v0 = [row(0), row(1), row(2)];
    let e1 = [row(3) - v0[0], row(4) - v0[1], row(5) - v0[2]];
    let e2 = [row(6) - v0[0], row(7) - v0[1], row(8) - v0[2]];
    let d = [L::splat(d[0]), L::splat(d[1]), L::splat(d[2])];
    let c = [
        v0[0] - L::splat(o[0]),
        v0[1] - L::splat(o[1]),
        v0[2] - L::splat(o[2]),
    ];
    // The depth from the plane through `v0` with the normal `n` that the determinant uses
    // too: their roundings of `n` cancel in the quotient, so the depth's point lies on the
    // triangle's plane within a few units in the last place (a flat box holds it).
    let n = cross(&e1, &e2);
    let r = cross(&c, &d);
    let det = dot(&d, &n);
    let (u, v_neg, t) = (dot(&r, &e2), dot(&r, &e1), dot(&c, &n));
    // The barycentrics' signs and sum against the determinant's, before any division, with
    // the determinant's sign folded in (exact negations): a determinant `d >= m` accepts
    // `0 <= u`, `0 <= v`, `u + v <= d`, one `d <= -m` accepts `u <= 0`, `v <= 0`, `d <= u + v`,
    // where `m` is the least normal float (below it the reciprocal is not finite), and
    // anything NaN accepts nothing.
    let (zero, uv) = (L::splat(0.0), u - v_neg);
    let v = zero - v_neg;
    let abs_det = det.abs();
    let inside = L::le_bits(zero, u.sign_of(det))
        & L::le_bits(zero, v.sign_of(det))
        & L::le_bits(uv.sign_of(det), abs_det)
        & L::le_bits(L::splat(f32::MIN_POSITIVE), abs_det);
    (inside & ((1 << L::WIDTH) - 1), MollerLanes { det, u, v, t })
}

/// [`moller_trumbore_rows`]' numbers per lane before the division by the determinant.
pub(crate) struct MollerLanes<L> {
    det: L,
    u: L,
    v: L,
    t: L,
}

impl<L: SimdLanes> MollerLanes<L> {
    /// `[t, u, v]`: each numerator times the determinant's reciprocal.
    #[inline(always)]
    pub(crate) fn values(&self) -> [L; 3] {
        let inv = L::splat(1.0) / self.det;
        [self.t * inv, self.u * inv, self.v * inv]
    }
}

/// The lanes (triangles as in [`moller_trumbore_rows`]) whose hit cannot lie in the ray's
/// interval: a depth held in a triangle's box ([`crate::Aabb::holds_hit`]) lies, on every axis
/// the ray moves along, between the ray parameters at which it meets the vertices'
/// coordinates (by a margin), and these spans miss the interval or each other (the triangle
/// beyond the interval or behind it, or a box the ray passes). A filter only: sound for every
/// lane, deciding some. On a flat box (a triangle in a plane of constant coordinate, as walls
/// and floors are) it rules out the triangle a ray leaves.
#[inline(always)]
pub(crate) fn moller_trumbore_span<L: SimdLanes>(row: impl Fn(usize) -> L, ray: &Ray) -> u32 {
    let (o, d) = (ray.origin().to_array(), ray.dir().to_array());
    // Each parameter is two roundings (a relative 2^-23 at most, three with the reciprocal);
    // a held depth lies within half the box tests' padding (about 2^-22.6) of the box along
    // each axis: 2^-19 covers both several times over.
    let m = L::splat(1.0 / (1 << 19) as f32);
    let (mut lo, mut hi) = (L::splat(f32::NEG_INFINITY), L::splat(f32::INFINITY));
    for k in 0..3 {
        let inv = 1.0 / d[k];
        if !inv.is_finite() {
            // An axis the ray does not move along (or barely): it bounds no parameter.
            continue;
        }
        let (o, inv) = (L::splat(o[k]), L::splat(inv));
        let z = [
            (row(k) - o) * inv,
            (row(3 + k) - o) * inv,
            (row(6 + k) - o) * inv,
        ];
        let (zl, zh) = (z[0].min(z[1]).min(z[2]), z[0].max(z[1]).max(z[2]));
        lo = lo.max(zl - zl.abs() * m);
        hi = hi.min(zh + zh.abs() * m);
    }
    let (tmin, tmax) = (L::splat(ray.tmin), L::splat(ray.tmax));
    L::less_bits(hi, tmin) | L::less_bits(tmax, lo) | L::less_bits(hi, lo)
}

/// The lanes (triangles as in [`moller_trumbore_rows`]) whose depth `t` the triangle's box
/// surely holds ([`crate::Aabb::holds_hit`] true): the point `o + d t` inside the box by a
/// margin on every axis, in `f32` with room for its roundings. A lane it leaves out may still
/// be held (the scalar check decides); flat boxes never pass.
#[inline(always)]
pub(crate) fn moller_trumbore_held<L: SimdLanes>(row: impl Fn(usize) -> L, ray: &Ray, t: L) -> u32 {
    let (o, d) = (ray.origin().to_array(), ray.dir().to_array());
    // Every value below is one or two roundings of its exact counterpart (a relative 2^-23
    // at most); the margins, 2^-20 of each magnitude, cover them and the roundings of the
    // margins themselves several times over.
    let m = L::splat(1.0 / (1 << 20) as f32);
    let mut held = u32::MAX;
    for k in 0..3 {
        let (a, b, c) = (row(k), row(3 + k), row(6 + k));
        let o = L::splat(o[k]);
        let (lo, hi) = (a.min(b).min(c) - o, a.max(b).max(c) - o);
        let step = L::splat(d[k]) * t;
        let (step_lo, step_hi) = (step - step.abs() * m, step + step.abs() * m);
        held &= L::le_bits(lo + lo.abs() * m, step_lo) & L::le_bits(step_hi, hi - hi.abs() * m);
    }
    held
}

impl Triangle {
    /// Möller & Trumbore 1997, no epsilon: fast, not watertight (a ray can slip through an
    /// edge two triangles share, or hit both). The barycentrics and the depth are computed in
    /// `f32` (the same operations a leaf test of eight lanes runs); a depth whose point lies
    /// outside the triangle's box by more than half the box tests' padding
    /// ([`crate::Aabb::holds_hit`]: the `f32` normal of a sliver, whose products cancel,
    /// tilts the plane the depth lies on) is recomputed in `f64` and held in the box, as the
    /// watertight kernel's are, so that every structure agrees
    /// with brute force on this kernel too. The depth so held decides whether the hit lies in
    /// the ray's interval. Zero-area triangles never hit.
    #[inline]
    pub fn intersect_moller_trumbore(&self, ray: &Ray) -> Option<PrimHit> {
        if !ray.is_valid() || self.is_degenerate() {
            return None;
        }
        let c = |j: usize| self.v[j / 3][j % 3];
        let (inside, lanes) = moller_trumbore_rows::<f32>(c, ray);
        if inside == 0 {
            return None;
        }
        let [t, u, v] = lanes.values();
        self.moller_trumbore_hit(ray, t, u, v)
    }

    /// The hit of this triangle (of nonzero area) whose barycentrics
    /// [`moller_trumbore_rows`] accepted, with its `f32` values `(t, u, v)`: the depth held in
    /// the triangle's box, and `None` where that lies outside the ray's interval.
    #[inline(always)]
    pub(crate) fn moller_trumbore_hit(&self, ray: &Ray, t: f32, u: f32, v: f32) -> Option<PrimHit> {
        let t = if self.bounds().holds_hit(ray, t) {
            t
        } else {
            self.moller_trumbore_moved(ray)?
        };
        ray.in_range(t).then_some(PrimHit { t, u, v })
    }

    /// The depth of [`Self::moller_trumbore_hit`] where the `f32` one is not held: computed
    /// in `f64` from the same `f32` inputs, then held in the box ([`Self::held_in_box`]).
    #[cold]
    #[inline(never)]
    fn moller_trumbore_moved(&self, ray: &Ray) -> Option<f32> {
        let [a, b, c] = self.v.map(|p| p.as_dvec3());
        let (o, d): (DVec3, DVec3) = (ray.origin().as_dvec3(), ray.dir().as_dvec3());
        let (e1, e2) = (b - a, c - a);
        let depth = e2.dot((o - a).cross(e1)) / e1.dot(d.cross(e2));
        self.held_in_box(ray, if depth.is_finite() { depth } else { 0.0 })
    }
}
