//! Surface area heuristic splits: binned (Wald 2007) and full sweep.

use super::naive::partition;
use super::{PrimRef, Split, split_cost};
use crate::params::BvhParams;
use rayon::prelude::*;
use rt_geom::Aabb;

/// Box and centroid box of the references, in parallel.
pub(crate) fn parallel_bounds(refs: &[PrimRef]) -> (Aabb, Aabb) {
    refs.par_chunks(8192)
        .map(|c| {
            c.iter().fold((Aabb::EMPTY, Aabb::EMPTY), |(b, cb), r| {
                (b.union(r.bounds), cb.grow(r.centroid))
            })
        })
        .reduce(
            || (Aabb::EMPTY, Aabb::EMPTY),
            |(a, b), (c, d)| (a.union(c), b.union(d)),
        )
}

#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: usize,
}

const EMPTY_BIN: Bin = Bin {
    bounds: Aabb::EMPTY,
    count: 0,
};

/// Per-axis bins of a range.
#[derive(Clone)]
struct Bins {
    axes: [Vec<Bin>; 3],
}

impl Bins {
    fn new(k: usize) -> Self {
        Self {
            axes: [vec![EMPTY_BIN; k], vec![EMPTY_BIN; k], vec![EMPTY_BIN; k]],
        }
    }

    fn merge(mut self, other: Bins) -> Bins {
        for (a, b) in self.axes.iter_mut().zip(other.axes) {
            for (x, y) in a.iter_mut().zip(b) {
                x.bounds = x.bounds.union(y.bounds);
                x.count += y.count;
            }
        }
        self
    }
}

/// Maps a centroid coordinate to a bin in `0..k`.
#[derive(Clone, Copy)]
struct Binner {
    min: [f32; 3],
    scale: [f32; 3],
    k: usize,
}

impl Binner {
    #[inline]
    fn bin(&self, r: &PrimRef, axis: usize) -> usize {
        let b = ((r.centroid[axis] - self.min[axis]) * self.scale[axis]) as usize;
        b.min(self.k - 1)
    }

    fn fill(&self, refs: &[PrimRef]) -> Bins {
        let mut bins = Bins::new(self.k);
        for r in refs {
            for axis in 0..3 {
                if self.scale[axis] > 0.0 {
                    let b = &mut bins.axes[axis][self.bin(r, axis)];
                    b.bounds = b.bounds.union(r.bounds);
                    b.count += 1;
                }
            }
        }
        bins
    }
}

/// The best binned object split found for a range of references.
pub(crate) struct ObjectSplit {
    pub cost: f32,
    pub axis: usize,
    /// First bin on the right.
    plane: usize,
    binner: Binner,
    /// Boxes of the two sides (for the spatial-split overlap test).
    pub left: Aabb,
    pub right: Aabb,
}

impl ObjectSplit {
    /// Whether a reference goes to the left side.
    #[inline]
    pub fn is_left(&self, r: &PrimRef) -> bool {
        self.binner.bin(r, self.axis) < self.plane
    }
}

/// The cheapest binned SAH object split (`bins` per axis), or `None` when all centroids
/// coincide.
pub(crate) fn best_binned(
    refs: &[PrimRef],
    bounds: &Aabb,
    centroids: &Aabb,
    bins: u32,
    params: &BvhParams,
) -> Option<ObjectSplit> {
    // Small ranges need no more bins than references (fewer bins to fill and sweep).
    let k = (bins as usize).min(refs.len().next_power_of_two().max(4));
    let extent = centroids.extent();
    let mut binner = Binner {
        min: centroids.min.to_array(),
        scale: [0.0; 3],
        k,
    };
    for axis in 0..3 {
        if extent[axis] > 0.0 {
            // Slightly below k / extent so that the largest centroid lands in bin k - 1.
            binner.scale[axis] = k as f32 * (1.0 - 1e-6) / extent[axis];
        }
    }
    if binner.scale == [0.0; 3] {
        return None;
    }
    let filled = if refs.len() > params.parallel_threshold {
        refs.par_chunks(16384)
            .map(|c| binner.fill(c))
            .reduce(|| Bins::new(k), Bins::merge)
    } else {
        binner.fill(refs)
    };
    let parent = bounds.half_area();
    let mut best: Option<ObjectSplit> = None;
    let mut right_box = vec![Aabb::EMPTY; k];
    for axis in 0..3 {
        if binner.scale[axis] == 0.0 {
            continue;
        }
        let bins = &filled.axes[axis];
        let mut acc = Aabb::EMPTY;
        for i in (1..k).rev() {
            acc = acc.union(bins[i].bounds);
            right_box[i] = acc;
        }
        let mut left = Aabb::EMPTY;
        let mut nl = 0;
        let total = refs.len();
        for i in 1..k {
            left = left.union(bins[i - 1].bounds);
            nl += bins[i - 1].count;
            let nr = total - nl;
            if nl == 0 || nr == 0 {
                continue;
            }
            let cost = split_cost(
                params,
                parent,
                (left.half_area(), nl),
                (right_box[i].half_area(), nr),
            );
            if best.as_ref().is_none_or(|b| cost < b.cost) {
                best = Some(ObjectSplit {
                    cost,
                    axis,
                    plane: i,
                    binner,
                    left,
                    right: right_box[i],
                });
            }
        }
    }
    best
}

/// The best binned SAH split (`bins` per axis), or `Leaf` when a leaf is cheaper and allowed.
pub(crate) fn binned(
    refs: &mut [PrimRef],
    bounds: &Aabb,
    centroids: &Aabb,
    bins: u32,
    params: &BvhParams,
) -> Split {
    let Some(best) = best_binned(refs, bounds, centroids, bins, params) else {
        return Split::Leaf;
    };
    let leaf_cost = params.intersection_cost * refs.len() as f32;
    if refs.len() <= params.max_leaf_size as usize && leaf_cost <= best.cost {
        return Split::Leaf;
    }
    let mid = partition(refs, |r| best.is_left(r));
    Split::At {
        mid,
        axis: best.axis,
    }
}

/// The best SAH split over all `n - 1` positions between sorted centroids on each axis.
pub(crate) fn sweep(refs: &mut [PrimRef], bounds: &Aabb, params: &BvhParams) -> Split {
    let n = refs.len();
    let parent = bounds.half_area();
    let mut best: Option<(f32, usize, usize)> = None;
    let mut right_area = vec![0.0f32; n];
    for axis in 0..3 {
        sort_along(refs, axis);
        let mut acc = Aabb::EMPTY;
        for i in (1..n).rev() {
            acc = acc.union(refs[i].bounds);
            right_area[i] = acc.half_area();
        }
        let mut left = Aabb::EMPTY;
        for i in 1..n {
            left = left.union(refs[i - 1].bounds);
            let cost = split_cost(
                params,
                parent,
                (left.half_area(), i),
                (right_area[i], n - i),
            );
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, i));
            }
        }
    }
    let Some((cost, axis, mid)) = best else {
        return Split::Leaf;
    };
    let leaf_cost = params.intersection_cost * n as f32;
    if n <= params.max_leaf_size as usize && leaf_cost <= cost {
        return Split::Leaf;
    }
    sort_along(refs, axis);
    Split::At { mid, axis }
}

fn sort_along(refs: &mut [PrimRef], axis: usize) {
    refs.sort_unstable_by(|a, b| {
        a.centroid[axis]
            .total_cmp(&b.centroid[axis])
            .then(a.index.cmp(&b.index))
    });
}
