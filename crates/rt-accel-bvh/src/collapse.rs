//! Collapsing a binary BVH into an `N`-wide one: which binary nodes become wide nodes, which
//! become leaves, and which are opened so that their children share a parent's lanes.
//!
//! Two plans, both over the flattened binary nodes (children after their parent), and their
//! mix ([`WideCollapse`](crate::WideCollapse)):
//! - [`greedy_lanes`]: open the inner child of largest surface area until `N` lanes are used
//!   (Embree's collapse);
//! - [`SahCollapse`]: the collapse of least SAH cost (Ylitie, Karras & Laine 2017, dynamic
//!   programming bottom-up over "`n`'s subtree in at most `i` lanes"), which may also make a
//!   whole small subtree one leaf;
//! - the default: the greedy rule for wide nodes of at least a tenth of the root's area, the
//!   SAH plan below them.
//!
//! Without leaf merges the SAH plan minimises the summed area of the binary nodes that head
//! wide nodes (the leaves are fixed), so the node and leaf cost constants do not change it;
//! merges, which the SAH costs of the `for_soa_leaves` preset rarely choose, are where they
//! count. The plan makes fewer, fuller nodes; alone it loses where rays start inside the
//! boxes near the root (which the SAH's rays from outside model poorly), so the default keeps
//! the greedy rule at the top (measurements: `docs/notes/wide-collapse.md`).

use crate::BvhParams;
use crate::node::BvhNode;

/// One lane of a wide node: a binary node that becomes a leaf (its primitive range) or the
/// root of the wide child node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Lane {
    Leaf { node: usize, first: u32, count: u32 },
    Inner(usize),
}

impl Lane {
    pub(crate) fn node(&self) -> usize {
        match *self {
            Lane::Leaf { node, .. } | Lane::Inner(node) => node,
        }
    }
}

fn lane_of(bin: &[BvhNode], k: usize) -> Lane {
    let n = &bin[k];
    if n.is_leaf() {
        Lane::Leaf {
            node: k,
            first: n.offset,
            count: n.count(),
        }
    } else {
        Lane::Inner(k)
    }
}

/// The lanes of the wide node that replaces inner binary node `b`: its two children, then the
/// inner lane of largest surface area opened until there are `n` lanes or only leaves.
pub(crate) fn greedy_lanes(bin: &[BvhNode], b: usize, n: usize) -> Vec<Lane> {
    let mut kids: Vec<usize> = vec![b + 1, bin[b].offset as usize];
    while kids.len() < n {
        let open = kids
            .iter()
            .enumerate()
            .filter(|(_, k)| !bin[**k].is_leaf())
            .max_by(|x, y| {
                bin[*x.1]
                    .bounds()
                    .half_area()
                    .total_cmp(&bin[*y.1].bounds().half_area())
            });
        let Some((pos, &k)) = open else { break };
        kids.swap_remove(pos);
        kids.push(k + 1);
        kids.push(bin[k].offset as usize);
    }
    kids.into_iter().map(|k| lane_of(bin, k)).collect()
}

/// The SAH-optimal collapse into nodes of `N` lanes.
///
/// Per binary node `n` and lane budget `i` (1..=N), `cost[n][i]` is the least SAH cost of
/// `n`'s subtree in at most `i` lanes of a parent, with absolute half areas `A` (dividing by
/// the root's area would scale every cost alike):
/// - `i = 1`: a leaf of the whole subtree, `A(n) * leaf_cost(count)` (if it holds at most
///   `max_leaf_size` primitives, in one contiguous range, and merging is allowed; a binary
///   leaf always can), or a wide node, `A(n) * node_cost + distribute(n, N)`;
/// - `i > 1`: `min(distribute(n, i), cost[n][i - 1])`,
///
/// where `distribute(n, j) = min over k of cost[left][k] + cost[right][j - k]` spreads `j`
/// lanes over the two children.
pub(crate) struct SahCollapse<const N: usize> {
    /// `cost[n][i - 1]` as above.
    cost: Vec<[f32; N]>,
    /// `split[n][j - 1]`: the left child's share of `distribute(n, j)` (`j >= 2`).
    split: Vec<[u8; N]>,
    /// Bit `j - 1` (`j >= 2`): `cost[n][j - 1]` is `distribute(n, j)`, not fewer lanes.
    spread: Vec<u32>,
    /// Whether `n`'s subtree in one lane is a leaf (always for a binary leaf).
    leaf: Vec<bool>,
    /// `(first, count)`: the subtree's primitive range, count 0 if not contiguous.
    range: Vec<(u32, u32)>,
}

impl<const N: usize> SahCollapse<N> {
    /// Plans the collapse of `bin` (root inner) with `params`' costs: a wide node step costs
    /// `traversal_cost`, leaves `leaf_cost`.
    pub(crate) fn plan(bin: &[BvhNode], params: &BvhParams) -> Self {
        Self::plan_with(bin, params, params.traversal_cost, true)
    }

    /// [`Self::plan`] with a node cost of its own; `merge_leaves` lets whole small subtrees
    /// become leaves.
    pub(crate) fn plan_with(
        bin: &[BvhNode],
        params: &BvhParams,
        node_cost: f32,
        merge_leaves: bool,
    ) -> Self {
        assert!((2..=32).contains(&N), "2..=32 lanes");
        let len = bin.len();
        let mut plan = Self {
            cost: vec![[0.0; N]; len],
            split: vec![[0; N]; len],
            spread: vec![0; len],
            leaf: vec![false; len],
            range: vec![(0, 0); len],
        };
        // Children follow their parent: a reverse sweep sees both before it.
        for b in (0..len).rev() {
            let node = &bin[b];
            let area = node.bounds().half_area();
            if node.is_leaf() {
                plan.range[b] = (node.offset, node.count());
                plan.cost[b] = [area * params.leaf_cost(node.count() as usize); N];
                plan.leaf[b] = true;
                continue;
            }
            let (l, r) = (b + 1, node.offset as usize);
            let ((fl, cl), (fr, cr)) = (plan.range[l], plan.range[r]);
            plan.range[b] = if cl > 0 && cr > 0 && fl + cl == fr {
                (fl, cl + cr)
            } else {
                (0, 0)
            };
            let mut dist = [f32::INFINITY; N];
            for j in 2..=N {
                for k in 1..j {
                    let c = plan.cost[l][k - 1] + plan.cost[r][j - k - 1];
                    if c < dist[j - 1] {
                        dist[j - 1] = c;
                        plan.split[b][j - 1] = k as u8;
                    }
                }
            }
            let inner = area * node_cost + dist[N - 1];
            let count = plan.range[b].1;
            let leaf = if merge_leaves && count > 0 && count <= params.max_leaf_size {
                area * params.leaf_cost(count as usize)
            } else {
                f32::INFINITY
            };
            plan.leaf[b] = leaf < inner;
            let mut c = leaf.min(inner);
            plan.cost[b][0] = c;
            for j in 2..=N {
                if dist[j - 1] < c {
                    c = dist[j - 1];
                    plan.spread[b] |= 1 << (j - 1);
                }
                plan.cost[b][j - 1] = c;
            }
        }
        plan
    }

    /// The SAH cost of the whole collapsed tree (root as a wide node) times the root's area.
    #[cfg(test)]
    pub(crate) fn root_cost(&self, bin: &[BvhNode], node_cost: f32) -> f32 {
        let (l, r) = (1, bin[0].offset as usize);
        let k = self.split[0][N - 1] as usize;
        bin[0].bounds().half_area() * node_cost + self.cost[l][k - 1] + self.cost[r][N - k - 1]
    }

    /// The lanes of the wide node that replaces inner binary node `b`.
    pub(crate) fn lanes(&self, bin: &[BvhNode], b: usize) -> Vec<Lane> {
        let mut out = Vec::with_capacity(N);
        self.spread_over(bin, b, N, &mut out);
        out
    }

    /// Places the children of inner node `b` in `j` lanes as `distribute(b, j)` chose.
    fn spread_over(&self, bin: &[BvhNode], b: usize, j: usize, out: &mut Vec<Lane>) {
        let k = self.split[b][j - 1] as usize;
        self.place(bin, b + 1, k, out);
        self.place(bin, bin[b].offset as usize, j - k, out);
    }

    /// Places node `n`'s subtree in at most `i` lanes.
    fn place(&self, bin: &[BvhNode], n: usize, mut i: usize, out: &mut Vec<Lane>) {
        while i > 1 && self.spread[n] & (1 << (i - 1)) == 0 {
            i -= 1;
        }
        if i > 1 {
            self.spread_over(bin, n, i, out);
        } else if self.leaf[n] {
            let (first, count) = self.range[n];
            out.push(Lane::Leaf {
                node: n,
                first,
                count,
            });
        } else {
            out.push(Lane::Inner(n));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Bvh;
    use rt_geom::Triangle;
    use rt_testkit::scenes;

    /// Every cut of `n`'s subtree with at most `max` nodes.
    fn cuts(bin: &[BvhNode], n: usize, max: usize) -> Vec<Vec<usize>> {
        let mut out = vec![vec![n]];
        // Opening `n` takes at least two lanes.
        if !bin[n].is_leaf() && max >= 2 {
            for a in cuts(bin, n + 1, max - 1) {
                for b in cuts(bin, bin[n].offset as usize, max - a.len()) {
                    out.push([a.clone(), b].concat());
                }
            }
        }
        out.retain(|c| c.len() <= max);
        out
    }

    /// The exhaustive search: every cut of lanes below every wide node.
    struct Search<'a> {
        bin: &'a [BvhNode],
        params: &'a BvhParams,
        node_cost: f32,
        merge: bool,
        lanes: usize,
    }

    impl Search<'_> {
        /// The least cost of inner node `n` as a wide node.
        fn wide_cost(&self, n: usize) -> f32 {
            let (bin, lanes) = (self.bin, self.lanes);
            let (l, r) = (n + 1, bin[n].offset as usize);
            let mut best = f32::INFINITY;
            for a in cuts(bin, l, lanes - 1) {
                for b in cuts(bin, r, lanes - a.len()) {
                    let c: f32 = a.iter().chain(&b).map(|&m| self.one_lane(m)).sum();
                    best = best.min(c);
                }
            }
            bin[n].bounds().half_area() * self.node_cost + best
        }

        /// The least cost of `n`'s subtree in one lane: a leaf or a wide node.
        fn one_lane(&self, n: usize) -> f32 {
            let node = &self.bin[n];
            let area = node.bounds().half_area();
            if node.is_leaf() {
                return area * self.params.leaf_cost(node.count() as usize);
            }
            let inner = self.wide_cost(n);
            let count = subtree_count(self.bin, n);
            if self.merge && count <= self.params.max_leaf_size as usize {
                inner.min(area * self.params.leaf_cost(count))
            } else {
                inner
            }
        }
    }

    fn subtree_count(bin: &[BvhNode], n: usize) -> usize {
        if bin[n].is_leaf() {
            bin[n].count() as usize
        } else {
            subtree_count(bin, n + 1) + subtree_count(bin, bin[n].offset as usize)
        }
    }

    /// The cost of the tree the plan writes: nodes and leaves summed.
    fn written_cost<const N: usize>(
        bin: &[BvhNode],
        plan: &SahCollapse<N>,
        params: &BvhParams,
        node_cost: f32,
        b: usize,
    ) -> (f32, usize) {
        let mut cost = bin[b].bounds().half_area() * node_cost;
        let mut prims = 0;
        let lanes = plan.lanes(bin, b);
        assert!((2..=N).contains(&lanes.len()));
        for lane in lanes {
            match lane {
                Lane::Leaf { node, count, .. } => {
                    cost += bin[node].bounds().half_area() * params.leaf_cost(count as usize);
                    prims += count as usize;
                }
                Lane::Inner(k) => {
                    let (c, p) = written_cost(bin, plan, params, node_cost, k);
                    cost += c;
                    prims += p;
                }
            }
        }
        (cost, prims)
    }

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() <= 1e-4 * a.abs().max(b.abs())
    }

    #[test]
    fn plan_is_the_least_cost_collapse() {
        for (seed, n) in [(1, 9), (2, 14), (3, 20), (4, 12)] {
            let tris = scenes::random_soup(n, seed);
            for params in [
                BvhParams {
                    max_leaf_size: 1,
                    ..BvhParams::quality()
                },
                BvhParams {
                    max_leaf_size: 2,
                    ..BvhParams::balanced()
                }
                .for_soa_leaves(),
            ] {
                let bvh = Bvh::<Triangle>::build(&tris, params).unwrap();
                let bin = &bvh.nodes;
                assert!(!bin[0].is_leaf());
                for (node_cost, merge) in [(1.0, false), (2.0, true), (0.5, true)] {
                    let plan = SahCollapse::<4>::plan_with(bin, &params, node_cost, merge);
                    // Brute force over every cut (4 lanes keeps the enumeration small).
                    let search = Search {
                        bin,
                        params: &params,
                        node_cost,
                        merge,
                        lanes: 4,
                    };
                    let exhaustive = search.wide_cost(0);
                    let planned = plan.root_cost(bin, node_cost);
                    assert!(
                        close(planned, exhaustive),
                        "seed {seed}: {planned} vs {exhaustive}"
                    );
                    let (written, prims) = written_cost(bin, &plan, &params, node_cost, 0);
                    assert!(close(written, planned), "{written} vs {planned}");
                    assert_eq!(prims, bvh.prims.len());
                }
            }
        }
    }

    #[test]
    fn plan_costs_no_more_than_greedy() {
        let tris = scenes::tessellated_sphere(5000, rt_geom::Vec3::ZERO, 1.0);
        let params = BvhParams::balanced().for_soa_leaves();
        let bvh = Bvh::<Triangle>::build(&tris, params).unwrap();
        let bin = &bvh.nodes;
        let plan = SahCollapse::<8>::plan(bin, &params);
        fn greedy(bin: &[BvhNode], params: &BvhParams, b: usize) -> f32 {
            let mut cost = bin[b].bounds().half_area() * params.traversal_cost;
            for lane in greedy_lanes(bin, b, 8) {
                cost += match lane {
                    Lane::Leaf { node, count, .. } => {
                        bin[node].bounds().half_area() * params.leaf_cost(count as usize)
                    }
                    Lane::Inner(k) => greedy(bin, params, k),
                };
            }
            cost
        }
        let g = greedy(bin, &params, 0);
        let p = plan.root_cost(bin, params.traversal_cost);
        assert!(p <= g * (1.0 + 1e-5), "{p} > {g}");
    }
}
