//! Triangles: the watertight ray/triangle test (reference kernel) with its `f64` refinement,
//! and Möller–Trumbore (option). Beside it:
//!
//! | file | what it holds |
//! |---|---|
//! | `clip.rs` | [`Triangle::clipped_bounds`]: the part of a triangle inside a box (perfect kd-tree splits) |
//! | `simd.rs` | [`SimdLanes`]: the vectors of four or eight lanes the kernel runs on; the lanes' triangles and sheared frame |
//! | `avx.rs` | `Avx8`: eight lanes in one AVX register, the leaf test's vectors at the AVX2 level; the walk's sorting network of eight lanes |
//! | `lanes.rs` | the lane kernel: four or eight triangles' edge functions and sign test at once ([`watertight_lanes`]), the batched leaf test |
//! | `bounds.rs` | the error bounds that decide a lane without the `f64` refinement: [`hits_before_tmin`], [`hits_outside`], [`proven_hit`] |

#[cfg(target_arch = "x86_64")]
mod avx;
mod bounds;
mod clip;
mod lanes;
mod moller;
mod simd;

#[cfg(target_arch = "x86_64")]
pub(crate) use avx::Avx8;
#[cfg(target_arch = "x86_64")]
pub(crate) use bounds::outside_and_proven_lanes;
pub use bounds::{hits_before_tmin, hits_outside, proven_hit};
pub(crate) use bounds::{hits_outside_and_proven, woop_hit};
pub(crate) use lanes::test_triangles;
pub(crate) use lanes::watertight_rows_at;
pub use lanes::{lane_edges, watertight_lanes, watertight_rows};
pub(crate) use moller::{moller_trumbore_held, moller_trumbore_rows, moller_trumbore_span};
pub use simd::{ShearedLanes, SimdLanes, TriangleLanes};

use crate::{Aabb, PrimHit, Ray};
use glam::{DVec3, Vec3};

/// Whether the `f32` edge functions do not disagree in sign (none below zero, or none above):
/// the watertight test's acceptance, before the `f64` refinement.
#[inline(always)]
pub(crate) fn signs_agree((u, v, w): (f32, f32, f32)) -> bool {
    !((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0))
}

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
    /// Möller & Trumbore 1997: fast, not watertight (rays can slip through shared edges),
    /// its depth held in the triangle's box as the watertight kernel's is
    /// ([`Triangle::intersect_moller_trumbore`]).
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
    /// Where the edge tests accept, `t` is computed in `f64` ([`Self::refine`]). In `f32`, the
    /// paper's `t = (U az + V bz + W cz) / (U + V + W)` loses most of its digits on thin
    /// slivers, whose edge functions cancel: a sliver of the test scenes reports a hit 5e-5
    /// (relative) before its own plane and before its bounding box, where no box-culling
    /// structure can agree with brute force. In `f64` the error mostly stays far below the
    /// padding of [`Aabb::clip_ray`]; where it does not (vertices far from a hit close to the
    /// origin), the hit is moved into the triangle's box, so every structure that culls by
    /// box entry agrees exactly.
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
    pub fn finish_watertight(&self, ray: &Ray, edges: (f32, f32, f32)) -> Option<PrimHit> {
        if !signs_agree(edges) {
            return None;
        }
        self.finish_accepted(ray, edges)
    }

    /// [`Self::finish_watertight`] inlined whole into the caller, refinement included: for
    /// kernels compiled per instruction set, where an out-of-line refinement would run at the
    /// baseline ([`crate::isa`]).
    #[inline(always)]
    pub fn finish_watertight_inline(&self, ray: &Ray, edges: (f32, f32, f32)) -> Option<PrimHit> {
        if !signs_agree(edges) {
            return None;
        }
        self.finish_accepted_inline(ray, edges)
    }

    /// [`Self::finish_watertight`] once the edge functions agree in sign. Where the `f32` edge
    /// functions decide nothing (they all underflow to zero, for tiny triangles, or overflow,
    /// for vertices near the largest floats), the `f64` ones decide alone.
    #[inline(never)]
    pub(crate) fn finish_accepted(&self, ray: &Ray, e: (f32, f32, f32)) -> Option<PrimHit> {
        self.finish_accepted_inline(ray, e)
    }

    /// [`Self::finish_accepted`]'s body, inlined into kernels compiled per level (through
    /// [`Self::finish_watertight_inline`]).
    #[inline(always)]
    pub(crate) fn finish_accepted_inline(
        &self,
        ray: &Ray,
        (u, v, w): (f32, f32, f32),
    ) -> Option<PrimHit> {
        if self.is_degenerate() {
            return None;
        }
        Self::finish_nondegenerate_inline(&self.along_axes(ray), ray, (u, v, w))
    }

    /// [`Self::finish_accepted`] of a triangle known to have nonzero area (leaf tests that
    /// drop the zero-area ones beforehand), given by its vertices along the ray's axes
    /// ([`AxisVertices`]), out of line.
    #[inline(never)]
    pub(crate) fn finish_nondegenerate(
        p: &AxisVertices,
        ray: &Ray,
        e: (f32, f32, f32),
    ) -> Option<PrimHit> {
        Self::finish_nondegenerate_inline(p, ray, e)
    }

    /// [`Self::finish_nondegenerate`]'s body, inlined into the AVX2 level's leaf test.
    #[inline(always)]
    pub(crate) fn finish_nondegenerate_inline(
        p: &AxisVertices,
        ray: &Ray,
        (u, v, w): (f32, f32, f32),
    ) -> Option<PrimHit> {
        let sum = u + v + w;
        if sum == 0.0 || !sum.is_finite() {
            return refine_in_f64(p, ray);
        }
        refine_along_axes(p, ray, (u, v, w))
    }

    /// The vertices along `ray`'s watertight axes (see [`AxisVertices`]).
    #[inline(always)]
    pub(crate) fn along_axes(&self, ray: &Ray) -> AxisVertices {
        let [kx, ky, kz] = ray.watertight_axes();
        self.v.map(|q| {
            let q = q.to_array();
            [q[kx], q[ky], q[kz]]
        })
    }

    /// Distance of a hit that the edge tests accepted, in `f64` from the `f32` inputs, with
    /// the barycentrics `(u, v) = (V, W) / (U + V + W)` of those tests: `None` when the hit
    /// degenerates or `t` is outside `[tmin, tmax]`. SIMD kernels call this on their candidate
    /// hits to report bit-identical answers.
    ///
    /// `t` is the depth of the point of the triangle that the ray meets, computed so that the
    /// point lies *in the triangle* (to `f64` rounding), which is what lets every structure
    /// find the hit in the cells and boxes that hold the triangle:
    /// - the edge functions are recomputed in `f64` in the ray's shear, scaled by the
    ///   direction's major component (the inputs are `f32`: vertex minus origin is exact, the
    ///   shear's products and differences rounded once each); when all three agree
    ///   the ray pierces the triangle, and `t = (U za + V zb + W zc) / (U + V + W)` with
    ///   `z = (p - o)[kz] / d[kz]` (the depth interpolation of Woop et al., exact here where in
    ///   `f32` it loses most digits on thin slivers), moved into the ray's interval over the
    ///   triangle's box where it lies outside by more than the box tests' padding (vertices
    ///   `1e8` away from a hit a thousandth from the origin leave `f64` too few digits);
    /// - when they do not (the `f32` test accepted a ray that passes a rounding error outside
    ///   an edge or vertex, typically grazing the plane, where the plane equation would put the
    ///   hit far along the ray, outside the triangle's box), `t` is the ray parameter of the
    ///   point of the ray closest to the triangle's boundary, held to the ray's interval over
    ///   the triangle's box (no hit where the ray passes the box by more than the box
    ///   tests' padding).
    #[inline(always)]
    pub fn refine(&self, ray: &Ray, edges: (f32, f32, f32)) -> Option<PrimHit> {
        refine_along_axes(&self.along_axes(ray), ray, edges)
    }

    /// The depth of a grazing hit (the `f32` test accepts it, the `f64` edge functions do
    /// not agree): the parameter of the point of the ray closest to the triangle's boundary,
    /// [`Self::held_in_box`].
    fn grazing_depth(&self, ray: &Ray) -> Option<f32> {
        let (o, d) = (ray.origin().as_dvec3(), ray.dir().as_dvec3());
        self.held_in_box(ray, self.closest_on_boundary(o, d)?)
    }

    /// The parameter `s` along `ray` as a hit that every structure whose padded boxes or
    /// cells hold the triangle finds there: kept where [`Aabb::holds_hit`] holds it, else
    /// moved into the ray's interval over the triangle's box (or, for a ray that passes the
    /// box, between its exit and its entry) and kept only where `holds_hit` holds it then.
    /// A depth interpolated in `f64` between vertices far from the origin (a sliver seen
    /// nearly edge-on, a hit close to the origin) can lie before or after the box by more
    /// than the box tests' padding, which is relative to the hit's own distance.
    #[cold]
    #[inline(never)]
    fn held_in_box(&self, ray: &Ray, s: f64) -> Option<f32> {
        let b = self.bounds();
        if b.holds_hit(ray, s as f32) {
            return Some(s as f32);
        }
        let (enter, exit) = b.slab_interval_f64(ray);
        // `+ 0.0`: a face through the origin is entered at `-0.0` along a negative axis.
        let t = s.max(enter.min(exit)).min(enter.max(exit)) as f32 + 0.0;
        b.holds_hit(ray, t).then_some(t)
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
}

/// Edge functions of a triangle in a ray's shear (scaled by `dz^2`), the vertices' offsets
/// from the origin along the ray's axes `[kx, ky, kz]` and the direction along them, in
/// `f64`.
struct EdgesF64 {
    e: [f64; 3],
    /// Vertex `i`'s offset from the origin along the ray's axes (exact: two `f32`s).
    off: [[f64; 3]; 3],
    /// The direction along the ray's axes.
    d: [f64; 3],
}

impl EdgesF64 {
    /// The depth `(U za + V zb + W zc) / ((U + V + W) dz)` of the point the ray meets, when
    /// the edge functions say it pierces the triangle (all `>= 0`, sum `> 0`): along the
    /// major axis, a convex combination of the vertices' offsets `z`.
    #[inline(always)]
    fn depth(&self) -> Option<f64> {
        let [e0, e1, e2] = self.e;
        let sum = e0 + e1 + e2;
        let z = [self.off[0][2], self.off[1][2], self.off[2][2]];
        (e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0 && sum > 0.0)
            .then(|| (e0 * z[0] + e1 * z[1] + e2 * z[2]) / (sum * self.d[2]))
    }

    /// [`Aabb::holds_hit`] of the triangle's box at `t`, from the offsets at hand: whether
    /// every structure that holds the triangle in its padded boxes finds the hit there.
    #[inline(always)]
    fn holds(&self, t: f32) -> bool {
        // `step_held` of the vertices' least and greatest offsets, as comparisons with each
        // (the same answers: `f64::min` and `max` cost more than the comparisons). A
        // function, not a closure: see `crate::isa`.
        #[inline(always)]
        fn axis([a, b, c]: [f64; 3], step: f64) -> bool {
            let (below, above) = crate::aabb::step_reach(step);
            ((a <= above) | (b <= above) | (c <= above))
                & ((a >= below) | (b >= below) | (c >= below))
        }
        let [a, b, c] = self.off;
        let t = t as f64;
        axis([a[0], b[0], c[0]], self.d[0] * t)
            & axis([a[1], b[1], c[1]], self.d[1] * t)
            & axis([a[2], b[2], c[2]], self.d[2] * t)
    }

    /// The depth `t` (from [`Self::depth`]) as a hit: kept where [`Self::holds`] holds it,
    /// else [`Triangle::held_in_box`] of the triangle whose vertices along the ray's axes are
    /// `p` (the cold path: far slivers).
    #[inline(always)]
    fn held(&self, t: f64, p: &AxisVertices, ray: &Ray) -> Option<f32> {
        if self.holds(t as f32) {
            Some(t as f32)
        } else {
            from_axes(p, ray).held_in_box(ray, t)
        }
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

/// A triangle's vertices along a ray's watertight axes `[kx, ky, kz]`
/// ([`Ray::watertight_axes`]): vertex `j` as `[v[kx], v[ky], v[kz]]`. The `f64` refinement
/// reads them in this order; a leaf test takes them straight from the rows its axes picked.
pub(crate) type AxisVertices = [[f32; 3]; 3];

/// The triangle whose vertices along `ray`'s axes are `p` (the inverse of
/// [`Triangle::along_axes`]).
fn from_axes(p: &AxisVertices, ray: &Ray) -> Triangle {
    let [kx, ky, kz] = ray.watertight_axes();
    Triangle {
        v: p.map(|q| {
            let mut c = [0.0; 3];
            (c[kx], c[ky], c[kz]) = (q[0], q[1], q[2]);
            Vec3::from_array(c)
        }),
    }
}

/// [`Triangle::refine`] of the triangle whose vertices along the ray's axes are `p`.
#[inline(always)]
fn refine_along_axes(p: &AxisVertices, ray: &Ray, (u, v, w): (f32, f32, f32)) -> Option<PrimHit> {
    let orient = if u + v + w < 0.0 { -1.0 } else { 1.0 };
    let edges = edges_in_f64(p, ray, orient);
    let t = match edges.depth() {
        Some(t) => edges.held(t, p, ray)?,
        None => from_axes(p, ray).grazing_depth(ray)?,
    };
    if !ray.in_range(t) {
        return None;
    }
    let rcp = 1.0 / (u + v + w);
    let (bu, bv) = (v * rcp, w * rcp);
    // An `f32` sum that underflows to a subnormal makes `rcp` infinite: such hits take the
    // `f64` barycentrics.
    let (u, v) = if bu.is_finite() && bv.is_finite() {
        (bu, bv)
    } else {
        edges.barycentrics()
    };
    Some(PrimHit { t, u, v })
}

/// The watertight test decided by the `f64` edge functions alone (no `f32` test to follow
/// to the boundary): a hit when they agree in sign, with their barycentrics.
fn refine_in_f64(p: &AxisVertices, ray: &Ray) -> Option<PrimHit> {
    let mut edges = edges_in_f64(p, ray, 1.0);
    if edges.e.iter().sum::<f64>() < 0.0 {
        edges.e = edges.e.map(|e| -e);
    }
    let t = edges.held(edges.depth()?, p, ray)?;
    if !ray.in_range(t) {
        return None;
    }
    let (u, v) = edges.barycentrics();
    Some(PrimHit { t, u, v })
}

/// The edge functions `(U, V, W)` times `orient`, in `f64` from the `f32` inputs (the
/// vertices `p` along the ray's axes), and the vertices' offsets along the ray's major axis.
/// The shear is taken scaled by that axis's direction component `d[kz]`: `p[kx] d[kz] -
/// d[kx] p[kz]` rather than `p[kx] - (d[kx] / d[kz]) p[kz]`. Vertex minus origin is exact;
/// each product is rounded at most once (exact where `p` has at most 29 significant bits),
/// the difference once, where the quotient form rounds three times and divides. The edge
/// functions come out scaled by `d[kz]^2 > 0` (same signs, same barycentrics), and the depth
/// takes the one division by `d[kz]` left ([`EdgesF64::depth`]) instead of three for the
/// shear.
#[inline(always)]
fn edges_in_f64(p: &AxisVertices, ray: &Ray, orient: f64) -> EdgesF64 {
    let [kx, ky, kz] = ray.watertight_axes();
    let (d, o) = (ray.dir().to_array(), ray.origin().to_array());
    let (dx, dy, dz) = (d[kx] as f64, d[ky] as f64, d[kz] as f64);
    let (ox, oy, oz) = (o[kx] as f64, o[ky] as f64, o[kz] as f64);
    // A function, not a closure in `map`: see `crate::isa`.
    #[inline(always)]
    fn offset(q: [f32; 3], (ox, oy, oz): (f64, f64, f64)) -> [f64; 3] {
        [q[0] as f64 - ox, q[1] as f64 - oy, q[2] as f64 - oz]
    }
    let off = [
        offset(p[0], (ox, oy, oz)),
        offset(p[1], (ox, oy, oz)),
        offset(p[2], (ox, oy, oz)),
    ];
    let shear = |[x, y, z]: [f64; 3]| (x * dz - dx * z, y * dz - dy * z);
    let (ax, ay) = shear(off[0]);
    let (bx, by) = shear(off[1]);
    let (cx, cy) = shear(off[2]);
    EdgesF64 {
        e: [
            (cx * by - cy * bx) * orient,
            (ax * cy - ay * cx) * orient,
            (bx * ay - by * ax) * orient,
        ],
        off,
        d: [dx, dy, dz],
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
}
