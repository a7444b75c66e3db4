//! Wide BVHs specialised for triangles: leaf triangles stored as structure of arrays and tested
//! four at a time (the watertight edge tests of four triangles are one SIMD operation each),
//! with exactly the answers of the scalar kernel.
//!
//! Triangle layout ([`TriangleSoa`]): nine `f32` arrays `v0.x, v0.y, v0.z, v1.x, ... v2.z` in
//! leaf order, padded by [`LANES`] zeros so that a leaf's four-lane window never runs off the
//! end. A leaf `(first, count)` covers indices `first .. first + count`; lanes past `count`
//! belong to the next leaf and are masked off.

use crate::stats::check_leaf_primitive;
use crate::wide::WideTree;
use crate::{Bvh, BvhParams};
use rt_geom::all_referenced;
use rt_geom::{
    Aabb, Accel, AccelStats, BuildError, Hit, PrimHit, Ray, Triangle, Vec3, replaces,
    watertight_edges,
};

/// Triangles tested together in a leaf.
pub const LANES: usize = 4;

/// Leaf-ordered triangles as structure of arrays (see the module documentation).
#[derive(Clone, Debug, Default)]
pub struct TriangleSoa {
    /// `coords[3 * vertex + axis][i]`.
    coords: [Vec<f32>; 9],
    len: usize,
}

impl TriangleSoa {
    pub fn new(tris: &[Triangle]) -> Self {
        let mut coords: [Vec<f32>; 9] = Default::default();
        for (j, c) in coords.iter_mut().enumerate() {
            c.reserve_exact(tris.len() + LANES);
            c.extend(tris.iter().map(|t| t.v[j / 3][j % 3]));
            c.extend([0.0; LANES]);
        }
        Self {
            coords,
            len: tris.len(),
        }
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Triangle `i` (leaf order).
    #[inline]
    pub fn get(&self, i: usize) -> Triangle {
        let c = |j: usize| self.coords[j][i];
        Triangle::new(
            Vec3::new(c(0), c(1), c(2)),
            Vec3::new(c(3), c(4), c(5)),
            Vec3::new(c(6), c(7), c(8)),
        )
    }

    fn bytes(&self) -> usize {
        self.coords.iter().map(|c| c.len() * 4).sum()
    }

    /// The four-lane window starting at `i`.
    #[inline(always)]
    fn window(&self, i: usize) -> [&[f32; LANES]; 9] {
        std::array::from_fn(|j| {
            self.coords[j][i..i + LANES]
                .try_into()
                .expect("padded by LANES")
        })
    }

    /// Tests triangles `first .. first + count` against the ray, nearest accepted hit last:
    /// the edge functions of four triangles at once, then, lane by lane, the scalar kernel's
    /// own [`Triangle::finish_watertight`] for the lanes that may hit. Returns true when
    /// `ANY_HIT` and a hit was found.
    #[inline(always)]
    pub fn intersect_range<const ANY_HIT: bool>(
        &self,
        first: usize,
        count: usize,
        r: &mut Ray,
        ids: &[u32],
        best: &mut Option<(PrimHit, u32)>,
    ) -> bool {
        let o = r.origin().to_array();
        let [mx, my, _] = r.watertight_rows();
        let (mx, my) = (mx.to_array(), my.to_array());
        let end = first + count;
        let mut i = first;
        while i < end {
            let w = self.window(i);
            // Sheared coordinates: (v - o) . row, summed in the order of `Vec3::dot`.
            let mut sh = [[0.0f32; LANES]; 6];
            for v in 0..3 {
                for l in 0..LANES {
                    let d = [
                        w[3 * v][l] - o[0],
                        w[3 * v + 1][l] - o[1],
                        w[3 * v + 2][l] - o[2],
                    ];
                    sh[2 * v][l] = d[0] * mx[0] + d[1] * mx[1] + d[2] * mx[2];
                    sh[2 * v + 1][l] = d[0] * my[0] + d[1] * my[1] + d[2] * my[2];
                }
            }
            let [ax, ay, bx, by, cx, cy] = sh;
            let mut may_hit = [false; LANES];
            for l in 0..LANES {
                let u = cx[l] * by[l] - cy[l] * bx[l];
                let v = ax[l] * cy[l] - ay[l] * cx[l];
                let w = bx[l] * ay[l] - by[l] * ax[l];
                let mixed = (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0);
                let zero = u == 0.0 || v == 0.0 || w == 0.0;
                may_hit[l] = !mixed || zero;
            }
            for l in 0..(end - i).min(LANES) {
                if !may_hit[l] {
                    continue;
                }
                let edges = watertight_edges([ax[l], ay[l], bx[l], by[l], cx[l], cy[l]]);
                if let Some(h) = self.get(i + l).finish_watertight(r, edges) {
                    let id = ids[i + l];
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
            i += LANES;
        }
        false
    }
}

/// A wide BVH over triangles with four-lane leaf tests. `N` = 4 or 8 children per node.
#[derive(Clone, Debug)]
pub struct TriBvh<const N: usize> {
    tree: WideTree<N>,
    tris: TriangleSoa,
    ids: Vec<u32>,
    count: usize,
    params: BvhParams,
}

pub type TriBvh4 = TriBvh<4>;
pub type TriBvh8 = TriBvh<8>;

impl<const N: usize> TriBvh<N> {
    pub fn build(tris: &[Triangle], params: BvhParams) -> Result<Self, BuildError> {
        Ok(Self::from_binary(Bvh::build(tris, params)?))
    }

    /// Collapses a binary BVH and converts its leaf-ordered triangles.
    pub fn from_binary(bvh: Bvh<Triangle>) -> Self {
        Self {
            tree: WideTree::collapse(&bvh.nodes),
            tris: TriangleSoa::new(&bvh.prims),
            ids: bvh.ids,
            count: bvh.count,
            params: bvh.params,
        }
    }

    pub fn tree(&self) -> &WideTree<N> {
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

impl<const N: usize> Accel for TriBvh<N> {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.traverse::<false>(ray)
    }

    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        self.traverse::<true>(ray).is_some()
    }

    fn stats(&self) -> AccelStats {
        let mut s = self.tree.stats(self.count, &self.params);
        s.bytes += self.tris.bytes() + std::mem::size_of_val(self.ids.as_slice());
        s
    }

    fn validate(&self) -> Result<(), String> {
        let mut seen = vec![false; self.count];
        self.tree.check(|first, count, bounds: &Aabb| {
            for k in first as usize..(first + count) as usize {
                if k >= self.tris.len() {
                    return Err("leaf points past the triangles".into());
                }
                let split = self.params.splits_primitives();
                check_leaf_primitive(&self.tris.get(k), self.ids[k], bounds, &mut seen, split)?;
            }
            Ok(())
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
            triangles: |p: &[Triangle]| TriBvh8::build(p, BvhParams::balanced()),
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
        let soa = TriangleSoa::new(&tris);
        assert_eq!(soa.len(), 10);
        for (i, t) in tris.iter().enumerate() {
            assert_eq!(soa.get(i), *t);
        }
    }
}
