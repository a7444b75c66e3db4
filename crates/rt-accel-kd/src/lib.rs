//! # rt-accel-kd: kd-trees and BSP trees
//!
//! | module | what it holds |
//! |---|---|
//! | [`node`] | [`KdNode`], the 8-byte flattened node (layout documented there) |
//! | [`params`] | [`KdParams`] with presets `sah()`, `midpoint()`, `centroid()`; [`KdBuilder`], [`KdTraversal`] |
//! | `build` | split-plane events, the O(N log N) SAH sweep (Wald & Havran 2006), naive planes, perfect splits, flattening |
//! | [`traverse`] | front-to-back traversal, iterative and recursive, closest- and any-hit ([`traverse::step`]) |
//! | `stats` | `stats()` and `validate()` |
//! | [`bsp`] | [`BspTree`]: planes of any orientation (the primitives' own, and axis-aligned), same nodes and walk |
//!
//! ```
//! use rt_accel_kd::{KdParams, KdTree};
//! use rt_geom::{Accel, Ray, Triangle, Vec3};
//!
//! let tris = [
//!     Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y),
//!     Triangle::new(Vec3::new(0.0, 0.0, -1.0), Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, 1.0, -1.0)),
//! ];
//! let kd = KdTree::build(&tris, KdParams::sah()).expect("finite input");
//! let hit = kd.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z)).unwrap();
//! assert_eq!((hit.t, hit.prim), (1.0, 0));
//! kd.validate().unwrap();
//! ```

pub mod bsp;
mod build;
pub mod node;
pub mod params;
mod stats;
pub mod traverse;

pub use bsp::{BspParams, BspTree, SplitPlane};
pub use node::KdNode;
pub use params::{KdBuilder, KdParams, KdTraversal, MAX_DEPTH};

use rt_geom::{Aabb, Accel, AccelStats, BuildError, Hit, Primitive, Ray, check_primitives};

/// A kd-tree over primitives `P`: 8-byte nodes flattened depth-first, leaves referring to the
/// primitives by index (a primitive cut by planes is in several leaves).
#[derive(Clone, Debug)]
pub struct KdTree<P> {
    nodes: Vec<KdNode>,
    /// Leaves of more than one primitive hold ranges of this array.
    indices: Vec<u32>,
    /// The caller's primitives, in the caller's order.
    prims: Vec<P>,
    bounds: Aabb,
    params: KdParams,
}

impl<P: Primitive> KdTree<P> {
    /// Builds over `prims` (copied). Empty input gives an empty tree.
    pub fn build(prims: &[P], params: KdParams) -> Result<Self, BuildError> {
        params.validate()?;
        check_primitives(prims, build::MAX_LOCAL)?;
        let bounds = prims.iter().fold(Aabb::EMPTY, |b, p| b.union(p.bounds()));
        let mut nodes = Vec::new();
        let mut indices = Vec::new();
        if !prims.is_empty() {
            let root = build::build_tree(prims, bounds, &params);
            build::flatten(
                &root,
                &mut nodes,
                &mut indices,
                &mut |&(axis, pos), above| KdNode::inner(axis, pos, above),
            );
            if nodes.len() > node::MAX_NODE_FIELD as usize {
                return Err(BuildError::TooManyPrimitives {
                    count: prims.len(),
                    max: prims.len() / 2,
                });
            }
        }
        Ok(Self {
            nodes,
            indices,
            prims: prims.to_vec(),
            bounds,
            params,
        })
    }

    /// The flattened nodes (read-only; layout in [`node`]).
    pub fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    /// The index array leaves of several primitives point into.
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// The primitives, in the caller's order.
    pub fn prims(&self) -> &[P] {
        &self.prims
    }

    /// The root cell: the bounds of all primitives.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    pub fn params(&self) -> &KdParams {
        &self.params
    }

    /// The same tree, traversed the other way.
    pub fn with_traversal(mut self, traversal: KdTraversal) -> Self {
        self.params.traversal = traversal;
        self
    }
}

impl<P: Primitive> Accel for KdTree<P> {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.traverse::<false>(ray)
    }

    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        self.traverse::<true>(ray).is_some()
    }

    fn stats(&self) -> AccelStats {
        self.compute_stats()
    }

    fn validate(&self) -> Result<(), String> {
        self.check()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_geom::{Sphere, Triangle};

    macro_rules! per_builder {
        ($($name:ident: $params:expr),* $(,)?) => {$(
            mod $name {
                use super::*;
                rt_testkit::conformance_tests!(
                    triangles: |p: &[Triangle]| KdTree::build(p, $params),
                    spheres: |p: &[Sphere]| KdTree::build(p, $params),
                );
            }
        )*};
    }

    per_builder! {
        sah: KdParams::sah(),
        sah_recursive: KdParams::sah().with_traversal(KdTraversal::Recursive),
        midpoint: KdParams::midpoint(),
        centroid: KdParams::centroid(),
        centroid_recursive: KdParams::centroid().with_traversal(KdTraversal::Recursive),
        sah_serial: KdParams { parallel_threshold: usize::MAX, ..KdParams::sah() },
        sah_parallel: KdParams { parallel_threshold: 16, ..KdParams::sah() },
        sah_cheap_traversal: KdParams { traversal_cost: 1.0, intersection_cost: 1.5, ..KdParams::sah() },
        sah_no_budget: KdParams { reference_budget: 1.0, ..KdParams::sah() },
        midpoint_leaf1: KdParams { max_leaf_size: 1, ..KdParams::midpoint() },
        shallow: KdParams { max_depth: Some(3), ..KdParams::sah() },
    }
}
