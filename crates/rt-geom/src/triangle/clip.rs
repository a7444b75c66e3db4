//! Clipping a triangle to a box: the bounds of the part inside (Sutherland–Hodgman), for the
//! perfect splits of kd-trees.

use super::Triangle;
use crate::Aabb;
use glam::{DVec3, Vec3};

impl Triangle {
    /// Bounds of the part of the triangle inside `clip` (Sutherland–Hodgman against the six
    /// planes), or an empty box. New vertices on a clipping plane are put exactly on it, so the
    /// result never pokes out of `clip`; the result is also limited to the triangle's bounds.
    pub fn clipped_bounds(&self, clip: &Aabb) -> Aabb {
        let bounds = self.bounds();
        if clip.contains(&bounds) {
            return bounds;
        }
        // A triangle clipped by six planes has at most 9 vertices: fixed arrays, no allocation.
        let mut poly = [DVec3::ZERO; 9];
        let mut len = 3;
        for (slot, p) in poly.iter_mut().zip(self.v) {
            *slot = p.as_dvec3();
        }
        let mut next = [DVec3::ZERO; 9];
        for axis in 0..3 {
            for (plane, keep_above) in [(clip.min[axis], true), (clip.max[axis], false)] {
                let plane = plane as f64;
                let inside = |p: &DVec3| {
                    if keep_above {
                        p[axis] >= plane
                    } else {
                        p[axis] <= plane
                    }
                };
                let mut n = 0;
                for i in 0..len {
                    let p = poly[i];
                    let q = poly[(i + 1) % len];
                    let (pin, qin) = (inside(&p), inside(&q));
                    if pin {
                        next[n] = p;
                        n += 1;
                    }
                    if pin != qin {
                        let s = (plane - p[axis]) / (q[axis] - p[axis]);
                        let mut x = p + (q - p) * s;
                        x[axis] = plane;
                        next[n] = x;
                        n += 1;
                    }
                }
                std::mem::swap(&mut poly, &mut next);
                len = n;
                if len == 0 {
                    return Aabb::EMPTY;
                }
            }
        }
        let mut out = Aabb::EMPTY;
        for p in &poly[..len] {
            // Round outwards so that the f32 box still contains the f64 polygon.
            let lo = p.as_vec3();
            let lo = Vec3::select(lo.as_dvec3().cmpgt(*p), next_down(lo), lo);
            let hi = p.as_vec3();
            let hi = Vec3::select(hi.as_dvec3().cmplt(*p), next_up(hi), hi);
            out.min = out.min.min(lo);
            out.max = out.max.max(hi);
        }
        out.intersection(*clip).intersection(bounds)
    }
}

fn next_up(v: Vec3) -> Vec3 {
    Vec3::new(v.x.next_up(), v.y.next_up(), v.z.next_up())
}

fn next_down(v: Vec3) -> Vec3 {
    Vec3::new(v.x.next_down(), v.y.next_down(), v.z.next_down())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping() {
        let t = Triangle::new(
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        );
        let clip = Aabb::new(Vec3::new(1.0, 0.0, -1.0), Vec3::new(3.0, 3.0, 1.0));
        let b = t.clipped_bounds(&clip);
        assert_eq!(b.min, Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(b.max, Vec3::new(2.0, 1.0, 0.0));
        let far = Aabb::new(Vec3::splat(5.0), Vec3::splat(6.0));
        assert!(t.clipped_bounds(&far).is_empty());
        // The corner region beyond the hypotenuse: box overlaps bounds but not the triangle.
        let corner = Aabb::new(Vec3::new(1.5, 1.5, -1.0), Vec3::new(2.0, 2.0, 1.0));
        assert!(t.clipped_bounds(&corner).is_empty());
        assert_eq!(
            t.clipped_bounds(&Aabb::new(Vec3::splat(-9.0), Vec3::splat(9.0))),
            t.bounds()
        );
    }
}
