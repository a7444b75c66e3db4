//! [`Bvh`], the binary BVH: built top-down by one of the builders in `build`, flattened
//! depth-first into [`BvhNode`](crate::BvhNode)s, optionally improved by reinsertion; walked by
//! `traverse`.

use crate::{BvhBuilder, BvhNode, BvhParams, build};
use rt_geom::pages::Pages;
use rt_geom::{
    Aabb, Accel, AccelStats, BuildError, FilteredAccel, Frame, Hit, Isa, Keep, Level, Primitive,
    Ray, Walk, check_primitives,
};

/// A binary BVH over primitives `P`, flattened depth-first, primitives stored in leaf order.
#[derive(Clone, Debug)]
pub struct Bvh<P> {
    pub(crate) nodes: Pages<BvhNode>,
    /// Primitives in leaf order.
    pub(crate) prims: Pages<P>,
    /// `ids[i]`: the caller's index of `prims[i]` (repeated with spatial splits).
    pub(crate) ids: Pages<u32>,
    /// Primitives the tree was built from (`prims` may hold some several times).
    pub(crate) count: usize,
    pub(crate) params: BvhParams,
    /// The instruction set its queries (and rt-packet's packet queries) run compiled for.
    pub(crate) isa: Isa,
}

impl<P: Primitive> Bvh<P> {
    /// Builds over `prims` (copied, reordered). Empty input gives an empty tree. Far from the
    /// origin the tree is built over the primitives' boxes in the scene's frame
    /// ([`rt_geom::Frame`], where their centres keep the precision binning needs) and its
    /// boxes are then refitted from the primitives in world coordinates.
    pub fn build(prims: &[P], params: BvhParams) -> Result<Self, BuildError> {
        params.validate()?;
        check_primitives(prims, u32::MAX as usize - 1)?;
        let prims_len = prims.len();
        if prims.is_empty() {
            return Ok(Self {
                nodes: Pages::default(),
                prims: Pages::default(),
                ids: Pages::default(),
                count: 0,
                params,
                isa: Isa::selected(),
            });
        }
        let frame = Frame::of(&Aabb::around(prims));
        let mut refs = build::prim_refs_in(prims, &frame);
        let (root, count, ids) = match (params.builder, params.spatial_alpha) {
            (BvhBuilder::BinnedSah { bins }, Some(alpha)) => build::spatial::build(
                prims,
                &frame,
                refs,
                &params,
                bins,
                alpha,
                params.spatial_budget,
            ),
            _ => {
                let (root, count) = build::build_tree(&mut refs, &params);
                (root, count, refs.iter().map(|r| r.index()).collect())
            }
        };
        let nodes = build::flatten(&root, count);
        drop(root);
        let (nodes, ids) = build::reinsert::optimize(nodes, ids, params.reinsertion);
        let in_leaf_order: Vec<P> = {
            use rayon::prelude::*;
            ids.par_iter()
                .with_min_len(1 << 14)
                .map(|&i| prims[i as usize].clone())
                .collect()
        };
        let mut bvh = Self {
            nodes: nodes.into(),
            prims: in_leaf_order.into(),
            ids: ids.into(),
            count: prims_len,
            params,
            isa: Isa::selected(),
        };
        if !frame.is_world() {
            bvh.boxes_to_world(&frame);
        }
        Ok(bvh)
    }

    /// The flattened nodes (read-only; layout in [`node`](crate::node)).
    pub fn nodes(&self) -> &[BvhNode] {
        &self.nodes
    }

    /// Primitives in leaf order; leaf `n` holds `prims()[n.offset..n.offset + n.count()]`.
    pub fn prims(&self) -> &[P] {
        &self.prims
    }

    /// The caller's index of each primitive in leaf order.
    pub fn ids(&self) -> &[u32] {
        &self.ids
    }

    /// The parameters the tree was built with.
    pub fn params(&self) -> &BvhParams {
        &self.params
    }

    /// Primitives the tree was built from.
    pub fn primitive_count(&self) -> usize {
        self.count
    }

    /// The same tree, its queries run compiled for `isa` (or, where this CPU lacks it, for the
    /// best level it has): for tests and measurements of each level.
    pub fn with_isa(mut self, isa: Isa) -> Self {
        self.isa = isa.or_best();
        self
    }
}

impl<P: Primitive> Walk for Bvh<P> {
    fn isa(&self) -> Isa {
        self.isa
    }

    #[inline(always)]
    fn walk<const ANY_HIT: bool, L: Level, K: Keep>(
        &self,
        ray: &Ray,
        _level: L,
        best: K,
    ) -> Option<Hit> {
        self.traverse::<ANY_HIT, K>(ray, || best)
    }
}

impl<P: Primitive> FilteredAccel for Bvh<P> {
    rt_geom::filtered_from_walk!(per_isa);
}

impl<P: Primitive> Accel for Bvh<P> {
    rt_geom::queries_from_walk!(per_isa);

    fn stats(&self) -> AccelStats {
        self.compute_stats()
    }

    fn validate(&self) -> Result<(), String> {
        self.check()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{BvList, BvListParams, MAX_DEPTH};
    use rt_geom::{Ray, Sphere, Triangle, Vec3};
    use rt_testkit::scenes;

    rt_testkit::conformance_per_params!(Bvh::build {
        binned: BvhParams::balanced(),
        binned_fast: BvhParams::fast(),
        sweep: BvhParams::quality(),
        midpoint: BvhParams::balanced().with_builder(BvhBuilder::Midpoint),
        median: BvhParams::balanced().with_builder(BvhBuilder::Median),
        leaf1: BvhParams {
            max_leaf_size: 1,
            ..BvhParams::balanced()
        },
        serial: BvhParams {
            parallel_threshold: usize::MAX,
            ..BvhParams::balanced()
        },
        parallel: BvhParams {
            parallel_threshold: 16,
            ..BvhParams::balanced()
        },
        spatial: BvhParams::spatial(),
        spatial_everywhere: BvhParams {
            spatial_alpha: Some(0.0),
            spatial_budget: 4.0,
            ..BvhParams::spatial()
        },
        spatial_parallel: BvhParams {
            parallel_threshold: 16,
            ..BvhParams::spatial()
        },
        spatial_no_budget: BvhParams {
            spatial_budget: 0.0,
            ..BvhParams::spatial()
        },
        reinserted: BvhParams::balanced().with_reinsertion(1.0),
        reinserted_leaf1_midpoint: BvhParams {
            max_leaf_size: 1,
            ..BvhParams::balanced()
                .with_builder(BvhBuilder::Midpoint)
                .with_reinsertion(1.0)
        },
        reinserted_spatial: BvhParams::spatial().with_reinsertion(0.5),
    });

    /// Each instruction set's walk answers as brute force (a level this CPU lacks runs its
    /// best one).
    mod isa_baseline {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| Bvh::build(p, BvhParams::balanced()).map(|b| b.with_isa(Isa::Baseline)),
            spheres: |p: &[Sphere]| Bvh::build(p, BvhParams::balanced()).map(|b| b.with_isa(Isa::Baseline)),
        );
    }
    mod isa_avx2 {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| Bvh::build(p, BvhParams::balanced()).map(|b| b.with_isa(Isa::Avx2)),
            spheres: |p: &[Sphere]| Bvh::build(p, BvhParams::balanced()).map(|b| b.with_isa(Isa::Avx2)),
        );
    }

    #[test]
    fn spatial_splits_duplicate_long_triangles() {
        // Two clusters of small triangles at x = 0 and x = 10, bridged by a few long slivers:
        // object splits put the slivers on one side, whose box then spans everything; a
        // spatial split at x = 5 cuts them and leaves two compact halves.
        let mut tris = scenes::random_soup(200, 7);
        for t in tris.iter_mut().skip(100) {
            t.v = t.v.map(|p| p + Vec3::new(9.0, 0.0, 0.0));
        }
        for i in 0..8 {
            let y = i as f32 * 0.1;
            tris.push(Triangle::new(
                Vec3::new(0.0, y, 0.0),
                Vec3::new(10.0, y, 0.0),
                Vec3::new(10.0, y + 0.01, 0.0),
            ));
        }
        let plain = Bvh::build(&tris, BvhParams::balanced()).unwrap();
        let split = Bvh::build(&tris, BvhParams::spatial()).unwrap();
        split.validate().unwrap();
        let (p, s) = (plain.stats(), split.stats());
        assert_eq!(s.primitives, tris.len());
        assert!(s.references > p.references, "{s}");
        assert!(
            s.references <= 2 * tris.len(),
            "budget of one extra reference each: {s}"
        );
        // The root is cut in space: neither child spans the whole scene along x.
        let n = split.nodes();
        for child in [1, n[0].offset as usize] {
            assert!(
                n[child].bounds().extent().x < 9.0,
                "{:?}",
                n[child].bounds()
            );
        }
        let pn = plain.nodes();
        let spans = [1, pn[0].offset as usize]
            .iter()
            .filter(|&&c| pn[c].bounds().extent().x >= 9.0)
            .count();
        assert!(
            spans >= 1,
            "object splits keep a child that spans the scene"
        );
    }

    #[test]
    fn all_primitives_at_one_point() {
        let p = Vec3::splat(0.5);
        let tris = vec![Triangle::new(p, p, p); 1000];
        let bvh = Bvh::build(&tris, BvhParams::balanced()).unwrap();
        bvh.validate().unwrap();
        let s = bvh.stats();
        assert!(s.max_depth <= MAX_DEPTH);
        assert!(s.leaves >= 1000 / 4, "{s}");
        let spheres = vec![Sphere::new(p, 0.1); 1000];
        let bvh = Bvh::build(&spheres, BvhParams::quality()).unwrap();
        bvh.validate().unwrap();
        assert_eq!(
            bvh.intersect(&Ray::new(Vec3::ZERO, p)).unwrap().t,
            1.0 - 0.1 / p.length()
        );
    }

    #[test]
    fn more_primitives_than_the_index_type_holds() {
        let too_many = vec![rt_testkit::NoGeometry; u32::MAX as usize];
        let err = Bvh::build(&too_many, BvhParams::balanced()).unwrap_err();
        assert!(matches!(err, BuildError::TooManyPrimitives { .. }), "{err}");
        assert!(matches!(
            BvList::<_, rt_geom::Aabb>::build(&too_many, BvListParams::default()),
            Err(BuildError::TooManyPrimitives { .. })
        ));
    }

    #[test]
    fn bad_parameters_are_rejected() {
        let tris = scenes::random_soup(10, 1);
        for params in [
            BvhParams {
                max_leaf_size: 0,
                ..BvhParams::balanced()
            },
            BvhParams {
                max_leaf_size: 1000,
                ..BvhParams::balanced()
            },
            BvhParams::balanced().with_builder(BvhBuilder::BinnedSah { bins: 1 }),
            BvhParams {
                traversal_cost: f32::NAN,
                ..BvhParams::balanced()
            },
            BvhParams {
                intersection_cost: 0.0,
                ..BvhParams::balanced()
            },
        ]
        .into_iter()
        .chain([0, 3, 32].map(|leaf_block| BvhParams {
            leaf_block,
            ..BvhParams::balanced()
        }))
        .chain(
            [-0.5, 1.5, f32::NAN, f32::INFINITY].map(|r| BvhParams::balanced().with_reinsertion(r)),
        ) {
            assert!(matches!(
                Bvh::build(&tris, params),
                Err(BuildError::InvalidParameter { .. })
            ));
        }
    }

    #[test]
    fn depth_is_capped_on_pathological_input() {
        // Exponentially spaced triangles: naive midpoint splits peel one off per level.
        let tris: Vec<Triangle> = (0..200)
            .map(|i| {
                let x = 2f32.powi(-i / 2);
                Triangle::new(
                    Vec3::new(x, 0.0, 0.0),
                    Vec3::new(x, 1.0, 0.0),
                    Vec3::new(x, 0.0, 1.0),
                )
            })
            .collect();
        let bvh = Bvh::build(
            &tris,
            BvhParams::balanced().with_builder(BvhBuilder::Midpoint),
        )
        .unwrap();
        bvh.validate().unwrap();
        assert!(bvh.stats().max_depth <= MAX_DEPTH);
        let r = Ray::new(Vec3::new(-1.0, 0.25, 0.25), Vec3::X);
        // x = 2^-i/2 below 6e-8 is lost in t = 1 + x (t = 1.0 in f32): many ties, all at t = 1.
        let hit = bvh.intersect(&r).unwrap();
        assert_eq!(hit.t, 1.0);
        assert!(tris[hit.prim as usize].v[0].x < 6e-8);
    }
}
