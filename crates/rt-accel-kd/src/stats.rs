//! `stats()` and `validate()`: what the tree reports about itself, and its invariants.

use crate::KdTree;
use crate::build::child_bounds;
use crate::params::MAX_DEPTH;
use rt_geom::{Aabb, AccelStats, Primitive};

impl<P: Primitive> KdTree<P> {
    /// Calls `f(node index, cell, depth)` for every node, parents before children.
    pub(crate) fn walk(&self, mut f: impl FnMut(usize, &Aabb, usize)) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = vec![(0usize, self.root, 0usize)];
        while let Some((i, cell, d)) = stack.pop() {
            f(i, &cell, d);
            let n = &self.nodes[i];
            if !n.is_leaf() && n.above() < self.nodes.len() && i + 1 < self.nodes.len() {
                let (below, above) = child_bounds(&cell, n.axis(), n.split());
                stack.push((n.above(), above, d + 1));
                stack.push((i + 1, below, d + 1));
            }
        }
    }

    pub(crate) fn compute_stats(&self) -> AccelStats {
        let s = AccelStats {
            primitives: self.prims.len(),
            nodes: self.nodes.len(),
            bytes: std::mem::size_of_val(self.nodes.as_slice())
                + std::mem::size_of_val(self.indices.as_slice())
                + std::mem::size_of_val(self.prims.as_slice())
                + self.listed.bytes(),
            ..AccelStats::default()
        };
        if self.nodes.is_empty() {
            return s;
        }
        let mut acc = rt_geom::StatsSum::new(s, &self.root);
        self.walk(|i, cell, d| acc.add(cell, d, self.nodes[i].is_leaf(), self.nodes[i].count()));
        acc.finish()
    }

    pub(crate) fn check(&self) -> Result<(), String> {
        if self.nodes.is_empty() {
            return if self.prims.is_empty() {
                Ok(())
            } else {
                Err("no nodes for a non-empty scene".into())
            };
        }
        let mut seen = vec![false; self.prims.len()];
        let mut err: Option<String> = None;
        let mut fail = |e: String| {
            err.get_or_insert(e);
        };
        let len = self.nodes.len();
        self.walk(|i, cell, d| {
            let n = &self.nodes[i];
            if d > MAX_DEPTH as usize {
                return fail(format!("node {i} at depth {d} > {MAX_DEPTH}"));
            }
            if !n.is_leaf() {
                let (a, split) = (n.axis(), n.split());
                if n.above() <= i + 1 || n.above() >= len || i + 1 >= len {
                    return fail(format!("node {i} has children {} and {}", i + 1, n.above()));
                }
                if !(split >= cell.min[a] && split <= cell.max[a]) {
                    return fail(format!("node {i} splits at {split}, outside its cell"));
                }
                return;
            }
            if let Some(list) = n.list() {
                if let Err(e) = self.listed.check_list(&self.prims, &self.indices, list) {
                    return fail(format!("leaf {i}: {e}"));
                }
            }
            // A referenced primitive really touches the cell.
            for &p in n.leaf_prims(&self.indices) {
                let Some(prim) = self.prims.get(p as usize) else {
                    return fail(format!("leaf {i} holds primitive {p}, out of range"));
                };
                if !rt_geom::touches_cell(prim, &self.frame.to_world(cell)) {
                    return fail(format!("primitive {p} is in leaf {i} but not in its cell"));
                }
                seen[p as usize] = true;
            }
        });
        if let Some(e) = err {
            return Err(e);
        }
        rt_geom::all_referenced(&seen)
    }
}
