//! Writing the wide nodes: each inner binary node that heads a wide node becomes one, its lanes
//! the cut of its subtree that the collapse plan chose.

use super::{NodeLayout, WideNode, WideTree};
use crate::collapse::{Lane, SahCollapse, greedy_lanes};
use crate::node::BvhNode;
use crate::{BvhParams, WideCollapse};
use rt_geom::Aabb;
use rt_geom::pages::Pages;

impl<const N: usize, Node: NodeLayout<N>> WideTree<N, Node> {
    /// Collapses a binary BVH built with `params` as `params.collapse` says: every wide node
    /// replaces an inner binary node, its lanes are a cut of that node's subtree (binary
    /// leaves, whole subtrees made one leaf, or inner nodes that head wide nodes of their
    /// own); see the `collapse` module. Leaves keep their primitive ranges. Each node is
    /// written in the layout `Node` from its exact boxes.
    pub fn collapse(bin: &[BvhNode], params: &BvhParams) -> Self {
        assert!((2..=32).contains(&N), "2..=32 lanes");
        let mut nodes = Vec::new();
        let mut tree = Self {
            nodes: Pages::default(),
            root_bounds: bin.first().map_or(Aabb::EMPTY, |n| n.bounds()),
            root_leaf: None,
            depth: 0,
            isa: rt_geom::Isa::selected(),
        };
        match bin.first() {
            None => {}
            Some(root) if root.is_leaf() => tree.root_leaf = Some((root.offset, root.count())),
            Some(_) => {
                let area = |b: usize| bin[b].bounds().half_area();
                let greedy = |b: usize| greedy_lanes(bin, b, N);
                let out = &mut nodes;
                tree.depth = match params.collapse {
                    WideCollapse::LargestArea => write_nodes(bin, 0, out, 1, &greedy),
                    WideCollapse::Sah => {
                        let plan = SahCollapse::<N>::plan(bin, params);
                        write_nodes(bin, 0, out, 1, &|b| plan.lanes(bin, b))
                    }
                    WideCollapse::LargestAreaThenSah { above } => {
                        let plan = SahCollapse::<N>::plan(bin, params);
                        let top = above * area(0);
                        let lanes = |b| {
                            if area(b) >= top {
                                greedy(b)
                            } else {
                                plan.lanes(bin, b)
                            }
                        };
                        write_nodes(bin, 0, out, 1, &lanes)
                    }
                };
            }
        }
        tree.nodes = Pages::from(nodes);
        tree
    }
}

/// Writes the wide node for inner binary node `b` with the lanes `lanes(b)` and its subtree;
/// returns the depth of the subtree.
fn write_nodes<const N: usize, Node: NodeLayout<N>>(
    bin: &[BvhNode],
    b: usize,
    out: &mut Vec<Node>,
    depth: usize,
    lanes: &impl Fn(usize) -> Vec<Lane>,
) -> usize {
    let index = out.len();
    out.push(Node::from_exact(&WideNode::EMPTY));
    let mut node = WideNode::EMPTY;
    let mut deepest = depth;
    for (lane, kid) in lanes(b).into_iter().enumerate() {
        node.set_bounds(lane, bin[kid.node()].bounds());
        match kid {
            Lane::Leaf { first, count, .. } => {
                node.child[lane] = first;
                node.count[lane] = count;
            }
            Lane::Inner(k) => {
                node.child[lane] = out.len() as u32;
                deepest = deepest.max(write_nodes(bin, k, out, depth + 1, lanes));
            }
        }
    }
    out[index] = Node::from_exact(&node);
    deepest
}
