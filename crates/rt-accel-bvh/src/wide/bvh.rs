//! [`WideBvh`]: a wide topology that owns its leaf-ordered primitives.

use super::{NodeLayout, WideNode, WideTree, test_leaf};
use crate::refit::{Refit, check_moved, leaf_bounds, refill_in_leaf_order};
use crate::stats::check_leaf_primitive;
use crate::{Bvh, BvhParams};
use rt_geom::all_referenced;
use rt_geom::pages::Pages;
use rt_geom::{
    Accel, AccelStats, BuildError, FilteredAccel, Hit, Isa, Keep, Level, Primitive, Ray, Walk,
};

/// A BVH with `N` children per node (`N` = 4 or 8) in the layout `Node` (exact boxes by
/// default), sharing the leaf-ordered primitives of the binary tree it was collapsed from.
#[derive(Clone, Debug)]
pub struct WideBvh<P, const N: usize, Node = WideNode<N>> {
    pub(crate) tree: WideTree<N, Node>,
    pub(crate) prims: Pages<P>,
    pub(crate) ids: Pages<u32>,
    pub(crate) count: usize,
    pub(crate) params: BvhParams,
}

/// A 4-wide BVH over primitives `P`.
pub type Bvh4<P> = WideBvh<P, 4>;
/// An 8-wide BVH over primitives `P`.
pub type Bvh8<P> = WideBvh<P, 8>;

impl<P: Primitive, const N: usize, Node: NodeLayout<N>> WideBvh<P, N, Node> {
    /// Builds a binary BVH with `params` and collapses it.
    pub fn build(prims: &[P], params: BvhParams) -> Result<Self, BuildError> {
        Ok(Self::from_binary(Bvh::build(prims, params)?))
    }

    /// Collapses a binary BVH (see [`WideTree::collapse`]).
    pub fn from_binary(bvh: Bvh<P>) -> Self {
        let tree = WideTree::<N, Node>::collapse(&bvh.nodes, &bvh.params);
        let Bvh {
            prims,
            ids,
            count,
            params,
            ..
        } = bvh;
        Self::assemble(tree, prims, ids, count, params)
    }

    /// The structure of a tree, its leaf-ordered primitives and their ids.
    pub(crate) fn assemble(
        tree: WideTree<N, Node>,
        prims: Pages<P>,
        ids: Pages<u32>,
        count: usize,
        params: BvhParams,
    ) -> Self {
        Self {
            tree,
            prims,
            ids,
            count,
            params,
        }
    }

    /// The wide topology.
    pub fn tree(&self) -> &WideTree<N, Node> {
        &self.tree
    }

    /// Primitives in leaf order.
    pub fn prims(&self) -> &[P] {
        &self.prims
    }

    /// The caller's index of each primitive in leaf order.
    pub fn ids(&self) -> &[u32] {
        &self.ids
    }

    /// The same structure, its queries run compiled for `isa` ([`WideTree::with_isa`]).
    pub fn with_isa(mut self, isa: Isa) -> Self {
        self.tree = self.tree.with_isa(isa);
        self
    }
}

impl<P: Primitive, const N: usize, Node: NodeLayout<N>> Walk for WideBvh<P, N, Node> {
    fn isa(&self) -> Isa {
        self.tree.isa()
    }

    #[inline(always)]
    fn walk<const ANY_HIT: bool, L: Level, K: Keep>(
        &self,
        ray: &Ray,
        level: L,
        best: K,
    ) -> Option<Hit> {
        self.tree.traverse::<ANY_HIT, L, K>(
            level,
            ray,
            || best,
            #[inline(always)]
            |first, count, r, best| {
                test_leaf::<P, _, ANY_HIT>(&self.prims, &self.ids, first, count, r, best)
            },
        )
    }
}

impl<P: Primitive, const N: usize, Node: NodeLayout<N>> Refit<P> for WideBvh<P, N, Node> {
    fn refit(&mut self, prims: &[P]) -> Result<(), BuildError> {
        check_moved(prims, self.count)?;
        refill_in_leaf_order(&mut self.prims, prims, &self.ids);
        let prims = &self.prims;
        self.tree
            .refit(&|first, count| leaf_bounds(prims, first, count));
        Ok(())
    }
}

impl<P: Primitive, const N: usize, Node: NodeLayout<N>> FilteredAccel for WideBvh<P, N, Node> {
    rt_geom::filtered_from_walk!(per_isa);
}

impl<P: Primitive, const N: usize, Node: NodeLayout<N>> Accel for WideBvh<P, N, Node> {
    rt_geom::queries_from_walk!(per_isa);

    fn stats(&self) -> AccelStats {
        let mut s = self.tree.stats(self.count, &self.params);
        s.bytes += std::mem::size_of_val(self.prims.as_slice())
            + std::mem::size_of_val(self.ids.as_slice());
        s
    }

    fn validate(&self) -> Result<(), String> {
        let mut seen = vec![false; self.count];
        self.tree.check(|first, count, bounds| {
            for k in first as usize..(first + count) as usize {
                let p = self.prims.get(k).ok_or("leaf points past the primitives")?;
                let split = self.params.splits_primitives();
                check_leaf_primitive(p, self.ids[k], bounds, &mut seen, split)?;
            }
            Ok(())
        })?;
        all_referenced(&seen)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::WideCollapse;
    use rt_geom::{Sphere, Triangle};

    mod bvh4 {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| Bvh4::build(p, BvhParams::balanced()),
            spheres: |p: &[Sphere]| Bvh4::build(p, BvhParams::balanced()),
            shapes: |p: &[rt_geom::Shape]| Bvh4::build(p, BvhParams::balanced()),
        );
        rt_testkit::disc_tests!(|p: &[rt_testkit::Disc]| Bvh4::build(p, BvhParams::balanced()));
        rt_testkit::filter_tests!(
            triangles: |p: &[Triangle]| Bvh4::build(p, BvhParams::balanced()),
            spheres: |p: &[Sphere]| Bvh4::build(p, BvhParams::balanced()),
            shapes: |p: &[rt_geom::Shape]| Bvh4::build(p, BvhParams::balanced()),
        );
    }

    mod bvh8 {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| Bvh8::build(p, BvhParams::balanced()),
            spheres: |p: &[Sphere]| Bvh8::build(p, BvhParams::balanced()),
            shapes: |p: &[rt_geom::Shape]| Bvh8::build(p, BvhParams::balanced()),
        );
        rt_testkit::disc_tests!(|p: &[rt_testkit::Disc]| Bvh8::build(p, BvhParams::balanced()));
    }

    mod bvh8_pure_sah_collapse {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| Bvh8::build(p, BvhParams { collapse: WideCollapse::Sah, ..BvhParams::balanced() }),
        );
    }

    mod bvh4_greedy_collapse {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| Bvh4::build(p, BvhParams { collapse: WideCollapse::LargestArea, ..BvhParams::balanced() }),
        );
    }

    #[test]
    fn hybrid_collapse_spans_both_rules() {
        let tris = rt_testkit::scenes::tessellated_sphere(3000, rt_geom::Vec3::ZERO, 1.0);
        let bvh = Bvh::build(&tris, BvhParams::balanced()).unwrap();
        let with = |collapse| {
            let params = BvhParams {
                collapse,
                ..*bvh.params()
            };
            WideTree::<8>::collapse(&bvh.nodes, &params).nodes
        };
        let hybrid = |above| with(WideCollapse::LargestAreaThenSah { above });
        assert_eq!(hybrid(0.0), with(WideCollapse::LargestArea));
        assert_eq!(hybrid(1.5), with(WideCollapse::Sah));
        assert_ne!(with(WideCollapse::Sah), with(WideCollapse::LargestArea));
        for above in [-1.0, f32::NAN] {
            let params = BvhParams {
                collapse: WideCollapse::LargestAreaThenSah { above },
                ..BvhParams::balanced()
            };
            assert!(Bvh8::build(&tris, params).is_err());
        }
    }

    mod bvh8_leaf1 {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| Bvh8::build(p, BvhParams { max_leaf_size: 1, ..BvhParams::quality() }),
        );
    }
}
