//! Refit of a wide topology: every child box recomputed bottom-up, the topology kept.

use super::WideTree;
use rt_geom::Aabb;

impl<const N: usize> WideTree<N> {
    /// Recomputes every child box: a leaf lane's box is `leaf_bounds(first, count)`, an inner
    /// lane's the union of its node's lanes. Nodes follow their parents (the build writes them
    /// depth-first, `validate` checks it), so a reverse sweep sees children first.
    pub fn refit(&mut self, leaf_bounds: &dyn Fn(u32, u32) -> Aabb) {
        let mut node_bounds = vec![Aabb::EMPTY; self.nodes.len()];
        for i in (0..self.nodes.len()).rev() {
            let mut node = self.nodes[i];
            let mut all = Aabb::EMPTY;
            for lane in 0..N {
                if !node.is_used(lane) {
                    continue;
                }
                let b = match node.count[lane] {
                    0 => node_bounds[node.child[lane] as usize],
                    count => leaf_bounds(node.child[lane], count),
                };
                node.set_bounds(lane, b);
                all = all.union(b);
            }
            self.nodes[i] = node;
            node_bounds[i] = all;
        }
        self.root_bounds = match self.root_leaf {
            Some((first, count)) => leaf_bounds(first, count),
            None => node_bounds.first().copied().unwrap_or(Aabb::EMPTY),
        };
    }
}
