//! Wide BVHs specialised for triangles: leaf triangles stored as structure of arrays and tested
//! four at a time (the watertight edge tests of four triangles are one SIMD operation each),
//! with exactly the answers of the scalar kernel.
//!
//! Triangle layout ([`TriangleSoa`]): one `f32` array holding, leaf after leaf, each leaf's
//! triangles as structure of arrays. A leaf `(first, count)` (triangles `first .. first + count`
//! in leaf order) occupies `9 * count` floats from `9 * first`: the `count` values of `v0.x`,
//! then of `v0.y`, ... `v2.z`. A leaf's bytes are as contiguous as an array of triangles (the
//! same cache lines), and the four-lane window of triangles `k .. k + 4` reads coordinate `j`
//! at `9 * first + j * count + k`; lanes past the leaf read its next row (or the next leaf, or
//! the [`LANES`] floats of padding at the end) and are masked off.

use crate::compressed::CompressedTree;
use crate::stats::check_leaf_primitive;
use crate::wide::{WideTopology, WideTree};
use crate::{Bvh, BvhParams};
use rt_geom::all_referenced;
use rt_geom::{
    Aabb, Accel, AccelStats, BuildError, Hit, PrimHit, Ray, Triangle, TriangleLanes, Vec3,
    replaces, watertight_edges, watertight_lanes,
};

/// Triangles tested together in a leaf.
pub const LANES: usize = 4;

/// Leaf-ordered triangles, each leaf as structure of arrays (see the module documentation).
#[derive(Clone, Debug, Default)]
pub struct TriangleSoa {
    data: Vec<f32>,
    len: usize,
}

impl TriangleSoa {
    /// Lays out the leaf-ordered `tris`; `leaves` are the `(first, count)` ranges that cover
    /// them (each triangle in exactly one).
    pub fn new(tris: &[Triangle], leaves: impl IntoIterator<Item = (u32, u32)>) -> Self {
        let mut data = vec![0.0; 9 * tris.len() + LANES];
        for (first, count) in leaves {
            let (first, count) = (first as usize, count as usize);
            for (k, t) in tris[first..first + count].iter().enumerate() {
                for j in 0..9 {
                    data[9 * first + j * count + k] = t.v[j / 3][j % 3];
                }
            }
        }
        Self {
            data,
            len: tris.len(),
        }
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Triangle `k` of the leaf `(first, count)`.
    #[inline]
    pub fn get(&self, first: usize, count: usize, k: usize) -> Triangle {
        let c = |j: usize| self.data[9 * first + j * count + k];
        Triangle::new(
            Vec3::new(c(0), c(1), c(2)),
            Vec3::new(c(3), c(4), c(5)),
            Vec3::new(c(6), c(7), c(8)),
        )
    }

    fn bytes(&self) -> usize {
        self.data.len() * 4
    }

    /// Checks the triangles of leaf `(first, count)` against its `bounds` and marks their ids
    /// in `seen` (see [`check_leaf_primitive`]).
    fn check_leaf(
        &self,
        ids: &[u32],
        (first, count): (u32, u32),
        bounds: &Aabb,
        seen: &mut [bool],
        split: bool,
    ) -> Result<(), String> {
        let (first, count) = (first as usize, count as usize);
        if first + count > self.len {
            return Err("leaf points past the triangles".into());
        }
        for k in 0..count {
            let t = self.get(first, count, k);
            check_leaf_primitive(&t, ids[first + k], bounds, seen, split)?;
        }
        Ok(())
    }

    /// Tests triangles `first .. first + count` against the ray, nearest accepted hit last:
    /// the edge functions and their sign test for four triangles at once (SIMD lanes, one bit
    /// mask), then the scalar kernel's own [`Triangle::finish_watertight`] for the lanes that
    /// may hit. Returns true when `ANY_HIT` and a hit was found.
    #[inline(always)]
    pub fn intersect_range<const ANY_HIT: bool>(
        &self,
        first: usize,
        count: usize,
        r: &mut Ray,
        ids: &[u32],
        best: &mut Option<(PrimHit, u32)>,
    ) -> bool {
        let leaf = &self.data[9 * first..9 * (first + count) + LANES];
        let mut k = 0;
        while k < count {
            let w: TriangleLanes = std::array::from_fn(|j| {
                let c: [f32; LANES] = leaf[j * count + k..][..LANES].try_into().expect("padded");
                wide::f32x4::from(c)
            });
            let (may_hit, sheared) = watertight_lanes(&w, r);
            // Lanes past the leaf belong to the next one.
            let in_leaf = (1u32 << (count - k).min(LANES)) - 1;
            let mut may_hit = may_hit & in_leaf;
            while may_hit != 0 {
                let l = may_hit.trailing_zeros() as usize;
                may_hit &= may_hit - 1;
                let edges = watertight_edges(sheared.map(|x| x[l]));
                if let Some(h) = self.get(first, count, k + l).finish_watertight(r, edges) {
                    let id = ids[first + k + l];
                    if ANY_HIT {
                        *best = Some((h, id));
                        return true;
                    }
                    if replaces(h.t, id, best.map(|(b, id)| (b.t, id))) {
                        *best = Some((h, id));
                        r.tmax = h.t;
                    }
                }
            }
            k += LANES;
        }
        false
    }
}

/// A wide BVH over triangles with four-lane leaf tests, over a topology `T`: [`WideTree<N>`]
/// (`N` = 4 or 8 children per node) or the quantized [`CompressedTree`].
#[derive(Clone, Debug)]
pub struct TriBvh<T> {
    tree: T,
    tris: TriangleSoa,
    ids: Vec<u32>,
    count: usize,
    params: BvhParams,
    stats: AccelStats,
}

pub type TriBvh4 = TriBvh<WideTree<4>>;
pub type TriBvh8 = TriBvh<WideTree<8>>;
/// [`TriBvh8`] with child boxes quantized to 8 bits per plane: the SIMD triangle leaves and
/// half-size nodes.
pub type CompressedTriBvh8 = TriBvh<CompressedTree>;

impl<const N: usize> TriBvh<WideTree<N>> {
    pub fn build(tris: &[Triangle], params: BvhParams) -> Result<Self, BuildError> {
        Ok(Self::from_binary(Bvh::build(tris, params)?))
    }

    /// Collapses a binary BVH and converts its leaf-ordered triangles.
    pub fn from_binary(bvh: Bvh<Triangle>) -> Self {
        let tree = WideTree::<N>::collapse(&bvh.nodes);
        let tris = TriangleSoa::new(&bvh.prims, tree.leaves());
        let mut stats = tree.stats(bvh.count, &bvh.params);
        stats.bytes += tris.bytes() + std::mem::size_of_val(bvh.ids.as_slice());
        Self {
            tree,
            tris,
            ids: bvh.ids,
            count: bvh.count,
            params: bvh.params,
            stats,
        }
    }
}

impl TriBvh<CompressedTree> {
    pub fn build(tris: &[Triangle], params: BvhParams) -> Result<Self, BuildError> {
        Ok(Self::from_tri_bvh(TriBvh8::build(tris, params)?))
    }

    /// Compresses the nodes of `bvh`, keeping its triangles.
    pub fn from_tri_bvh(bvh: TriBvh8) -> Self {
        let tree = CompressedTree::compress(&bvh.tree);
        let leaf_bytes = bvh.tris.bytes() + std::mem::size_of_val(bvh.ids.as_slice());
        let stats = tree.stats(&bvh.tree, bvh.count, &bvh.params, leaf_bytes);
        Self {
            tree,
            tris: bvh.tris,
            ids: bvh.ids,
            count: bvh.count,
            params: bvh.params,
            stats,
        }
    }
}

impl<T: WideTopology> TriBvh<T> {
    pub fn tree(&self) -> &T {
        &self.tree
    }

    pub fn triangles(&self) -> &TriangleSoa {
        &self.tris
    }

    pub fn ids(&self) -> &[u32] {
        &self.ids
    }

    #[inline]
    fn traverse<const ANY_HIT: bool>(&self, ray: &Ray) -> Option<Hit> {
        self.tree.traverse::<ANY_HIT>(ray, |first, count, r, best| {
            self.tris
                .intersect_range::<ANY_HIT>(first as usize, count as usize, r, &self.ids, best)
        })
    }
}

impl<T: WideTopology> Accel for TriBvh<T> {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.traverse::<false>(ray)
    }

    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        self.traverse::<true>(ray).is_some()
    }

    fn stats(&self) -> AccelStats {
        self.stats.clone()
    }

    fn validate(&self) -> Result<(), String> {
        let mut seen = vec![false; self.count];
        let split = self.params.splits_primitives();
        self.tree.check(|first, count, bounds| {
            self.tris
                .check_leaf(&self.ids, (first, count), bounds, &mut seen, split)
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
    }

    mod tri8 {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| TriBvh8::build(p, BvhParams::balanced().for_soa_leaves()),
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
    }

    mod tri8_big_leaves {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| TriBvh8::build(p, BvhParams { max_leaf_size: 11, ..BvhParams::fast() }),
        );
    }

    #[test]
    fn soa_round_trips() {
        let tris = rt_testkit::scenes::random_soup(10, 3);
        let leaves = [(0, 3), (3, 1), (4, 6)];
        let soa = TriangleSoa::new(&tris, leaves);
        assert_eq!(soa.len(), 10);
        for (first, count) in leaves {
            for k in 0..count {
                let t = tris[(first + k) as usize];
                assert_eq!(soa.get(first as usize, count as usize, k as usize), t);
            }
        }
    }
}
