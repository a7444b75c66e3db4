//! Both walks. Each octant's box is the same `octant()` of its parent that the build used.
//!
//! - `recursive`: the seeds' walk. At an inner node, every non-empty octant the ray enters
//!   (the padded box test) is collected with its entry distance, and they are visited nearest
//!   first; octants entered beyond the closest hit are skipped.
//! - `parametric` (Revelles, Ureña & Lastra 2000): per axis, the distances to the node's near
//!   and far planes and to its centre plane. The first octant follows from the plane the ray
//!   enters through (the largest near distance): an axis's upper half is taken if the ray has
//!   crossed its centre plane before entering. The next octant is across the plane of the
//!   smallest exit distance; leaving through a far plane leaves the node. Octants are numbered
//!   in the mirrored frame where every direction is positive, and XOR-ed with the direction
//!   mask to find the real one. The distances are computed afresh at each node (not averaged
//!   from the parent's), NaN (a ray lying in a plane) counts as "inside the slab", and each
//!   octant's interval is padded like the box test before it is compared with the closest
//!   hit.
//!
//! Both walks keep a per-ray mailbox of the last 8 primitives tested: a primitive listed in
//! several leaves along the ray is tested once.

use crate::Octree;
use crate::node::octant;
use rt_geom::aabb::{pad_down, pad_up};
use rt_geom::{Aabb, Hit, Mailbox, Primitive, Ray, test_primitives};

struct Walk<'a, P> {
    tree: &'a Octree<P>,
    origin: [f32; 3],
    inv: [f32; 3],
    /// Bit `a` set: the ray runs towards -a (octant bits mirrored).
    mirror: usize,
    ray: Ray,
    best: Option<Hit>,
    /// Primitives listed in several leaves are tested once per ray.
    mailbox: Mailbox<8>,
}

impl<P: Primitive> Walk<'_, P> {
    /// Tests leaf `i`; true when `ANY_HIT` and something was hit.
    fn leaf<const ANY_HIT: bool>(&mut self, i: usize) -> bool {
        let tree = self.tree;
        let ids = &tree.indices[tree.nodes[i].prims()];
        let mailbox = &mut self.mailbox;
        test_primitives::<P, ANY_HIT>(&tree.prims, ids, &mut self.ray, &mut self.best, |p| {
            mailbox.seen(p)
        })
    }

    /// True when a pending part of the ray entered at `t` cannot hold a closer hit.
    #[inline]
    fn beyond(&self, t: f32) -> bool {
        self.best.is_some_and(|h| t > h.t) || t > self.ray.tmax
    }

    fn recursive<const ANY_HIT: bool>(&mut self, i: usize, bounds: &Aabb) -> bool {
        let node = self.tree.nodes[i];
        if node.is_leaf() {
            return self.leaf::<ANY_HIT>(i);
        }
        let mut entered: [(f32, usize, Aabb); 8] = [(0.0, 0, Aabb::EMPTY); 8];
        let mut count = 0;
        for o in 0..8 {
            if let Some(child) = node.child(o) {
                let b = octant(bounds, o);
                if let Some((t0, _)) = b.clip_ray(&self.ray) {
                    entered[count] = (t0, child, b);
                    count += 1;
                }
            }
        }
        let entered = &mut entered[..count];
        entered.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        for &(t0, child, b) in entered.iter() {
            if self.beyond(t0) {
                break;
            }
            if self.recursive::<ANY_HIT>(child, &b) {
                return true;
            }
        }
        false
    }

    /// `(near, mid, far)` distances along each axis, in the mirrored frame.
    #[inline]
    fn planes(&self, b: &Aabb) -> [[f32; 3]; 3] {
        let c = b.center();
        std::array::from_fn(|a| {
            let (lo, hi) = if self.mirror >> a & 1 == 1 {
                (b.max[a], b.min[a])
            } else {
                (b.min[a], b.max[a])
            };
            let t = |x: f32| (x - self.origin[a]) * self.inv[a];
            // NaN: the ray lies in that plane; for the slab it is inside, and it never
            // crosses the centre plane.
            let near = t(lo);
            let far = t(hi);
            let mid = t(c[a]);
            [
                if near.is_nan() {
                    f32::NEG_INFINITY
                } else {
                    near
                },
                if mid.is_nan() { f32::INFINITY } else { mid },
                if far.is_nan() { f32::INFINITY } else { far },
            ]
        })
    }

    fn parametric<const ANY_HIT: bool>(&mut self, i: usize, bounds: &Aabb) -> bool {
        let node = self.tree.nodes[i];
        if node.is_leaf() {
            return self.leaf::<ANY_HIT>(i);
        }
        let p = self.planes(bounds);
        // The axis of the entry plane, and the first octant (mirrored numbering).
        let entry = (0..3)
            .max_by(|&a, &b| p[a][0].total_cmp(&p[b][0]))
            .unwrap_or(0);
        let t_enter = p[entry][0];
        let j0 = p
            .iter()
            .enumerate()
            .filter(|&(a, pa)| a != entry && pa[1] < t_enter)
            .fold(0usize, |j, (a, _)| j | 1 << a);
        let mut j = j0;
        loop {
            // This octant's interval along each axis: [near, mid] or [mid, far].
            let lower = |a: usize| if j >> a & 1 == 1 { p[a][1] } else { p[a][0] };
            let upper = |a: usize| if j >> a & 1 == 1 { p[a][2] } else { p[a][1] };
            let t0 = pad_down(lower(0).max(lower(1)).max(lower(2)));
            let t1 = pad_up(upper(0).min(upper(1)).min(upper(2)));
            if self.beyond(t0) {
                return false;
            }
            let real = j ^ self.mirror;
            if t1 >= self.ray.tmin {
                if let Some(child) = node.child(real) {
                    if self.parametric::<ANY_HIT>(child, &octant(bounds, real)) {
                        return true;
                    }
                }
            }
            // Across the plane the ray leaves through first; a far plane ends the node.
            let exit = (0..3)
                .min_by(|&a, &b| upper(a).total_cmp(&upper(b)))
                .unwrap_or(0);
            if j >> exit & 1 == 1 {
                return false;
            }
            j |= 1 << exit;
        }
    }
}

impl<P: Primitive> Octree<P> {
    pub(crate) fn traverse<const ANY_HIT: bool>(&self, ray: &Ray) -> Option<Hit> {
        if self.nodes.is_empty() || !ray.is_valid() {
            return None;
        }
        self.bounds.clip_ray(ray)?;
        let dir = ray.dir();
        let mut walk = Walk {
            tree: self,
            origin: ray.origin().to_array(),
            inv: ray.inv_dir().to_array(),
            mirror: (0..3).fold(0, |m, a| m | ((dir[a].is_sign_negative() as usize) << a)),
            ray: *ray,
            best: None,
            mailbox: Mailbox::default(),
        };
        match self.params.traversal {
            crate::OctreeTraversal::Recursive => walk.recursive::<ANY_HIT>(0, &self.bounds),
            crate::OctreeTraversal::Parametric => walk.parametric::<ANY_HIT>(0, &self.bounds),
        };
        walk.best
    }
}
