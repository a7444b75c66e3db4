//! General BSP trees: splitting planes of any orientation, taken from the primitives' own
//! planes (autopartition) or axis-aligned, traversed front to back by signed distance.
//!
//! Nodes are [`KdNode`]s whose `data` indexes [`BspTree::planes`]. A primitive goes below a
//! plane if all of it is below `margin` (see [`SplitPlane`]), above if all of it is above
//! `-margin`, to one side (the cheaper) if it lies within the margin, and to both otherwise.
//! The walk pads each crossing by the margin over `|n . dir|`, so that a hit within the band
//! is inside both children's intervals.

mod build;

use crate::build::{BuildNode, MAX_LOCAL, flatten, root_budget};
use crate::params::{KdTraversal, MAX_DEPTH};
use crate::traverse::{self, SplitPlanes, Step, ordered_children};
use crate::{KdNode, KdParams};
use build::{Side, classify, clip_cell};
use rt_geom::aabb::{pad_down, pad_up};
use rt_geom::glam::DVec3;
use rt_geom::{
    Aabb, Accel, AccelStats, BuildError, Hit, LeafPrims, Primitive, Ray, Vec3, check_primitives,
};

/// A splitting plane `normal . p = d` (unit normal), with the band `|normal . p - d| <=
/// margin` inside which rounding cannot tell the sides apart.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplitPlane {
    /// Unit normal of the plane.
    pub normal: Vec3,
    /// Offset: the plane is `normal . p = d`.
    pub d: f32,
    /// Primitives within this distance of the plane count as lying in it.
    pub margin: f32,
}

/// Parameters of [`BspTree::build`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BspParams {
    /// SAH cost of traversing an inner node.
    pub traversal_cost: f32,
    /// SAH cost of one primitive test.
    pub intersection_cost: f32,
    /// Planes of the node's own primitives tried per node (spread evenly over them).
    pub candidates: u32,
    /// Also try the three axis-aligned planes through the median centroid.
    pub axis_planes: bool,
    /// Nodes of at most this many primitives become leaves.
    pub max_leaf_size: u32,
    /// Depth cap. `None`: `8 + 1.3 log2 N`, at most [`MAX_DEPTH`].
    pub max_depth: Option<u32>,
    /// At most `reference_budget * N` references in all (as [`KdParams::reference_budget`]).
    pub reference_budget: f32,
    /// Subtrees with more primitives than this are built in parallel.
    pub parallel_threshold: usize,
    /// Iterative or recursive walk.
    pub traversal: KdTraversal,
}

impl BspParams {
    /// 16 primitive planes and 3 axis-aligned planes per node, the kd-tree's SAH constants.
    pub const fn standard() -> Self {
        let kd = KdParams::sah();
        Self {
            traversal_cost: kd.traversal_cost,
            intersection_cost: kd.intersection_cost,
            candidates: 16,
            axis_planes: true,
            max_leaf_size: 1,
            max_depth: None,
            reference_budget: kd.reference_budget,
            parallel_threshold: kd.parallel_threshold,
            traversal: KdTraversal::Iterative,
        }
    }

    /// Autopartition only: planes of the primitives, no axis-aligned ones.
    pub const fn autopartition() -> Self {
        Self {
            axis_planes: false,
            ..Self::standard()
        }
    }

    /// Checks every field; the error names the first one out of range.
    pub fn validate(&self) -> Result<(), BuildError> {
        // The fields shared with the kd-tree are checked by its rules.
        KdParams {
            traversal_cost: self.traversal_cost,
            intersection_cost: self.intersection_cost,
            max_depth: self.max_depth,
            max_leaf_size: self.max_leaf_size,
            reference_budget: self.reference_budget,
            ..KdParams::sah()
        }
        .validate()?;
        let c = self.candidates;
        let ok = c <= 1024 && (c > 0 || self.axis_planes);
        BuildError::require(ok, "candidates", c, "0..=1024, and > 0 without axis planes")?;
        Ok(())
    }
}

impl Default for BspParams {
    fn default() -> Self {
        Self::standard()
    }
}

/// A BSP tree over primitives `P`.
#[derive(Clone, Debug)]
pub struct BspTree<P> {
    nodes: Vec<KdNode>,
    planes: Vec<SplitPlane>,
    indices: Vec<u32>,
    prims: Vec<P>,
    /// The primitives of the leaves of several, laid out for the leaf test ([`LeafPrims`]).
    listed: LeafPrims<P>,
    bounds: Aabb,
    params: BspParams,
}

impl<P: Primitive> BspTree<P> {
    /// Builds over `prims` (copied). Empty input gives an empty tree.
    pub fn build(prims: &[P], params: BspParams) -> Result<Self, BuildError> {
        params.validate()?;
        check_primitives(prims, MAX_LOCAL)?;
        let bounds = prims.iter().fold(Aabb::EMPTY, |b, p| b.union(p.bounds()));
        let (mut nodes, mut planes, mut indices) = (Vec::new(), Vec::new(), Vec::new());
        if !prims.is_empty() {
            let n = prims.len();
            let depth_cap = KdParams {
                max_depth: params.max_depth,
                ..KdParams::sah()
            }
            .depth_cap(n);
            let ctx = build::Ctx {
                prims,
                params: &params,
                depth_cap,
                scale: bounds.min.abs().max(bounds.max.abs()).max_element(),
            };
            let root: BuildNode<SplitPlane> = build::build_node(
                &ctx,
                (0..n as u32).collect(),
                bounds,
                0,
                root_budget(params.reference_budget, n),
            );
            flatten(&root, &mut nodes, &mut indices, &mut |plane, above| {
                planes.push(*plane);
                KdNode::inner_plane(planes.len() as u32 - 1, above)
            });
            if nodes.len() > crate::node::MAX_NODE_FIELD as usize {
                return Err(BuildError::TooManyPrimitives {
                    count: n,
                    max: n / 2,
                });
            }
        }
        let listed = LeafPrims::new(prims, &indices, nodes.iter().filter_map(KdNode::list));
        Ok(Self {
            nodes,
            planes,
            indices,
            prims: prims.to_vec(),
            listed,
            bounds,
            params,
        })
    }

    /// The flattened nodes; an inner node's `data()` indexes [`Self::planes`].
    pub fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    /// The split planes, indexed by the inner nodes.
    pub fn planes(&self) -> &[SplitPlane] {
        &self.planes
    }

    /// Primitive indices, leaf by leaf.
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// The parameters the tree was built with.
    pub fn params(&self) -> &BspParams {
        &self.params
    }

    /// Calls `f(node, cell box, planes above the node with the side taken, depth)` for every
    /// node, parents first.
    fn walk(&self, mut f: impl FnMut(usize, &Aabb, &[(usize, bool)])) {
        fn go<P: Primitive>(
            t: &BspTree<P>,
            i: usize,
            cell: Aabb,
            path: &mut Vec<(usize, bool)>,
            f: &mut impl FnMut(usize, &Aabb, &[(usize, bool)]),
        ) {
            f(i, &cell, path);
            let n = &t.nodes[i];
            let ok = n.above() < t.nodes.len() && (n.data() as usize) < t.planes.len();
            if n.is_leaf() || !ok || path.len() > MAX_DEPTH as usize {
                return;
            }
            let plane = &t.planes[n.data() as usize];
            for (child, below) in [(i + 1, true), (n.above(), false)] {
                path.push((n.data() as usize, below));
                go(t, child, clip_cell(&cell, plane, below), path, f);
                path.pop();
            }
        }
        if !self.nodes.is_empty() {
            go(self, 0, self.bounds, &mut Vec::new(), &mut f);
        }
    }
}

/// The ray in `f64`, where the crossing with an arbitrary plane is computed.
pub(crate) struct PlaneRay {
    origin: DVec3,
    dir: DVec3,
}

impl<P: Primitive> SplitPlanes for BspTree<P> {
    type RayData = PlaneRay;

    fn ray_data(ray: &Ray, _inv: [f32; 3]) -> PlaneRay {
        PlaneRay {
            origin: ray.origin().as_dvec3(),
            dir: ray.dir().as_dvec3(),
        }
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
    /// the primitives' own extents), plus the relative padding of the box test.
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
        let step = if lo > t1 {
            Step::First
        } else if hi < t0 {
            Step::Second
        } else {
            Step::Both {
                first_end: hi.min(t1),
                second_start: lo.max(t0),
            }
        };
        (first, second, step)
    }
}

impl<P: Primitive> BspTree<P> {
    /// The walk, for the closest hit or any hit.
    #[inline]
    fn traverse<const ANY_HIT: bool>(&self, ray: &Ray) -> Option<Hit> {
        let t = self.params.traversal;
        traverse::query::<_, _, ANY_HIT>(self, (&self.prims, &self.listed), &self.bounds, t, ray)
    }
}

impl<P: Primitive> Accel for BspTree<P> {
    rt_geom::queries_from_walk!();

    fn stats(&self) -> AccelStats {
        let s = AccelStats {
            primitives: self.prims.len(),
            nodes: self.nodes.len(),
            bytes: std::mem::size_of_val(self.nodes.as_slice())
                + std::mem::size_of_val(self.planes.as_slice())
                + std::mem::size_of_val(self.indices.as_slice())
                + std::mem::size_of_val(self.prims.as_slice())
                + self.listed.bytes(),
            ..AccelStats::default()
        };
        if self.nodes.is_empty() {
            return s;
        }
        let mut acc = rt_geom::StatsSum::new(s, &self.bounds);
        self.walk(|i, cell, path| {
            let n = &self.nodes[i];
            acc.add(cell, path.len(), n.is_leaf(), n.count())
        });
        acc.finish()
    }

    /// Structure and indices in range; every plane finite with a unit normal; every primitive
    /// in some leaf; no primitive in a leaf on the far side of a plane above it.
    fn validate(&self) -> Result<(), String> {
        if self.nodes.is_empty() {
            return if self.prims.is_empty() {
                Ok(())
            } else {
                Err("no nodes for a non-empty scene".into())
            };
        }
        for (k, p) in self.planes.iter().enumerate() {
            let unit = (p.normal.length() - 1.0).abs() < 1e-4;
            if !(unit && p.d.is_finite() && p.margin.is_finite() && p.margin >= 0.0) {
                return Err(format!(
                    "plane {k} is not a unit-normal finite plane: {p:?}"
                ));
            }
        }
        let mut seen = vec![false; self.prims.len()];
        let mut err = None;
        let len = self.nodes.len();
        self.walk(|i, _, path| {
            if err.is_some() {
                return;
            }
            let n = &self.nodes[i];
            if path.len() > MAX_DEPTH as usize {
                err = Some(format!("node {i} deeper than {MAX_DEPTH}"));
            } else if !n.is_leaf() {
                if n.above() <= i + 1 || n.above() >= len || n.data() as usize >= self.planes.len()
                {
                    err = Some(format!("inner node {i} has a child or plane out of range"));
                }
            } else if let Some(Err(e)) = n
                .list()
                .map(|l| self.listed.check_list(&self.prims, &self.indices, l))
            {
                err = Some(format!("leaf {i}: {e}"));
            } else {
                for &p in n.leaf_prims(&self.indices) {
                    let Some(prim) = self.prims.get(p as usize) else {
                        err = Some(format!("leaf {i} holds primitive {p}, out of range"));
                        return;
                    };
                    seen[p as usize] = true;
                    for &(plane, below) in path {
                        let wrong = if below { Side::Above } else { Side::Below };
                        if classify(prim, &self.planes[plane]) == wrong {
                            err = Some(format!(
                                "primitive {p} in leaf {i} lies on the other side of plane {plane}"
                            ));
                            return;
                        }
                    }
                }
            }
        });
        if let Some(e) = err {
            return Err(e);
        }
        rt_geom::all_referenced(&seen)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    rt_testkit::conformance_per_params!(BspTree::build {
        standard: BspParams::standard(),
        recursive: BspParams {
            traversal: KdTraversal::Recursive,
            ..BspParams::standard()
        },
        autopartition: BspParams::autopartition(),
        many_candidates: BspParams {
            candidates: 64,
            parallel_threshold: 16,
            ..BspParams::standard()
        },
    });
}
