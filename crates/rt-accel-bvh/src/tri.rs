//! Wide BVHs specialised for triangles: leaf triangles stored leaf by leaf as structure of
//! arrays ([`TriangleSoa`], from rt-geom) and tested four at a time (the watertight edge tests
//! of four triangles are one SIMD operation each), with exactly the answers of the scalar
//! kernel.

use crate::compressed::CompressedNode;
use crate::refit::{Refit, check_moved, in_leaf_order, leaf_bounds};
use crate::stats::check_leaf_primitive;
use crate::wide::{NodeLayout, WideNode, WideTree};
use crate::{Bvh, BvhParams};
use rt_geom::pages::Pages;
use rt_geom::{
    Aabb, Accel, AccelStats, BuildError, FilteredAccel, Hit, Isa, Keep, Level, Ray, Triangle,
    TriangleKernel, TriangleSoa, Vec3, Walk, all_referenced,
};

/// Checks the triangles of leaf `(first, count)` against its `bounds` and marks their ids
/// in `seen` (see [`check_leaf_primitive`]).
fn check_leaf(
    tris: &TriangleSoa,
    ids: &[u32],
    (first, count): (u32, u32),
    bounds: &Aabb,
    seen: &mut [bool],
    split: bool,
) -> Result<(), String> {
    let (first, count) = (first as usize, count as usize);
    if first + count > tris.len() {
        return Err("leaf points past the triangles".into());
    }
    for k in 0..count {
        let t = tris.get(first, count, k);
        check_leaf_primitive(&t, ids[first + k], bounds, seen, split)?;
    }
    Ok(())
}

/// A wide BVH over triangles with four-lane leaf tests: `N` children per node (4 or 8) in
/// the layout `Node` (exact boxes by default, or the quantized [`CompressedNode`]).
#[derive(Clone, Debug)]
pub struct TriBvh<const N: usize, Node = WideNode<N>> {
    pub(crate) tree: WideTree<N, Node>,
    tris: TriangleSoa,
    pub(crate) ids: Pages<u32>,
    pub(crate) count: usize,
    pub(crate) params: BvhParams,
    stats: AccelStats,
}

/// A 4-wide BVH over triangles stored leaf by leaf as SoA (one SSE-width node test).
pub type TriBvh4 = TriBvh<4>;
/// An 8-wide BVH over triangles stored leaf by leaf as SoA: rt's fastest single-ray
/// structure; [`TriBvh8::build_for_tracing`] builds it with the preset that traces fastest.
pub type TriBvh8 = TriBvh<8>;
/// [`TriBvh8`] with child boxes quantized to 8 bits per plane: the SIMD triangle leaves and
/// half-size nodes.
pub type CompressedTriBvh8 = TriBvh<8, CompressedNode>;

impl<const N: usize, Node: NodeLayout<N>> TriBvh<N, Node> {
    /// Builds a binary BVH with `params` and collapses it to `N`-wide nodes.
    pub fn build(tris: &[Triangle], params: BvhParams) -> Result<Self, BuildError> {
        Ok(Self::from_binary(Bvh::build(tris, params)?))
    }

    /// Builds with [`BvhParams::fastest_trace`], the preset rt traces fastest with: no tuning
    /// to know, the same build as the `bvh8-tri` / `bvh4-tri` entries of rt's benchmarks.
    pub fn build_for_tracing(tris: &[Triangle]) -> Result<Self, BuildError> {
        Self::build(tris, BvhParams::fastest_trace())
    }

    /// Collapses a binary BVH and converts its leaf-ordered triangles.
    pub fn from_binary(bvh: Bvh<Triangle>) -> Self {
        let tree = WideTree::<N, Node>::collapse(&bvh.nodes, &bvh.params);
        let tris = TriangleSoa::new(&bvh.prims, tree.leaves());
        Self::assemble(tree, tris, bvh.ids, bvh.count, bvh.params)
    }

    /// The structure of a tree, its leaf-ordered triangles and their ids, with its stats.
    pub(crate) fn assemble(
        tree: WideTree<N, Node>,
        tris: TriangleSoa,
        ids: Pages<u32>,
        count: usize,
        params: BvhParams,
    ) -> Self {
        let mut stats = tree.stats(count, &params);
        stats.bytes += tris.bytes() + std::mem::size_of_val(ids.as_slice());
        Self {
            tree,
            tris,
            ids,
            count,
            params,
            stats,
        }
    }

    /// The triangles in the caller's order, from the leaves (each once, wherever a spatial
    /// split listed it twice).
    pub(crate) fn caller_triangles(&self) -> Vec<Triangle> {
        let mut out = vec![Triangle::new(Vec3::ZERO, Vec3::ZERO, Vec3::ZERO); self.count];
        for (first, count) in self.tree.leaves() {
            let (first, count) = (first as usize, count as usize);
            for k in 0..count {
                out[self.ids[first + k] as usize] = self.tris.get(first, count, k);
            }
        }
        out
    }

    /// The wide topology.
    pub fn tree(&self) -> &WideTree<N, Node> {
        &self.tree
    }

    /// The triangles, leaf by leaf, as structure of arrays.
    pub fn triangles(&self) -> &TriangleSoa {
        &self.tris
    }

    /// The caller's index of each triangle in leaf order.
    pub fn ids(&self) -> &[u32] {
        &self.ids
    }

    /// The same structure, its queries run compiled for `isa` ([`WideTree::with_isa`]).
    pub fn with_isa(mut self, isa: Isa) -> Self {
        self.tree = self.tree.with_isa(isa);
        self
    }

    /// The same structure, its leaves tested with `kernel` ([`TriangleSoa::kernel`]): the
    /// watertight test by default, or [`TriangleKernel::MollerTrumbore`] (faster, not
    /// watertight, as Embree's default mode is). Either way the answers are exactly those of
    /// brute force with that kernel ([`Triangle::intersect_with`]).
    pub fn with_kernel(mut self, kernel: TriangleKernel) -> Self {
        self.tris.set_kernel(kernel);
        self
    }

    /// The kernel the leaves are tested with ([`Self::with_kernel`]).
    pub fn kernel(&self) -> TriangleKernel {
        self.tris.kernel()
    }

    /// The same structure, its walks asking for every child a node's test enters (the node,
    /// or the leaf's triangles) as soon as the test is done (`true`), or not
    /// ([`TriangleSoa::prefetches`]; by default, for large scenes). The answers are the
    /// same.
    pub fn with_prefetch(mut self, on: bool) -> Self {
        self.tris.set_prefetch(on);
        self
    }
}

impl<const N: usize, Node: NodeLayout<N>> Walk for TriBvh<N, Node> {
    const CLOSEST_AVX512: bool = true;

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
        // Large scenes: the nodes and leaf rows a node's test enters asked for early.
        let prefetch = self.tris.prefetches().then_some(
            #[inline(always)]
            |first: u32| self.tris.leaf_address(first as usize),
        );
        self.tree.traverse_prefetching::<ANY_HIT, L, K>(
            level,
            ray,
            || best,
            #[inline(always)]
            |first, count, r, best| {
                self.tris.intersect_range::<ANY_HIT, L>(
                    level,
                    first as usize,
                    count as usize,
                    r,
                    &self.ids,
                    best,
                )
            },
            prefetch,
        )
    }
}

impl<const N: usize, Node: NodeLayout<N>> Refit<Triangle> for TriBvh<N, Node> {
    fn refit(&mut self, tris: &[Triangle]) -> Result<(), BuildError> {
        check_moved(tris, self.count)?;
        let leaf_tris = in_leaf_order(tris, &self.ids);
        let (prefetch, kernel) = (self.tris.prefetches(), self.tris.kernel());
        self.tris = TriangleSoa::new(&leaf_tris, self.tree.leaves());
        self.tris.set_prefetch(prefetch);
        self.tris.set_kernel(kernel);
        self.tree
            .refit(&|first, count| leaf_bounds(&leaf_tris, first, count));
        let mut stats = self.tree.stats(self.count, &self.params);
        stats.bytes += self.tris.bytes() + std::mem::size_of_val(&self.ids[..]);
        self.stats = stats;
        Ok(())
    }
}

impl<const N: usize, Node: NodeLayout<N>> FilteredAccel for TriBvh<N, Node> {
    rt_geom::filtered_from_walk!(per_isa);
}

impl<const N: usize, Node: NodeLayout<N>> Accel for TriBvh<N, Node> {
    rt_geom::queries_from_walk!(per_isa);

    fn stats(&self) -> AccelStats {
        self.stats.clone()
    }

    fn validate(&self) -> Result<(), String> {
        let mut seen = vec![false; self.count];
        let split = self.params.splits_primitives();
        self.tree.check(|first, count, bounds| {
            check_leaf(
                &self.tris,
                &self.ids,
                (first, count),
                bounds,
                &mut seen,
                split,
            )
        })?;
        all_referenced(&seen)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    mod tri4 {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| TriBvh4::build(p, BvhParams::balanced()),
        );
        rt_testkit::filter_tests!(
            triangles: |p: &[Triangle]| TriBvh4::build(p, BvhParams::balanced()),
        );
    }

    mod tri8 {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| TriBvh8::build(p, BvhParams::balanced().for_soa_leaves()),
        );
        rt_testkit::conformance_tests!(
            moller_trumbore: |p: &[Triangle]| TriBvh8::build_for_tracing(p)
                .map(|b| b.with_kernel(TriangleKernel::MollerTrumbore)),
        );
    }

    mod compressed_tri8 {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| CompressedTriBvh8::build(p, BvhParams::balanced()),
        );
    }

    mod compressed_tri8_spatial {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| CompressedTriBvh8::build(p, BvhParams::spatial().for_soa_leaves()),
        );
        rt_testkit::filter_tests!(
            triangles: |p: &[Triangle]| CompressedTriBvh8::build(p, BvhParams::spatial().for_soa_leaves()),
        );
    }

    mod tri8_spatial {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| TriBvh8::build(p, BvhParams::fastest_trace_spatial()),
        );
        rt_testkit::conformance_tests!(
            moller_trumbore: |p: &[Triangle]| TriBvh8::build(p, BvhParams::fastest_trace_spatial())
                .map(|b| b.with_kernel(TriangleKernel::MollerTrumbore)),
        );
    }

    mod tri8_prefetch {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| TriBvh8::build(p, BvhParams::balanced().for_soa_leaves()).map(|b| b.with_prefetch(true)),
        );
    }

    mod tri8_reinserted {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| TriBvh8::build(p, BvhParams::balanced().for_soa_leaves().with_reinsertion(1.0)),
        );
    }

    /// Every instruction set's walk answers as brute force (the default one, the best this
    /// CPU has, runs everywhere else); a level this CPU lacks runs its best one.
    macro_rules! per_isa {
        ($($name:ident: $isa:expr;)*) => {$(
            mod $name {
                use super::*;
                mod tri8 {
                    use super::*;
                    rt_testkit::conformance_tests!(
                        triangles: |p: &[Triangle]| TriBvh8::build(p, BvhParams::balanced().for_soa_leaves()).map(|b| b.with_isa($isa)),
                    );
                    rt_testkit::filter_tests!(
                        triangles: |p: &[Triangle]| TriBvh8::build(p, BvhParams::balanced().for_soa_leaves()).map(|b| b.with_isa($isa)),
                    );
                    rt_testkit::conformance_tests!(
                        moller_trumbore: |p: &[Triangle]| TriBvh8::build_for_tracing(p)
                            .map(|b| b.with_isa($isa).with_kernel(TriangleKernel::MollerTrumbore)),
                    );
                }
                mod tri4 {
                    use super::*;
                    rt_testkit::conformance_tests!(
                        triangles: |p: &[Triangle]| TriBvh4::build(p, BvhParams::balanced()).map(|b| b.with_isa($isa)),
                    );
                }
                mod bvh8 {
                    use super::*;
                    rt_testkit::conformance_tests!(
                        triangles: |p: &[Triangle]| crate::Bvh8::build(p, BvhParams::balanced()).map(|b| b.with_isa($isa)),
                        spheres: |p: &[rt_geom::Sphere]| crate::Bvh8::build(p, BvhParams::balanced()).map(|b| b.with_isa($isa)),
                    );
                    rt_testkit::filter_tests!(
                        triangles: |p: &[Triangle]| crate::Bvh8::build(p, BvhParams::balanced()).map(|b| b.with_isa($isa)),
                        spheres: |p: &[rt_geom::Sphere]| crate::Bvh8::build(p, BvhParams::balanced()).map(|b| b.with_isa($isa)),
                    );
                }
            }
        )*};
    }
    per_isa! {
        isa_baseline: Isa::Baseline;
        isa_avx2: Isa::Avx2;
    }

    /// The walk's stack is sized for the deepest tree the build and loading allow
    /// (`MAX_DEPTH + 1` levels): a tree recorded that deep walks with the same answers.
    #[test]
    fn trees_at_the_depth_cap_walk_with_the_frame_stack() {
        let tris = rt_testkit::scenes::random_soup(3000, 5);
        let bvh = TriBvh8::build(&tris, BvhParams::balanced().for_soa_leaves()).unwrap();
        let mut deep = bvh.clone();
        deep.tree.depth = crate::params::MAX_DEPTH + 1;
        let mut hits = 0;
        for ray in rt_testkit::rays::rays_through_unit_cube(4000) {
            let hit = bvh.intersect(&ray);
            assert_eq!(deep.intersect(&ray), hit);
            assert_eq!(deep.occluded(&ray), bvh.occluded(&ray));
            hits += hit.is_some() as usize;
        }
        assert!(hits > 1000, "{hits} hits: the rays must meet the soup");
    }

    mod tri8_big_leaves {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| TriBvh8::build(p, BvhParams { max_leaf_size: 11, ..BvhParams::fast() }),
        );
    }
}
