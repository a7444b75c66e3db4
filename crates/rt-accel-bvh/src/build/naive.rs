//! The naive splits the SAH is measured against: largest-extent midpoint, and object median.

use super::{Box4, PrimRef, Split};
use rt_geom::Aabb;

/// Partition at the middle of the largest centroid extent; the median when one side would be
/// empty.
pub(crate) fn midpoint(refs: &mut [PrimRef], centroids: &Aabb) -> Split {
    let axis = centroids.largest_axis();
    let extent = centroids.extent()[axis];
    if !(extent > 0.0) {
        return median(refs, centroids);
    }
    let mid = centroids.center()[axis];
    let (split, _) = partition(refs, |r| r.centroid()[axis] < mid);
    if split == 0 || split == refs.len() {
        return median(refs, centroids);
    }
    Split::At {
        mid: split,
        axis,
        sides: None,
    }
}

/// Partition at the median centroid along the largest centroid extent (by index when all
/// centroids coincide, so that the two halves are always non-empty).
pub(crate) fn median(refs: &mut [PrimRef], centroids: &Aabb) -> Split {
    if refs.len() < 2 {
        return Split::Leaf;
    }
    let axis = centroids.largest_axis();
    let mid = refs.len() / 2;
    refs.select_nth_unstable_by(mid, |a, b| {
        a.centroid()[axis].total_cmp(&b.centroid()[axis])
    });
    Split::At {
        mid,
        axis,
        sides: None,
    }
}

/// Moves the references satisfying `left` to the front; returns how many there are and the
/// centroid boxes of the two sides (grown as each reference finds its side).
pub(crate) fn partition(
    refs: &mut [PrimRef],
    left: impl Fn(&PrimRef) -> bool,
) -> (usize, [Aabb; 2]) {
    let (mut lc, mut rc) = (Box4::EMPTY, Box4::EMPTY);
    let mut i = 0;
    let mut j = refs.len();
    while i < j {
        let r = refs[i];
        if left(&r) {
            lc = lc.grow(r.centroid4());
            i += 1;
        } else {
            rc = rc.grow(r.centroid4());
            j -= 1;
            refs.swap(i, j);
        }
    }
    (i, [lc.aabb(), rc.aabb()])
}
