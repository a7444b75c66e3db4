//! Refit: new vertex positions, same topology. Bounds are recomputed bottom-up; the tree keeps
//! its shape (its quality degrades as primitives move far, its answers stay exact). Every
//! layout a renderer traces with implements [`Refit`]: [`Bvh`], [`WideBvh`](crate::WideBvh),
//! [`CompressedBvh8`](crate::CompressedBvh8) and the triangle BVHs [`TriBvh`](crate::TriBvh).

use crate::Bvh;
use rt_geom::{Aabb, BuildError, Frame, Primitive, check_primitives};

/// A structure whose boxes can be recomputed for moved primitives, keeping its topology.
pub trait Refit<P> {
    /// Replaces the primitives by `prims` (same count, same order as at build time) and
    /// recomputes every box. Fails, leaving the structure unchanged, on a count mismatch or
    /// non-finite (or out-of-range) input.
    fn refit(&mut self, prims: &[P]) -> Result<(), BuildError>;
}

/// The check every refit starts with: as many primitives as the structure was built from, all
/// finite and within range.
pub(crate) fn check_moved<P: Primitive>(prims: &[P], count: usize) -> Result<(), BuildError> {
    if prims.len() != count {
        return Err(BuildError::InvalidParameter {
            name: "prims.len()",
            value: prims.len().to_string(),
            expected: "the primitive count the structure was built with",
        });
    }
    check_primitives(prims, u32::MAX as usize - 1)
}

/// The box of the leaf `(first, count)` of the leaf-ordered `prims`.
pub(crate) fn leaf_bounds<P: Primitive>(prims: &[P], first: u32, count: u32) -> Aabb {
    Aabb::around(&prims[first as usize..(first + count) as usize])
}

/// `prims` in leaf order: `ids[k]` is the caller's index of the primitive at leaf slot `k`.
pub(crate) fn in_leaf_order<P: Primitive>(prims: &[P], ids: &[u32]) -> Vec<P> {
    ids.iter().map(|&i| prims[i as usize].clone()).collect()
}

/// [`in_leaf_order`] written over `slots` (as long as `ids`), which keep their memory.
pub(crate) fn refill_in_leaf_order<P: Primitive>(slots: &mut [P], prims: &[P], ids: &[u32]) {
    for (slot, &i) in slots.iter_mut().zip(ids) {
        slot.clone_from(&prims[i as usize]);
    }
}

impl<P: Primitive> Refit<P> for Bvh<P> {
    fn refit(&mut self, prims: &[P]) -> Result<(), BuildError> {
        check_moved(prims, self.count)?;
        refill_in_leaf_order(&mut self.prims, prims, &self.ids);
        self.refit_boxes();
        Ok(())
    }
}

impl<P: Primitive> Bvh<P> {
    /// Recomputes every node box from the primitives the tree holds.
    pub(crate) fn refit_boxes(&mut self) {
        self.refit_within(|_, b| b);
    }

    /// Moves boxes built in `frame` to world coordinates: each is the part of the refitted
    /// box (around its primitives) inside the frame's box rounded outward (around the
    /// primitives' parts that spatial splits clipped to it). Both hold what the node holds.
    pub(crate) fn boxes_to_world(&mut self, frame: &Frame) {
        let local: Vec<Aabb> = self.nodes.iter().map(|n| n.bounds()).collect();
        self.refit_within(|i, b| b.intersection(frame.to_world(&local[i])));
    }

    /// The refit's reverse sweep, node `i`'s box passed through `limit(i, box)` before its
    /// parent sees it.
    fn refit_within(&mut self, limit: impl Fn(usize, Aabb) -> Aabb) {
        // Children always follow their parent: a reverse sweep sees children first.
        for i in (0..self.nodes.len()).rev() {
            let n = self.nodes[i];
            let b = limit(
                i,
                if n.is_leaf() {
                    leaf_bounds(&self.prims, n.offset, n.count())
                } else {
                    self.nodes[i + 1]
                        .bounds()
                        .union(self.nodes[n.offset as usize].bounds())
                },
            );
            self.nodes[i].min = b.min.to_array();
            self.nodes[i].max = b.max.to_array();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Bvh4, Bvh8, BvhParams, CompressedBvh8, CompressedTriBvh8, TriBvh4, TriBvh8};
    use rt_geom::{Accel, Ray, Shape, Sphere, Triangle, Vec3};
    use rt_testkit::scenes;

    /// A large, non-rigid motion of every point: a twist about y, a squash and a shear, so that
    /// boxes grow, shrink and swap order.
    fn moved(p: Vec3) -> Vec3 {
        let (s, c) = (p.y * 0.7).sin_cos();
        Vec3::new(
            c * p.x - s * p.z,
            p.y * 0.4 + 0.3,
            s * p.x + c * p.z + 0.5 * p.x,
        )
    }

    fn move_triangles(tris: &[Triangle]) -> Vec<Triangle> {
        tris.iter()
            .map(|t| Triangle { v: t.v.map(moved) })
            .collect()
    }

    /// Builds over every triangle scene of the suite, moves every vertex, refits, and holds the
    /// refitted structure to brute force on the moved scene; then checks the errors.
    fn refit_conforms<A: Accel + Refit<Triangle>>(build: impl Fn(&[Triangle]) -> A) {
        for name in [
            "sphere_mesh",
            "soup",
            "teapot_in_stadium",
            "axis_slivers",
            "duplicates",
        ] {
            let scene = scenes::triangle_scene(name);
            let mut accel = build(&scene.prims);
            let after = move_triangles(&scene.prims);
            accel.refit(&after).unwrap();
            let moved_scene = rt_testkit::Scene::new(format!("{name}_moved"), after);
            let once = std::cell::RefCell::new(Some(accel));
            rt_testkit::conformance::assert_conforms(&moved_scene, |_p: &[Triangle]| {
                Ok::<_, BuildError>(once.borrow_mut().take().expect("built once"))
            });
        }
        let tris = scenes::triangle_scene("sphere_mesh").prims;
        let mut accel = build(&tris);
        let probe = Ray::new(Vec3::new(0.5, 0.4, -10.0), Vec3::Z);
        let before = accel.intersect(&probe);
        assert!(before.is_some());
        let short = accel.refit(&tris[..10]).unwrap_err();
        assert!(short.to_string().contains("primitive count"), "{short}");
        let mut bad = move_triangles(&tris);
        bad[3].v[1].y = f32::NAN;
        assert_eq!(accel.refit(&bad), Err(BuildError::NonFinite { prim: 3 }));
        bad[3].v[1].y = 1e30;
        assert_eq!(accel.refit(&bad), Err(BuildError::OutOfRange { prim: 3 }));
        // Left unchanged.
        assert_eq!(accel.intersect(&probe), before);
        accel.validate().unwrap();
    }

    #[test]
    fn bvh2() {
        refit_conforms(|p| Bvh::build(p, BvhParams::balanced()).unwrap());
        refit_conforms(|p| Bvh::build(p, BvhParams::spatial()).unwrap());
    }

    #[test]
    fn bvh4_and_bvh8() {
        refit_conforms(|p| Bvh4::build(p, BvhParams::balanced()).unwrap());
        refit_conforms(|p| Bvh8::build(p, BvhParams::quality()).unwrap());
    }

    #[test]
    fn compressed_bvh8() {
        refit_conforms(|p| CompressedBvh8::build(p, BvhParams::balanced()).unwrap());
    }

    #[test]
    fn triangle_soa_bvhs() {
        refit_conforms(|p| TriBvh4::build(p, BvhParams::balanced()).unwrap());
        refit_conforms(|p| TriBvh8::build_for_tracing(p).unwrap());
        refit_conforms(|p| TriBvh8::build(p, BvhParams::spatial().for_soa_leaves()).unwrap());
    }

    #[test]
    fn compressed_triangle_bvh8() {
        refit_conforms(|p| CompressedTriBvh8::build(p, BvhParams::fastest_trace()).unwrap());
    }

    #[test]
    fn one_leaf_and_empty_trees() {
        let one = scenes::triangle_scene("sphere_mesh").prims[..3].to_vec();
        refit_conforms_small(&one);
        refit_conforms_small(&[]);
    }

    fn refit_conforms_small(tris: &[Triangle]) {
        let mut a = TriBvh8::build_for_tracing(tris).unwrap();
        let mut b = CompressedTriBvh8::build(tris, BvhParams::balanced()).unwrap();
        let after = move_triangles(tris);
        a.refit(&after).unwrap();
        b.refit(&after).unwrap();
        let brute = rt_geom::BruteForce::build(&after).unwrap();
        for t in &after {
            let ray = Ray::new(t.centroid() - Vec3::Z * 5.0, Vec3::Z);
            assert_eq!(a.intersect(&ray), brute.intersect(&ray));
            assert_eq!(b.intersect(&ray), brute.intersect(&ray));
        }
        a.validate().unwrap();
        b.validate().unwrap();
    }

    #[test]
    fn spheres_and_shapes_move_too() {
        let spheres = scenes::random_spheres(300, 4);
        let mut w = Bvh8::build(&spheres, BvhParams::balanced()).unwrap();
        let after: Vec<Sphere> = spheres
            .iter()
            .map(|s| Sphere::new(moved(s.center), s.radius * 1.5))
            .collect();
        w.refit(&after).unwrap();
        let scene = rt_testkit::Scene::new("spheres_moved", after);
        let once = std::cell::RefCell::new(Some(w));
        rt_testkit::conformance::assert_conforms(&scene, |_p: &[Sphere]| {
            Ok::<_, BuildError>(once.borrow_mut().take().expect("built once"))
        });
        let shapes = scenes::mixed_shapes(200, 9);
        let mut c = CompressedBvh8::build(&shapes, BvhParams::balanced()).unwrap();
        let half: Vec<Shape> = scenes::mixed_shapes(200, 10);
        c.refit(&half).unwrap();
        c.validate().unwrap();
    }
}
