//! `stats()` and `validate()`: what the octree reports about itself, and its invariants.

use crate::Octree;
use rt_geom::{Aabb, AccelStats, Primitive};

impl<P: Primitive> Octree<P> {
    pub(crate) fn compute_stats(&self) -> AccelStats {
        let s = AccelStats {
            primitives: self.prims.len(),
            nodes: self.nodes.len() + self.leaves.len(),
            bytes: std::mem::size_of_val(self.nodes.as_slice())
                + std::mem::size_of_val(self.leaves.as_slice())
                + std::mem::size_of_val(self.indices.as_slice())
                + std::mem::size_of_val(self.prims.as_slice())
                + self.leaf_prims.bytes(),
            ..AccelStats::default()
        };
        if self.leaves.is_empty() {
            return s;
        }
        let mut acc = rt_geom::StatsSum::new(s, &self.bounds);
        self.walk(&mut |r, b, d, _| {
            let count = match r.is_leaf() {
                true => self.leaves[r.index()].count as usize,
                false => 0,
            };
            acc.add(b, d, r.is_leaf(), count)
        });
        acc.finish()
    }

    /// Inner children after their parent and every child in range; every leaf within the
    /// index array; every referenced primitive overlapping its leaf's cell, and inside the
    /// leaf's content box where it is inside the cell; every node and every primitive
    /// reached.
    pub(crate) fn check(&self) -> Result<(), String> {
        if self.leaves.is_empty() {
            return if self.prims.is_empty() && self.nodes.is_empty() {
                Ok(())
            } else {
                Err("no leaves for a non-empty scene".into())
            };
        }
        let mut err = None;
        let (mut inner_reached, mut leaves_reached) = (0, 0);
        // The leaves reached, with their cells and content boxes; their primitives are checked
        // after the walk, in parallel.
        let mut reached = Vec::new();
        self.walk(&mut |r, b, d, content| {
            let i = r.index();
            if d > self.params.max_depth as usize {
                err.get_or_insert(format!("node {r:?} at depth {d}"));
            }
            if !r.is_leaf() {
                inner_reached += 1;
                let Some(n) = self.nodes.get(i) else {
                    err.get_or_insert(format!("inner node {i} out of range"));
                    return;
                };
                let inner = (n.mask() & !n.leaf_mask()).count_ones() as usize;
                let leaves = n.leaf_mask().count_ones() as usize;
                if n.mask() == 0
                    || n.leaf_mask() & !n.mask() != 0
                    || (inner > 0 && n.inner_base() <= i)
                    || n.inner_base() + inner > self.nodes.len()
                    || n.leaf_base() + leaves > self.leaves.len()
                {
                    err.get_or_insert(format!("inner node {i} has children out of range"));
                }
                return;
            }
            leaves_reached += 1;
            reached.push((i, *b, *content));
        });
        if let Some(e) = err {
            return Err(e);
        }
        use rayon::prelude::*;
        let listed: Result<Vec<&[u32]>, String> = reached
            .par_iter()
            .map(|&(i, b, content)| self.check_leaf(i, &b, &content))
            .collect();
        let mut seen = vec![false; self.prims.len()];
        for &p in listed?.iter().copied().flatten() {
            seen[p as usize] = true;
        }
        if inner_reached != self.nodes.len() || leaves_reached != self.leaves.len() {
            return Err(format!(
                "{} inner nodes and {} leaves, {inner_reached} and {leaves_reached} reachable",
                self.nodes.len(),
                self.leaves.len()
            ));
        }
        rt_geom::all_referenced(&seen)
    }
}

impl<P: Primitive> Octree<P> {
    /// Leaf `i` (whose cell is `b` and content box `content`) in range, its list laid out as
    /// the index array says, and each of its primitives in range, overlapping the cell, and
    /// inside the content box where inside the cell; its primitives.
    fn check_leaf(&self, i: usize, b: &Aabb, content: &Aabb) -> Result<&[u32], String> {
        let leaf = self
            .leaves
            .get(i)
            .ok_or_else(|| format!("leaf {i} out of range"))?;
        let list = (leaf.first, leaf.count);
        self.leaf_prims
            .check_list(&self.prims, &self.indices, list)
            .map_err(|e| format!("leaf {i}: {e}"))?;
        let ids = &self.indices[leaf.prims()];
        for &p in ids {
            let prim = self
                .prims
                .get(p as usize)
                .ok_or_else(|| format!("leaf {i} holds primitive {p}, out of range"))?;
            // Most primitives lie in one cell: their whole box decides both checks without
            // clipping (it lies in the cell, and holds the part in the cell).
            let bounds = self.frame.to_local(&prim.bounds());
            let inside = !bounds.is_empty() && holds(b, &bounds);
            if !inside && !rt_geom::touches_cell(prim, &self.frame.to_world(b)) {
                return Err(format!("primitive {p} is in leaf {i} but not in its box"));
            }
            let whole = bounds.intersection(*b);
            if !holds(content, &whole)
                && !holds(
                    content,
                    &self.frame.clipped_bounds(prim, b).intersection(*b),
                )
            {
                return Err(format!(
                    "primitive {p} reaches outside the content box of leaf {i}"
                ));
            }
        }
        Ok(ids)
    }
}

/// `outer` holds `inner` (an empty `inner` is held by anything).
fn holds(outer: &Aabb, inner: &Aabb) -> bool {
    inner.is_empty() || (outer.min.cmple(inner.min).all() && outer.max.cmpge(inner.max).all())
}
