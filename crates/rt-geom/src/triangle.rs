//! Triangles: the watertight ray/triangle test (reference kernel), Möller–Trumbore (option),
//! and clipping to a box (for perfect kd-tree splits).

use crate::{Aabb, Hit, PrimHit, Ray, keep_hit};
use glam::{DVec3, Vec3};
use wide::f32x4;

/// A triangle given by its three vertices.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Triangle {
    /// The three vertices; their order gives the geometric normal.
    pub v: [Vec3; 3],
}

/// Which ray/triangle kernel to run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum TriangleKernel {
    /// Woop, Benthin & Wald, "Watertight Ray/Triangle Intersection", JCGT 2013. No ray passes
    /// through a shared edge or vertex of a closed mesh; no epsilon.
    #[default]
    Watertight,
    /// Möller & Trumbore 1997: fast, not watertight (rays can slip through shared edges).
    MollerTrumbore,
}

impl Triangle {
    /// The triangle `v0, v1, v2`.
    #[inline]
    pub const fn new(v0: Vec3, v1: Vec3, v2: Vec3) -> Self {
        Self { v: [v0, v1, v2] }
    }

    /// `(v1 - v0) x (v2 - v0)`: twice the area, along the geometric normal.
    #[inline]
    pub fn cross(&self) -> Vec3 {
        (self.v[1] - self.v[0]).cross(self.v[2] - self.v[0])
    }

    /// Unit geometric normal (zero for a zero-area triangle).
    #[inline]
    pub fn normal(&self) -> Vec3 {
        self.cross().normalize_or_zero()
    }

    /// Area.
    #[inline]
    pub fn area(&self) -> f32 {
        0.5 * self.cross().length()
    }

    /// Zero area, in `f32` and in `f64` (tiny triangles, whose `f32` cross product
    /// underflows, keep their area): such triangles are kept but never hit.
    #[inline]
    pub fn is_degenerate(&self) -> bool {
        self.cross() == Vec3::ZERO && {
            let [a, b, c] = self.v.map(|p| p.as_dvec3());
            (b - a).cross(c - a) == DVec3::ZERO
        }
    }

    /// The box around the three vertices.
    #[inline]
    pub fn bounds(&self) -> Aabb {
        Aabb::new(
            self.v[0].min(self.v[1]).min(self.v[2]),
            self.v[0].max(self.v[1]).max(self.v[2]),
        )
    }

    /// The mean of the vertices.
    #[inline]
    pub fn centroid(&self) -> Vec3 {
        (self.v[0] + self.v[1] + self.v[2]) * (1.0 / 3.0)
    }

    /// The point at barycentric `(u, v)`.
    #[inline]
    pub fn point(&self, u: f32, v: f32) -> Vec3 {
        self.v[0] * (1.0 - u - v) + self.v[1] * u + self.v[2] * v
    }

    /// The hit of `ray` by the chosen kernel.
    #[inline]
    pub fn intersect_with(&self, ray: &Ray, kernel: TriangleKernel) -> Option<PrimHit> {
        match kernel {
            TriangleKernel::Watertight => self.intersect_watertight(ray),
            TriangleKernel::MollerTrumbore => self.intersect_moller_trumbore(ray),
        }
    }

    /// The watertight test of Woop, Benthin & Wald (JCGT 2013), the reference kernel.
    ///
    /// The triangle is translated to the ray origin, sheared so that the ray runs along +z, and
    /// the signs of the 2D edge functions `U, V, W` decide the hit (a zero edge function is
    /// recomputed in `f64`, as in the paper), so hits on shared edges are decided the same way
    /// for both triangles. Hits exactly on an edge or vertex count. Zero-area triangles never
    /// hit.
    ///
    /// Where the edge tests accept, `t` is computed in `f64` from the plane equation
    /// ([`Self::refine`]). In `f32`, the paper's `t = (U az + V bz + W cz) / (U + V + W)` loses
    /// most of its digits on thin slivers, whose edge functions cancel: a sliver of the test
    /// scenes reports a hit 5e-5 (relative) before its own plane and before its bounding box,
    /// where no box-culling structure can agree with brute force. In `f64` the error stays far
    /// below the padding of [`Aabb::clip_ray`], so every structure that culls by box entry
    /// agrees exactly.
    #[inline]
    pub fn intersect_watertight(&self, ray: &Ray) -> Option<PrimHit> {
        if !ray.is_valid() {
            return None;
        }
        let [mx, my] = ray.watertight_rows();
        let o = ray.origin();
        let a = self.v[0] - o;
        let b = self.v[1] - o;
        let c = self.v[2] - o;
        // a[kx] - Sx a[kz] and a[ky] - Sy a[kz], as dot products with exact zero terms (a
        // `Vec3` indexed by a run-time axis costs more than the products).
        let sheared = [
            a.dot(*mx),
            a.dot(*my),
            b.dot(*mx),
            b.dot(*my),
            c.dot(*mx),
            c.dot(*my),
        ];
        self.finish_watertight(ray, watertight_edges(sheared))
    }

    /// The rest of the watertight test once the edge functions `(U, V, W)` are known (from
    /// [`watertight_edges`]): the sign test, the zero-area rejections and [`Self::refine`].
    /// SIMD kernels compute the edge functions lane by lane with the same arithmetic and call
    /// this for the lanes that pass, so that they report exactly what the scalar kernel does.
    ///
    /// The sign test (which rejects most triangles a traversal tries) is inlined into the
    /// caller; the rest runs out of line, only for the triangles it accepts.
    #[inline(always)]
    pub fn finish_watertight(&self, ray: &Ray, (u, v, w): (f32, f32, f32)) -> Option<PrimHit> {
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        self.finish_accepted(ray, (u, v, w))
    }

    /// [`Self::finish_watertight`] once the edge functions agree in sign. Where the `f32` edge
    /// functions decide nothing (they all underflow to zero, for tiny triangles, or overflow,
    /// for vertices near the largest floats), the `f64` ones decide alone.
    #[inline(never)]
    fn finish_accepted(&self, ray: &Ray, (u, v, w): (f32, f32, f32)) -> Option<PrimHit> {
        if self.is_degenerate() {
            return None;
        }
        let sum = u + v + w;
        if sum == 0.0 || !sum.is_finite() {
            return self.refine_in_f64(ray);
        }
        self.refine(ray, (u, v, w))
    }

    /// Distance of a hit that the edge tests accepted, in `f64` from the `f32` inputs, with
    /// the barycentrics `(u, v) = (V, W) / (U + V + W)` of those tests: `None` when the hit
    /// degenerates or `t` is outside `[tmin, tmax]`. SIMD kernels call this on their candidate
    /// hits to report bit-identical answers.
    ///
    /// `t` is the depth of the point of the triangle that the ray meets, computed so that the
    /// point lies *in the triangle* (to `f64` rounding), which is what lets every structure
    /// find the hit in the cells and boxes that hold the triangle:
    /// - the edge functions are recomputed in `f64` in the ray's exact shear (the inputs are
    ///   `f32`: vertex minus origin is exact, each product rounded once); when all three agree
    ///   the ray pierces the triangle, and `t = (U za + V zb + W zc) / (U + V + W)` with
    ///   `z = (p - o)[kz] / d[kz]` (the depth interpolation of Woop et al., exact here where in
    ///   `f32` it loses most digits on thin slivers);
    /// - when they do not (the `f32` test accepted a ray that passes a rounding error outside
    ///   an edge or vertex, typically grazing the plane, where the plane equation would put the
    ///   hit far along the ray, outside the triangle's box), `t` is the ray parameter of the
    ///   point of the ray closest to the triangle's boundary.
    #[inline]
    pub fn refine(&self, ray: &Ray, (u, v, w): (f32, f32, f32)) -> Option<PrimHit> {
        let orient = if u + v + w < 0.0 { -1.0 } else { 1.0 };
        let edges = self.edges_in_f64(ray, orient);
        let t = match edges.depth() {
            Some(t) => t as f32,
            None => self.closest_on_boundary(ray.origin().as_dvec3(), ray.dir().as_dvec3())? as f32,
        };
        if !ray.in_range(t) {
            return None;
        }
        let rcp = 1.0 / (u + v + w);
        let (bu, bv) = (v * rcp, w * rcp);
        // An `f32` sum that underflows to a subnormal makes `rcp` infinite: such hits take
        // the `f64` barycentrics.
        let (u, v) = if bu.is_finite() && bv.is_finite() {
            (bu, bv)
        } else {
            edges.barycentrics()
        };
        Some(PrimHit { t, u, v })
    }

    /// The watertight test decided by the `f64` edge functions alone (no `f32` test to
    /// follow to the boundary): a hit when they agree in sign, with their barycentrics.
    fn refine_in_f64(&self, ray: &Ray) -> Option<PrimHit> {
        let mut edges = self.edges_in_f64(ray, 1.0);
        if edges.e.iter().sum::<f64>() < 0.0 {
            edges.e = edges.e.map(|e| -e);
        }
        let t = edges.depth()? as f32;
        if !ray.in_range(t) {
            return None;
        }
        let (u, v) = edges.barycentrics();
        Some(PrimHit { t, u, v })
    }

    /// The edge functions `(U, V, W)` times `orient`, in `f64` from the `f32` inputs in the
    /// ray's exact shear (vertex minus origin is exact, each product rounded once), and the
    /// vertices' depths along the ray.
    fn edges_in_f64(&self, ray: &Ray, orient: f64) -> EdgesF64 {
        // Coordinates as arrays indexed by the ray's axes (one load each; a `DVec3` indexed
        // at run time branches on the index).
        let [kx, ky, kz] = ray.watertight_axes();
        let da = ray.dir().as_dvec3().to_array();
        let (sx, sy, sz) = (da[kx] / da[kz], da[ky] / da[kz], 1.0 / da[kz]);
        let o = ray.origin().as_dvec3();
        let shear = |p: Vec3| {
            let p = (p.as_dvec3() - o).to_array();
            (p[kx] - sx * p[kz], p[ky] - sy * p[kz], p[kz] * sz)
        };
        let (ax, ay, az) = shear(self.v[0]);
        let (bx, by, bz) = shear(self.v[1]);
        let (cx, cy, cz) = shear(self.v[2]);
        EdgesF64 {
            e: [
                (cx * by - cy * bx) * orient,
                (ax * cy - ay * cx) * orient,
                (bx * ay - by * ax) * orient,
            ],
            z: [az, bz, cz],
        }
    }

    /// The parameter `s` of the point of the line `o + s d` closest to the triangle's edges.
    fn closest_on_boundary(&self, o: DVec3, d: DVec3) -> Option<f64> {
        let a = d.dot(d);
        if !(a > 0.0) {
            return None;
        }
        let mut best: Option<(f64, f64)> = None;
        for i in 0..3 {
            let p = self.v[i].as_dvec3();
            let e = self.v[(i + 1) % 3].as_dvec3() - p;
            let w0 = o - p;
            let (b, c, dd, ee) = (d.dot(e), e.dot(e), d.dot(w0), e.dot(w0));
            let den = a * c - b * b;
            let tau = if den > 0.0 {
                ((a * ee - b * dd) / den).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let q = p + e * tau;
            let s = (q - o).dot(d) / a;
            let dist = (o + d * s - q).length_squared();
            if best.is_none_or(|(bd, _)| dist < bd) {
                best = Some((dist, s));
            }
        }
        best.map(|(_, s)| s)
    }

    /// Möller & Trumbore 1997 (no epsilon: only an exactly zero determinant is rejected).
    #[inline]
    pub fn intersect_moller_trumbore(&self, ray: &Ray) -> Option<PrimHit> {
        if !ray.is_valid() {
            return None;
        }
        let e1 = self.v[1] - self.v[0];
        let e2 = self.v[2] - self.v[0];
        let p = ray.dir().cross(e2);
        let det = e1.dot(p);
        if det == 0.0 || det.is_nan() {
            return None;
        }
        let inv = 1.0 / det;
        let tv = ray.origin() - self.v[0];
        let u = tv.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = tv.cross(e1);
        let v = ray.dir().dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = e2.dot(q) * inv;
        if !ray.in_range(t) || self.is_degenerate() {
            return None;
        }
        Some(PrimHit { t, u, v })
    }

    /// Bounds of the part of the triangle inside `clip` (Sutherland–Hodgman against the six
    /// planes), or an empty box. New vertices on a clipping plane are put exactly on it, so the
    /// result never pokes out of `clip`; the result is also limited to the triangle's bounds.
    pub fn clipped_bounds(&self, clip: &Aabb) -> Aabb {
        let bounds = self.bounds();
        if clip.contains(&bounds) {
            return bounds;
        }
        // A triangle clipped by six planes has at most 9 vertices: fixed arrays, no allocation.
        let mut poly = [DVec3::ZERO; 9];
        let mut len = 3;
        for (slot, p) in poly.iter_mut().zip(self.v) {
            *slot = p.as_dvec3();
        }
        let mut next = [DVec3::ZERO; 9];
        for axis in 0..3 {
            for (plane, keep_above) in [(clip.min[axis], true), (clip.max[axis], false)] {
                let plane = plane as f64;
                let inside = |p: &DVec3| {
                    if keep_above {
                        p[axis] >= plane
                    } else {
                        p[axis] <= plane
                    }
                };
                let mut n = 0;
                for i in 0..len {
                    let p = poly[i];
                    let q = poly[(i + 1) % len];
                    let (pin, qin) = (inside(&p), inside(&q));
                    if pin {
                        next[n] = p;
                        n += 1;
                    }
                    if pin != qin {
                        let s = (plane - p[axis]) / (q[axis] - p[axis]);
                        let mut x = p + (q - p) * s;
                        x[axis] = plane;
                        next[n] = x;
                        n += 1;
                    }
                }
                std::mem::swap(&mut poly, &mut next);
                len = n;
                if len == 0 {
                    return Aabb::EMPTY;
                }
            }
        }
        let mut out = Aabb::EMPTY;
        for p in &poly[..len] {
            // Round outwards so that the f32 box still contains the f64 polygon.
            let lo = p.as_vec3();
            let lo = Vec3::select(lo.as_dvec3().cmpgt(*p), next_down(lo), lo);
            let hi = p.as_vec3();
            let hi = Vec3::select(hi.as_dvec3().cmplt(*p), next_up(hi), hi);
            out.min = out.min.min(lo);
            out.max = out.max.max(hi);
        }
        out.intersection(*clip).intersection(bounds)
    }
}

/// Edge functions and vertex depths of a triangle in a ray's shear, in `f64`.
struct EdgesF64 {
    e: [f64; 3],
    z: [f64; 3],
}

impl EdgesF64 {
    /// The depth `(U za + V zb + W zc) / (U + V + W)` of the point the ray meets, when the
    /// edge functions say it pierces the triangle (all `>= 0`, sum `> 0`): a convex
    /// combination of the vertices' depths, so the point lies in the triangle's box.
    fn depth(&self) -> Option<f64> {
        let [e0, e1, e2] = self.e;
        let sum = e0 + e1 + e2;
        (e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0 && sum > 0.0)
            .then(|| (e0 * self.z[0] + e1 * self.z[1] + e2 * self.z[2]) / sum)
    }

    /// The barycentrics `(V, W) / (U + V + W)` of the edge functions clamped to `>= 0` (the
    /// point of the triangle nearest the ray where they disagree in sign); `(0, 0)` when all
    /// vanish.
    fn barycentrics(&self) -> (f32, f32) {
        let [e0, e1, e2] = self.e.map(|e| e.max(0.0));
        let sum = e0 + e1 + e2;
        if sum > 0.0 {
            ((e1 / sum) as f32, (e2 / sum) as f32)
        } else {
            (0.0, 0.0)
        }
    }
}

/// The 2D edge functions `(U, V, W)` of the watertight test from the sheared vertex
/// coordinates `[ax, ay, bx, by, cx, cy]` (vertex minus ray origin, sheared by
/// [`Ray::watertight_shear`]: `p[kx] - Sx p[kz]`, `p[ky] - Sy p[kz]`). An edge function that
/// is exactly zero in `f32` is recomputed, with the other two, in `f64`, as Woop, Benthin &
/// Wald prescribe for edges hit exactly.
#[inline]
pub fn watertight_edges([ax, ay, bx, by, cx, cy]: [f32; 6]) -> (f32, f32, f32) {
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if u == 0.0 || v == 0.0 || w == 0.0 {
        let (ax, ay, bx, by, cx, cy) = (
            ax as f64, ay as f64, bx as f64, by as f64, cx as f64, cy as f64,
        );
        return (
            (cx * by - cy * bx) as f32,
            (ax * cy - ay * cx) as f32,
            (bx * ay - by * ax) as f32,
        );
    }
    (u, v, w)
}

/// The SIMD vectors the triangle lane kernel runs on: four lanes (`wide::f32x4`, SSE) or
/// eight (`wide::f32x8`: one AVX register in builds for such CPUs, two SSE registers
/// elsewhere). Only what [`watertight_lanes`] needs.
pub trait SimdLanes:
    Copy + std::ops::Add<Output = Self> + std::ops::Sub<Output = Self> + std::ops::Mul<Output = Self>
{
    /// Number of lanes.
    const WIDTH: usize;
    /// The lanes as an array.
    type Array: Copy + std::ops::Index<usize, Output = f32>;
    /// Every lane `x`.
    fn splat(x: f32) -> Self;
    /// Lanes from `WIDTH` consecutive floats.
    fn load(src: &[f32]) -> Self;
    /// The lanes as an array.
    fn to_lanes(self) -> Self::Array;
    /// Bits of the lanes where some of `a`, `b`, `c` is below zero, above zero, zero.
    fn sign_bits(a: Self, b: Self, c: Self) -> (u32, u32, u32);
    /// Lane-wise absolute value.
    fn abs(self) -> Self;
    /// Lane-wise maximum (either lane when one is NaN).
    fn max(self, other: Self) -> Self;
    /// Lane-wise minimum (either lane when one is NaN).
    fn min(self, other: Self) -> Self;
    /// Bits of the lanes where `a < b` (false for NaN).
    fn less_bits(a: Self, b: Self) -> u32;
}

macro_rules! simd_lanes {
    ($t:ty, $n:expr) => {
        impl SimdLanes for $t {
            const WIDTH: usize = $n;
            type Array = [f32; $n];
            #[inline(always)]
            fn splat(x: f32) -> Self {
                <$t>::splat(x)
            }
            #[inline(always)]
            fn load(src: &[f32]) -> Self {
                let a: [f32; $n] = src[..$n].try_into().expect("WIDTH floats");
                <$t>::from(a)
            }
            #[inline(always)]
            fn to_lanes(self) -> [f32; $n] {
                self.to_array()
            }
            #[inline(always)]
            fn sign_bits(a: Self, b: Self, c: Self) -> (u32, u32, u32) {
                use wide::{CmpEq, CmpGt, CmpLt};
                let z = <$t>::ZERO;
                (
                    (a.cmp_lt(z) | b.cmp_lt(z) | c.cmp_lt(z)).move_mask() as u32,
                    (a.cmp_gt(z) | b.cmp_gt(z) | c.cmp_gt(z)).move_mask() as u32,
                    (a.cmp_eq(z) | b.cmp_eq(z) | c.cmp_eq(z)).move_mask() as u32,
                )
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline(always)]
            fn max(self, other: Self) -> Self {
                self.fast_max(other)
            }
            #[inline(always)]
            fn min(self, other: Self) -> Self {
                self.fast_min(other)
            }
            #[inline(always)]
            fn less_bits(a: Self, b: Self) -> u32 {
                use wide::CmpLt;
                a.cmp_lt(b).move_mask() as u32
            }
        }
    };
}
simd_lanes!(f32x4, 4);

/// One lane: the scalar form of the lane kernels' bounds ([`proven_hit`]).
impl SimdLanes for f32 {
    const WIDTH: usize = 1;
    type Array = [f32; 1];
    #[inline(always)]
    fn splat(x: f32) -> Self {
        x
    }
    #[inline(always)]
    fn load(src: &[f32]) -> Self {
        src[0]
    }
    #[inline(always)]
    fn to_lanes(self) -> [f32; 1] {
        [self]
    }
    #[inline(always)]
    fn sign_bits(a: Self, b: Self, c: Self) -> (u32, u32, u32) {
        (
            (a < 0.0 || b < 0.0 || c < 0.0) as u32,
            (a > 0.0 || b > 0.0 || c > 0.0) as u32,
            (a == 0.0 || b == 0.0 || c == 0.0) as u32,
        )
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
    #[inline(always)]
    fn max(self, other: Self) -> Self {
        f32::max(self, other)
    }
    #[inline(always)]
    fn min(self, other: Self) -> Self {
        f32::min(self, other)
    }
    #[inline(always)]
    fn less_bits(a: Self, b: Self) -> u32 {
        (a < b) as u32
    }
}
simd_lanes!(wide::f32x8, 8);

/// Triangles in SIMD lanes (four by default): coordinate `j` of `[v0.x, v0.y, v0.z, v1.x,
/// .., v2.z]` in vector `j`, lane `l` holding triangle `l`.
pub type TriangleLanes<L = f32x4> = [L; 9];

/// A triangle per lane in the watertight test's sheared frame: per vertex the sheared `x`
/// and `y`, the depth `v[kz] - o[kz]` before and after scaling by the shear's `sz` (`dz`,
/// `z`), the absolute edge functions (`|U|`, `|V|`, `|W|`), and Woop's depth estimate
/// `num / den` from them (`num = |U| za + |V| zb + |W| zc`, `den = |U| + |V| + |W|`), all as
/// computed in `f32`.
pub struct ShearedLanes<L> {
    /// Sheared `x` per vertex.
    pub x: [L; 3],
    /// Sheared `y` per vertex.
    pub y: [L; 3],
    /// Depth `v[kz] - o[kz]` per vertex, before scaling.
    pub dz: [L; 3],
    /// Depth per vertex scaled by the shear's `sz`.
    pub z: [L; 3],
    /// Absolute edge functions `|U|`, `|V|`, `|W|`.
    pub edges: [L; 3],
    /// Numerator of Woop's depth estimate.
    pub num: L,
    /// Denominator of Woop's depth estimate.
    pub den: L,
}

/// The lanes whose hit, if [`Triangle::refine`] found one, would certainly lie before `tmin`
/// (`tmin > 0`), so that it returns `None`: decided from the `f32` numbers with the error
/// bounds of Pharr, Jakob & Humphreys (pbrt-v4, `IntersectTriangle`, the bounds that keep
/// `t > 0`), each taken twice over.
///
/// - A lane qualifies only when every edge function exceeds its error bound `dE`: the exact
///   edge functions then agree in sign, `refine` takes its interpolating branch, and its `t`
///   is the exact `T / D` to `f64` rounding, `T = |U| za + |V| zb + |W| zc` and `D = |U| +
///   |V| + |W|` (the absolute values flip both by the common sign).
/// - The bounds: sheared `x`, `y` off by `gamma(8) (max |x| + max |dz|)` (the subtraction,
///   the shear product, the `f32` rounding of the shear constant, `|sx| <= 1`), the depths
///   `z = dz sz` by `gamma(4) max |z|`, each edge function (two products, a difference) by
///   `dE = 4 (gamma(2) max|x| max|y| + dY max|x| + dX max|y|)`, `T` by
///   `dT = 3 (gamma(3) max|e| max|z| + dE max|z| + dZ max|e|)`, `D` by `3 gamma(2) max|e| + 3 dE`.
/// - Culled when `T + 2 dT < tmin (D - 2 dD) (1 - 2^-20)`: the exact `T / D` lies below `tmin`
///   by more than the `f64` evaluation and its rounding to `f32` can move it.
///
/// NaN or infinite inputs fail the comparisons: such lanes are never culled. Out of line:
/// [`watertight_lanes`] asks only for rays with `tmin > 0` and lanes whose `f32` estimate
/// lies before `tmin`: inlined, or asked for every lane that passed the sign test, it cost
/// more than it saved.
#[inline(never)]
pub fn hits_before_tmin<L: SimdLanes>(t: &ShearedLanes<L>, tmin: f32) -> u32 {
    let b = EstimateBounds::of(t);
    let two = L::splat(2.0);
    let bound = L::splat(tmin) * (t.den - two * b.dd) * L::splat(1.0 - ROUNDING);
    L::less_bits(b.de, b.e_min) & L::less_bits(t.num + two * b.dt, bound)
}

/// How far the `f32` numbers of the depth estimate may lie from the exact ones, in
/// [`refine`](Triangle::refine)'s relative rounding to `f32` (`2^-20`, generous).
const ROUNDING: f32 = 1.0 / (1 << 20) as f32;

/// The error bounds of [`hits_before_tmin`] for Woop's depth estimate `T / D` of sheared
/// triangles: each edge function's `dE`, the smallest `|e|`, `dT` for `T`, `dD` for `D`.
struct EstimateBounds<L> {
    de: L,
    e_min: L,
    dt: L,
    dd: L,
}

impl<L: SimdLanes> EstimateBounds<L> {
    #[inline(always)]
    fn of(t: &ShearedLanes<L>) -> Self {
        use crate::aabb::gamma;
        let abs_max = |v: &[L; 3]| v[0].abs().max(v[1].abs()).max(v[2].abs());
        let (x_max, y_max) = (abs_max(&t.x), abs_max(&t.y));
        let (dz_max, z_max) = (abs_max(&t.dz), abs_max(&t.z));
        let g = |n| L::splat(gamma(n));
        let dx = g(8) * (x_max + dz_max);
        let dy = g(8) * (y_max + dz_max);
        let de = L::splat(4.0) * (g(2) * x_max * y_max + dy * x_max + dx * y_max);
        let e = &t.edges;
        let e_max = e[0].max(e[1]).max(e[2]);
        let e_min = e[0].min(e[1]).min(e[2]);
        let dzz = g(4) * z_max;
        let three = L::splat(3.0);
        let dt = three * (g(3) * e_max * z_max + de * z_max + dzz * e_max);
        let dd = three * g(2) * e_max + three * de;
        Self { de, e_min, dt, dd }
    }
}

/// An any-hit query's shortcut for one triangle that passed the sign test: `Some` when the
/// error bounds of [`hits_before_tmin`], mirrored, prove that [`Triangle::finish_watertight`]
/// would report a hit inside `[tmin, tmax]` (`tmin > 0`), so that the query can stop without
/// the `f64` refinement. Every edge function exceeds its bound (the exact ones agree in sign,
/// so `refine` interpolates) and `T - 2 dT > tmin (D + 2 dD) (1 + 2^-20)`, `T + 2 dT < tmax
/// (D - 2 dD) (1 - 2^-20)`. The hit returned carries Woop's `f32` estimates of `t`, `u`, `v`
/// (an any-hit query answers only whether something is hit); `None` sends the caller to the
/// refinement.
///
/// Inputs as [`watertight_lanes`] computes them for the triangle's lane: the sheared `x`, `y`
/// and the unscaled depth `v[kz] - o[kz]` per vertex, and its edge functions ([`lane_edges`]).
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
    let b = EstimateBounds::of(&t);
    let after_tmin = (num - 2.0 * b.dt) > tmin * (den + 2.0 * b.dd) * (1.0 + ROUNDING);
    let before_tmax = (num + 2.0 * b.dt) < tmax * (den - 2.0 * b.dd) * (1.0 - ROUNDING);
    if !(b.de < b.e_min && 2.0 * b.dd < den && after_tmin && before_tmax) {
        return None;
    }
    let rcp = 1.0 / (u + v + w);
    let (bu, bv) = (v * rcp, w * rcp);
    (bu.is_finite() && bv.is_finite()).then(|| PrimHit {
        t: (num / den).clamp(tmin, tmax),
        u: bu,
        v: bv,
    })
}

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
/// [`hits_before_tmin`] does not prove to lie before `tmin`, as bits, and the sheared
/// coordinates `[ax, ay, bx, by, cx, cy]` of every lane: for such a lane `l`,
/// `tri.finish_watertight(ray, lane_edges(&sheared, l))` is exactly what
/// [`Triangle::intersect_watertight`] returns, and for every other lane that is `None`.
#[inline(always)]
pub fn watertight_lanes<L: SimdLanes>(tris: &TriangleLanes<L>, ray: &Ray) -> (u32, [L::Array; 6]) {
    watertight_rows(|j| tris[j], ray)
}

/// [`watertight_lanes`] with coordinate row `j` of the lanes (as in [`TriangleLanes`]) from
/// `row(j)`: a leaf test loads the rows the ray's axes pick straight from its leaf's memory,
/// instead of first storing all nine in an array that the axes index.
#[inline(always)]
pub fn watertight_rows<L: SimdLanes>(row: impl Fn(usize) -> L, ray: &Ray) -> (u32, [L::Array; 6]) {
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
    let dz = |v: usize| row(3 * v + kz) - oz;
    let shear = |v: usize| {
        let dz = dz(v);
        (
            row(3 * v + kx) - ox - sx * dz,
            row(3 * v + ky) - oy - sy * dz,
        )
    };
    let ((ax, ay), (bx, by), (cx, cy)) = (shear(0), shear(1), shear(2));
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let (neg, pos, on_edge) = L::sign_bits(u, v, w);
    let mut may_hit = (!(neg & pos) | on_edge) & ((1 << L::WIDTH) - 1);
    // Rays that leave a surface (shadow rays, bounces, `tmin > 0`) pierce the triangle they
    // start on at `t` near 0: rejected here in SIMD rather than one by one in `f64`.
    if may_hit != 0 && ray.tmin > 0.0 {
        // Woop's depth estimate `T / D` first (a few operations): only lanes it puts before
        // `tmin` are worth the rigorous bounds, out of line; real hits skip them.
        let sz = L::splat(s.z);
        let dz = [dz(0), dz(1), dz(2)];
        let z = [dz[0] * sz, dz[1] * sz, dz[2] * sz];
        let e = [u.abs(), v.abs(), w.abs()];
        let num = e[0] * z[0] + e[1] * z[1] + e[2] * z[2];
        let den = e[0] + e[1] + e[2];
        if L::less_bits(num, L::splat(ray.tmin) * den) & may_hit != 0 {
            let sheared = ShearedLanes {
                x: [ax, bx, cx],
                y: [ay, by, cy],
                dz,
                z,
                edges: e,
                num,
                den,
            };
            may_hit &= !hits_before_tmin(&sheared, ray.tmin);
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
    (may_hit, lanes)
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
    best: &mut Option<Hit>,
    skip: impl FnMut(u32) -> bool,
) -> bool {
    if ids.len() < 4 {
        crate::test_each::<Triangle, ANY_HIT>(tris, ids, ray, best, skip)
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
    best: &mut Option<Hit>,
    mut skip: impl FnMut(u32) -> bool,
) -> bool {
    if !ray.is_valid() {
        return false;
    }
    let mut batch = [0u32; 4];
    let mut n = 0;
    for &p in ids {
        if skip(p) {
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
                    if keep_hit::<ANY_HIT>(h, batch[l], &mut ray.tmax, best) {
                        return true;
                    }
                }
            }
        }
    }
    crate::counters::prims(n as u32);
    for &p in &batch[..n] {
        if let Some(h) = tris[p as usize].intersect_watertight(ray) {
            if keep_hit::<ANY_HIT>(h, p, &mut ray.tmax, best) {
                return true;
            }
        }
    }
    false
}

fn next_up(v: Vec3) -> Vec3 {
    Vec3::new(v.x.next_up(), v.y.next_up(), v.z.next_up())
}

fn next_down(v: Vec3) -> Vec3 {
    Vec3::new(v.x.next_down(), v.y.next_down(), v.z.next_down())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn tri() -> Triangle {
        Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)
    }

    #[test]
    fn hits_and_misses() {
        let r = Ray::new(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z);
        for k in [TriangleKernel::Watertight, TriangleKernel::MollerTrumbore] {
            let h = tri().intersect_with(&r, k).unwrap();
            assert_relative_eq!(h.t, 1.0);
            assert_relative_eq!(h.u, 0.25);
            assert_relative_eq!(h.v, 0.25);
            assert!(tri().point(h.u, h.v).abs_diff_eq(r.at(h.t), 1e-6));
            // Back side hits as well (no culling).
            let back = Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::Z);
            assert!(tri().intersect_with(&back, k).is_some());
            let miss = Ray::new(Vec3::new(0.75, 0.75, 1.0), -Vec3::Z);
            assert!(tri().intersect_with(&miss, k).is_none());
            assert!(tri().intersect_with(&r.with_range(0.0, 0.5), k).is_none());
            assert!(tri().intersect_with(&r.with_range(1.5, 9.0), k).is_none());
        }
    }

    #[test]
    fn shear_rows_give_the_indexed_shear_bit_for_bit() {
        let mut uniform = crate::test_uniform(99);
        let mut rnd = || uniform() * 4.0 - 2.0;
        for _ in 0..10_000 {
            let d = Vec3::new(rnd(), rnd(), rnd());
            let r = Ray::new(Vec3::ZERO, d);
            let [kx, ky, kz] = r.watertight_axes();
            let s = r.watertight_shear();
            let [mx, my] = r.watertight_rows();
            let a = Vec3::new(rnd(), rnd(), rnd()) * 100.0;
            assert_eq!(a.dot(*mx), a[kx] - s.x * a[kz]);
            assert_eq!(a.dot(*my), a[ky] - s.y * a[kz]);
            // The shear itself, as `Ray::segment` computes it (signed zeros included).
            let want = [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]];
            assert_eq!(s.to_array().map(f32::to_bits), want.map(f32::to_bits));
        }
        // Axis-aligned directions: shears of `+0` and `-0`.
        for d in [
            Vec3::X,
            -Vec3::Y,
            Vec3::new(0.0, -0.0, 2.0),
            Vec3::new(-0.0, 3.0, 0.0),
        ] {
            let r = Ray::new(Vec3::ZERO, d);
            let [kx, ky, kz] = r.watertight_axes();
            let want = [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]];
            let got = r.watertight_shear().to_array();
            assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits), "{d:?}");
        }
    }

    #[test]
    fn tmin_tmax_are_inclusive() {
        let r = Ray::new(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z);
        let t = tri().intersect_watertight(&r).unwrap().t;
        assert!(tri().intersect_watertight(&r.with_range(t, t)).is_some());
    }

    #[test]
    fn shared_edge_is_watertight() {
        // Two triangles sharing the diagonal of the unit square; rays through the diagonal hit.
        let a = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0));
        let b = Triangle::new(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y);
        for i in 1..1000 {
            let s = i as f32 / 1000.0;
            let o = Vec3::new(s, s, 1.0) + Vec3::new(0.3, -0.2, 0.0);
            let r = Ray::new(o, Vec3::new(s, s, 0.0) - o);
            assert!(
                a.intersect_watertight(&r).is_some() || b.intersect_watertight(&r).is_some(),
                "ray {i} slipped through the shared edge"
            );
        }
    }

    #[test]
    fn sliver_hits_lie_inside_the_sliver_box() {
        // A thin sliver from the conformance scenes: in f32 the barycentric form put this hit
        // at t = 0.9999467, before the sliver's own plane (t = 1.0) and its bounding box.
        let tri = Triangle::new(
            Vec3::new(0.27604538, 0.21344042, 0.6332848),
            Vec3::new(0.27604538, 0.21344042, 1.630063),
            Vec3::new(0.2760583, 0.21344042, 1.630063),
        );
        let r = Ray::new(
            Vec3::new(2.0939884, -0.8425082, -0.8554015),
            Vec3::new(-1.8179386, 1.0559486, 2.2832537),
        );
        let h = tri.intersect_watertight(&r).unwrap();
        let (t0, t1) = tri.bounds().clip_ray(&r).unwrap();
        assert!(t0 <= h.t && h.t <= t1, "{t0} {} {t1}", h.t);
        let plane_t = (tri.v[0].y - r.origin().y) / r.dir().y;
        assert!(
            (h.t - plane_t).abs() <= 2.0 * f32::EPSILON,
            "{} vs {plane_t}",
            h.t
        );
    }

    #[test]
    fn degenerate_triangles_never_hit() {
        let dup = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::X);
        let line = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0));
        let point = Triangle::new(Vec3::ONE, Vec3::ONE, Vec3::ONE);
        for t in [dup, line, point] {
            assert!(t.is_degenerate());
            for o in [
                Vec3::new(0.5, 0.0, 1.0),
                Vec3::new(1.0, 0.0, 1.0),
                Vec3::new(1.0, 1.0, 2.0),
            ] {
                let r = Ray::new(o, Vec3::new(0.0, 0.0, -1.0));
                assert!(t.intersect_watertight(&r).is_none());
                assert!(t.intersect_moller_trumbore(&r).is_none());
            }
        }
    }

    #[test]
    fn invalid_and_parallel_rays_miss() {
        let zero = Ray::new(Vec3::new(0.25, 0.25, 1.0), Vec3::ZERO);
        assert!(tri().intersect_watertight(&zero).is_none());
        let nan = Ray::new(Vec3::new(0.25, 0.25, 1.0), Vec3::new(f32::NAN, 0.0, -1.0));
        assert!(tri().intersect_watertight(&nan).is_none());
        // In the triangle's plane.
        let coplanar = Ray::new(Vec3::new(-1.0, 0.25, 0.0), Vec3::X);
        assert!(tri().intersect_watertight(&coplanar).is_none());
    }

    #[test]
    fn clipping() {
        let t = Triangle::new(
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        );
        let clip = Aabb::new(Vec3::new(1.0, 0.0, -1.0), Vec3::new(3.0, 3.0, 1.0));
        let b = t.clipped_bounds(&clip);
        assert_eq!(b.min, Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(b.max, Vec3::new(2.0, 1.0, 0.0));
        let far = Aabb::new(Vec3::splat(5.0), Vec3::splat(6.0));
        assert!(t.clipped_bounds(&far).is_empty());
        // The corner region beyond the hypotenuse: box overlaps bounds but not the triangle.
        let corner = Aabb::new(Vec3::new(1.5, 1.5, -1.0), Vec3::new(2.0, 2.0, 1.0));
        assert!(t.clipped_bounds(&corner).is_empty());
        assert_eq!(
            t.clipped_bounds(&Aabb::new(Vec3::splat(-9.0), Vec3::splat(9.0))),
            t.bounds()
        );
    }

    #[test]
    fn grazing_hits_lie_in_the_triangle() {
        // Triangles through one vertex, rays aimed at it almost in their planes: the hit the
        // watertight test accepts must be reported at a point of the triangle (its box), not
        // where the ray meets the nearly parallel plane.
        let p = Vec3::splat(0.5);
        let mut uniform = crate::test_uniform(7);
        let mut rnd = || uniform() * 2.0 - 1.0;
        let mut hits = 0;
        for _ in 0..20_000 {
            let b = p + Vec3::new(rnd(), rnd(), rnd());
            let c = p + Vec3::new(rnd(), rnd(), rnd());
            let tri = Triangle::new(p, b, c);
            let n = tri.normal();
            // A direction in the plane, tilted by a hair.
            let along = (b - p).normalize() + (c - p).normalize() * rnd();
            let dir = along + n * (1e-4 * rnd());
            let origin = p - dir * 2.0;
            let ray = Ray::new(origin, p - origin);
            if let Some(h) = tri.intersect_watertight(&ray) {
                hits += 1;
                let x = ray.at(h.t);
                let bb = tri.bounds();
                let pad = Vec3::splat(1e-5);
                assert!(
                    Aabb::new(bb.min - pad, bb.max + pad).contains_point(x),
                    "{tri:?} {ray:?} t={} at {x:?}",
                    h.t
                );
            }
        }
        assert!(hits > 1000, "{hits}");
        // A case from the conformance scene `overlapping_fan`: the ray is aimed at the shared
        // vertex and grazes the plane (n . d = 2e-4); the plane equation put the hit at
        // t = 0.99994, 7e-5 outside the triangle's box, and structures disagreed with brute
        // force on it.
        let tri = Triangle::new(
            Vec3::splat(0.5),
            Vec3::new(-0.21281451, 0.36131966, -0.18750513),
            Vec3::new(0.7021762, -0.47747344, 0.43941617),
        );
        let ray = Ray::new(
            Vec3::new(-1.4116699, 1.6713568, -0.956732),
            Vec3::new(1.9116699, -1.1713568, 1.456732),
        );
        let h = tri.intersect_watertight(&ray).expect("hits the vertex");
        let bb = tri.bounds();
        let pad = Vec3::splat(1e-6);
        assert!(
            Aabb::new(bb.min - pad, bb.max + pad).contains_point(ray.at(h.t)),
            "t = {}",
            h.t
        );
    }

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
            let a2 = crate::test_each::<Triangle, false>(&tris, &ids, &mut r2, &mut b2, skip);
            assert_eq!((a1, b1, r1.tmax), (a2, b2, r2.tmax), "case {case}");
            hits += b1.is_some() as usize;
            let (mut r1, mut r2) = (ray, ray);
            let (mut b1, mut b2) = (None, None);
            let a1 = test_triangles::<true>(&tris, &ids, &mut r1, &mut b1, skip);
            let a2 = crate::test_each::<Triangle, true>(&tris, &ids, &mut r2, &mut b2, skip);
            assert_eq!((a1, b1), (a2, b2), "case {case} (any hit)");
        }
        assert!(hits > 500, "{hits} hits: the rays must meet the triangles");
    }

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
            let mut cut = all & !kept;
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
            while cut != 0 {
                let l = cut.trailing_zeros() as usize;
                cut &= cut - 1;
                let h = tris[l].finish_watertight(&ray, lane_edges(&sheared, l));
                assert!(
                    h.is_none(),
                    "case {case} lane {l}: {:?} {ray:?} -> {h:?}",
                    tris[l]
                );
            }
        }
        assert!(
            own > 2_000 && own_culled * 100 > own * 95,
            "own triangle culled {own_culled} of {own}"
        );
        assert!(culled > 5_000, "{culled}");
    }
}
