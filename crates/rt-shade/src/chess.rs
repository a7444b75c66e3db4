//! The built-in scene: the classic chess board. An 8x8 reflective board in a wooden frame on a
//! table, 32 lathed pieces of about 100 triangles each (smooth normals from the lathe), the
//! white king, queen and bishops in glass, lit by two lights. Needs no files.

use crate::scene::{ObjectShapes, SceneInstance};
use crate::{Camera, Material, PointLight, Scene, SceneObjects};
use glam::{Affine3A, Vec3, Vec3A};
use rt_geom::Triangle;

/// Scale of the pieces (profiles are given for a king 1.1 squares tall).
const PIECE_SCALE: f32 = 1.3;

/// Segments around the axis of a lathed piece.
const SEGMENTS: usize = 10;

/// Lift of the pieces above the board: no face of a piece lies in the board's plane (coplanar
/// faces would make the closest hit a tie between structures).
const LIFT: f32 = 1e-3;

/// Profiles `(radius, height)` from the bottom centre to the top, per piece.
const PAWN: &[(f32, f32)] = &[
    (0.0, 0.0),
    (0.28, 0.0),
    (0.28, 0.08),
    (0.12, 0.30),
    (0.19, 0.34),
    (0.15, 0.48),
    (0.12, 0.60),
    (0.0, 0.64),
];
const ROOK: &[(f32, f32)] = &[
    (0.0, 0.0),
    (0.32, 0.0),
    (0.32, 0.08),
    (0.20, 0.18),
    (0.18, 0.55),
    (0.25, 0.60),
    (0.25, 0.75),
    (0.0, 0.75),
];
const KNIGHT: &[(f32, f32)] = &[
    (0.0, 0.0),
    (0.32, 0.0),
    (0.32, 0.08),
    (0.20, 0.16),
    (0.15, 0.40),
    (0.20, 0.60),
    (0.12, 0.78),
    (0.0, 0.82),
];
const BISHOP: &[(f32, f32)] = &[
    (0.0, 0.0),
    (0.30, 0.0),
    (0.30, 0.08),
    (0.14, 0.22),
    (0.11, 0.60),
    (0.17, 0.70),
    (0.13, 0.88),
    (0.0, 0.98),
];
const QUEEN: &[(f32, f32)] = &[
    (0.0, 0.0),
    (0.34, 0.0),
    (0.34, 0.09),
    (0.15, 0.25),
    (0.11, 0.75),
    (0.23, 0.92),
    (0.14, 1.00),
    (0.0, 1.10),
];
const KING: &[(f32, f32)] = &[
    (0.0, 0.0),
    (0.34, 0.0),
    (0.34, 0.09),
    (0.15, 0.25),
    (0.12, 0.80),
    (0.22, 0.92),
    (0.16, 1.05),
    (0.0, 1.08),
];

#[derive(Clone, Copy, PartialEq)]
enum Piece {
    Pawn,
    Rook,
    Knight,
    Bishop,
    Queen,
    King,
}

/// The chess scene (4:3 view), one flat list of triangles.
pub fn chess() -> Scene {
    chess_objects(ChessForm::Pieces).0
}

/// The chess scene with a lamp hanging over the board: a glowing bulb on a cord, with a point
/// light inside it. The bulb casts no shadow ([`Material::without_shadow`]): shadow rays to its
/// light pass through it by a ray mask, where they would otherwise all stop at the glass
/// around the light.
pub fn chess_lamp() -> Scene {
    let mut s = chess();
    s.name = "chess-lamp".to_string();
    let at = Vec3::new(-0.5, 1.4, -1.5);
    let radius = 0.2;
    s.lights.push(PointLight {
        position: at,
        colour: Vec3::new(0.9, 0.7, 0.45),
    });
    let bulb = s.add_material(
        Material {
            ambient: Vec3::new(8.0, 7.0, 4.5),
            ..Material::matte(Vec3::ZERO)
        }
        .without_shadow(),
    );
    let cord = s.add_material(Material::matte(Vec3::splat(0.05)));
    // A sphere as a lathe profile (radius, height) from the bottom pole to the top one.
    let bands = 12;
    let profile: Vec<(f32, f32)> = (0..=bands)
        .map(|i| {
            let a = std::f32::consts::PI * i as f32 / bands as f32;
            (radius * a.sin(), -radius * a.cos())
        })
        .map(|(r, y)| (r / PIECE_SCALE, y / PIECE_SCALE))
        .collect();
    lathe(&mut s, &profile, at, bulb);
    let top = radius * 0.98 / PIECE_SCALE;
    let thin = 0.02 / PIECE_SCALE;
    lathe(&mut s, &[(thin, top), (thin, 12.0)], at, cord);
    s
}

/// The forms the chess scene takes for two-level ray tracing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChessForm {
    /// The board (squares, frame and table) and each of the 32 pieces an object of its own,
    /// in world space, each placed once by the identity: the bounding-volume argument's
    /// "board and 32 boxes". Flattened, exactly [`chess`].
    Pieces,
    /// The board and one object per piece shape (pawn, rook, knight, bishop, queen, king)
    /// around the origin; 33 instances translate them to their squares (the black pieces
    /// turned half a turn to face white).
    Instanced,
}

/// The chess scene as objects and instances ([`ChessForm`]), and the same scene flattened:
/// the world-space triangles in the order of the instances, with their materials and normals,
/// for shading by global primitive id.
pub fn chess_objects(form: ChessForm) -> (Scene, SceneObjects) {
    let camera = Camera::perspective(
        Vec3::new(-5.0, 7.5, -10.5),
        Vec3::new(0.3, 0.3, 0.2),
        Vec3::Y,
        40.0,
    );
    let mut s = Scene::new("chess", camera);
    s.resolution = Some((800, 600));
    s.background = Vec3::new(0.05, 0.07, 0.12);
    s.ambient = Vec3::splat(0.12);
    s.lights = vec![
        PointLight {
            position: Vec3::new(-6.0, 10.0, -7.0),
            colour: Vec3::splat(0.75),
        },
        PointLight {
            position: Vec3::new(8.0, 7.0, -2.0),
            colour: Vec3::new(0.45, 0.42, 0.38),
        },
    ];
    let light_sq = s.add_material(
        Material::matte(Vec3::new(0.85, 0.80, 0.68))
            .with_highlight(0.3, 60.0)
            .with_reflection(0.25),
    );
    let dark_sq = s.add_material(
        Material::matte(Vec3::new(0.28, 0.14, 0.07))
            .with_highlight(0.3, 60.0)
            .with_reflection(0.25),
    );
    let frame =
        s.add_material(Material::matte(Vec3::new(0.35, 0.20, 0.10)).with_highlight(0.2, 20.0));
    let table = s.add_material(Material::matte(Vec3::new(0.30, 0.32, 0.36)));
    let ivory = s.add_material(
        Material::matte(Vec3::new(0.90, 0.86, 0.76))
            .with_highlight(0.5, 40.0)
            .with_reflection(0.08),
    );
    let ebony = s.add_material(
        Material::matte(Vec3::new(0.07, 0.07, 0.09))
            .with_highlight(0.6, 80.0)
            .with_reflection(0.3),
    );
    let glass = s.add_material(Material {
        ambient: Vec3::ZERO,
        ..Material::matte(Vec3::splat(0.02))
            .with_highlight(0.8, 200.0)
            .with_reflection(0.1)
            .with_transmission(Vec3::new(0.85, 0.92, 0.88), 1.5)
    });

    // Board: 8x8 unit squares, top face at y = 0, a1 (dark) at x = -4, z = -4.
    for rank in 0..8 {
        for file in 0..8 {
            let (x, z) = (file as f32 - 4.0, rank as f32 - 4.0);
            let m = if (rank + file) % 2 == 0 {
                dark_sq
            } else {
                light_sq
            };
            rect_y(&mut s, (x, z), (x + 1.0, z + 1.0), 0.0, m);
        }
    }
    // Frame: a ring around the squares and its outer walls, down to the table.
    let (inner, outer, bottom) = (4.0, 4.4, -0.25);
    rect_y(&mut s, (-outer, -outer), (outer, -inner), 0.0, frame);
    rect_y(&mut s, (-outer, inner), (outer, outer), 0.0, frame);
    rect_y(&mut s, (-outer, -inner), (-inner, inner), 0.0, frame);
    rect_y(&mut s, (inner, -inner), (outer, inner), 0.0, frame);
    let c = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    for (a, b, out) in [
        (c(-outer, 0.0, -outer), c(outer, 0.0, -outer), -Vec3::Z),
        (c(outer, 0.0, -outer), c(outer, 0.0, outer), Vec3::X),
        (c(outer, 0.0, outer), c(-outer, 0.0, outer), Vec3::Z),
        (c(-outer, 0.0, outer), c(-outer, 0.0, -outer), -Vec3::X),
    ] {
        let down = Vec3::Y * bottom;
        s.add_quad([a + down, b + down, b, a], out, frame);
    }
    rect_y(&mut s, (-20.0, -20.0), (20.0, 20.0), bottom, table);
    let mut objects = SceneObjects {
        objects: vec![ObjectShapes::from_scene(&s, 0..s.shapes.len())],
        instances: vec![SceneInstance {
            object: 0,
            transform: Affine3A::IDENTITY,
            material: None,
        }],
    };

    // Pieces: each back-rank piece, then the pawn in front of it, white then black.
    use Piece::*;
    let back = [Rook, Knight, Bishop, Queen, King, Bishop, Knight, Rook];
    // The instanced form's objects: one per piece shape, standing at the origin facing +z.
    let mut kinds: Vec<Piece> = Vec::new();
    let mut placed = SceneObjects::default();
    for (file, &kind) in back.iter().enumerate() {
        for (white, rank, pawn_rank) in [(true, 0, 1), (false, 7, 6)] {
            let glass_piece = white && matches!(kind, King | Queen | Bishop);
            let m = if glass_piece {
                glass
            } else if white {
                ivory
            } else {
                ebony
            };
            let pawn_m = if white { ivory } else { ebony };
            for (kind, at, m) in [
                (kind, square_centre(file, rank), m),
                (Pawn, square_centre(file, pawn_rank), pawn_m),
            ] {
                match form {
                    ChessForm::Pieces => {
                        let start = s.shapes.len();
                        piece(&mut s, kind, at, if white { 1.0 } else { -1.0 }, m);
                        objects.instances.push(SceneInstance {
                            object: objects.objects.len() as u32,
                            transform: Affine3A::IDENTITY,
                            material: None,
                        });
                        objects
                            .objects
                            .push(ObjectShapes::from_scene(&s, start..s.shapes.len()));
                    }
                    ChessForm::Instanced => {
                        let object = kinds.iter().position(|k| *k == kind).unwrap_or_else(|| {
                            let mut proto = Scene::new("piece", camera);
                            piece(&mut proto, kind, Vec3::ZERO, 1.0, 0);
                            objects
                                .objects
                                .push(ObjectShapes::from_scene(&proto, 0..proto.shapes.len()));
                            kinds.push(kind);
                            kinds.len() - 1
                        });
                        // Black pieces turn half a turn about the vertical (exactly).
                        let turn = if white { 1.0 } else { -1.0 };
                        let transform = Affine3A::from_cols(
                            Vec3A::X * turn,
                            Vec3A::Y,
                            Vec3A::Z * turn,
                            at.into(),
                        );
                        placed.instances.push(SceneInstance {
                            object: object as u32 + 1,
                            transform,
                            material: Some(m),
                        });
                    }
                }
            }
        }
    }
    if form == ChessForm::Instanced {
        placed.objects = objects.objects.clone();
        placed.flatten_into(&mut s);
        objects.instances.extend(placed.instances);
    }
    (s, objects)
}

/// The instanced chess scene `t` of the way (0 to 1) through a short sequence: the white
/// king's knight jumps from g1 to f3 over an arc, the black queen's pawn topples towards the
/// frame and drops to the table, and a cloth beside the board ripples (a deforming object,
/// the last one, placed by the identity). The flattened scene follows the new positions.
pub fn chess_moving(t: f32) -> (Scene, SceneObjects) {
    let (mut scene, mut objects) = chess_objects(ChessForm::Instanced);
    let t = t.clamp(0.0, 1.0);
    // Instances follow the board: 1 + 4 * file + (0 back piece, 1 pawn) white, (2, 3) black.
    let knight = 1 + 4 * 6;
    let pawn = 1 + 4 * 3 + 3;
    let (from, to) = (square_centre(6, 0), square_centre(5, 2));
    let hop = Vec3::Y * (4.0 * t * (1.0 - t)) * 1.5;
    objects.instances[knight].transform.translation = (from.lerp(to, t) + hop).into();
    // The pawn tips over about x through its base, then slides off the board and drops.
    let p = &mut objects.instances[pawn];
    let base = Vec3::from(p.transform.translation);
    let tip = (t * 2.0).min(1.0) * std::f32::consts::FRAC_PI_2;
    let slide = (t * 2.0 - 1.0).max(0.0);
    let at = base + Vec3::new(0.0, -0.3 * slide * slide, (4.8 - base.z) * slide);
    p.transform = Affine3A::from_translation(at)
        * Affine3A::from_rotation_x(tip)
        * Affine3A::from_mat3(p.transform.matrix3.into());
    // The cloth: a 24 x 24 grid of quads standing beyond the board's right edge, rippling.
    let cloth_m =
        scene.add_material(Material::matte(Vec3::new(0.55, 0.12, 0.15)).with_highlight(0.2, 10.0));
    let mut cloth = Scene::new("cloth", scene.camera);
    let n = 24;
    let phase = t * std::f32::consts::TAU;
    let point = |i: usize, j: usize| {
        let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
        let wave = 0.25 * u * (6.0 * u + 4.0 * v - phase * 2.0).sin();
        Vec3::new(5.2 + wave, -0.25 + 2.5 * v, -3.0 + 6.0 * u)
    };
    for i in 0..n {
        for j in 0..n {
            let quad = [
                point(i, j),
                point(i + 1, j),
                point(i + 1, j + 1),
                point(i, j + 1),
            ];
            cloth.add_quad(quad, -Vec3::X, cloth_m);
        }
    }
    objects
        .objects
        .push(ObjectShapes::from_scene(&cloth, 0..cloth.shapes.len()));
    objects.instances.push(SceneInstance {
        object: objects.objects.len() as u32 - 1,
        transform: Affine3A::IDENTITY,
        material: None,
    });
    scene.shapes.clear();
    scene.material_of.clear();
    scene.vertex_normals.clear();
    objects.flatten_into(&mut scene);
    (scene, objects)
}

fn square_centre(file: usize, rank: usize) -> Vec3 {
    Vec3::new(file as f32 - 3.5, LIFT, rank as f32 - 3.5)
}

/// A horizontal rectangle facing +y.
fn rect_y(s: &mut Scene, (x0, z0): (f32, f32), (x1, z1): (f32, f32), y: f32, m: u32) {
    let p = |x, z| Vec3::new(x, y, z);
    s.add_quad([p(x0, z0), p(x1, z0), p(x1, z1), p(x0, z1)], Vec3::Y, m);
}

fn piece(s: &mut Scene, kind: Piece, at: Vec3, facing: f32, m: u32) {
    let profile = match kind {
        Piece::Pawn => PAWN,
        Piece::Rook => ROOK,
        Piece::Knight => KNIGHT,
        Piece::Bishop => BISHOP,
        Piece::Queen => QUEEN,
        Piece::King => KING,
    };
    lathe(s, profile, at, m);
    match kind {
        // The knight's head: a block leaning towards the opponent.
        Piece::Knight => cuboid(
            s,
            at,
            Vec3::new(0.0, 0.66, 0.1 * facing),
            Vec3::new(0.09, 0.08, 0.2),
            m,
        ),
        // The king's cross.
        Piece::King => {
            cuboid(
                s,
                at,
                Vec3::new(0.0, 1.18, 0.0),
                Vec3::new(0.035, 0.13, 0.035),
                m,
            );
            cuboid(
                s,
                at,
                Vec3::new(0.0, 1.2, 0.0),
                Vec3::new(0.1, 0.035, 0.035),
                m,
            );
        }
        _ => {}
    }
}

/// A box on the piece standing at `at`: centre offset and half-size in unscaled piece units.
fn cuboid(s: &mut Scene, at: Vec3, offset: Vec3, half: Vec3, m: u32) {
    let centre = at + offset * PIECE_SCALE;
    s.add_box(centre - half * PIECE_SCALE, centre + half * PIECE_SCALE, m);
}

/// A surface of revolution about the vertical axis through `at`, with vertex normals that are
/// smooth across gentle profile bends and sharp at corners (over 50 degrees).
fn lathe(s: &mut Scene, profile: &[(f32, f32)], at: Vec3, m: u32) {
    let seg_normal = |i: usize| {
        let (r0, y0) = profile[i];
        let (r1, y1) = profile[i + 1];
        glam::Vec2::new(y1 - y0, -(r1 - r0)).normalize()
    };
    let bands = profile.len() - 1;
    let smooth_cos = 50f32.to_radians().cos();
    // Normal of band `j` at its end on profile point `i` (i = j or j + 1).
    let end_normal = |j: usize, i: usize| {
        let n = seg_normal(j);
        let other = if i == j {
            j.checked_sub(1)
        } else {
            (j + 1 < bands).then_some(j + 1)
        };
        match other.map(seg_normal) {
            Some(o) if o.dot(n) >= smooth_cos => (n + o).normalize(),
            _ => n,
        }
    };
    let angle = |k: usize| std::f32::consts::TAU * k as f32 / SEGMENTS as f32;
    let point = |i: usize, k: usize| {
        let (r, y) = profile[i];
        at + Vec3::new(r * angle(k).cos(), y, r * angle(k).sin()) * PIECE_SCALE
    };
    let normal3 =
        |n: glam::Vec2, k: usize| Vec3::new(n.x * angle(k).cos(), n.y, n.x * angle(k).sin());
    for j in 0..bands {
        let (n0, n1) = (end_normal(j, j), end_normal(j, j + 1));
        let mid = seg_normal(j);
        for k in 0..SEGMENTS {
            let k1 = k + 1;
            let out = normal3(mid, k).lerp(normal3(mid, k1), 0.5);
            let (a, b, c, d) = (point(j, k), point(j, k1), point(j + 1, k1), point(j + 1, k));
            let (na, nb, nc, nd) = (
                normal3(n0, k),
                normal3(n0, k1),
                normal3(n1, k1),
                normal3(n1, k),
            );
            s.add_facing(Triangle::new(a, b, c), out, m, Some([na, nb, nc]));
            s.add_facing(Triangle::new(a, c, d), out, m, Some([na, nc, nd]));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chess_has_the_classic_shape() {
        let s = chess();
        s.check().unwrap();
        assert_eq!(s.lights.len(), 2);
        assert!(s.triangles().is_some(), "every shape is a triangle");
        // 128 board triangles, 8 frame top + 8 walls, 2 table: 146; the rest are 32 pieces.
        let pieces = s.shapes.len() - 146;
        let per_piece = pieces as f32 / 32.0;
        assert!(
            (90.0..=140.0).contains(&per_piece),
            "{per_piece} triangles per piece"
        );
        // Some pieces are glass.
        let glass = s
            .materials
            .iter()
            .position(|m| m.is_transmissive())
            .unwrap() as u32;
        let glass_tris = s.material_of.iter().filter(|&&m| m == glass).count();
        assert!(glass_tris > 300 && glass_tris < pieces / 2, "{glass_tris}");
    }

    #[test]
    fn the_three_forms_are_one_scene() {
        let flat = chess();
        let (pieces, objects) = chess_objects(ChessForm::Pieces);
        assert_eq!(pieces.shapes, flat.shapes);
        assert_eq!((objects.objects.len(), objects.instances.len()), (33, 33));
        let flat_tris = flat.triangles().unwrap();
        assert_eq!(objects.flattened_triangles(), flat_tris);
        let (instanced, objects) = chess_objects(ChessForm::Instanced);
        // The board and six piece shapes; every instance's shapes follow in order.
        assert_eq!((objects.objects.len(), objects.instances.len()), (7, 33));
        assert_eq!(
            objects.flattened_triangles(),
            instanced.triangles().unwrap()
        );
        assert_eq!(instanced.shapes.len(), flat.shapes.len());
        assert_eq!(instanced.material_of, flat.material_of);
        // The same surfaces: each instance's vertices match, within rounding, vertices of
        // the same piece in the flat scene (black pieces turn half a turn, so their
        // triangles come in another order, and their boxes split along the other diagonal).
        let tris = instanced.triangles().unwrap();
        let mut first = 0;
        for inst in &objects.instances {
            let range = first..first + objects.objects[inst.object as usize].shapes.len();
            first = range.end;
            let flat_points: Vec<Vec3> =
                flat_tris[range.clone()].iter().flat_map(|t| t.v).collect();
            for p in tris[range].iter().flat_map(|t| t.v) {
                let near = |q: &Vec3| (p - *q).abs().max_element() < 1e-5;
                assert!(flat_points.iter().any(near), "{p:?}");
            }
        }
    }

    #[test]
    fn the_moving_scene_keeps_its_topology() {
        let (start, objects) = chess_moving(0.0);
        assert_eq!(objects.flattened_triangles(), start.triangles().unwrap());
        for t in [0.3, 0.7, 1.0] {
            let (s, o) = chess_moving(t);
            s.check().unwrap();
            assert_eq!(s.shapes.len(), start.shapes.len());
            assert_eq!(o.instances.len(), objects.instances.len());
            assert_ne!(s.shapes, start.shapes, "nothing moved at {t}");
        }
    }

    #[test]
    fn pieces_are_closed_and_wound_outwards() {
        let s = chess();
        // Every lathed triangle's normal agrees with its vertex normals (outward winding).
        for (t, n) in s.shapes.iter().zip(&s.vertex_normals) {
            if let (Some(t), Some(n)) = (t.as_triangle(), n) {
                let avg = n[0] + n[1] + n[2];
                assert!(t.normal().dot(avg) > 0.0, "{t:?}");
            }
        }
    }
}
