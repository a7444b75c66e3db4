//! `stats()` and `validate()`: what the tree reports about itself, and its invariants.

use crate::Bvh;
use crate::params::MAX_DEPTH;
use rt_geom::{Aabb, AccelStats, Primitive, all_referenced};

/// The leaf invariants every tree of this crate checks: the leaf's box contains the primitive
/// (with spatial splits: the primitive's part inside the box is not empty, and a primitive
/// may be in several leaves), and the id is in range and, without spatial splits, seen once.
pub(crate) fn check_leaf_primitive<P: Primitive>(
    prim: &P,
    id: u32,
    leaf: &Aabb,
    seen: &mut [bool],
    split: bool,
) -> Result<(), String> {
    let inside = if split {
        !prim.clipped_bounds(leaf).is_empty()
    } else {
        leaf.contains(&prim.bounds())
    };
    if !inside {
        return Err(format!("primitive {id} pokes out of its leaf"));
    }
    match seen.get_mut(id as usize) {
        Some(s) if !*s || split => {
            *s = true;
            Ok(())
        }
        Some(_) => Err(format!("primitive {id} in two leaves")),
        None => Err(format!("id {id} out of range")),
    }
}

impl<P: Primitive> Bvh<P> {
    /// Calls `f(node index, depth)` for every node, parents before children.
    pub(crate) fn walk(&self, mut f: impl FnMut(usize, usize)) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = vec![(0usize, 0usize)];
        while let Some((i, d)) = stack.pop() {
            f(i, d);
            let n = &self.nodes[i];
            if !n.is_leaf() {
                // Children come after their parent: anything else is a fault `check` reports,
                // and is not followed (no index out of range, no cycle).
                for c in [n.offset as usize, i + 1] {
                    if c > i && c < self.nodes.len() {
                        stack.push((c, d + 1));
                    }
                }
            }
        }
    }

    pub(crate) fn compute_stats(&self) -> AccelStats {
        let mut s = AccelStats {
            primitives: self.count,
            nodes: self.nodes.len(),
            bytes: std::mem::size_of_val(self.nodes.as_slice())
                + std::mem::size_of_val(self.prims.as_slice())
                + std::mem::size_of_val(self.ids.as_slice()),
            ..AccelStats::default()
        };
        if self.nodes.is_empty() {
            return s;
        }
        let root_area = self.nodes[0].bounds().half_area_f64();
        let mut sah = 0.0f64;
        self.walk(|i, d| {
            let n = &self.nodes[i];
            s.max_depth = s.max_depth.max(d);
            let area = n.bounds().half_area_f64();
            if n.is_leaf() {
                s.leaves += 1;
                s.references += n.count() as usize;
                sah += area
                    * self.params.intersection_cost as f64
                    * self.params.tests(n.count() as usize) as f64;
            } else {
                sah += area * self.params.traversal_cost as f64;
            }
        });
        s.sah_cost = Some(if root_area > 0.0 {
            (sah / root_area) as f32
        } else {
            0.0
        });
        s
    }

    pub(crate) fn check(&self) -> Result<(), String> {
        if self.prims.len() != self.ids.len() {
            return Err("primitive and id arrays differ in length".into());
        }
        if self.nodes.is_empty() {
            return if self.prims.is_empty() && self.count == 0 {
                Ok(())
            } else {
                Err("no nodes for a non-empty scene".into())
            };
        }
        let mut seen = vec![false; self.count];
        let mut err: Option<String> = None;
        let mut fail = |e: String| {
            err.get_or_insert(e);
        };
        self.walk(|i, d| {
            let n = &self.nodes[i];
            let b = n.bounds();
            if d > MAX_DEPTH {
                fail(format!("node {i} at depth {d} > {MAX_DEPTH}"));
            }
            if n.is_leaf() {
                let (first, count) = (n.offset as usize, n.count() as usize);
                if first + count > self.prims.len() {
                    return fail(format!("leaf {i} points past the primitives"));
                }
                for k in first..first + count {
                    if let Err(e) = check_leaf_primitive(
                        &self.prims[k],
                        self.ids[k],
                        &b,
                        &mut seen,
                        self.params.splits_primitives(),
                    ) {
                        fail(e);
                    }
                }
            } else {
                if n.axis() > 2 {
                    return fail(format!("node {i} splits axis {}", n.axis()));
                }
                for c in [i + 1, n.offset as usize] {
                    if c >= self.nodes.len() || c <= i {
                        return fail(format!("node {i} has child index {c}"));
                    }
                    if !b.contains(&self.nodes[c].bounds()) {
                        fail(format!("node {c} pokes out of its parent {i}"));
                    }
                }
            }
        });
        if let Some(e) = err {
            return Err(e);
        }
        all_referenced(&seen)
    }
}
