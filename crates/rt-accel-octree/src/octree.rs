//! [`Octree`]: the octree over any primitive, its build entry points and queries.

use crate::node::{MAX_NODES, octant};
use crate::{ChildRef, MAX_DEPTH, OctLeaf, OctNode, OctreeParams, OctreeTraversal, build};
use rt_geom::pages::Pages;
use rt_geom::{
    Aabb, Accel, BuildError, FilteredAccel, Frame, Isa, LeafPrims, Primitive, Vec3,
    check_primitives,
};

/// An octree over primitives `P`.
#[derive(Clone, Debug)]
pub struct Octree<P> {
    pub(crate) nodes: Pages<OctNode>,
    pub(crate) leaves: Pages<OctLeaf>,
    pub(crate) indices: Pages<u32>,
    /// The root node (unused when there are no primitives).
    pub(crate) root: ChildRef,
    pub(crate) prims: Vec<P>,
    /// The listed primitives in `indices` order, laid out for the leaf test.
    pub(crate) leaf_prims: LeafPrims<P>,
    /// The root cube, in `frame`.
    pub(crate) bounds: Aabb,
    pub(crate) params: OctreeParams,
    /// The frame the cells are in (the world's, for scenes about the origin).
    pub(crate) frame: Frame,
    /// The instruction set its leaf tests run compiled for (one dispatch per leaf: the walk
    /// itself recurses, so it stays at the baseline).
    pub(crate) isa: Isa,
}

impl<P: Primitive> Octree<P> {
    /// Builds over `prims` (copied) inside the cube around them. Empty input gives an empty
    /// tree. References are capped at [`MAX_NODES`] in all (beyond the memory of any machine
    /// this runs on), so that every index fits its field.
    pub fn build(prims: &[P], params: OctreeParams) -> Result<Self, BuildError> {
        params.validate()?;
        check_primitives(prims, MAX_NODES - 1)?;
        let mut flat = build::Flat::default();
        let mut root = ChildRef::inner(0);
        let (frame, bounds) = Self::root_cube(prims);
        if !prims.is_empty() {
            let ctx = build::Ctx {
                prims,
                params: &params,
                frame,
            };
            let n = prims.len();
            let budget = (params.reference_budget as f64 * n as f64).min((MAX_NODES - 1) as f64);
            let budget = (budget as usize).max(n);
            let tree = build::build(&ctx, (0..n as u32).collect(), bounds, 0, budget);
            root = flat.add_root(&tree, &bounds);
        }
        let lists = flat.leaves.iter().map(|l| (l.first, l.count));
        Ok(Self {
            leaf_prims: LeafPrims::new(prims, &flat.indices, lists),
            nodes: flat.nodes.into(),
            leaves: flat.leaves.into(),
            indices: flat.indices.into(),
            root,
            prims: prims.to_vec(),
            bounds,
            params,
            frame,
            isa: Isa::selected(),
        })
    }

    /// The frame of `prims` and the cube the root covers in it (empty for no primitives): a
    /// cube, so that octants stay cubes (no flat octants duplicating everything).
    pub(crate) fn root_cube(prims: &[P]) -> (Frame, Aabb) {
        let world = Aabb::around(prims);
        let frame = Frame::of(&world);
        if prims.is_empty() {
            return (frame, Aabb::EMPTY);
        }
        let b = frame.to_local(&world);
        let half = Vec3::splat(0.5 * b.extent().max_element());
        let c = b.center();
        (
            frame,
            Aabb::new((c - half).min(b.min), (c + half).max(b.max)),
        )
    }

    /// The inner nodes, root first.
    pub fn nodes(&self) -> &[OctNode] {
        &self.nodes
    }

    /// The leaves.
    pub fn leaves(&self) -> &[OctLeaf] {
        &self.leaves
    }

    /// The root node; meaningless for an empty tree (no leaves).
    pub fn root(&self) -> ChildRef {
        self.root
    }

    /// Primitive indices, leaf by leaf.
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// The root cube, in [`Self::frame`].
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The same octree, its leaf tests run compiled for `isa` (or, where this CPU lacks it,
    /// for the best level it has): for tests and measurements of each level.
    pub fn with_isa(mut self, isa: Isa) -> Self {
        self.isa = isa.or_best();
        self
    }

    /// The frame the cells are in: world coordinates minus its anchor (the world's own for
    /// scenes about the origin).
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// The parameters the octree was built with.
    pub fn params(&self) -> &OctreeParams {
        &self.params
    }

    /// The same tree, walked the other way.
    pub fn with_traversal(mut self, traversal: OctreeTraversal) -> Self {
        self.params.traversal = traversal;
        self
    }

    /// Calls `f(node, cell, depth, content)` for every node, parents first, where `content`
    /// is the node's content box as its parent stores it, cut to its ancestors' (the cell for
    /// the root): a walk reaches a node only through all of them.
    pub(crate) fn walk(&self, f: &mut impl FnMut(ChildRef, &Aabb, usize, &Aabb)) {
        if self.leaves.is_empty() {
            return;
        }
        let mut stack = vec![(self.root, self.bounds, 0usize, self.bounds)];
        while let Some((r, cell, d, content)) = stack.pop() {
            f(r, &cell, d, &content);
            if r.is_leaf() || d > MAX_DEPTH as usize {
                continue;
            }
            let Some(n) = self.nodes.get(r.index()) else {
                continue;
            };
            for o in 0..8 {
                if let Some(c) = n.child(o) {
                    stack.push((
                        c,
                        octant(&cell, o),
                        d + 1,
                        n.content_box(&cell, o).intersection(content),
                    ));
                }
            }
        }
    }
}

impl<P: Primitive> FilteredAccel for Octree<P> {
    rt_geom::filtered_from_walk!();
}

impl<P: Primitive> Accel for Octree<P> {
    rt_geom::queries_from_walk!(stats: compute_stats, validate: check);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_geom::Triangle;
    use rt_testkit::scenes;

    rt_testkit::conformance_per_params!(Octree::build {
        parametric: OctreeParams::standard(),
        recursive: OctreeParams::standard().with_traversal(OctreeTraversal::Recursive),
        parametric_leaf1: OctreeParams {
            max_prims: 1,
            ..OctreeParams::standard()
        },
        recursive_leaf1: OctreeParams {
            max_prims: 1,
            traversal: OctreeTraversal::Recursive,
            ..OctreeParams::standard()
        },
        parametric_mailbox: OctreeParams::standard().with_mailbox(true),
        recursive_mailbox: OctreeParams::standard()
            .with_traversal(OctreeTraversal::Recursive)
            .with_mailbox(true),
        parametric_serial: OctreeParams {
            parallel_threshold: usize::MAX,
            ..OctreeParams::standard()
        },
        shallow: OctreeParams {
            max_depth: 2,
            ..OctreeParams::standard()
        },
        deepest: OctreeParams {
            max_prims: 1,
            max_depth: MAX_DEPTH,
            ..OctreeParams::standard()
        },
        deepest_recursive: OctreeParams {
            max_prims: 1,
            max_depth: MAX_DEPTH,
            traversal: OctreeTraversal::Recursive,
            ..OctreeParams::standard()
        },
    });

    /// Each instruction set's leaf tests answer as brute force (a level this CPU lacks runs
    /// its best one), in both walks, with and without mailboxes.
    macro_rules! per_isa {
        ($($name:ident: $isa:expr;)*) => {$(
            mod $name {
                use super::*;
                rt_testkit::conformance_tests!(
                    triangles: |p: &[Triangle]| Octree::build(p, OctreeParams::standard()).map(|t| t.with_isa($isa)),
                );
                mod recursive_mailbox {
                    use super::*;
                    rt_testkit::conformance_tests!(
                        triangles: |p: &[Triangle]| Octree::build(p, OctreeParams::standard().with_traversal(OctreeTraversal::Recursive).with_mailbox(true)).map(|t| t.with_isa($isa)),
                    );
                }
            }
        )*};
    }
    per_isa! {
        isa_baseline: Isa::Baseline;
        isa_avx2: Isa::Avx2;
    }

    #[test]
    fn memory_is_bounded_on_pathological_input() {
        for tris in [
            scenes::overlapping_fan(3000, 1),
            scenes::long_slivers(3000, 2),
            scenes::teapot_in_stadium(3000),
        ] {
            for params in [
                OctreeParams::standard(),
                OctreeParams {
                    max_prims: 1,
                    max_depth: MAX_DEPTH,
                    reference_budget: 4.0,
                    ..OctreeParams::standard()
                },
            ] {
                let t = Octree::build(&tris, params).unwrap();
                t.validate().unwrap();
                let s = t.stats();
                assert!(
                    s.references as f32 <= params.reference_budget * tris.len() as f32,
                    "{s}"
                );
                assert!(s.max_depth <= params.max_depth as usize, "{s}");
                // Every inner node has a non-empty octant holding fewer than all of its
                // primitives, so nodes are bounded by references times depth.
                assert!(s.nodes <= 8 * (params.max_depth as usize + 1) * s.references.max(1));
            }
        }
    }

    #[test]
    fn empty_octants_are_not_stored() {
        // Two clusters in opposite corners: the root stores two octants, not eight.
        let mut tris = scenes::random_soup(50, 1);
        for t in tris.iter_mut().skip(25) {
            t.v = t.v.map(|p| p * 0.1 + Vec3::splat(0.9));
        }
        for t in tris.iter_mut().take(25) {
            t.v = t.v.map(|p| p * 0.1);
        }
        let t = Octree::build(&tris, OctreeParams::standard()).unwrap();
        assert!(!t.root().is_leaf());
        let root = t.nodes()[0];
        assert_eq!(root.mask().count_ones(), 2, "{:08b}", root.mask());
    }

    #[test]
    fn bad_parameters_are_rejected() {
        let tris: Vec<Triangle> = scenes::random_soup(10, 1);
        let s = OctreeParams::standard();
        for params in [
            OctreeParams { max_prims: 0, ..s },
            OctreeParams { max_depth: 25, ..s },
            OctreeParams {
                reference_budget: 0.5,
                ..s
            },
            OctreeParams {
                reference_budget: f32::NAN,
                ..s
            },
        ] {
            assert!(matches!(
                Octree::build(&tris, params),
                Err(BuildError::InvalidParameter { .. })
            ));
        }
        let too_many = vec![rt_testkit::NoGeometry; u32::MAX as usize];
        assert!(matches!(
            Octree::build(&too_many, s),
            Err(BuildError::TooManyPrimitives { .. })
        ));
    }
}
