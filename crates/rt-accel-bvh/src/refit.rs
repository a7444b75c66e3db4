//! Refit: new vertex positions, same topology. Bounds are recomputed bottom-up; the tree keeps
//! its shape (its quality degrades as primitives move far, its answers stay exact).

use crate::Bvh;
use rt_geom::{Aabb, BuildError, Primitive, check_primitives};

impl<P: Primitive> Bvh<P> {
    /// Replaces the primitives by `prims` (same count, same order as at build time) and
    /// recomputes every box. Fails, leaving the tree unchanged, on a count mismatch or
    /// non-finite input.
    pub fn refit(&mut self, prims: &[P]) -> Result<(), BuildError> {
        if prims.len() != self.count {
            return Err(BuildError::InvalidParameter {
                name: "prims.len()",
                value: prims.len().to_string(),
                expected: "the primitive count the tree was built with",
            });
        }
        check_primitives(prims, u32::MAX as usize - 1)?;
        for (slot, &id) in self.prims.iter_mut().zip(&self.ids) {
            *slot = prims[id as usize].clone();
        }
        // Children always follow their parent: a reverse sweep sees children first.
        for i in (0..self.nodes.len()).rev() {
            let n = self.nodes[i];
            let b = if n.is_leaf() {
                let first = n.offset as usize;
                self.prims[first..first + n.count() as usize]
                    .iter()
                    .fold(Aabb::EMPTY, |b, p| b.union(p.bounds()))
            } else {
                self.nodes[i + 1]
                    .bounds()
                    .union(self.nodes[n.offset as usize].bounds())
            };
            self.nodes[i].min = b.min.to_array();
            self.nodes[i].max = b.max.to_array();
        }
        Ok(())
    }
}
