//! How a ray meets a BSP tree's planes: the crossing with an arbitrary plane in `f64`, padded
//! by the plane's band, then the kd-tree's step rule; the walk itself is the kd-tree's.

use super::BspTree;
use crate::KdNode;
use crate::traverse::{self, SplitPlanes, Step, ordered_children};
use rt_geom::aabb::{pad_down, pad_up};
use rt_geom::glam::DVec3;
use rt_geom::{Frame, Primitive, Ray};

/// The ray in `f64`, where the crossing with an arbitrary plane is computed, its origin in
/// the tree's frame (exact: two `f32` subtracted in `f64`).
pub(crate) struct PlaneRay {
    pub origin: DVec3,
    pub dir: DVec3,
}

impl PlaneRay {
    /// `ray` in `frame`.
    pub(crate) fn new(ray: &Ray, frame: &Frame) -> Self {
        Self {
            origin: ray.origin().as_dvec3() - frame.anchor.as_dvec3(),
            dir: ray.dir().as_dvec3(),
        }
    }
}

impl<P: Primitive> SplitPlanes for BspTree<P> {
    type RayData = PlaneRay;

    fn ray_data(&self, ray: &Ray, _inv: [f32; 3]) -> PlaneRay {
        PlaneRay::new(ray, &self.frame)
    }

    #[inline(always)]
    fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    #[inline(always)]
    fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// The ray's signed distance to the plane is `s0 + t denom`; it is below the plane for
    /// `t` before the crossing `-s0 / denom` when `denom > 0`, above when `denom < 0`. Each
    /// side's interval is widened by the band: `2 margin / |denom|` (twice, for the rounding of
    /// the primitives' own extents), plus the relative padding of the box test; from that
    /// crossing the step is the kd-tree's rule ([`traverse::step_between`]).
    #[inline(always)]
    fn at(&self, ray: &PlaneRay, i: usize, t0: f32, t1: f32) -> (usize, usize, Step) {
        let node = &self.nodes[i];
        let plane = &self.planes[node.data() as usize];
        let n = plane.normal.as_dvec3();
        let s0 = n.dot(ray.origin) - plane.d as f64;
        let denom = n.dot(ray.dir);
        let band = 2.0 * plane.margin as f64;
        if denom == 0.0 {
            let (first, second) = ordered_children(i, node, s0 < 0.0);
            let step = if s0.abs() <= band {
                Step::Both {
                    first_end: t1,
                    second_start: t0,
                }
            } else {
                Step::First
            };
            return (first, second, step);
        }
        let (first, second) = ordered_children(i, node, denom > 0.0);
        let ts = -s0 / denom;
        let delta = band / denom.abs() + ts.abs() * 1e-12;
        let lo = pad_down((ts - delta) as f32);
        let hi = pad_up((ts + delta) as f32);
        (first, second, traverse::step_between(lo, hi, t0, t1))
    }
}
