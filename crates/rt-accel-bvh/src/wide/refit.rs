//! Refit of a wide topology: every child box recomputed bottom-up, the topology kept.

use super::{NodeLayout, WideNode, WideTree};
use rt_geom::Aabb;

impl<const N: usize, Node: NodeLayout<N>> WideTree<N, Node> {
    /// Recomputes every child box: a leaf lane's box is `leaf_bounds(first, count)`, an inner
    /// lane's the union of its node's lanes, each node written again in its layout from those
    /// exact boxes. Nodes follow their parents (the build writes them depth-first, `validate`
    /// checks it), so a reverse sweep sees children first.
    pub fn refit(&mut self, leaf_bounds: &dyn Fn(u32, u32) -> Aabb) {
        let mut node_bounds = vec![Aabb::EMPTY; self.nodes.len()];
        for i in (0..self.nodes.len()).rev() {
            let old = self.nodes[i];
            let mut node = WideNode::<N>::EMPTY;
            let mut all = Aabb::EMPTY;
            for lane in (0..N).filter(|&l| old.is_used(l)) {
                node.child[lane] = old.child(lane);
                node.count[lane] = old.count(lane);
                let b = match old.count(lane) {
                    0 => node_bounds[old.child(lane) as usize],
                    count => leaf_bounds(old.child(lane), count),
                };
                node.set_bounds(lane, b);
                all = all.union(b);
            }
            self.nodes[i] = Node::from_exact(&node);
            node_bounds[i] = all;
        }
        self.root_bounds = match self.root_leaf {
            Some((first, count)) => leaf_bounds(first, count),
            None => node_bounds.first().copied().unwrap_or(Aabb::EMPTY),
        };
    }
}
