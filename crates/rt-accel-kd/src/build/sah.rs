//! The SAH sweep (Wald & Havran 2006, algorithm 4): one pass over each axis's sorted events
//! finds the cheapest plane among all faces of the primitives' clipped boxes.

use super::events::{END, PLANAR, START};
use super::{NodeInput, Split};
use crate::params::KdParams;

/// Cost of splitting at `pos`: `lambda * (K_T + K_I * (P_below n_below + P_above n_above))`,
/// with the probabilities from surface areas and `lambda = 1 - empty_bonus` when a child of
/// non-zero thickness is empty.
struct Costs {
    inv_area: f32,
    lo: f32,
    hi: f32,
    /// Half areas are `cross + ext * perimeter` for a child of extent `ext` along the axis.
    cross: f32,
    perimeter: f32,
    kt: f32,
    ki: f32,
    bonus: f32,
}

impl Costs {
    #[inline]
    fn cost(&self, pos: f32, n_below: usize, n_above: usize) -> f32 {
        let area_below = self.cross + (pos - self.lo) * self.perimeter;
        let area_above = self.cross + (self.hi - pos) * self.perimeter;
        let c = self.kt
            + self.ki * self.inv_area * (area_below * n_below as f32 + area_above * n_above as f32);
        let empty = (n_below == 0 && pos > self.lo) || (n_above == 0 && pos < self.hi);
        if empty { c * (1.0 - self.bonus) } else { c }
    }
}

/// The cheapest split of the node, or `None` when no split costs less than a leaf.
pub(super) fn best_split(input: &NodeInput, params: &KdParams) -> Option<Split> {
    let n = input.ids.len();
    let b = &input.bounds;
    let area = b.half_area();
    if !(area > 0.0) {
        return None;
    }
    let e = b.extent();
    let leaf_cost = params.intersection_cost * n as f32;
    let mut best: Option<(f32, Split)> = None;
    for (axis, events) in input.events.iter().enumerate() {
        let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
        let costs = Costs {
            inv_area: 1.0 / area,
            lo: b.min[axis],
            hi: b.max[axis],
            cross: e[i] * e[j],
            perimeter: e[i] + e[j],
            kt: params.traversal_cost,
            ki: params.intersection_cost,
            bonus: params.empty_bonus,
        };
        let (mut n_below, mut n_above) = (0usize, n);
        let mut k = 0;
        while k < events.len() {
            let pos = events[k].pos;
            let count = |k: &mut usize, kind| {
                let mut c = 0;
                while *k < events.len() && events[*k].pos == pos && events[*k].kind() == kind {
                    c += 1;
                    *k += 1;
                }
                c
            };
            let ending = count(&mut k, END);
            let planar = count(&mut k, PLANAR);
            let starting = count(&mut k, START);
            n_above -= planar + ending;
            // Planar primitives below, then above: keep the cheaper.
            let c_below = costs.cost(pos, n_below + planar, n_above);
            let c_above = costs.cost(pos, n_below, n_above + planar);
            let (c, planar_below) = if c_below <= c_above {
                (c_below, true)
            } else {
                (c_above, false)
            };
            if best.is_none_or(|(bc, _)| c < bc) {
                best = Some((
                    c,
                    Split {
                        axis,
                        pos,
                        planar_below,
                    },
                ));
            }
            n_below += starting + planar;
        }
    }
    best.filter(|(c, _)| *c < leaf_cost).map(|(_, s)| s)
}
