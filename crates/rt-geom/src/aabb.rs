//! Axis-aligned bounding boxes and the robust ray/box slab test.

use crate::Ray;
use glam::{Vec3, Vec3A};

/// `gamma(n)` of Pharr, Jakob & Humphreys: a bound on the relative error of `n` float operations.
#[inline]
pub const fn gamma(n: i32) -> f32 {
    let e = f32::EPSILON * 0.5;
    (n as f32 * e) / (1.0 - n as f32 * e)
}

/// The factor by which the far slab distance is enlarged so that rounding in the slab test can
/// never make a ray slip between two boxes that share a face (Ize, "Robust BVH Ray Traversal",
/// JCGT 2013: `1 + 2 gamma(3)`).
pub const FAR_PAD: f32 = 1.0 + 2.0 * gamma(3);

/// The relative margin of [`FAR_PAD`]: `2 gamma(3)`.
pub const PAD: f32 = 2.0 * gamma(3);

/// `t` moved towards `-inf` by the relative margin [`PAD`] (branch-free: `t - |t| PAD`).
#[inline]
pub fn pad_down(t: f32) -> f32 {
    t - t.abs() * PAD
}

/// `t` moved towards `+inf` by the relative margin [`PAD`] (branch-free: `t + |t| PAD`).
#[inline]
pub fn pad_up(t: f32) -> f32 {
    t + t.abs() * PAD
}

/// The largest `f32` at or below `v` (an `f64` rounded towards `-inf`).
#[inline]
pub fn f32_at_or_below(v: f64) -> f32 {
    let f = v as f32;
    if f as f64 > v { f.next_down() } else { f }
}

/// The smallest `f32` at or above `v` (an `f64` rounded towards `+inf`).
#[inline]
pub fn f32_at_or_above(v: f64) -> f32 {
    let f = v as f32;
    if (f as f64) < v { f.next_up() } else { f }
}

/// The fused form's offsets are moved outward by this much of their magnitude (and by the
/// smallest normal float): at least two units in the last place, so that the offset's own
/// rounding and that of the move leave it beyond the exact `-origin * inv`.
const OFFSET_SLACK: f32 = 1.0 / (1u32 << 22) as f32;

/// The per-ray constants of the slab test, computed once per ray for traversals that test
/// many boxes ([`SlabRay::entry`], and the lane loops of wide BVH nodes).
///
/// The padding of [`Aabb::clip_ray`] (relative [`PAD`]) is folded into the reciprocal
/// direction: `inv_near = inv (1 - PAD)` and `inv_far = inv (1 + PAD)` scale the magnitude of
/// every plane distance down (near planes) or up (far planes), which saves the two paddings
/// per box. Plane distances keep their exact sign (a rounded difference or product never
/// changes sign), so a positive entry moves towards the ray's start and a positive exit away
/// from it; the four roundings involved (difference, reciprocal, scaled reciprocal, product)
/// stay below `PAD = 2 gamma(3)`. Negative distances move the wrong way, but while
/// `tmin >= 0` they only lose against `tmin` (entries) or mean a box behind the ray (exits).
/// Rays with `tmin < 0` keep the plain reciprocal and pad the interval afterwards
/// (`pad_after`), as `clip_ray` does.
///
/// Levels with fused multiply-add take each plane distance in one operation instead,
/// `plane * inv + offset` ([`Self::fused_distances`], Embree's form): the offset `-origin *
/// inv` is moved outward once per ray (down for near planes, up for far ones) past its
/// rounding error, so it only moves entries earlier and exits later, and the one rounding of
/// the fused operation stays within the padding budgeted for four. An axis whose reciprocal
/// or offset is not finite (a zero direction component, or a tiny one with an origin far
/// away) constrains nothing in that form: conservative, where the difference form culls boxes
/// beside the ray. The form gives no NaN: an empty box (min `+inf`, max `-inf`) is entered at
/// `+inf` and left at `-inf` on every axis, so that it is missed whatever order the axes are
/// combined in.
#[derive(Clone, Copy, Debug)]
pub struct SlabRay {
    /// The ray origin.
    pub origin: [f32; 3],
    /// Reciprocal direction scaled for the plane the ray enters by (padding folded in).
    pub inv_near: [f32; 3],
    /// Reciprocal direction scaled for the plane the ray leaves by (padding folded in).
    pub inv_far: [f32; 3],
    /// Per axis: the direction is negative (`-0.0` included): the near plane is the box's max.
    pub neg: [bool; 3],
    /// The interval is padded after the planes (rays with `tmin < 0`).
    pub pad_after: bool,
    /// Per axis, the reciprocal of the fused form for near planes and for far planes (the
    /// padded ones; `f32::MIN_POSITIVE` of the direction's sign where the axis constrains
    /// nothing).
    pub fused_inv: [[f32; 3]; 2],
    /// Per axis, `-origin * inv` of the fused form moved down (near planes) and up (far
    /// planes) past its rounding; `f32::MIN` and `f32::MAX` where the axis constrains
    /// nothing.
    pub fused_offset: [[f32; 3]; 2],
}

impl SlabRay {
    /// The factors of the near and the far plane's reciprocal for an interval from `tmin`:
    /// `(1 - PAD, 1 + PAD)`, or `(1, 1)` when `tmin < 0` (or NaN), which pads afterwards.
    #[inline(always)]
    pub fn fold_factors(tmin: f32) -> (f32, f32) {
        if tmin >= 0.0 {
            (1.0 - PAD, 1.0 + PAD)
        } else {
            (1.0, 1.0)
        }
    }

    /// The slab data of `ray`, computed once for all the boxes it meets.
    #[inline(always)]
    pub fn new(ray: &Ray) -> Self {
        Self::from_lanes(ray, Vec3A::ONE / Vec3A::from(ray.dir()))
    }

    /// [`Self::new`] with the ray's reciprocal direction already computed
    /// ([`Ray::inv_dir`]), for walks that use it elsewhere too.
    #[inline(always)]
    pub fn with_inv_dir(ray: &Ray, inv: [f32; 3]) -> Self {
        Self::from_lanes(ray, Vec3A::from_array(inv))
    }

    /// [`Self::with_inv_dir`] with the three axes as the lanes of one vector: the same
    /// operations per axis, a few vector instructions per ray instead of scalar ones and
    /// selects (every query pays this setup once).
    #[inline(always)]
    fn from_lanes(ray: &Ray, inv: Vec3A) -> Self {
        let pad_after = !(ray.tmin >= 0.0);
        let (near, far) = Self::fold_factors(ray.tmin);
        let origin = Vec3A::from(ray.origin());
        let (inv_near, inv_far) = (inv * near, inv * far);
        let (lo, hi) = (-(origin * inv_near), -(origin * inv_far));
        let lo = lo - (lo.abs() * OFFSET_SLACK + f32::MIN_POSITIVE);
        let hi = hi + (hi.abs() * OFFSET_SLACK + f32::MIN_POSITIVE);
        let ok = inv_near.is_finite_mask()
            & inv_far.is_finite_mask()
            & lo.is_finite_mask()
            & hi.is_finite_mask();
        let neg = inv.is_negative_bitmask();
        // An axis that constrains nothing: the smallest normal reciprocal of the direction's
        // sign and the most negative (near) and positive (far) finite offsets. A finite plane
        // then lies at `f32::MIN` and `f32::MAX`, and an empty lane's infinite planes at
        // `+inf` (entry) and `-inf` (exit), as on every other axis: no NaN in this form.
        let tiny = Vec3A::splat(f32::MIN_POSITIVE).copysign(inv);
        Self {
            origin: origin.to_array(),
            inv_near: inv_near.to_array(),
            inv_far: inv_far.to_array(),
            neg: [0, 1, 2].map(|a| neg & (1 << a) != 0),
            pad_after,
            fused_inv: [
                Vec3A::select(ok, inv_near, tiny).to_array(),
                Vec3A::select(ok, inv_far, tiny).to_array(),
            ],
            fused_offset: [
                Vec3A::select(ok, lo, Vec3A::splat(f32::MIN)).to_array(),
                Vec3A::select(ok, hi, Vec3A::splat(f32::MAX)).to_array(),
            ],
        }
    }

    /// The distances of the near plane `near` and the far plane `far` of axis `a` in the
    /// fused form (one multiply-add each; see the type's documentation). Where the CPU has
    /// no fused multiply-add, `f32::mul_add` is a library call: only levels with
    /// [`Level::FMA`](crate::Level::FMA) use it in their walks.
    #[inline(always)]
    pub fn fused_distances(&self, a: usize, near: f32, far: f32) -> (f32, f32) {
        (
            near.mul_add(self.fused_inv[0][a], self.fused_offset[0][a]),
            far.mul_add(self.fused_inv[1][a], self.fused_offset[1][a]),
        )
    }

    /// The reciprocals for planes met as a box's min and as its max plane, per axis (the
    /// near or far one by the direction's sign).
    #[inline(always)]
    pub fn plane_reciprocals(&self) -> ([f32; 3], [f32; 3]) {
        let pick = |min_plane: bool| {
            std::array::from_fn(|a| {
                if self.neg[a] == min_plane {
                    self.inv_far[a]
                } else {
                    self.inv_near[a]
                }
            })
        };
        (pick(true), pick(false))
    }

    /// The entry distance into the box `min..max` within `[tmin, tmax]` (never before
    /// `tmin`, never after the true entry), or `None` when the ray misses it: the answers of
    /// [`Aabb::clip_ray`] up to its last ulps, without branches on the data.
    #[inline(always)]
    pub fn entry(&self, min: &[f32; 3], max: &[f32; 3], tmin: f32, tmax: f32) -> Option<f32> {
        self.entry_with(min, max, tmin, tmax, |a, near, far| {
            (
                (near - self.origin[a]) * self.inv_near[a],
                (far - self.origin[a]) * self.inv_far[a],
            )
        })
    }

    /// [`Self::entry`] with the plane distances of the fused form
    /// ([`Self::fused_distances`]), as the walks of levels with fused multiply-add compute
    /// them.
    #[inline(always)]
    pub fn entry_fused(&self, min: &[f32; 3], max: &[f32; 3], tmin: f32, tmax: f32) -> Option<f32> {
        self.entry_with(min, max, tmin, tmax, |a, near, far| {
            self.fused_distances(a, near, far)
        })
    }

    /// [`Self::entry`] with the distances of axis `a`'s near and far plane from `planes`.
    #[inline(always)]
    fn entry_with(
        &self,
        min: &[f32; 3],
        max: &[f32; 3],
        tmin: f32,
        tmax: f32,
        planes: impl Fn(usize, f32, f32) -> (f32, f32),
    ) -> Option<f32> {
        let (mut t0, mut t1) = (tmin, tmax);
        for a in 0..3 {
            let (near, far) = if self.neg[a] {
                (max[a], min[a])
            } else {
                (min[a], max[a])
            };
            let (tn, tf) = planes(a, near, far);
            // NaN (origin on the plane, zero direction) leaves the interval unchanged.
            t0 = if tn > t0 { tn } else { t0 };
            t1 = if tf < t1 { tf } else { t1 };
        }
        if self.pad_after {
            (t0, t1) = pad_interval(t0, t1, tmin);
        }
        (t0 <= t1).then_some(t0)
    }
}

/// `[t0, t1]` padded outward by [`PAD`], the start clamped to `tmin`; a start of NaN when the
/// padded interval is empty (`pad_down(+inf)` is NaN: a ray parallel to a slab outside it).
#[inline(always)]
pub fn pad_interval(t0: f32, t1: f32, tmin: f32) -> (f32, f32) {
    let (lo, hi) = (pad_down(t0), pad_up(t1));
    (if lo <= hi { lo.max(tmin) } else { f32::NAN }, hi)
}

/// [`Aabb::holds_hit`] along one axis: whether a ray's step `step` from its origin lies
/// between the faces' offsets `lo` and `hi` from it, up to `PAD / 2` of the step.
#[inline(always)]
pub(crate) fn step_held(lo: f64, hi: f64, step: f64) -> bool {
    let (below, above) = step_reach(step);
    lo <= above && below <= hi
}

/// The span `step -+ PAD / 2 |step|` in which [`step_held`] looks for a face's offset.
#[inline(always)]
pub(crate) fn step_reach(step: f64) -> (f64, f64) {
    let slack = step.abs() * (PAD as f64 * 0.5);
    (step - slack, step + slack)
}

/// An axis-aligned box. The empty box has `min = +inf`, `max = -inf`, so that `union` with it is
/// the identity. A box may be flat (zero extent along an axis): planar geometry has flat boxes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The box around all of `prims` (empty for none).
    pub fn around<P: crate::Primitive>(prims: &[P]) -> Aabb {
        prims.iter().fold(Aabb::EMPTY, |b, p| b.union(p.bounds()))
    }

    /// The empty box (min +inf, max -inf): the identity of [`Aabb::union`].
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// The box from `min` to `max`.
    #[inline]
    pub fn new(min: Vec3, max: Vec3) -> Self {
        Self { min, max }
    }

    /// The smallest box around `points`.
    pub fn from_points(points: impl IntoIterator<Item = Vec3>) -> Self {
        points.into_iter().fold(Self::EMPTY, |b, p| b.grow(p))
    }

    /// True when the box holds no point (some `min > max`, or a NaN).
    #[inline]
    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    /// Whether every coordinate is finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.min.is_finite() && self.max.is_finite()
    }

    /// The box grown to hold `p`.
    #[inline]
    pub fn grow(self, p: Vec3) -> Self {
        Self {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// The box around both boxes.
    #[inline]
    pub fn union(self, o: Aabb) -> Self {
        Self {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    /// The overlap of two boxes (empty if they are disjoint).
    #[inline]
    pub fn intersection(self, o: Aabb) -> Self {
        Self {
            min: self.min.max(o.min),
            max: self.max.min(o.max),
        }
    }

    /// Size per axis (`max - min`).
    #[inline]
    pub fn extent(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            self.max - self.min
        }
    }

    /// Centre point.
    #[inline]
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Surface area; 0 for an empty box.
    #[inline]
    pub fn surface_area(&self) -> f32 {
        2.0 * self.half_area()
    }

    /// Half the surface area (what SAH builders compare); 0 for an empty box.
    #[inline]
    pub fn half_area(&self) -> f32 {
        let e = self.extent();
        e.x * e.y + e.y * e.z + e.z * e.x
    }

    /// [`Self::half_area`] computed in `f64`: finite for every finite box (the `f32` area
    /// overflows for boxes wider than about 1e19), for statistics that sum and divide areas.
    #[inline]
    pub fn half_area_f64(&self) -> f64 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.max.as_dvec3() - self.min.as_dvec3();
        e.x * e.y + e.y * e.z + e.z * e.x
    }

    /// Whether the point at `t` of `ray` lies in the box up to half the box test's padding
    /// (`PAD / 2` of the ray's step along each axis): a hit this accepts, every structure's
    /// padded box test accepts too. The step `d t` is compared, in `f64`, with the faces'
    /// offsets from the origin (exact there but for far-apart magnitudes), not the point
    /// `o + d t` with the faces: far from the origin the point's own rounding exceeds the
    /// padding of a short step. The analytic kernels (spheres, cones) and the triangle's
    /// `f64` refinement check their hits with it: from far away (or on a cone far longer than
    /// wide, or a sliver seen edge-on) their `f64` depths lose the digits that place a hit.
    #[inline]
    pub fn holds_hit(&self, ray: &Ray, t: f32) -> bool {
        let (o, d) = (ray.origin().as_dvec3(), ray.dir().as_dvec3());
        let step = d * t as f64;
        (0..3).all(|k| {
            step_held(
                self.min[k] as f64 - o[k],
                self.max[k] as f64 - o[k],
                step[k],
            )
        })
    }

    /// The parameters at which `ray`'s line enters and leaves the box's slabs, in `f64` from
    /// the `f32` inputs (each one rounded once), the axes the ray does not move along left
    /// out and the ray's interval ignored: entry after exit where the line passes the box.
    pub(crate) fn slab_interval_f64(&self, ray: &Ray) -> (f64, f64) {
        let (o, d) = (ray.origin().to_array(), ray.dir().to_array());
        let (mut enter, mut exit) = (f64::NEG_INFINITY, f64::INFINITY);
        for a in (0..3).filter(|&a| d[a] != 0.0) {
            let (lo, hi, o, d) = (
                self.min[a] as f64,
                self.max[a] as f64,
                o[a] as f64,
                d[a] as f64,
            );
            let (t0, t1) = ((lo - o) / d, (hi - o) / d);
            enter = enter.max(t0.min(t1));
            exit = exit.min(t0.max(t1));
        }
        (enter, exit)
    }

    /// Index of the axis with the largest extent (0 = x).
    #[inline]
    pub fn largest_axis(&self) -> usize {
        let e = self.extent();
        if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        }
    }

    /// Whether `p` lies in the box, faces included.
    #[inline]
    pub fn contains_point(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// True when `o` lies inside `self` (an empty `o` is inside anything).
    #[inline]
    pub fn contains(&self, o: &Aabb) -> bool {
        o.is_empty() || (o.min.cmpge(self.min).all() && o.max.cmple(self.max).all())
    }

    /// The part `[t_enter, t_exit]` of `[ray.tmin, ray.tmax]` that lies in the box, or `None`.
    ///
    /// Robust in the sense of Ize (JCGT 2013): the far distance is enlarged by [`FAR_PAD`], so
    /// that a ray never passes between adjacent boxes, and the near distance is lowered by the
    /// same relative amount, so that a primitive hit lying on the box's face (whose `t` the
    /// primitive's kernel rounds differently) is never entered "too late" and culled. Zero
    /// direction components need no special case: `1/0 = inf` gives `+-inf` slab distances, and
    /// the NaN of `0 * inf` (origin exactly on a slab plane) leaves the interval unchanged,
    /// because every comparison with NaN is false. A ray lying in a face of the box enters it.
    ///
    /// The interval returned is the padded one: it may reach a few ulps beyond the box and
    /// beyond `ray.tmax`, never below `ray.tmin`.
    #[inline]
    pub fn clip_ray(&self, ray: &Ray) -> Option<(f32, f32)> {
        self.clip_ray_with_inv(ray, &ray.inv_dir().to_array())
    }

    /// [`Self::clip_ray`] with the ray's reciprocal direction already computed
    /// ([`Ray::inv_dir`], once per query by walks that clip many boxes).
    #[inline(always)]
    pub fn clip_ray_with_inv(&self, ray: &Ray, inv: &[f32; 3]) -> Option<(f32, f32)> {
        self.clip_interval(&ray.origin().to_array(), inv, (ray.tmin, ray.tmax))
    }

    /// [`Self::clip_ray`] of the ray from `o` with reciprocal direction `inv` over
    /// `[tmin, tmax]` (for walks that keep a ray's numbers as arrays).
    #[inline(always)]
    pub fn clip_interval(
        &self,
        o: &[f32; 3],
        inv: &[f32; 3],
        (tmin, tmax): (f32, f32),
    ) -> Option<(f32, f32)> {
        let mut t0 = tmin;
        let mut t1 = tmax;
        for a in 0..3 {
            let (near, far) = if inv[a].is_sign_negative() {
                (self.max[a], self.min[a])
            } else {
                (self.min[a], self.max[a])
            };
            let tn = (near - o[a]) * inv[a];
            let tf = (far - o[a]) * inv[a];
            if tn > t0 {
                t0 = tn;
            }
            if tf < t1 {
                t1 = tf;
            }
        }
        let t0 = pad_down(t0);
        let t1 = pad_up(t1);
        if t0 <= t1 {
            Some((t0.max(tmin), t1))
        } else {
            None
        }
    }

    /// Entry distance of the ray into the box (clamped to `ray.tmin`), or `None`.
    #[inline]
    pub fn hit_distance(&self, ray: &Ray) -> Option<f32> {
        self.clip_ray(ray).map(|(t0, _)| t0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit() -> Aabb {
        Aabb::new(Vec3::ZERO, Vec3::ONE)
    }

    #[test]
    fn empty_box_behaves() {
        let e = Aabb::EMPTY;
        assert!(e.is_empty());
        assert_eq!(e.surface_area(), 0.0);
        assert_eq!(e.union(unit()), unit());
        assert!(
            e.clip_ray(&Ray::new(Vec3::splat(-1.0), Vec3::ONE))
                .is_none()
        );
        assert!(
            unit()
                .intersection(Aabb::new(Vec3::splat(2.0), Vec3::splat(3.0)))
                .is_empty()
        );
    }

    #[test]
    fn slab_test_basic() {
        let r = Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X);
        let (t0, t1) = unit().clip_ray(&r).unwrap();
        assert!((1.0 - 1e-6..=1.0).contains(&t0));
        assert!((2.0..2.0 + 1e-5).contains(&t1));
        // Behind the origin.
        assert!(
            unit()
                .clip_ray(&Ray::new(Vec3::new(2.0, 0.5, 0.5), Vec3::X))
                .is_none()
        );
        // Starting inside: enters at tmin.
        let inside = Ray::new(Vec3::splat(0.5), Vec3::new(0.3, -1.0, 0.2));
        assert_eq!(unit().hit_distance(&inside), Some(0.0));
        // A hit on the face at exactly tmax still enters the box.
        assert!(unit().clip_ray(&r.with_range(0.0, 1.0)).is_some());
        // Limited by tmax before reaching the box.
        assert!(unit().clip_ray(&r.with_range(0.0, 0.5)).is_none());
    }

    #[test]
    fn rays_on_faces_and_edges_enter() {
        // Axis-parallel ray lying exactly in the face x = 0 (origin on the slab plane, dir.x = 0).
        let r = Ray::new(Vec3::new(0.0, 0.5, -1.0), Vec3::Z);
        assert!(unit().clip_ray(&r).is_some());
        let r = Ray::new(Vec3::new(1.0, 0.5, -1.0), Vec3::new(-0.0, 0.0, 1.0));
        assert!(unit().clip_ray(&r).is_some());
        // Along an edge.
        let r = Ray::new(Vec3::new(1.0, 1.0, -1.0), Vec3::Z);
        assert!(unit().clip_ray(&r).is_some());
        // Just outside the face: a miss.
        let r = Ray::new(Vec3::new(1.0 + 1e-6, 0.5, -1.0), Vec3::Z);
        assert!(unit().clip_ray(&r).is_none());
        // A flat box, the ray in its plane.
        let flat = Aabb::new(Vec3::new(0.0, 0.0, 0.5), Vec3::new(1.0, 1.0, 0.5));
        let r = Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X);
        assert!(flat.clip_ray(&r).is_some());
    }

    #[test]
    fn no_ray_slips_between_adjacent_boxes() {
        // Two boxes sharing the face x = 1/3 (not representable): rays through the shared face
        // at many angles must enter one of them.
        let s = 1.0f32 / 3.0;
        let a = Aabb::new(Vec3::ZERO, Vec3::new(s, 1.0, 1.0));
        let b = Aabb::new(Vec3::new(s, 0.0, 0.0), Vec3::ONE);
        let mut rnd = crate::test_uniform(12345);
        for _ in 0..100_000 {
            let target = Vec3::new(s, rnd(), rnd());
            let origin = Vec3::new(-3.0 * rnd(), 2.0 * rnd() - 0.5, 2.0 * rnd() - 0.5);
            let r = Ray::new(origin, target - origin);
            assert!(
                a.clip_ray(&r).is_some() || b.clip_ray(&r).is_some(),
                "{r:?}"
            );
        }
    }

    /// The exact (f64) interval of the ray in the box, with the same conventions as the slab
    /// test (NaN planes ignored).
    fn exact(b: &Aabb, r: &Ray) -> Option<(f64, f64)> {
        let (o, d) = (r.origin(), r.dir());
        if (0..3).any(|a| d[a] == 0.0 && (o[a] < b.min[a] || o[a] > b.max[a])) {
            return None;
        }
        let (enter, exit) = b.slab_interval_f64(r);
        let (t0, t1) = (enter.max(r.tmin as f64), exit.min(r.tmax as f64));
        (t0 <= t1).then_some((t0, t1))
    }

    /// `entry` is the ray's entry into `b` within its interval, or earlier (never before
    /// `tmin`), wherever the exact interval is not empty.
    fn assert_conservative(b: &Aabb, r: &Ray, entry: Option<f32>) {
        if let Some((t0, _)) = exact(b, r) {
            let t = entry.unwrap_or_else(|| panic!("missed {b:?} {r:?}"));
            assert!(
                t as f64 <= t0 && t >= r.tmin,
                "late entry {t} > {t0}: {b:?} {r:?}"
            );
        }
    }

    #[test]
    fn fused_slab_test_is_conservative_far_from_the_origin() {
        // Origins up to 2^24 from the world's origin (where the offset `-origin * inv` is
        // large and its rounding moves every plane's distance), boxes and rays near them,
        // many grazing: the fused form must still enter every box the exact interval enters.
        let mut rnd = crate::test_uniform(24681357);
        let mut hits = 0;
        for i in 0..100_000 {
            let far = Vec3::new(rnd(), rnd(), rnd()) * [1e3, 1e5, 1.6e7][i % 3];
            let c = far + Vec3::new(rnd(), rnd(), rnd()) * 20.0 - 10.0;
            let e = Vec3::new(rnd(), rnd(), rnd()) * [3.0, 0.01, 1.0][(i / 3) % 3];
            let b = Aabb::new(c - e, c + e);
            let mut o = far + Vec3::new(rnd(), rnd(), rnd()) * 30.0 - 15.0;
            if i % 5 == 0 {
                o[i % 3] = b.max[i % 3];
            }
            let target = b.min + (b.max - b.min) * Vec3::new(rnd(), rnd(), rnd()) * 1.2;
            let tmin = [0.0, 0.5 * rnd(), -rnd()][i % 3];
            let r = Ray::segment(o, target - o, tmin, f32::INFINITY);
            if !r.is_valid() {
                continue;
            }
            let slab = SlabRay::new(&r);
            for a in 0..3 {
                let exact = |inv: f32| -(o[a] as f64) * inv as f64;
                let [near, far] = slab.fused_offset.map(|off| off[a] as f64);
                if slab.fused_inv[0][a] == slab.inv_near[a] {
                    assert!(near <= exact(slab.inv_near[a]) && far >= exact(slab.inv_far[a]));
                }
            }
            let (min, max) = (b.min.to_array(), b.max.to_array());
            assert_conservative(&b, &r, slab.entry_fused(&min, &max, r.tmin, r.tmax));
            assert_conservative(&b, &r, slab.entry(&min, &max, r.tmin, r.tmax));
            hits += exact(&b, &r).is_some() as usize;
        }
        assert!(hits > 20_000, "{hits} hits");
    }

    #[test]
    fn slab_ray_is_conservative_and_agrees_with_clip_ray() {
        // Random boxes and rays, many of them grazing: origins on box planes, axis-parallel
        // directions, boxes just touched; intervals starting at 0, inside, and behind (tmin < 0).
        let mut rnd = crate::test_uniform(987654321);
        let (mut hits, mut differ) = (0, 0);
        for i in 0..200_000 {
            let c = Vec3::new(rnd(), rnd(), rnd()) * 20.0 - 10.0;
            let e = Vec3::new(rnd(), rnd(), rnd()) * [3.0, 0.01, 1.0][i % 3];
            let b = Aabb::new(c - e, c + e);
            let mut o = Vec3::new(rnd(), rnd(), rnd()) * 30.0 - 15.0;
            if i % 5 == 0 {
                o[i % 3] = b.min[i % 3];
            }
            let target = b.min + (b.max - b.min) * Vec3::new(rnd(), rnd(), rnd()) * 1.2;
            let mut d = target - o;
            if i % 7 == 0 {
                d[(i / 7) % 3] = if i % 2 == 0 { 0.0 } else { -0.0 };
            }
            let tmin = [0.0, 0.5 * rnd(), -rnd()][i % 3];
            let r = Ray::segment(o, d, tmin, [f32::INFINITY, 1.0, 2.0 * rnd()][i % 3]);
            if !r.is_valid() {
                continue;
            }
            let slab = SlabRay::new(&r);
            let (min, max) = (b.min.to_array(), b.max.to_array());
            let got = slab.entry(&min, &max, r.tmin, r.tmax);
            assert_conservative(&b, &r, got);
            assert_conservative(&b, &r, slab.entry_fused(&min, &max, r.tmin, r.tmax));
            if exact(&b, &r).is_some() {
                hits += 1;
            }
            // clip_ray pads `tmax` too: its entries beyond `tmax` are culled by every caller.
            let clip = b.clip_ray(&r).map(|(t0, _)| t0).filter(|&t| t <= r.tmax);
            if got.is_some() != clip.is_some() {
                differ += 1;
            } else if let (Some(x), Some(y)) = (got, clip) {
                assert!(
                    (x - y).abs() <= 4.0 * PAD * x.abs().max(y.abs()),
                    "{x} vs {y}"
                );
            }
        }
        assert!(hits > 20_000, "{hits} hits");
        // Only boxes touched within the padding may be judged differently.
        assert!(differ < 10, "{differ} differ from clip_ray");
    }
}
