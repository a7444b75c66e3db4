//! Flat bounding-volume lists, the oldest technique: one volume (sphere, box or k-DOP)
//! per object or per cluster of primitives; a ray tests every volume, then visits the ones it
//! enters front to back by entry distance, skipping each one that starts beyond the closest hit
//! so far. With `two_level`, volumes are grouped under volumes of volumes (the classic
//! "hierarchy of bounding boxes" baseline, two levels deep).

use rt_geom::aabb::pad_up;
use rt_geom::{
    Aabb, Accel, AccelStats, BoundingVolume, BuildError, FilteredAccel, Frame, Hit, Keep,
    Primitive, Ray, check_primitives,
};
use std::cell::RefCell;
use std::ops::Range;

/// How primitives are grouped under volumes.
#[derive(Clone, Debug, PartialEq)]
pub enum Grouping {
    /// Clusters of `size` primitives, consecutive along a Morton curve of their centroids.
    Clusters {
        /// Primitives per cluster.
        size: usize,
    },
    /// The caller's groups (OBJ objects and groups: [`rt_geom::MeshGroup::triangles`]); they
    /// must cover every primitive exactly once.
    Ranges(Vec<Range<usize>>),
}

/// Parameters of [`BvList::build`].
#[derive(Clone, Debug, PartialEq)]
pub struct BvListParams {
    /// How primitives are grouped under each volume.
    pub grouping: Grouping,
    /// Group this many volumes under each top-level volume (`None`: one flat list).
    pub two_level: Option<usize>,
}

impl Default for BvListParams {
    /// Clusters of 32 primitives, one level.
    fn default() -> Self {
        Self {
            grouping: Grouping::Clusters { size: 32 },
            two_level: None,
        }
    }
}

/// A list of bounding volumes of type `V` over primitives `P`.
#[derive(Clone, Debug)]
pub struct BvList<P, V> {
    volumes: Vec<V>,
    /// Primitive range (in `prims`) of each volume.
    ranges: Vec<Range<u32>>,
    /// Volumes of volumes and the range of `volumes` each one covers (empty: one level).
    top: Vec<V>,
    top_ranges: Vec<Range<u32>>,
    prims: Vec<P>,
    ids: Vec<u32>,
    /// The frame spheres and k-DOPs are kept in (by the primitives' box).
    frame: Frame,
}

thread_local! {
    /// Per-thread scratch for the sorted candidate lists (no allocation per ray).
    static SCRATCH: RefCell<(Vec<(f32, u32)>, Vec<(f32, u32)>)> = const { RefCell::new((Vec::new(), Vec::new())) };
}

impl<P: Primitive, V: BoundingVolume> BvList<P, V> {
    /// Builds the list over `prims` (copied). Empty input gives an empty list.
    pub fn build(prims: &[P], params: BvListParams) -> Result<Self, BuildError> {
        check_primitives(prims, u32::MAX as usize - 1)?;
        let (order, groups) = match &params.grouping {
            Grouping::Clusters { size } => {
                if !(1..=1 << 20).contains(size) {
                    return Err(BuildError::InvalidParameter {
                        name: "cluster size",
                        value: size.to_string(),
                        expected: "1..=1048576",
                    });
                }
                let order = morton_order(prims);
                let groups = (0..prims.len())
                    .step_by(*size)
                    .map(|s| s..(s + size).min(prims.len()))
                    .collect::<Vec<_>>();
                (order, groups)
            }
            Grouping::Ranges(ranges) => {
                let mut covered = vec![false; prims.len()];
                for r in ranges {
                    for i in r.clone() {
                        match covered.get_mut(i) {
                            Some(c) if !*c => *c = true,
                            _ => {
                                return Err(BuildError::InvalidParameter {
                                    name: "grouping ranges",
                                    value: format!("{r:?}"),
                                    expected: "disjoint ranges covering every primitive once",
                                });
                            }
                        }
                    }
                }
                if covered.iter().any(|c| !c) {
                    return Err(BuildError::InvalidParameter {
                        name: "grouping ranges",
                        value: format!("{} ranges", ranges.len()),
                        expected: "disjoint ranges covering every primitive once",
                    });
                }
                let order: Vec<u32> = ranges
                    .iter()
                    .flat_map(|r| r.clone())
                    .map(|i| i as u32)
                    .collect();
                let mut start = 0;
                let groups = ranges
                    .iter()
                    .filter(|r| !r.is_empty())
                    .map(|r| {
                        let g = start..start + r.len();
                        start += r.len();
                        g
                    })
                    .collect();
                (order, groups)
            }
        };
        if let Some(k) = params.two_level {
            if !(2..=1 << 20).contains(&k) {
                return Err(BuildError::InvalidParameter {
                    name: "two_level",
                    value: k.to_string(),
                    expected: "2..=1048576 volumes per group",
                });
            }
        }
        let prims: Vec<P> = order.iter().map(|&i| prims[i as usize].clone()).collect();
        let frame = Frame::of(&Aabb::around(&prims));
        let volumes: Vec<V> = groups
            .iter()
            .map(|g| V::enclosing(&prims[g.clone()], &frame))
            .collect();
        let ranges: Vec<Range<u32>> = groups
            .iter()
            .map(|g| g.start as u32..g.end as u32)
            .collect();
        let (top, top_ranges) = match params.two_level {
            None => (vec![], vec![]),
            Some(k) => (0..volumes.len())
                .step_by(k)
                .map(|s| {
                    let r = s..(s + k).min(volumes.len());
                    let v = volumes[r.clone()]
                        .iter()
                        .skip(1)
                        .fold(volumes[s].clone(), |acc, v| acc.merge(v));
                    (v, r.start as u32..r.end as u32)
                })
                .unzip(),
        };
        Ok(Self {
            volumes,
            ranges,
            top,
            top_ranges,
            prims,
            ids: order,
            frame,
        })
    }

    /// Collects `(entry, index)` of the volumes in `range` that the ray enters, nearest first.
    fn entered(
        volumes: &[V],
        range: Range<u32>,
        (r, data): (&Ray, &V::RayData),
        out: &mut Vec<(f32, u32)>,
    ) {
        out.clear();
        for i in range {
            if let Some(t) = volumes[i as usize].entry_from(r, data) {
                out.push((t, i));
            }
        }
        out.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    }

    fn visit<const ANY_HIT: bool>(
        &self,
        volumes: &[(f32, u32)],
        r: &mut Ray,
        best: &mut impl Keep,
    ) -> bool {
        for &(t, v) in volumes {
            // Padded like the box tests: a volume entered a few ulps past the closest hit may
            // still hold a primitive hit at the same t (a tie that must go to the lower id).
            if t > pad_up(r.tmax) {
                break;
            }
            for i in self.ranges[v as usize].clone() {
                let id = self.ids[i as usize];
                if best.skips(id) {
                    continue;
                }
                if let Some(h) = self.prims[i as usize].intersect(r) {
                    if best.keep::<ANY_HIT>(h, id, &mut r.tmax) {
                        return true;
                    }
                }
            }
        }
        false
    }

    fn traverse<const ANY_HIT: bool, K: Keep>(
        &self,
        ray: &Ray,
        best: impl FnOnce() -> K,
    ) -> Option<Hit> {
        if !ray.is_valid() || self.volumes.is_empty() {
            return None;
        }
        let mut best = best();
        let mut r = *ray;
        let data = V::ray_data(ray, &self.frame);
        SCRATCH.with(|s| {
            let (outer, inner) = &mut *s.borrow_mut();
            if self.top.is_empty() {
                let all = 0..self.volumes.len() as u32;
                Self::entered(&self.volumes, all, (&r, &data), inner);
                self.visit::<ANY_HIT>(inner, &mut r, &mut best);
                return;
            }
            Self::entered(&self.top, 0..self.top.len() as u32, (&r, &data), outer);
            for &(t, g) in outer.iter() {
                if t > r.tmax {
                    break;
                }
                let range = self.top_ranges[g as usize].clone();
                Self::entered(&self.volumes, range, (&r, &data), inner);
                if self.visit::<ANY_HIT>(inner, &mut r, &mut best) {
                    return;
                }
            }
        });
        best.best()
    }
}

/// Primitive indices sorted by the 30-bit Morton code of their centroids.
fn morton_order<P: Primitive>(prims: &[P]) -> Vec<u32> {
    let b = prims.iter().fold(Aabb::EMPTY, |b, p| b.grow(p.centroid()));
    let scale = b.extent().max_element();
    let inv = if scale > 0.0 { 1023.0 / scale } else { 0.0 };
    let spread = |x: u32| {
        let mut x = x & 0x3ff;
        x = (x | (x << 16)) & 0x0300_00ff;
        x = (x | (x << 8)) & 0x0300_f00f;
        x = (x | (x << 4)) & 0x030c_30c3;
        (x | (x << 2)) & 0x0924_9249
    };
    let mut keyed: Vec<(u32, u32)> = prims
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let q = (p.centroid() - b.min) * inv;
            let code = spread(q.x as u32) | (spread(q.y as u32) << 1) | (spread(q.z as u32) << 2);
            (code, i as u32)
        })
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

impl<P: Primitive, V: BoundingVolume> FilteredAccel for BvList<P, V> {
    rt_geom::filtered_from_walk!();
}

impl<P: Primitive, V: BoundingVolume> Accel for BvList<P, V> {
    rt_geom::queries_from_walk!();

    fn stats(&self) -> AccelStats {
        AccelStats {
            primitives: self.prims.len(),
            nodes: self.volumes.len() + self.top.len(),
            leaves: self.volumes.len(),
            references: self.prims.len(),
            max_depth: if self.top.is_empty() { 1 } else { 2 },
            bytes: std::mem::size_of_val(self.volumes.as_slice())
                + std::mem::size_of_val(self.ranges.as_slice())
                + std::mem::size_of_val(self.top.as_slice())
                + std::mem::size_of_val(self.top_ranges.as_slice())
                + std::mem::size_of_val(self.prims.as_slice())
                + std::mem::size_of_val(self.ids.as_slice()),
            sah_cost: None,
        }
    }

    fn validate(&self) -> Result<(), String> {
        let mut seen = vec![false; self.prims.len()];
        for &id in &self.ids {
            let s = seen
                .get_mut(id as usize)
                .ok_or(format!("id {id} out of range"))?;
            if std::mem::replace(s, true) {
                return Err(format!("primitive {id} listed twice"));
            }
        }
        let covered: usize = self.ranges.iter().map(|r| r.len()).sum();
        if covered != self.prims.len() {
            return Err(format!(
                "volumes cover {covered} of {} primitives",
                self.prims.len()
            ));
        }
        // Every volume is conservative: a ray aimed at a primitive's centroid from outside
        // enters the volume no later than it hits the primitive.
        for (k, r) in self.ranges.iter().enumerate() {
            for p in &self.prims[r.start as usize..r.end as usize] {
                let c = p.centroid();
                // From a few primitive sizes away (a far origin would test f32 rounding at
                // the origin's scale instead).
                let size = p.bounds().extent().max_element();
                if !(size > 0.0) {
                    continue;
                }
                let o = c + rt_geom::Vec3::new(1.0, 0.7, 0.4) * (2.0 * size);
                let ray = Ray::new(o, c - o);
                if let Some(h) = p.intersect(&ray) {
                    if self.volumes[k]
                        .entry_distance(&ray, &self.frame)
                        .is_none_or(|t| t > h.t)
                    {
                        return Err(format!("volume {k} does not contain its primitives"));
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_geom::{BoundingSphere, Kdop7, Sphere, Triangle};

    macro_rules! per_volume {
        ($($name:ident: $v:ty, $params:expr;)*) => {$(
            mod $name {
                use super::*;
                rt_testkit::conformance_tests!(
                    triangles: |p: &[Triangle]| BvList::<_, $v>::build(p, $params),
                    spheres: |p: &[Sphere]| BvList::<_, $v>::build(p, $params),
                    shapes: |p: &[rt_geom::Shape]| BvList::<_, $v>::build(p, $params),
                );
                rt_testkit::disc_tests!(|p: &[rt_testkit::Disc]| BvList::<_, $v>::build(p, $params));
                rt_testkit::filter_tests!(
                    triangles: |p: &[Triangle]| BvList::<_, $v>::build(p, $params),
                    spheres: |p: &[Sphere]| BvList::<_, $v>::build(p, $params),
                    shapes: |p: &[rt_geom::Shape]| BvList::<_, $v>::build(p, $params),
                );
            }
        )*};
    }

    per_volume! {
        spheres_flat: BoundingSphere, BvListParams::default();
        boxes_flat: Aabb, BvListParams::default();
        kdops_flat: Kdop7, BvListParams::default();
        boxes_two_level: Aabb, BvListParams { two_level: Some(8), ..BvListParams::default() };
        kdops_two_level: Kdop7, BvListParams { grouping: Grouping::Clusters { size: 5 }, two_level: Some(3) };
        spheres_single: BoundingSphere, BvListParams { grouping: Grouping::Clusters { size: 1 }, two_level: None };
    }

    #[test]
    fn caller_groups() {
        let scene = rt_testkit::scenes::triangle_scene("torus");
        let n = scene.prims.len();
        let groups = vec![0..n / 3, n / 3..n / 2, n / 2..n];
        let params = BvListParams {
            grouping: Grouping::Ranges(groups),
            two_level: None,
        };
        rt_testkit::conformance::assert_conforms(&scene, |p: &[Triangle]| {
            BvList::<_, Kdop7>::build(p, params.clone())
        });
        let overlapping = BvListParams {
            grouping: Grouping::Ranges(vec![0..n / 2, n / 3..n]),
            two_level: None,
        };
        assert!(BvList::<_, Aabb>::build(&scene.prims, overlapping).is_err());
        let short = BvListParams {
            grouping: Grouping::Ranges(std::iter::once(0..n - 1).collect()),
            two_level: None,
        };
        assert!(BvList::<_, Aabb>::build(&scene.prims, short).is_err());
        let zero = BvListParams {
            grouping: Grouping::Clusters { size: 0 },
            two_level: None,
        };
        assert!(BvList::<_, Aabb>::build(&scene.prims, zero).is_err());
    }
}
