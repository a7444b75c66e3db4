//! Surface area heuristic splits: binned (Wald 2007) and full sweep.
//!
//! The binned builder touches each reference twice per level: once to bin it (its box into one
//! bin per axis, SIMD lanes), once to partition it (growing each side's centroid box on the
//! way). The two sides' boxes come from the bins, so no level recomputes them.

use super::naive::partition;
use super::{Box4, PrimRef, SideBounds, Split, split_cost};
use crate::params::BvhParams;
use rayon::prelude::*;
use rt_geom::Aabb;
use rt_geom::glam::Vec4;

/// Box and centroid box of the references, in parallel.
pub(crate) fn parallel_bounds(refs: &[PrimRef]) -> SideBounds {
    refs.par_chunks(8192).map(super::bounds_of).reduce(
        || (Aabb::EMPTY, Aabb::EMPTY),
        |(a, b), (c, d)| (a.union(c), b.union(d)),
    )
}

/// Most bins per axis ([`BvhParams::validate`] allows 2..=256).
const MAX_BINS: usize = 256;

/// The bins of a range along the three axes, `k` per axis, axis `a`'s bin `i` at
/// `a * MAX_BINS + i` (fixed strides, so that indexing needs no bounds checks). Kept between
/// nodes of one build so that binning allocates nothing; only the first `k` of each axis are
/// reset per node.
#[derive(Clone, Default)]
pub(crate) struct Bins {
    k: usize,
    boxes: Vec<Box4>,
    counts: Vec<u32>,
    /// Scratch for the sweep: area and count of everything right of each plane.
    right: Vec<(f32, u32)>,
}

impl Bins {
    fn with_k(k: usize) -> Self {
        let mut bins = Bins::default();
        bins.reset(k);
        bins
    }

    /// Empties the bins and sizes them for `k` per axis.
    fn reset(&mut self, k: usize) {
        debug_assert!((1..=MAX_BINS).contains(&k));
        if self.boxes.is_empty() {
            self.boxes = vec![Box4::EMPTY; 3 * MAX_BINS];
            self.counts = vec![0; 3 * MAX_BINS];
            self.right = vec![(0.0, 0); MAX_BINS];
        }
        self.k = k;
        for axis in 0..3 {
            self.boxes[axis * MAX_BINS..][..k].fill(Box4::EMPTY);
            self.counts[axis * MAX_BINS..][..k].fill(0);
        }
    }

    fn merge(mut self, other: Bins) -> Bins {
        for axis in 0..3 {
            let range = axis * MAX_BINS..axis * MAX_BINS + self.k;
            for (a, b) in self.boxes[range.clone()]
                .iter_mut()
                .zip(&other.boxes[range.clone()])
            {
                *a = a.union(*b);
            }
            for (a, b) in self.counts[range.clone()]
                .iter_mut()
                .zip(&other.counts[range])
            {
                *a += b;
            }
        }
        self
    }

    /// The `k` bins of `axis`: boxes and counts.
    fn axis(&self, axis: usize) -> (&[Box4], &[u32]) {
        let start = axis * MAX_BINS;
        (
            &self.boxes[start..start + self.k],
            &self.counts[start..start + self.k],
        )
    }
}

/// Maps a centroid to a bin in `0..k` on each axis (all three in one SIMD computation).
#[derive(Clone, Copy)]
struct Binner {
    min: Vec4,
    /// 0 on axes whose centroids all coincide (everything in bin 0).
    scale: Vec4,
    /// `k - 1` in every lane.
    last: Vec4,
}

impl Binner {
    fn new(centroids: &Aabb, k: usize) -> Option<Self> {
        let extent = centroids.extent();
        let mut scale = [0.0; 4];
        for axis in 0..3 {
            if extent[axis] > 0.0 {
                // Slightly below k / extent so that the largest centroid lands in bin k - 1.
                scale[axis] = k as f32 * (1.0 - 1e-6) / extent[axis];
            }
        }
        (scale != [0.0; 4]).then(|| Binner {
            min: centroids.min.extend(0.0),
            scale: Vec4::from_array(scale),
            last: Vec4::splat((k - 1) as f32),
        })
    }

    /// Bin of `r` on each axis (lanes x, y, z). Clamped in floating point first, so that the
    /// conversion is one SIMD truncation (the centroids are finite: inputs are checked).
    #[inline]
    fn bins(&self, r: &PrimRef) -> [i32; 4] {
        let b = ((r.centroid4() - self.min) * self.scale).clamp(Vec4::ZERO, self.last);
        wide::f32x4::from(b.to_array()).fast_trunc_int().to_array()
    }

    #[inline]
    fn bin(&self, r: &PrimRef, axis: usize) -> usize {
        self.bins(r)[axis] as usize
    }

    fn fill(&self, refs: &[PrimRef], bins: &mut Bins) {
        let boxes: &mut [Box4; 3 * MAX_BINS] = (&mut bins.boxes[..]).try_into().expect("reset");
        let counts: &mut [u32; 3 * MAX_BINS] = (&mut bins.counts[..]).try_into().expect("reset");
        for r in refs {
            let b = self.bins(r);
            let bounds = r.box4();
            #[allow(clippy::needless_range_loop)] // indexing by axis compiles to less code here
            for axis in 0..3 {
                let i = axis * MAX_BINS + (b[axis] as usize & (MAX_BINS - 1));
                boxes[i] = boxes[i].union(bounds);
                counts[i] += 1;
            }
        }
    }
}

/// The best binned object split found for a range of references.
pub(crate) struct ObjectSplit {
    pub cost: f32,
    pub axis: usize,
    /// First bin on the right.
    plane: usize,
    binner: Binner,
    /// Boxes of the two sides.
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
/// coincide. `scratch` holds the bins.
pub(crate) fn best_binned(
    refs: &[PrimRef],
    bounds: &Aabb,
    centroids: &Aabb,
    bins: u32,
    params: &BvhParams,
    scratch: &mut Bins,
) -> Option<ObjectSplit> {
    // Small ranges need no more bins than references (fewer bins to fill and sweep).
    let k = (bins as usize).min(refs.len());
    let binner = Binner::new(centroids, k)?;
    if refs.len() > params.parallel_threshold {
        *scratch = refs
            .par_chunks(16384)
            .map(|c| {
                let mut bins = Bins::with_k(k);
                binner.fill(c, &mut bins);
                bins
            })
            .reduce(|| Bins::with_k(k), Bins::merge);
    } else {
        scratch.reset(k);
        binner.fill(refs, scratch);
    }
    let bins = scratch;
    // Sweep each axis: right-to-left for the areas and counts right of each plane, then
    // left-to-right for the cost `area_l * n_l + area_r * n_r` (the SAH up to constants).
    // A side with no reference has an empty box, whose "area" is infinite: its cost is
    // inf * 0 = NaN, which never compares below the best.
    let (mut best_cost, mut best) = (f32::INFINITY, None);
    let mut right = std::mem::take(&mut bins.right);
    for axis in 0..3 {
        if binner.scale[axis] == 0.0 {
            continue;
        }
        let (boxes, counts) = bins.axis(axis);
        let right = &mut right[..k];
        let (mut acc, mut n) = (Box4::EMPTY, 0);
        for i in (1..k).rev() {
            acc = acc.union(boxes[i]);
            n += counts[i];
            right[i] = (acc.half_area(), n);
        }
        let (mut left, mut nl) = (Box4::EMPTY, 0);
        for i in 1..k {
            left = left.union(boxes[i - 1]);
            nl += counts[i - 1];
            let (ar, nr) = right[i];
            let cost =
                left.half_area() * params.tests(nl as usize) + ar * params.tests(nr as usize);
            if cost < best_cost {
                (best_cost, best) = (cost, Some((axis, i)));
            }
        }
    }
    bins.right = right;
    let (axis, plane) = best?;
    let (boxes, counts) = bins.axis(axis);
    let union = |b: &[Box4]| b.iter().fold(Box4::EMPTY, |a, b| a.union(*b));
    let (left, right) = (union(&boxes[..plane]), union(&boxes[plane..]));
    let nl: u32 = counts[..plane].iter().sum();
    let cost = split_cost(
        params,
        bounds.half_area(),
        (left.half_area(), nl as usize),
        (right.half_area(), refs.len() - nl as usize),
    );
    Some(ObjectSplit {
        cost,
        axis,
        plane,
        binner,
        left: left.aabb(),
        right: right.aabb(),
    })
}

/// The best binned SAH split (`bins` per axis), or `Leaf` when a leaf is cheaper and allowed.
pub(crate) fn binned(
    refs: &mut [PrimRef],
    bounds: &Aabb,
    centroids: &Aabb,
    bins: u32,
    params: &BvhParams,
    scratch: &mut Bins,
) -> Split {
    if refs.len() <= SMALL {
        return small(refs, bounds, params);
    }
    let Some(best) = best_binned(refs, bounds, centroids, bins, params, scratch) else {
        return Split::Leaf;
    };
    let leaf_cost = params.leaf_cost(refs.len());
    if refs.len() <= params.max_leaf_size as usize && leaf_cost <= best.cost {
        return Split::Leaf;
    }
    let (mid, [lc, rc]) = partition(refs, |r| best.is_left(r));
    Split::At {
        mid,
        axis: best.axis,
        sides: Some([(best.left, lc), (best.right, rc)]),
    }
}

/// Ranges up to this size are split by an exact sweep over their sorted centroids rather than
/// by bins: cheaper than filling and sweeping the bins, and never worse.
const SMALL: usize = 8;
const _: () = assert!(SMALL == 8, "the index masks below assume 8");

/// The exact SAH split of at most [`SMALL`] references (an index sort per axis, then a sweep),
/// or `Leaf` when a leaf is cheaper and allowed.
fn small(refs: &mut [PrimRef], bounds: &Aabb, params: &BvhParams) -> Split {
    let n = refs.len();
    debug_assert!((2..=SMALL).contains(&n));
    let boxes: [Box4; SMALL] = std::array::from_fn(|i| refs[i.min(n - 1)].box4());
    let keys: [Vec4; SMALL] = std::array::from_fn(|i| refs[i.min(n - 1)].centroid4());
    let mut best: (f32, usize, [u8; SMALL], usize) = (f32::INFINITY, 0, [0; SMALL], 0);
    // Two references have one split, the same on every axis: take the axis that separates
    // their centroids most (the traversal orders children by it).
    let axes = if n == 2 {
        let d = (keys[1] - keys[0]).abs();
        let axis = if d.x >= d.y && d.x >= d.z {
            0
        } else if d.y >= d.z {
            1
        } else {
            2
        };
        axis..axis + 1
    } else {
        0..3
    };
    for axis in axes {
        // Insertion sort of the indices by centroid (stable: ties keep their order).
        let key: [f32; SMALL] = std::array::from_fn(|i| keys[i][axis]);
        let mut order: [u8; SMALL] = std::array::from_fn(|i| i as u8);
        for i in 1..n {
            let mut j = i;
            while j > 0 && key[order[j - 1] as usize & 7] > key[order[j] as usize & 7] {
                order.swap(j - 1, j);
                j -= 1;
            }
        }
        let mut right = [0.0f32; SMALL];
        let mut acc = Box4::EMPTY;
        for i in (1..n).rev() {
            acc = acc.union(boxes[order[i] as usize & 7]);
            right[i] = acc.half_area();
        }
        let mut left = Box4::EMPTY;
        for i in 1..n {
            left = left.union(boxes[order[i - 1] as usize & 7]);
            let cost = left.half_area() * params.tests(i) + right[i] * params.tests(n - i);
            // The first candidate is kept even when every cost overflows to infinity
            // (coordinates near the largest float): a split must have two sides.
            if cost < best.0 || best.3 == 0 {
                best = (cost, axis, order, i);
            }
        }
    }
    let (_, axis, order, mid) = best;
    let side_area = |r: &[PrimRef]| r.iter().fold(Box4::EMPTY, |a, r| a.union(r.box4()));
    let sorted: [PrimRef; SMALL] = std::array::from_fn(|i| refs[order[i.min(n - 1)] as usize]);
    let (l, r) = (side_area(&sorted[..mid]), side_area(&sorted[mid..n]));
    let cost = split_cost(
        params,
        bounds.half_area(),
        (l.half_area(), mid),
        (r.half_area(), n - mid),
    );
    if n <= params.max_leaf_size as usize && params.leaf_cost(n) <= cost {
        return Split::Leaf;
    }
    refs.copy_from_slice(&sorted[..n]);
    let (left, right) = refs.split_at(mid);
    Split::At {
        mid,
        axis,
        sides: Some([super::bounds_of(left), super::bounds_of(right)]),
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
            acc = acc.union(refs[i].bounds());
            right_area[i] = acc.half_area();
        }
        let mut left = Aabb::EMPTY;
        for i in 1..n {
            left = left.union(refs[i - 1].bounds());
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
    let leaf_cost = params.leaf_cost(n);
    if n <= params.max_leaf_size as usize && leaf_cost <= cost {
        return Split::Leaf;
    }
    sort_along(refs, axis);
    Split::At {
        mid,
        axis,
        sides: None,
    }
}

fn sort_along(refs: &mut [PrimRef], axis: usize) {
    refs.sort_unstable_by(|a, b| {
        a.centroid()[axis]
            .total_cmp(&b.centroid()[axis])
            .then(a.index().cmp(&b.index()))
    });
}
