//! [`KdTree`]: the kd-tree over any primitive, its build entry points and queries.

use crate::{KdBuilder, KdNode, KdParams, KdTraversal, build, node, traverse};
use rt_geom::pages::Pages;
use rt_geom::{
    Aabb, Accel, AccelStats, BuildError, FilteredAccel, Frame, Hit, Isa, Keep, LeafPrims, Level,
    Primitive, Ray, Walk, check_primitives,
};

/// A kd-tree over primitives `P`: 8-byte nodes flattened depth-first, leaves referring to the
/// primitives by index (a primitive cut by planes is in several leaves).
#[derive(Clone, Debug)]
pub struct KdTree<P> {
    pub(crate) nodes: Pages<KdNode>,
    /// Leaves of more than one primitive hold ranges of this array.
    pub(crate) indices: Pages<u32>,
    /// The caller's primitives, in the caller's order.
    pub(crate) prims: Vec<P>,
    /// The primitives of the leaves of several, in `indices` order, laid out for the leaf
    /// test.
    pub(crate) listed: LeafPrims<P>,
    /// The root cell in world coordinates (where queries clip the ray).
    pub(crate) bounds: Aabb,
    /// The frame the planes are in: the world's, but for naive planes far from the origin.
    pub(crate) frame: Frame,
    /// The root cell in the frame (where the planes split it).
    pub(crate) root: Aabb,
    pub(crate) params: KdParams,
    /// The instruction set queries run the walk compiled for ([`Isa::selected`] when built).
    pub(crate) isa: Isa,
}

impl<P: Primitive> KdTree<P> {
    /// Builds over `prims` (copied). Empty input gives an empty tree.
    pub fn build(prims: &[P], params: KdParams) -> Result<Self, BuildError> {
        params.validate()?;
        check_primitives(prims, build::MAX_LOCAL)?;
        let frame = Self::frame_for(prims, &params);
        let root = frame.to_local(&Aabb::around(prims));
        let mut nodes = Vec::new();
        let mut indices = Vec::new();
        if !prims.is_empty() {
            let root = build::build_tree(prims, root, &params, &frame);
            build::flatten(
                &root,
                &mut nodes,
                &mut indices,
                &mut |&(axis, pos), above| KdNode::inner(axis, pos, above),
            );
            if nodes.len() > node::MAX_NODE_FIELD as usize {
                return Err(BuildError::TooManyPrimitives {
                    count: prims.len(),
                    max: prims.len() / 2,
                });
            }
        }
        Ok(Self::assemble(prims, nodes, indices, frame, params))
    }

    /// The frame and root cell a build over `prims` with `params` splits in: SAH planes are
    /// values of the primitives' own coordinates; naive planes are positions of their own,
    /// which world `f32` far from the origin cannot place between the primitives'
    /// coordinates (robustness decision 9).
    pub(crate) fn frame_for(prims: &[P], params: &KdParams) -> Frame {
        match params.builder {
            KdBuilder::Sah => Frame::WORLD,
            KdBuilder::Midpoint | KdBuilder::Centroid => Frame::of(&Aabb::around(prims)),
        }
    }

    /// The tree of flattened `nodes` and `indices` over `prims` (copied), split in `frame`.
    pub(crate) fn assemble(
        prims: &[P],
        nodes: Vec<KdNode>,
        indices: Vec<u32>,
        frame: Frame,
        params: KdParams,
    ) -> Self {
        let root = frame.to_local(&Aabb::around(prims));
        let listed = LeafPrims::new(prims, &indices, nodes.iter().filter_map(KdNode::list));
        Self {
            nodes: Pages::from(nodes),
            indices: Pages::from(indices),
            prims: prims.to_vec(),
            listed,
            bounds: frame.to_world(&root),
            frame,
            root,
            params,
            isa: Isa::selected(),
        }
    }

    /// The same tree, its queries run compiled for `isa` (or, where this CPU lacks it, for the
    /// best level it has): for tests and measurements of each level.
    pub fn with_isa(mut self, isa: Isa) -> Self {
        self.isa = isa.or_best();
        self
    }

    /// The flattened nodes (read-only; layout in [`node`]).
    pub fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    /// The index array leaves of several primitives point into.
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// The primitives, in the caller's order.
    pub fn prims(&self) -> &[P] {
        &self.prims
    }

    /// The root cell in world coordinates: the bounds of all primitives.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The frame the split planes are in: world coordinates minus its anchor (the world's own
    /// for SAH planes and for scenes about the origin).
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// The parameters the tree was built with.
    pub fn params(&self) -> &KdParams {
        &self.params
    }

    /// The same tree, traversed the other way.
    pub fn with_traversal(mut self, traversal: KdTraversal) -> Self {
        self.params.traversal = traversal;
        self
    }

    /// The leaves (node indices) the iterative walk tests for `ray`, in order, and its answer:
    /// the closest hit, or with `ANY_HIT` the first hit found. With [`Self::test_leaf`], this
    /// measures what the walk costs beyond its leaves (the `kd_leaf_bound` example). Behind
    /// the `research` feature.
    #[cfg(feature = "research")]
    pub fn leaves_tested<const ANY_HIT: bool>(&self, ray: &Ray) -> (Vec<u32>, Option<Hit>) {
        let mut tested = Vec::new();
        let leaves = (self.prims.as_slice(), &self.listed, rt_geom::BaseLevel);
        let iterative = KdTraversal::Iterative;
        let on_leaf = |i| tested.push(i as u32);
        let hit = if self.frame.is_world() {
            traverse::query_with::<_, _, ANY_HIT, _, _>(
                self,
                leaves,
                &self.bounds,
                iterative,
                ray,
                || None,
                on_leaf,
            )
        } else {
            let framed = &traverse::InFrame(self);
            traverse::query_with::<_, _, ANY_HIT, _, _>(
                framed,
                leaves,
                &self.bounds,
                iterative,
                ray,
                || None,
                on_leaf,
            )
        };
        (tested, hit)
    }

    /// Tests leaf `node`'s primitives against `ray` as the walk does: the closest hit is kept
    /// in `best` (ties by [`rt_geom::replaces`]) and `ray.tmax` lowered to it; with `ANY_HIT`
    /// the first hit ends the test (true). Tests nothing when `node` is not a leaf. Behind the
    /// `research` feature.
    #[cfg(feature = "research")]
    pub fn test_leaf<const ANY_HIT: bool>(
        &self,
        node: usize,
        ray: &mut Ray,
        best: &mut impl Keep,
    ) -> bool {
        let Some(leaf) = self.nodes.get(node).filter(|n| n.is_leaf()) else {
            return false;
        };
        let leaves = (self.prims.as_slice(), &self.listed, rt_geom::BaseLevel);
        traverse::test_leaf::<P, ANY_HIT, _>(leaves, leaf, &self.indices, ray, best)
    }
}

impl<P: Primitive> Walk for KdTree<P> {
    fn isa(&self) -> Isa {
        self.isa
    }

    /// The walk, for the closest hit or any hit, its leaves' triangle windows at `level`.
    #[inline(always)]
    fn walk<const ANY_HIT: bool, L: Level, K: Keep>(
        &self,
        ray: &Ray,
        level: L,
        best: K,
    ) -> Option<Hit> {
        let t = self.params.traversal;
        let leaves = (self.prims.as_slice(), &self.listed, level);
        let (bounds, best) = (&self.bounds, || best);
        if self.frame.is_world() {
            traverse::query::<_, _, ANY_HIT, K, L>(self, leaves, bounds, t, ray, best)
        } else {
            let framed = &traverse::InFrame(self);
            traverse::query::<_, _, ANY_HIT, K, L>(framed, leaves, bounds, t, ray, best)
        }
    }
}

impl<P: Primitive> Accel for KdTree<P> {
    rt_geom::queries_from_walk!(per_isa);

    fn stats(&self) -> AccelStats {
        self.compute_stats()
    }

    fn validate(&self) -> Result<(), String> {
        self.check()
    }
}

impl<P: Primitive> FilteredAccel for KdTree<P> {
    rt_geom::filtered_from_walk!(per_isa);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{BspParams, BspTree, MAX_DEPTH};
    use rt_geom::{Triangle, Vec3};

    /// Every instruction set's walk answers as brute force (the default one, the best this
    /// CPU has, runs everywhere else); a level this CPU lacks runs its best one.
    macro_rules! per_isa {
        ($($name:ident: $isa:expr;)*) => {$(
            mod $name {
                use super::*;
                rt_testkit::conformance_tests!(
                    triangles: |p: &[Triangle]| KdTree::build(p, KdParams::sah()).map(|t| t.with_isa($isa)),
                    spheres: |p: &[rt_geom::Sphere]| KdTree::build(p, KdParams::sah()).map(|t| t.with_isa($isa)),
                );
                rt_testkit::filter_tests!(
                    triangles: |p: &[Triangle]| KdTree::build(p, KdParams::sah()).map(|t| t.with_isa($isa)),
                );
            }
        )*};
    }
    per_isa! {
        isa_baseline: Isa::Baseline;
        isa_avx2: Isa::Avx2;
    }

    /// The leaves a walk tests, tested again alone in order, give the walk's answer; nodes
    /// that are not leaves (or not nodes) test nothing.
    #[cfg(feature = "research")]
    #[test]
    fn leaves_tested_replay_to_the_same_answers() {
        for scene in rt_testkit::scenes::conformance_triangle_scenes() {
            let tree = KdTree::build(&scene.prims, KdParams::sah()).unwrap();
            let reference = rt_geom::BruteForce::build(&scene.prims).unwrap();
            let rays = rt_testkit::rays::conformance_rays(&scene.prims, &reference, 30, 3);
            for t in &rays {
                let ray = &t.ray;
                let (leaves, hit) = tree.leaves_tested::<false>(ray);
                assert_eq!(hit, tree.intersect(ray), "{}", scene.name);
                let (mut r, mut best) = (*ray, None);
                for &l in &leaves {
                    assert!(tree.nodes()[l as usize].is_leaf());
                    tree.test_leaf::<false>(l as usize, &mut r, &mut best);
                }
                assert_eq!(best, hit, "{}", scene.name);
                let (leaves, hit) = tree.leaves_tested::<true>(ray);
                assert_eq!(hit.is_some(), tree.occluded(ray), "{}", scene.name);
                let (mut r, mut best) = (*ray, None);
                let found = leaves
                    .iter()
                    .any(|&l| tree.test_leaf::<true>(l as usize, &mut r, &mut best));
                assert_eq!(found, hit.is_some(), "{}", scene.name);
            }
            let inner = tree.nodes().iter().position(|n| !n.is_leaf());
            let (mut r, mut best) = (rays[0].ray, None);
            for node in inner.into_iter().chain([tree.nodes().len(), usize::MAX]) {
                assert!(!tree.test_leaf::<true>(node, &mut r, &mut best));
                assert!(best.is_none());
            }
        }
    }

    rt_testkit::conformance_per_params!(KdTree::build {
        sah: KdParams::sah(),
        wald_havran: KdParams::wald_havran(),
        sah_recursive: KdParams::sah().with_traversal(KdTraversal::Recursive),
        midpoint: KdParams::midpoint(),
        centroid: KdParams::centroid(),
        centroid_recursive: KdParams::centroid().with_traversal(KdTraversal::Recursive),
        sah_serial: KdParams {
            parallel_threshold: usize::MAX,
            ..KdParams::sah()
        },
        sah_parallel: KdParams {
            parallel_threshold: 16,
            ..KdParams::sah()
        },
        sah_cheap_traversal: KdParams {
            traversal_cost: 1.0,
            intersection_cost: 1.5,
            ..KdParams::sah()
        },
        sah_no_budget: KdParams {
            reference_budget: 1.0,
            ..KdParams::sah()
        },
        midpoint_leaf1: KdParams {
            max_leaf_size: 1,
            ..KdParams::midpoint()
        },
        shallow: KdParams {
            max_depth: Some(3),
            ..KdParams::sah()
        },
    });

    /// The stated memory bound: at most `reference_budget * N` references, and at most
    /// `2 * depth_cap` nodes per reference (plus the root).
    fn assert_bounded(kd: &KdTree<Triangle>) -> AccelStats {
        kd.validate().unwrap();
        let s = kd.stats();
        let n = s.primitives;
        let cap = kd.params().depth_cap(n) as usize;
        assert!(
            s.references as f32 <= kd.params().reference_budget * n as f32,
            "{s}"
        );
        assert!(s.nodes <= 2 * cap * s.references.max(1) + 1, "{s}");
        assert!(s.max_depth <= cap, "{s}");
        s
    }

    #[test]
    fn memory_is_bounded_when_everything_overlaps_one_point() {
        // (The conformance suite checks the answers on the same scenes.)
        let tris = rt_testkit::scenes::overlapping_fan(3000, 1);
        for params in [KdParams::sah(), KdParams::midpoint(), KdParams::centroid()] {
            assert_bounded(&KdTree::build(&tris, params).unwrap());
        }
        // Zero-area triangles at one point: nothing to split.
        let p = Vec3::splat(0.5);
        let dots = vec![Triangle::new(p, p, p); 1000];
        let kd = KdTree::build(&dots, KdParams::sah()).unwrap();
        let s = assert_bounded(&kd);
        assert_eq!((s.leaves, s.references), (1, 1000), "{s}");
    }

    #[test]
    fn memory_is_bounded_on_long_slivers() {
        let tris = rt_testkit::scenes::long_slivers(3000, 2);
        for budget in [1.0, 2.0, 8.0] {
            let params = KdParams {
                reference_budget: budget,
                ..KdParams::sah()
            };
            let s = assert_bounded(&KdTree::build(&tris, params).unwrap());
            // With a budget of 1 no split may duplicate, and every useful plane here does.
            assert!(budget == 1.0 || s.leaves > 1, "{s}");
        }
    }

    #[test]
    fn depth_cap_follows_havran_and_is_respected() {
        let p = KdParams::sah();
        assert_eq!(p.depth_cap(1), 8);
        assert_eq!(p.depth_cap(1 << 20), 34);
        assert_eq!(p.depth_cap(usize::MAX), MAX_DEPTH);
        let tris = rt_testkit::scenes::triangle_scene("soup").prims;
        for d in [0, 1, 5] {
            let kd = KdTree::build(
                &tris,
                KdParams {
                    max_depth: Some(d),
                    ..KdParams::sah()
                },
            )
            .unwrap();
            assert!(kd.stats().max_depth <= d as usize);
            rt_testkit::conformance::assert_conforms(
                &rt_testkit::Scene::new("soup", tris.clone()),
                |_: &[Triangle]| Ok::<_, BuildError>(kd.clone()),
            );
        }
    }

    #[test]
    fn sah_beats_the_naive_planes() {
        let tris = rt_testkit::scenes::triangle_scene("teapot_in_stadium").prims;
        let cost = |p| KdTree::build(&tris, p).unwrap().stats().sah_cost.unwrap();
        // `stats()` weighs a step and a test alike, close to Wald & Havran's 15:20; the
        // default preset (15:7) minimises a cost with cheaper tests, not this one.
        let sah = cost(KdParams::wald_havran());
        assert!(sah < cost(KdParams::midpoint()), "{sah}");
        assert!(sah < cost(KdParams::centroid()), "{sah}");
    }

    #[test]
    fn bad_parameters_are_rejected() {
        let tris = rt_testkit::scenes::random_soup(10, 1);
        let s = KdParams::sah();
        for params in [
            KdParams {
                traversal_cost: f32::NAN,
                ..s
            },
            KdParams {
                traversal_cost: -1.0,
                ..s
            },
            KdParams {
                intersection_cost: 0.0,
                ..s
            },
            KdParams {
                intersection_cost: f32::INFINITY,
                ..s
            },
            KdParams {
                empty_bonus: 1.0,
                ..s
            },
            KdParams {
                empty_bonus: -0.1,
                ..s
            },
            KdParams {
                max_depth: Some(65),
                ..s
            },
            KdParams {
                max_leaf_size: 0,
                ..s
            },
            KdParams {
                reference_budget: 0.5,
                ..s
            },
            KdParams {
                reference_budget: f32::NAN,
                ..s
            },
        ] {
            let err = KdTree::build(&tris, params).unwrap_err();
            assert!(
                matches!(err, BuildError::InvalidParameter { .. }),
                "{params:?}: {err}"
            );
            // The BSP tree shares every field but the empty bonus, and the same checks.
            let bsp = BspParams {
                traversal_cost: params.traversal_cost,
                intersection_cost: params.intersection_cost,
                max_depth: params.max_depth,
                max_leaf_size: params.max_leaf_size,
                reference_budget: params.reference_budget,
                ..BspParams::standard()
            };
            let shared = params.empty_bonus == s.empty_bonus;
            assert_eq!(BspTree::build(&tris, bsp).is_err(), shared, "{bsp:?}");
        }
        for bad in [
            BspParams {
                candidates: 0,
                axis_planes: false,
                ..BspParams::standard()
            },
            BspParams {
                candidates: 5000,
                ..BspParams::standard()
            },
        ] {
            assert!(matches!(
                BspTree::build(&tris, bad),
                Err(BuildError::InvalidParameter { .. })
            ));
        }
    }

    #[test]
    fn non_finite_and_too_many_primitives_are_errors() {
        let mut tris = rt_testkit::scenes::random_soup(10, 1);
        tris[4].v[1].y = f32::NAN;
        assert_eq!(
            KdTree::build(&tris, KdParams::sah()).unwrap_err(),
            BuildError::NonFinite { prim: 4 }
        );
        assert_eq!(
            BspTree::build(&tris, BspParams::standard()).unwrap_err(),
            BuildError::NonFinite { prim: 4 }
        );
        let too_many = vec![rt_testkit::NoGeometry; build::MAX_LOCAL + 1];
        assert!(matches!(
            KdTree::build(&too_many, KdParams::sah()),
            Err(BuildError::TooManyPrimitives { .. })
        ));
        assert!(matches!(
            BspTree::build(&too_many, BspParams::standard()),
            Err(BuildError::TooManyPrimitives { .. })
        ));
    }

    #[test]
    fn rays_along_and_onto_split_planes() {
        // A 4x4 grid of unit quads in z = 0 and walls at every integer x: the SAH splits at
        // the integers, and rays run inside those planes and start on them.
        let mut tris = Vec::new();
        for i in 0..4 {
            for j in 0..4 {
                let (x, y) = (i as f32, j as f32);
                let q = [
                    Vec3::new(x, y, 0.0),
                    Vec3::new(x + 1.0, y, 0.0),
                    Vec3::new(x + 1.0, y + 1.0, 0.0),
                    Vec3::new(x, y + 1.0, 0.0),
                ];
                tris.push(Triangle::new(q[0], q[1], q[2]));
                tris.push(Triangle::new(q[0], q[2], q[3]));
            }
            let x = i as f32;
            tris.push(Triangle::new(
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x, 4.0, 0.0),
                Vec3::new(x, 0.0, 2.0),
            ));
        }
        let brute = rt_geom::BruteForce::build(&tris).unwrap();
        for params in [
            KdParams::sah(),
            KdParams::sah().with_traversal(KdTraversal::Recursive),
            KdParams::midpoint(),
        ] {
            let kd = KdTree::build(&tris, params).unwrap();
            assert!(kd.stats().nodes > 1);
            let bsp = BspTree::build(&tris, BspParams::standard()).unwrap();
            for x in [0.0f32, 1.0, 2.0, 3.0, 0.5] {
                for (o, d) in [
                    // In the plane x = const, down onto the floor.
                    (Vec3::new(x, 0.5, 1.0), Vec3::new(0.0, 0.3, -1.0)),
                    // In the plane x = const and z = 0: grazes floor and wall edges.
                    (Vec3::new(x, -1.0, 0.0), Vec3::Y),
                    // Starting on the plane, leaving it either way.
                    (Vec3::new(x, 0.5, 0.5), Vec3::new(1.0, 0.0, -1.0)),
                    (Vec3::new(x, 0.5, 0.5), Vec3::new(-1.0, 0.0, -1.0)),
                    // Crossing the planes at a shallow angle.
                    (Vec3::new(-1.0, 0.5, 0.25), Vec3::new(1.0, 0.01, -0.01)),
                ] {
                    let ray = Ray::new(o, d);
                    let want = brute.intersect(&ray).map(|h| h.t);
                    assert_eq!(kd.intersect(&ray).map(|h| h.t), want, "{params:?} {ray:?}");
                    assert_eq!(bsp.intersect(&ray).map(|h| h.t), want, "bsp {ray:?}");
                    assert_eq!(kd.occluded(&ray), want.is_some());
                }
            }
        }
    }
}
