//! Triangulation of planar polygons, convex or not (NFF's gear faces are concave 144-gons):
//! ear clipping in the polygon's plane. Triangles keep the polygon's winding.

use glam::{Vec2, Vec3};

/// Triangles `[i, j, k]` (indices into `points`) covering the polygon, wound like it; `None`
/// when the polygon has fewer than 3 points or no area. Convex polygons are fanned from the
/// first vertex; others are ear-clipped (Meisters 1975), O(n^2) per polygon.
pub fn triangulate(points: &[Vec3]) -> Option<Vec<[usize; 3]>> {
    let n = points.len();
    if n < 3 {
        return None;
    }
    let normal = newell_normal(points);
    if normal == Vec3::ZERO || !normal.is_finite() {
        return None;
    }
    // Project onto the plane of the two axes other than the normal's largest, oriented so that
    // the polygon runs counter-clockwise.
    let drop = normal.abs().max_position();
    let (a, b) = ((drop + 1) % 3, (drop + 2) % 3);
    let flip = normal[drop] < 0.0;
    let p2: Vec<Vec2> = points
        .iter()
        .map(|p| {
            if flip {
                Vec2::new(p[b], p[a])
            } else {
                Vec2::new(p[a], p[b])
            }
        })
        .collect();
    let corner = |i: usize, j: usize, k: usize| (p2[j] - p2[i]).perp_dot(p2[k] - p2[j]);
    if (0..n).all(|i| corner(i, (i + 1) % n, (i + 2) % n) >= 0.0) {
        return Some((1..n - 1).map(|i| [0, i, i + 1]).collect());
    }
    let mut ring: Vec<usize> = (0..n).collect();
    let mut out = Vec::with_capacity(n - 2);
    while ring.len() > 3 {
        let m = ring.len();
        let is_ear = |e: usize| {
            let (i, j, k) = (ring[(e + m - 1) % m], ring[e], ring[(e + 1) % m]);
            if corner(i, j, k) <= 0.0 {
                return false;
            }
            // No other vertex of the ring inside or on the candidate triangle.
            ring.iter()
                .filter(|&&q| q != i && q != j && q != k)
                .all(|&q| !inside(p2[q], p2[i], p2[j], p2[k]))
        };
        // Without an ear (rounding on nearly collinear points), clip the most convex corner.
        let e = (0..m).find(|&e| is_ear(e)).unwrap_or_else(|| {
            (0..m)
                .max_by(|&x, &y| {
                    let c = |e: usize| corner(ring[(e + m - 1) % m], ring[e], ring[(e + 1) % m]);
                    c(x).total_cmp(&c(y))
                })
                .unwrap_or(0)
        });
        out.push([ring[(e + m - 1) % m], ring[e], ring[(e + 1) % m]]);
        ring.remove(e);
    }
    out.push([ring[0], ring[1], ring[2]]);
    Some(out)
}

/// Newell's normal: robust for non-convex and slightly non-planar polygons; its length is twice
/// the area.
pub fn newell_normal(points: &[Vec3]) -> Vec3 {
    let n = points.len();
    (0..n).fold(Vec3::ZERO, |acc, i| {
        let (p, q) = (points[i], points[(i + 1) % n]);
        acc + Vec3::new(
            (p.y - q.y) * (p.z + q.z),
            (p.z - q.z) * (p.x + q.x),
            (p.x - q.x) * (p.y + q.y),
        )
    })
}

/// `p` inside or on the counter-clockwise triangle `abc`.
fn inside(p: Vec2, a: Vec2, b: Vec2, c: Vec2) -> bool {
    (b - a).perp_dot(p - a) >= 0.0
        && (c - b).perp_dot(p - b) >= 0.0
        && (a - c).perp_dot(p - c) >= 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(points: &[Vec3], tris: &[[usize; 3]]) -> Vec3 {
        tris.iter()
            .map(|&[a, b, c]| (points[b] - points[a]).cross(points[c] - points[a]) * 0.5)
            .sum()
    }

    #[test]
    fn convex_polygons_fan() {
        let quad = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        assert_eq!(triangulate(&quad).unwrap(), vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn star_shaped_gear_face_is_covered_exactly() {
        // A 24-point star (concave), in a tilted plane, clockwise as seen from +z.
        let tilt = glam::Quat::from_rotation_x(0.7);
        let pts: Vec<Vec3> = (0..24)
            .map(|i| {
                let a = -(i as f32) * std::f32::consts::TAU / 24.0;
                let r = if i % 2 == 0 { 1.0 } else { 0.4 };
                tilt * Vec3::new(r * a.cos(), r * a.sin(), 0.0)
            })
            .collect();
        let tris = triangulate(&pts).unwrap();
        assert_eq!(tris.len(), 22);
        // Same total (signed) area as the polygon: no overlap, same winding.
        let want = newell_normal(&pts) * 0.5;
        assert!(
            area(&pts, &tris).abs_diff_eq(want, 1e-5),
            "{} vs {want}",
            area(&pts, &tris)
        );
        // A fan from v0 would cover area outside the star.
        for &[a, b, c] in &tris {
            let n = (pts[b] - pts[a]).cross(pts[c] - pts[a]);
            assert!(
                n.dot(want) >= 0.0,
                "every triangle keeps the polygon's winding"
            );
        }
    }

    #[test]
    fn degenerate_polygons_are_refused() {
        assert!(triangulate(&[Vec3::ZERO, Vec3::X]).is_none());
        assert!(triangulate(&[Vec3::ZERO, Vec3::X, Vec3::X * 2.0]).is_none());
    }
}
