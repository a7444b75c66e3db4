//! [`BspTree`]: the type, its build entry point, and its statistics and invariants.

use super::BspParams;
use super::build::{self, Side, classify, clip_cell};
use crate::build::{BuildNode, MAX_LOCAL, flatten, root_budget};
use crate::params::MAX_DEPTH;
use crate::{KdNode, KdParams};
use rt_geom::pages::Pages;
use rt_geom::{
    Aabb, Accel, AccelStats, BuildError, FilteredAccel, Frame, Hit, Isa, Keep, LeafPrims, Level,
    Primitive, Ray, Vec3, Walk, check_primitives,
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

/// A BSP tree over primitives `P`.
#[derive(Clone, Debug)]
pub struct BspTree<P> {
    pub(super) nodes: Pages<KdNode>,
    pub(super) planes: Pages<SplitPlane>,
    pub(super) indices: Pages<u32>,
    pub(super) prims: Vec<P>,
    /// The primitives of the leaves of several, laid out for the leaf test ([`LeafPrims`]).
    pub(super) listed: LeafPrims<P>,
    /// The scene's box (world), where the walk clips the ray.
    pub(super) bounds: Aabb,
    pub(super) params: BspParams,
    /// The frame the planes are in (the world's, for scenes about the origin).
    pub(super) frame: Frame,
    /// The instruction set the queries run the walk compiled for.
    pub(super) isa: Isa,
}

impl<P: Primitive> BspTree<P> {
    /// Builds over `prims` (copied). Empty input gives an empty tree.
    pub fn build(prims: &[P], params: BspParams) -> Result<Self, BuildError> {
        params.validate()?;
        check_primitives(prims, MAX_LOCAL)?;
        let bounds = Aabb::around(prims);
        let frame = Frame::of(&bounds);
        let local = frame.to_local(&bounds);
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
                scale: local.min.abs().max(local.max.abs()).max_element(),
                frame,
            };
            let root: BuildNode<SplitPlane> = build::build_node(
                &ctx,
                (0..n as u32).collect(),
                local,
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
            nodes: Pages::from(nodes),
            planes: Pages::from(planes),
            indices: Pages::from(indices),
            prims: prims.to_vec(),
            listed,
            bounds,
            params,
            frame,
            isa: Isa::selected(),
        })
    }

    /// The same tree, its queries run compiled for `isa` (or, where this CPU lacks it, for the
    /// best level it has): for tests and measurements of each level.
    pub fn with_isa(mut self, isa: Isa) -> Self {
        self.isa = isa.or_best();
        self
    }

    /// The flattened nodes; an inner node's `data()` indexes [`Self::planes`].
    pub fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    /// The split planes, indexed by the inner nodes, in [`Self::frame`].
    pub fn planes(&self) -> &[SplitPlane] {
        &self.planes
    }

    /// Primitive indices, leaf by leaf.
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// The frame the planes are in: world coordinates minus its anchor (the world's own for
    /// scenes about the origin).
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// The parameters the tree was built with.
    pub fn params(&self) -> &BspParams {
        &self.params
    }

    /// Calls `f(node, cell box (in the frame), planes above the node with the side taken,
    /// depth)` for every node, parents first.
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
            go(
                self,
                0,
                self.frame.to_local(&self.bounds),
                &mut Vec::new(),
                &mut f,
            );
        }
    }
}

impl<P: Primitive> Walk for BspTree<P> {
    fn isa(&self) -> Isa {
        self.isa
    }

    /// The kd-tree's walk over the planes, its leaves' triangle windows at `level`.
    #[inline(always)]
    fn walk<const ANY_HIT: bool, L: Level, K: Keep>(
        &self,
        ray: &Ray,
        level: L,
        best: K,
    ) -> Option<Hit> {
        let leaves = (self.prims.as_slice(), &self.listed, level);
        let t = self.params.traversal;
        crate::traverse::query::<_, _, ANY_HIT, K, L>(self, leaves, &self.bounds, t, ray, || best)
    }
}

impl<P: Primitive> FilteredAccel for BspTree<P> {
    rt_geom::filtered_from_walk!(per_isa);
}

impl<P: Primitive> Accel for BspTree<P> {
    rt_geom::queries_from_walk!(per_isa);

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
        let mut acc = rt_geom::StatsSum::new(s, &self.frame.to_local(&self.bounds));
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
                        if classify(prim, &self.planes[plane], &self.frame) == wrong {
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
    use crate::KdTraversal;

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

    /// Each instruction set's walk answers as brute force (a level this CPU lacks runs its
    /// best one).
    mod isa_baseline {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[rt_geom::Triangle]| BspTree::build(p, BspParams::standard()).map(|t| t.with_isa(Isa::Baseline)),
        );
    }
    mod isa_avx2 {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[rt_geom::Triangle]| BspTree::build(p, BspParams::standard()).map(|t| t.with_isa(Isa::Avx2)),
        );
    }
}
