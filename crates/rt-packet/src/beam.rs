//! A packet's rays as one beam, for culling boxes that none of them enters (the interval
//! arithmetic of Wald, Boulos & Shirley 2007, in the shape of Reshetov's beams): the lanes
//! share the sign of their direction along a *main axis* `k`, and every ray is written as
//! `p(v) = o + v s` with `v` the distance travelled along `k` and slopes `s = d / |d[k]|`.
//! The beam keeps per axis the range of the origins and of the slopes, and the range of `v`
//! over the lanes' `[tmin, tmax]`. Lanes of mixed signs on the other axes are fine (the slopes
//! then span zero), which is what a camera tile in the middle of the image has.
//!
//! A box is culled when the beam's `v` range misses the box's slab along `k`, or when, over
//! that range, the beam's points miss the box's slab along another axis. Every range is
//! widened by a relative margin far above the rounding of the lanes' own padded slab tests,
//! so a box that some lane enters is never culled.

use crate::RayPacket;
use crate::simd::F8;

/// Relative widening of every range the beam computes.
const MARGIN: f32 = 1e-5;

/// The bounds of some lanes of a packet.
#[derive(Clone, Debug)]
pub struct Beam {
    /// The main axis, or `None` when the lanes' directions do not share the sign of the
    /// largest component of their sum (the beam then culls nothing).
    main: Option<usize>,
    /// Whether the lanes travel towards `-inf` along the main axis.
    negative: bool,
    origin: [(f32, f32); 3],
    slope: [(f32, f32); 3],
    /// Range of the distance travelled along the main axis over the lanes' intervals.
    travel: (f32, f32),
    /// The largest `|d[k]|` over the lanes (travel per unit of `t`).
    speed: f32,
    lanes: usize,
}

/// `u s`, with `0 inf = 0` (an unbounded travel times a zero slope moves nowhere).
fn mul(u: f32, s: f32) -> f32 {
    if u == 0.0 || s == 0.0 { 0.0 } else { u * s }
}

/// The range of `u s` over `u` in `[u0, u1]` and `s` in `[s0, s1]`.
fn product((u0, u1): (f32, f32), (s0, s1): (f32, f32)) -> (f32, f32) {
    let c = [mul(u0, s0), mul(u0, s1), mul(u1, s0), mul(u1, s1)];
    (
        c.iter().copied().fold(f32::INFINITY, f32::min),
        c.iter().copied().fold(f32::NEG_INFINITY, f32::max),
    )
}

impl Beam {
    /// The beam of the active lanes in `lanes` of `p`. The main axis is the largest
    /// component of the lanes' summed directions, if all lanes share its sign.
    pub fn new<const N: usize>(p: &RayPacket<'_, N>, lanes: std::ops::Range<usize>) -> Self {
        Self::new_on::<wide::f32x8, N>(p, lanes)
    }

    /// [`Self::new`] on the vectors `V` of the level the caller runs at.
    #[inline(always)]
    pub(crate) fn new_on<V: F8, const N: usize>(
        p: &RayPacket<'_, N>,
        lanes: std::ops::Range<usize>,
    ) -> Self {
        let none = (f32::INFINITY, f32::NEG_INFINITY);
        let mut beam = Self {
            main: None,
            negative: false,
            origin: [none; 3],
            slope: [none; 3],
            travel: none,
            speed: 0.0,
            lanes: p.active[lanes.clone()].iter().filter(|&&a| a).count(),
        };
        // The main axis: the largest direction component of a lane from the middle of the
        // beam; every lane must share its sign (checked below).
        let mid = (lanes.start + lanes.end) / 2;
        let Some(rep) = (mid..lanes.end)
            .chain(lanes.start..mid)
            .find(|&i| p.active[i])
        else {
            return beam;
        };
        let k = (0..3)
            .max_by(|&a, &b| p.dir[a][rep].abs().total_cmp(&p.dir[b][rep].abs()))
            .expect("three axes");
        let negative = p.dir[k][rep] < 0.0;
        beam.negative = negative;
        // One pass over the lanes, 8 at a time. |1 / d[k]|: slopes d / |d[k]| by a
        // product (within an ulp of the quotient, far inside the beam's margin). Active lanes
        // hold no NaN (their direction along k is not zero); inactive ones take the numbers of
        // the lane `rep` (which change no range), and are those whose interval is empty
        // (`tmax` is `-inf` in inactive lanes; conservative for lanes made inactive otherwise).
        // Functions, not closures: see `rt_geom::isa`.
        #[inline(always)]
        fn numbers<const N: usize>(p: &RayPacket<'_, N>, k: usize, i: usize) -> [f32; 10] {
            let (rcp, speed) = (p.inv_dir[k][i].abs(), p.dir[k][i].abs());
            [
                p.origin[0][i],
                p.origin[1][i],
                p.origin[2][i],
                p.dir[0][i] * rcp,
                p.dir[1][i] * rcp,
                p.dir[2][i] * rcp,
                p.tmin[i] * speed,
                p.tmax[i] * speed,
                speed,
                p.dir[k][i],
            ]
        }
        #[inline(always)]
        fn fold<V: F8>(v: V, f: fn(f32, f32) -> f32, init: f32) -> f32 {
            v.to_array().into_iter().fold(init, f)
        }
        let rep_numbers = numbers(p, k, rep).map(V::splat);
        let (mut lo8, mut hi8) = (rep_numbers, rep_numbers);
        let mut i = lanes.start;
        while i + 8 <= lanes.end {
            let (tmin, tmax) = (V::load(&p.tmin[i..]), V::load(&p.tmax[i..]));
            let on = tmin.le(tmax);
            let rcp = V::load(&p.inv_dir[k][i..]).abs();
            let dk = V::load(&p.dir[k][i..]);
            let speed = dk.abs();
            let v = [
                V::load(&p.origin[0][i..]),
                V::load(&p.origin[1][i..]),
                V::load(&p.origin[2][i..]),
                V::load(&p.dir[0][i..]) * rcp,
                V::load(&p.dir[1][i..]) * rcp,
                V::load(&p.dir[2][i..]) * rcp,
                tmin * speed,
                tmax * speed,
                speed,
                dk,
            ];
            for j in 0..v.len() {
                let v = on.select(v[j], rep_numbers[j]);
                lo8[j] = lo8[j].min(v);
                hi8[j] = hi8[j].max(v);
            }
            i += 8;
        }
        let mut lo = [0.0f32; 10];
        let mut hi = [0.0f32; 10];
        for j in 0..10 {
            lo[j] = fold(lo8[j], f32::min, f32::INFINITY);
            hi[j] = fold(hi8[j], f32::max, f32::NEG_INFINITY);
        }
        // The lanes past the last block of 8.
        for i in (i..lanes.end).filter(|&i| p.active[i]) {
            let v = numbers(p, k, i);
            for j in 0..v.len() {
                lo[j] = lo[j].min(v[j]);
                hi[j] = hi[j].max(v[j]);
            }
        }
        beam.speed = hi[8];
        let dk = (lo[9], hi[9]);
        // One sign along k over all lanes (no zero component), or no main axis.
        if !(if negative { dk.1 < 0.0 } else { dk.0 > 0.0 }) {
            return beam;
        }
        beam.main = Some(k);
        for a in 0..3 {
            beam.origin[a] = (lo[a], hi[a]);
            beam.slope[a] = (lo[3 + a], hi[3 + a]);
        }
        beam.travel = (lo[6], hi[7]);
        beam
    }

    /// Ends the beam where every lane's interval ends by `tmax` at the latest (their closest
    /// hits so far): boxes beyond are culled from then on.
    pub fn limit(&mut self, tmax: f32) {
        // (A negative end would not bound lanes slower than the fastest: left alone.)
        if tmax >= 0.0 || tmax == f32::NEG_INFINITY {
            self.travel.1 = self.travel.1.min(tmax * self.speed);
        }
    }

    /// [`Self::limit`] to the largest `tmax` of the lanes of `range` of `p`: their closest
    /// hits so far bound how far the beam may still find one. Inactive lanes hold `-inf`
    /// (see [`RayPacket`]'s `tmax`), so no lane is filtered: eight lanes are one `max`.
    pub fn limit_to_lanes<const N: usize>(
        &mut self,
        p: &RayPacket<'_, N>,
        range: std::ops::Range<usize>,
    ) {
        self.limit_to_lanes_on::<wide::f32x8, N>(p, range)
    }

    /// [`Self::limit_to_lanes`] on the vectors `V` of the level the caller runs at.
    #[inline(always)]
    pub(crate) fn limit_to_lanes_on<V: F8, const N: usize>(
        &mut self,
        p: &RayPacket<'_, N>,
        range: std::ops::Range<usize>,
    ) {
        let ninf = f32::NEG_INFINITY;
        let mut far = V::splat(ninf);
        let mut end = range.start;
        let mut base = range.start;
        while base + 8 <= range.end {
            far = far.max(V::load(&p.tmax[base..]));
            base += 8;
            end = base;
        }
        let far = far.to_array().into_iter().fold(ninf, f32::max);
        self.limit(p.tmax[end..range.end].iter().fold(far, |m, &t| m.max(t)));
    }

    /// The lanes' common direction sign along `axis` (`Some(true)`: all negative), if any.
    pub fn sign(&self, axis: usize) -> Option<bool> {
        let (lo, hi) = self.slope[axis];
        if self.main.is_none() || self.lanes == 0 {
            None
        } else if hi < 0.0 {
            Some(true)
        } else if lo > 0.0 {
            Some(false)
        } else {
            None
        }
    }

    /// Number of active lanes in the beam.
    pub fn lanes(&self) -> usize {
        self.lanes
    }

    /// False only when no lane of the beam can enter the box `[min, max]` (each lane's own
    /// padded slab test would fail).
    #[inline(always)]
    pub fn may_enter(&self, min: &[f32; 3], max: &[f32; 3]) -> bool {
        if self.lanes == 0 {
            return false;
        }
        let Some(k) = self.main else {
            return true;
        };
        // The travel at which the beam can be inside the box's slab along k. Margins: MARGIN
        // times a sum of the magnitudes involved (which bounds each of them).
        let (o_lo, o_hi) = self.origin[k];
        let (s0, s1) = if self.negative {
            (o_lo - max[k], o_hi - min[k])
        } else {
            (min[k] - o_hi, max[k] - o_lo)
        };
        let m = 2.0 * MARGIN * (min[k].abs() + max[k].abs() + o_lo.abs() + o_hi.abs());
        let (t0, t1) = self.travel;
        let t0 = t0 - t0.abs() * MARGIN;
        let t1 = t1 + t1.abs() * MARGIN;
        let v0 = if s0 - m > t0 { s0 - m } else { t0 };
        let v1 = if s1 + m < t1 { s1 + m } else { t1 };
        if !(v0 <= v1) {
            return false;
        }
        for a in (0..3).filter(|&a| a != k) {
            let (o_lo, o_hi) = self.origin[a];
            let (s_lo, s_hi) = self.slope[a];
            // The range of v s over v in [v0, v1] (v >= 0 here: a beam ahead of its origins)
            // and s in the slope range; both ends finite (the box is).
            let (d_lo, d_hi) = if v0 >= 0.0 {
                (
                    if s_lo >= 0.0 { v0 * s_lo } else { v1 * s_lo },
                    if s_hi >= 0.0 { v1 * s_hi } else { v0 * s_hi },
                )
            } else {
                product((v0, v1), self.slope[a])
            };
            let m = 2.0
                * MARGIN
                * (min[a].abs() + max[a].abs() + o_lo.abs() + o_hi.abs() + d_lo.abs() + d_hi.abs());
            if o_hi + d_hi + m < min[a] || o_lo + d_lo - m > max[a] {
                return false;
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_geom::{Aabb, Ray, Vec3};

    /// 8x8 rays of a small camera at `z = 5` looking down `-z`, spread `spread` wide at `t = 1`.
    fn camera(spread: f32) -> Vec<Ray> {
        (0..64)
            .map(|i| {
                let (x, y) = ((i % 8) as f32 / 8.0, (i / 8) as f32 / 8.0);
                Ray::new(
                    Vec3::new(0.0, 0.0, 5.0),
                    Vec3::new((x - 0.5) * spread, (y - 0.5) * spread, -1.0),
                )
            })
            .collect()
    }

    #[test]
    fn a_box_some_lane_enters_is_never_culled() {
        // Rays of a small camera against boxes all over the place: whenever one lane's own
        // clip test enters, the beam must say it may.
        let rays = camera(0.1);
        let p = RayPacket::<64>::new(&rays);
        let beam = Beam::new(&p, 0..64);
        let mut culled = 0;
        for k in 0..2000u32 {
            let f =
                |s: u32| ((k.wrapping_mul(2654435761).rotate_left(s) % 1000) as f32) / 250.0 - 2.0;
            let c = Vec3::new(f(0), f(7), f(13) - 1.0);
            let b = Aabb::new(c, c + Vec3::splat(0.05 + f(21).abs() * 0.05));
            let any = rays.iter().any(|r| b.clip_ray(r).is_some());
            let may = beam.may_enter(&b.min.to_array(), &b.max.to_array());
            assert!(may || !any, "box {b:?} culled but entered");
            culled += (!may) as u32;
        }
        assert!(
            culled > 500,
            "the beam culls most far-away boxes ({culled})"
        );
    }

    #[test]
    fn a_beam_limited_to_its_lanes_hits_keeps_every_box_before_them() {
        // The lanes' intervals end at hits from 4 to 7 (some lanes done: `-inf`); a box that a
        // lane enters before its own end is kept, and boxes past every end are culled.
        let rays = camera(0.2);
        let mut p = RayPacket::<64>::new(&rays);
        for i in 0..64 {
            p.tmax[i] = 4.0 + (i * 37 % 64) as f32 * 3.0 / 63.0;
            if i % 9 == 4 {
                p.active[i] = false;
                p.tmax[i] = f32::NEG_INFINITY;
            }
        }
        let mut beam = Beam::new(&p, 0..64);
        beam.limit_to_lanes(&p, 0..64);
        let (mut kept, mut culled) = (0, 0);
        // Small boxes along each lane's ray, from half its end to past it, and far beyond.
        for k in 0..4000u32 {
            let f = |s: u32| ((k.wrapping_mul(2654435761).rotate_left(s) % 1000) as f32) / 1000.0;
            let (i, s) = (k as usize % 64, 0.5 + f(3) * 0.7);
            let end = if p.tmax[i].is_finite() {
                p.tmax[i]
            } else {
                5.0
            };
            let c = rays[i].at(end * s) + Vec3::new(f(9), f(17), f(25)) * 0.01;
            let b = Aabb::new(c - Vec3::splat(0.004), c + Vec3::splat(0.004));
            let entered = (0..64).any(|i| p.active[i] && b.clip_ray(&p.ray(i)).is_some());
            let may = beam.may_enter(&b.min.to_array(), &b.max.to_array());
            assert!(may || !entered, "box {b:?} culled but entered");
            kept += entered as u32;
            culled += (!may) as u32;
        }
        assert!(kept > 300, "boxes entered before the hits ({kept})");
        assert!(culled > 200, "boxes past every hit culled ({culled})");
    }
}
