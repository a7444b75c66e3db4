//! The 8-wide BVH with child boxes quantized to 8 bits per plane (in the spirit of Ylitie,
//! Karras & Laine's compressed wide BVH, HPG 2017): half the bytes of [`WideNode<8>`], so
//! that more of a large scene's tree stays in cache.
//!
//! Node layout ([`CompressedNode`], 128 bytes, two cache lines; the first holds everything
//! the box test reads):
//!
//! ```text
//! offset  size  field
//!      0    12  origin[3]     f32   the node box's minimum corner
//!     12     3  exponent[3]   u8    per axis, the step 2^(exponent - 127) (an f32's biased exponent)
//!     15     1  used          u8    bit `lane` set for the lanes that hold a child
//!     16    24  qmin[3][8]    u8    per axis and lane: child box min = origin + qmin * step
//!     40    24  qmax[3][8]    u8    per axis and lane: child box max = origin + qmax * step
//!     64    32  child[8]      u32   inner: node index; leaf: first primitive; u32::MAX: empty lane
//!     96    32  count[8]      u32   0 for an inner child, else the leaf's primitive count
//! ```
//!
//! The step is a power of two, so `q * step` is exact and `origin + q * step` rounds once; the
//! build picks the step so that `origin + 255 * step` reaches the node's maximum, then rounds
//! each child's codes outward, checking them with that same expression (the one the traversal
//! evaluates), so every dequantized box holds its child's box. The walk (the one wide-BVH
//! stack loop, over [`NodeLayout`]) then visits a superset of the nodes the exact boxes would
//! give, and returns exactly their hits.

use crate::wide::{NodeLayout, WideBvh, WideNode, WideTree, lane_entries, near_far};
use rt_geom::aabb::SlabRay;
use rt_geom::{Aabb, Level, Vec3};

/// A node of [`CompressedBvh8`] (layout in the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct CompressedNode {
    /// Minimum corner of the node box: the origin of the child codes.
    pub origin: [f32; 3],
    /// Per axis, the `f32` exponent byte of the power-of-two step one code stands for.
    pub exponent: [u8; 3],
    /// Number of child lanes in use.
    pub used: u8,
    /// Per axis and child, the lower plane as a code (rounded down).
    pub qmin: [[u8; 8]; 3],
    /// Per axis and child, the upper plane as a code (rounded up).
    pub qmax: [[u8; 8]; 3],
    /// Per child, the node index (inner) or the first primitive (leaf).
    pub child: [u32; 8],
    /// Per child, the primitive count of a leaf; 0 for an inner child.
    pub count: [u32; 8],
}

const _: () = assert!(std::mem::size_of::<CompressedNode>() == 128);

/// Smallest exponent used: steps stay normal numbers, so `q * step` is exact.
const MIN_EXPONENT: u8 = 1;

impl CompressedNode {
    /// The step of axis `a`: `2^(exponent - 127)`.
    #[inline(always)]
    fn step(&self, a: usize) -> f32 {
        f32::from_bits((self.exponent[a] as u32) << 23)
    }

    /// The coordinate of code `q` along axis `a`: the one formula of build and traversal.
    #[inline(always)]
    fn at(&self, a: usize, q: u8) -> f32 {
        self.origin[a] + q as f32 * self.step(a)
    }

    /// The dequantized box of `lane`.
    fn dequantized(&self, lane: usize) -> Aabb {
        let corner = |q: &[[u8; 8]; 3]| {
            Vec3::new(
                self.at(0, q[0][lane]),
                self.at(1, q[1][lane]),
                self.at(2, q[2][lane]),
            )
        };
        Aabb::new(corner(&self.qmin), corner(&self.qmax))
    }

    /// Quantizes `wide`: same children, boxes rounded outward.
    fn compress(wide: &WideNode<8>) -> Self {
        let used: Vec<usize> = (0..8).filter(|&l| wide.is_used(l)).collect();
        let node_box = used
            .iter()
            .fold(Aabb::EMPTY, |b, &l| b.union(wide.bounds(l)));
        let mut node = Self {
            origin: node_box.min.to_array(),
            exponent: [MIN_EXPONENT; 3],
            used: used.iter().fold(0, |m, &l| m | 1 << l),
            // Empty lanes: a box from the far end to the origin (the traversal also skips
            // them by `child`).
            qmin: [[255; 8]; 3],
            qmax: [[0; 8]; 3],
            child: wide.child,
            count: wide.count,
        };
        if used.is_empty() {
            return node;
        }
        for a in 0..3 {
            // The smallest power-of-two step whose 255th code reaches the node's maximum.
            let extent = node_box.max[a] - node_box.min[a];
            let guess = (extent / 255.0).max(f32::MIN_POSITIVE);
            let mut e = ((guess.to_bits() >> 23) as u8).max(MIN_EXPONENT);
            node.exponent[a] = e;
            while e < 254 && node.at(a, 255) < node_box.max[a] {
                e += 1;
                node.exponent[a] = e;
            }
            for &l in &used {
                let b = wide.bounds(l);
                let code = |x: f32| ((x - node.origin[a]) / node.step(a)).clamp(0.0, 255.0);
                let mut lo = code(b.min[a]).floor() as u8;
                while lo > 0 && node.at(a, lo) > b.min[a] {
                    lo -= 1;
                }
                let mut hi = (code(b.max[a]).ceil() as u8).max(lo);
                while hi < 255 && node.at(a, hi) < b.max[a] {
                    hi += 1;
                }
                node.qmin[a][l] = lo;
                node.qmax[a][l] = hi;
            }
        }
        node
    }
}

impl NodeLayout<8> for CompressedNode {
    const EXACT: bool = false;

    fn from_exact(node: &WideNode<8>) -> Self {
        Self::compress(node)
    }

    #[inline(always)]
    fn entries<V: Level>(&self, level: V, ray: &SlabRay, tmin: f32, tmax: f32) -> (u32, [f32; 8]) {
        let dequantize = |q: &[[u8; 8]; 3]| -> [[f32; 8]; 3] {
            std::array::from_fn(|a| {
                let step = self.step(a);
                std::array::from_fn(|l| self.origin[a] + q[a][l] as f32 * step)
            })
        };
        let (min, max) = (dequantize(&self.qmin), dequantize(&self.qmax));
        lane_entries(level, near_far(&min, &max, ray), ray, tmin, tmax)
    }

    #[inline(always)]
    fn children(&self) -> &[u32; 8] {
        &self.child
    }

    #[inline(always)]
    fn counts(&self) -> &[u32; 8] {
        &self.count
    }

    fn bounds(&self, lane: usize) -> Aabb {
        self.dequantized(lane)
    }

    #[inline(always)]
    fn used_mask(&self) -> u32 {
        self.used as u32
    }
}

/// The topology of a compressed 8-wide BVH: [`WideTree`] over [`CompressedNode`].
pub type CompressedTree = WideTree<8, CompressedNode>;

/// An 8-wide BVH with quantized child boxes ([`CompressedNode`]): [`WideBvh`] over that
/// layout, the same leaves and primitives as [`Bvh8`](crate::Bvh8) built alike.
pub type CompressedBvh8<P> = WideBvh<P, 8, CompressedNode>;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Bvh8, BvhParams};
    use rt_geom::{Accel, Sphere, Triangle};

    rt_testkit::conformance_tests!(
        triangles: |p: &[Triangle]| CompressedBvh8::build(p, BvhParams::balanced()),
        spheres: |p: &[Sphere]| CompressedBvh8::build(p, BvhParams::balanced()),
        shapes: |p: &[rt_geom::Shape]| CompressedBvh8::build(p, BvhParams::balanced()),
    );
    rt_testkit::disc_tests!(|p: &[rt_testkit::Disc]| CompressedBvh8::build(
        p,
        BvhParams::balanced()
    ));

    mod spatial {
        use super::*;
        rt_testkit::conformance_tests!(
            triangles: |p: &[Triangle]| CompressedBvh8::build(p, BvhParams::spatial()),
        );
        rt_testkit::disc_tests!(|p: &[rt_testkit::Disc]| CompressedBvh8::build(
            p,
            BvhParams::spatial()
        ));
        rt_testkit::filter_tests!(
            triangles: |p: &[Triangle]| CompressedBvh8::build(p, BvhParams::spatial()),
        );
    }

    #[test]
    fn dequantized_boxes_hold_the_children() {
        // Boxes of every scale and offset, touching the node's faces, flat ones, far from
        // the origin.
        let mut rng = rt_testkit::Rng::new(5);
        for k in 0..3000 {
            let scale = [1e-4f32, 1.0, 300.0, 1e5][k % 4];
            let offset = [0.0f32, -7.5, 1e4, -3e6][k / 4 % 4];
            let mut wide = WideNode::<8> {
                min: [[f32::INFINITY; 8]; 3],
                max: [[f32::NEG_INFINITY; 8]; 3],
                child: [u32::MAX; 8],
                count: [0; 8],
            };
            let lanes = 1 + k % 8;
            for l in 0..lanes {
                let p = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * scale + Vec3::splat(offset);
                let q = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * scale + Vec3::splat(offset);
                let mut b = Aabb::new(p.min(q), p.max(q));
                if l == 1 {
                    b.max.y = b.min.y; // flat
                }
                for a in 0..3 {
                    wide.min[a][l] = b.min[a];
                    wide.max[a][l] = b.max[a];
                }
                wide.child[l] = l as u32;
                wide.count[l] = 1;
            }
            let node = CompressedNode::compress(&wide);
            for l in 0..lanes {
                let (got, want) = (node.bounds(l), wide.bounds(l));
                assert!(got.contains(&want), "{want:?} -> {got:?} ({node:?})");
                // Tight: within two steps of the child's box on every side.
                for a in 0..3 {
                    let step = f32::from_bits((node.exponent[a] as u32) << 23);
                    assert!(want.min[a] - got.min[a] <= 2.0 * step + want.min[a].abs() * 1e-6);
                    assert!(got.max[a] - want.max[a] <= 2.0 * step + want.max[a].abs() * 1e-6);
                }
            }
        }
    }

    #[test]
    fn half_the_bytes_of_bvh8() {
        let tris = rt_testkit::scenes::random_soup(5000, 3);
        let wide = Bvh8::build(&tris, BvhParams::balanced()).unwrap();
        let c = CompressedBvh8::build(&tris, BvhParams::balanced()).unwrap();
        c.validate().unwrap();
        assert_eq!(c.tree().leaves(), wide.tree().leaves());
        let bytes = std::mem::size_of_val(c.tree().nodes());
        assert_eq!(bytes * 2, std::mem::size_of_val(wide.tree().nodes()));
    }
}
