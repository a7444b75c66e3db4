//! Statistics and invariants of a wide topology.

use super::{NodeLayout, WideTree};
use crate::BvhParams;
use crate::params::MAX_DEPTH;
use rt_geom::{Aabb, AccelStats, Vec3};

impl<const N: usize, Node: NodeLayout<N>> WideTree<N, Node> {
    /// Statistics of the topology (boxes as the walk sees them); `bytes` counts the nodes
    /// only.
    pub fn stats(&self, prims: usize, params: &BvhParams) -> AccelStats {
        let mut s = AccelStats {
            primitives: prims,
            nodes: self.nodes.len(),
            max_depth: self.depth,
            bytes: std::mem::size_of_val(&self.nodes[..]),
            ..AccelStats::default()
        };
        let root_area = self.root_bounds.half_area_f64();
        let mut sah = 0.0f64;
        if let Some((_, count)) = self.root_leaf {
            s.leaves = 1;
            s.nodes = 1;
            s.references = count as usize;
            sah = root_area * params.tests(count as usize) as f64 * params.intersection_cost as f64;
        }
        for (i, n) in self.nodes.iter().enumerate() {
            if i == 0 {
                sah += root_area * params.traversal_cost as f64;
            }
            for lane in (0..N).filter(|&l| n.is_used(l)) {
                let area = n.bounds(lane).half_area_f64();
                if n.count(lane) > 0 {
                    s.leaves += 1;
                    s.references += n.count(lane) as usize;
                    sah += area
                        * params.tests(n.count(lane) as usize) as f64
                        * params.intersection_cost as f64;
                } else {
                    sah += area * params.traversal_cost as f64;
                }
            }
        }
        s.nodes += s.leaves;
        s.sah_cost = Some(if root_area > 0.0 {
            (sah / root_area) as f32
        } else {
            0.0
        });
        s
    }

    /// Checks the topology: children after their parents, depth bounded, exact boxes inside
    /// their parents, and `leaf(first, count, bounds)` for each leaf, with `bounds` the
    /// intersection of the boxes on the way down (what the walk relies on). Returns the
    /// depth in nodes (the root's level is 1; 0 without nodes), what the walk's stack is sized
    /// by.
    pub fn check(
        &self,
        mut leaf: impl FnMut(u32, u32, &Aabb) -> Result<(), String>,
    ) -> Result<usize, String> {
        if let Some((first, count)) = self.root_leaf {
            return leaf(first, count, &self.root_bounds).map(|()| 0);
        }
        if self.nodes.is_empty() {
            return Ok(0);
        }
        let mut stack = vec![(0usize, self.root_bounds, 0usize)];
        let mut deepest = 0;
        while let Some((i, parent, depth)) = stack.pop() {
            if depth > MAX_DEPTH {
                return Err(format!("node {i} deeper than {MAX_DEPTH}"));
            }
            deepest = deepest.max(depth + 1);
            let n = self
                .nodes
                .get(i)
                .ok_or(format!("child index {i} out of range"))?;
            // The walk tests the lanes of `used_mask`: every lane with a child, and no other
            // unless its box is empty (no ray enters it).
            for lane in 0..N {
                let walked = n.used_mask() >> lane & 1 == 1;
                let empty = || {
                    let b = n.bounds(lane);
                    b.min.cmpeq(Vec3::INFINITY).all() && b.max.cmpeq(Vec3::NEG_INFINITY).all()
                };
                if n.is_used(lane) && !walked {
                    return Err(format!("node {i} lane {lane} holds a child the walk skips"));
                }
                if !n.is_used(lane) && walked && !empty() {
                    return Err(format!("node {i} lane {lane} is empty but has a box"));
                }
            }
            for lane in (0..N).filter(|&l| n.is_used(l)) {
                let b = n.bounds(lane);
                // The walk's node test assumes planes that are numbers (its integer maxima
                // would take a NaN plane for a value).
                if b.min.is_nan() || b.max.is_nan() {
                    return Err(format!("node {i} lane {lane} has a NaN plane"));
                }
                if Node::EXACT && !parent.contains(&b) {
                    return Err(format!("node {i} lane {lane} pokes out of its parent"));
                }
                let b = b.intersection(parent);
                let child = n.child(lane);
                if n.count(lane) > 0 {
                    leaf(child, n.count(lane), &b)?;
                } else if child as usize <= i {
                    return Err(format!("node {i} lane {lane} points backwards"));
                } else {
                    stack.push((child as usize, b, depth + 1));
                }
            }
        }
        Ok(deepest)
    }
}
