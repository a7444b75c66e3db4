//! The naive planes the classic builders start from: the middle of the node's largest extent, or the
//! centre of gravity of its geometry along that axis.

use super::events::{END, PLANAR, START};
use super::{NodeInput, Split};
use crate::params::KdBuilder;

/// The plane of `builder` (`Midpoint` or `Centroid`), or `None` for a node with no extent.
pub(super) fn choose(input: &NodeInput, builder: KdBuilder) -> Option<Split> {
    let b = &input.bounds;
    let axis = b.largest_axis();
    let (lo, hi) = (b.min[axis], b.max[axis]);
    if !(hi > lo) {
        return None;
    }
    let pos = match builder {
        KdBuilder::Centroid => {
            // Each primitive's clipped box centre: (start + end) / 2, or its planar position.
            let mut sum = 0.0f64;
            for e in &input.events[axis] {
                sum += match e.kind() {
                    START | END => 0.5 * e.pos as f64,
                    PLANAR => e.pos as f64,
                    _ => 0.0,
                };
            }
            (sum / input.ids.len() as f64) as f32
        }
        _ => 0.5 * lo + 0.5 * hi,
    };
    // Rounding may land on the boundary; the middle is the fallback.
    let pos = if pos > lo && pos < hi {
        pos
    } else {
        0.5 * lo + 0.5 * hi
    };
    (pos > lo && pos < hi).then_some(Split {
        axis,
        pos,
        planar_below: true,
    })
}
