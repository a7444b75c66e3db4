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

/// `(lo, hi)` widened by [`MARGIN`] relative to `scale`.
fn widen((lo, hi): (f32, f32), scale: f32) -> (f32, f32) {
    let m = scale * MARGIN;
    (lo - lo.abs() * MARGIN - m, hi + hi.abs() * MARGIN + m)
}

impl Beam {
    /// The beam of the active lanes in `lanes` of `p`. The main axis is the largest
    /// component of the lanes' summed directions, if all lanes share its sign.
    pub fn new<const N: usize>(p: &RayPacket<'_, N>, lanes: std::ops::Range<usize>) -> Self {
        let mut sum = [0.0f32; 3];
        let mut count = 0;
        for i in lanes.clone().filter(|&i| p.active[i]) {
            for (a, s) in sum.iter_mut().enumerate() {
                *s += p.dir[a][i];
            }
            count += 1;
        }
        let k = (0..3)
            .max_by(|&a, &b| sum[a].abs().total_cmp(&sum[b].abs()))
            .expect("three axes");
        let negative = sum[k] < 0.0;
        let none = (f32::INFINITY, f32::NEG_INFINITY);
        let mut beam = Self {
            main: Some(k),
            negative,
            origin: [none; 3],
            slope: [none; 3],
            travel: none,
            speed: 0.0,
            lanes: count,
        };
        let grow = |r: &mut (f32, f32), v: f32| *r = (r.0.min(v), r.1.max(v));
        for i in lanes.filter(|&i| p.active[i]) {
            let dk = p.dir[k][i];
            if (dk < 0.0) != negative || dk == 0.0 {
                beam.main = None;
                return beam;
            }
            let len = dk.abs();
            for a in 0..3 {
                grow(&mut beam.origin[a], p.origin[a][i]);
                grow(&mut beam.slope[a], p.dir[a][i] / len);
            }
            grow(&mut beam.travel, p.tmin[i] * len);
            grow(&mut beam.travel, p.tmax[i] * len);
            beam.speed = beam.speed.max(len);
        }
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
    pub fn may_enter(&self, min: &[f32; 3], max: &[f32; 3]) -> bool {
        if self.lanes == 0 {
            return false;
        }
        let Some(k) = self.main else {
            return true;
        };
        // The travel at which the beam can be inside the box's slab along k.
        let (o_lo, o_hi) = self.origin[k];
        let slab = if self.negative {
            (o_lo - max[k], o_hi - min[k])
        } else {
            (min[k] - o_hi, max[k] - o_lo)
        };
        let scale = min[k]
            .abs()
            .max(max[k].abs())
            .max(o_lo.abs())
            .max(o_hi.abs());
        let slab = widen(slab, scale);
        let travel = widen(self.travel, 0.0);
        let v = (slab.0.max(travel.0), slab.1.min(travel.1));
        if !(v.0 <= v.1) {
            return false;
        }
        for a in (0..3).filter(|&a| a != k) {
            let (o_lo, o_hi) = self.origin[a];
            let (s_lo, s_hi) = self.slope[a];
            // The range of v s over v in [v0, v1] (v >= 0 here: a beam ahead of its origins)
            // and s in the slope range; both ends finite (the box is).
            let (d_lo, d_hi) = if v.0 >= 0.0 {
                (
                    if s_lo >= 0.0 { v.0 * s_lo } else { v.1 * s_lo },
                    if s_hi >= 0.0 { v.1 * s_hi } else { v.0 * s_hi },
                )
            } else {
                product(v, self.slope[a])
            };
            let scale = min[a]
                .abs()
                .max(max[a].abs())
                .max(o_lo.abs().max(o_hi.abs()))
                .max(d_lo.abs().max(d_hi.abs()));
            let (lo, hi) = widen((o_lo + d_lo, o_hi + d_hi), scale);
            if hi < min[a] || lo > max[a] {
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

    #[test]
    fn a_box_some_lane_enters_is_never_culled() {
        // Rays of a small camera against boxes all over the place: whenever one lane's own
        // clip test enters, the beam must say it may.
        let rays: Vec<Ray> = (0..64)
            .map(|i| {
                let (x, y) = ((i % 8) as f32 / 8.0, (i / 8) as f32 / 8.0);
                Ray::new(
                    Vec3::new(0.0, 0.0, 5.0),
                    Vec3::new((x - 0.5) * 0.1, (y - 0.5) * 0.1, -1.0),
                )
            })
            .collect();
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
}
