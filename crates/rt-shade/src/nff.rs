//! NFF, the format of Haines' Standard Procedural Databases: view, background, lights, fill
//! materials, spheres, cones and cylinders (analytic primitives), polygons (concave ones
//! triangulated by ear clipping) and polygonal patches with vertex normals.
//!
//! The file is read as a stream of whitespace-separated tokens (the SPD generators write `c` on
//! one line where NFF.TXT uses three). Every error names the line. Conventions:
//! - `angle` is the field of view between the centres of the top and bottom pixel rows of the
//!   file's `resolution`; the camera's edge-to-edge field of view is widened to match.
//! - Lights without a colour get intensity `1 / sqrt(number of lights)` each.
//! - `f r g b Kd Ks Shine T ior`: diffuse `Kd * rgb` (also the ambient coefficient), Phong
//!   highlight `Ks` with exponent `Shine`, reflected ray `Ks`, refracted ray `T` with `ior`
//!   (`ior` is read only when `T > 0`).

use crate::triangulate::triangulate;
use crate::{Camera, Material, PointLight, Scene, SceneError};
use glam::Vec3;
use rt_geom::{Cone, Sphere, Triangle};
use std::path::Path;

/// Loads an NFF file.
pub fn load_nff(path: &Path) -> Result<Scene, SceneError> {
    let bytes = std::fs::read(path).map_err(|e| SceneError::in_file(path, e.to_string()))?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    parse_nff_bytes(&bytes, path, &name)
}

/// Parses the bytes of an NFF file: text that is not UTF-8 is an error naming its line.
pub fn parse_nff_bytes(bytes: &[u8], path: &Path, name: &str) -> Result<Scene, SceneError> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let line = 1 + bytes[..e.valid_up_to()]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        SceneError::at(path, line, "not UTF-8 text")
    })?;
    parse_nff(text, path, name)
}

/// Parses NFF text; `path` names the source in errors.
pub fn parse_nff(text: &str, path: &Path, name: &str) -> Result<Scene, SceneError> {
    let mut tokens = Tokens::new(text, path);
    let mut scene = Scene::new(
        name,
        Camera::perspective(Vec3::Z, Vec3::ZERO, Vec3::Y, 45.0),
    );
    scene.background = Vec3::ZERO;
    let mut have_view = false;
    let mut light_colours = Vec::new();
    let mut material = None;
    while let Some((kw, line)) = tokens.next() {
        match kw {
            "v" => {
                read_view(&mut tokens, &mut scene, line)?;
                have_view = true;
            }
            "b" => scene.background = tokens.vec3("background colour")?,
            "l" => {
                let position = tokens.vec3("light position")?;
                let colour = if tokens.peek_is_number() {
                    Some(tokens.vec3("light colour")?)
                } else {
                    None
                };
                scene.lights.push(PointLight {
                    position,
                    colour: Vec3::ZERO,
                });
                light_colours.push(colour);
            }
            "f" => {
                let rgb = tokens.vec3("fill colour")?;
                let kd = tokens.number("Kd")?;
                let ks = tokens.number("Ks")?;
                let shine = tokens.number("Shine")?;
                let t = tokens.number("T")?;
                let ior = tokens.number("index of refraction")?;
                if [kd, ks, shine, t].iter().any(|&x| x < 0.0) || rgb.min_element() < 0.0 {
                    return Err(SceneError::at(path, line, "negative material coefficient"));
                }
                if t > 0.0 && !(ior > 0.0) {
                    return Err(SceneError::at(
                        path,
                        line,
                        format!("transmitting material needs ior > 0, got {ior}"),
                    ));
                }
                let mut m = Material::matte(rgb * kd)
                    .with_highlight(ks, shine)
                    .with_reflection(ks);
                if t > 0.0 {
                    m = m.with_transmission(Vec3::splat(t), ior);
                }
                material = Some(scene.add_material(m));
            }
            "s" => {
                let centre = tokens.vec3("sphere centre")?;
                let radius = tokens.number("sphere radius")?;
                if radius < 0.0 {
                    return Err(SceneError::at(
                        path,
                        line,
                        "negative radius (inside-only spheres) is not supported",
                    ));
                }
                let m = current(&mut scene, &mut material);
                scene.add(Sphere::new(centre, radius), m, None);
            }
            "c" => {
                let base = tokens.vec3("cone base")?;
                let rb = tokens.number("cone base radius")?;
                let apex = tokens.vec3("cone apex")?;
                let ra = tokens.number("cone apex radius")?;
                if rb < 0.0 || ra < 0.0 {
                    return Err(SceneError::at(
                        path,
                        line,
                        "negative radius (inside-only cones) is not supported",
                    ));
                }
                let m = current(&mut scene, &mut material);
                scene.add(Cone::new(base, rb, apex, ra), m, None);
            }
            "p" | "pp" => {
                let n = tokens.count("vertex count")?;
                let mut points = Vec::with_capacity(n);
                let mut normals = Vec::with_capacity(n);
                for _ in 0..n {
                    points.push(tokens.vec3("polygon vertex")?);
                    if kw == "pp" {
                        normals.push(tokens.vec3("patch normal")?.normalize_or_zero());
                    }
                }
                let Some(tris) = triangulate(&points) else {
                    scene.warnings.push(format!(
                        "{}:{line}: polygon with no area skipped",
                        path.display()
                    ));
                    continue;
                };
                let m = current(&mut scene, &mut material);
                for [a, b, c] in tris {
                    let smooth = (kw == "pp").then(|| [normals[a], normals[b], normals[c]]);
                    scene.add(Triangle::new(points[a], points[b], points[c]), m, smooth);
                }
            }
            other => {
                return Err(SceneError::at(
                    path,
                    line,
                    format!("unknown NFF command `{other}`"),
                ));
            }
        }
    }
    if !have_view {
        return Err(SceneError::in_file(path, "no view (`v`) in file"));
    }
    let default = 1.0 / (light_colours.len().max(1) as f32).sqrt();
    for (l, c) in scene.lights.iter_mut().zip(light_colours) {
        l.colour = c.unwrap_or(Vec3::splat(default));
    }
    scene
        .check()
        .map_err(|e| SceneError::in_file(path, e.what))?;
    Ok(scene)
}

/// The current fill material, or a default one (with a warning) before the first `f`.
fn current(scene: &mut Scene, material: &mut Option<u32>) -> u32 {
    *material.get_or_insert_with(|| {
        scene
            .warnings
            .push("object before any `f`: default material used".into());
        scene.add_material(Material::default())
    })
}

fn read_view(t: &mut Tokens, scene: &mut Scene, line: usize) -> Result<(), SceneError> {
    let (mut from, mut at, mut up, mut angle, mut res) = (None, None, None, None, None);
    while let Some(kw) = t.peek_word() {
        match kw {
            "from" => {
                t.next();
                from = Some(t.vec3("from")?);
            }
            "at" => {
                t.next();
                at = Some(t.vec3("at")?);
            }
            "up" => {
                t.next();
                up = Some(t.vec3("up")?);
            }
            "angle" => {
                t.next();
                angle = Some(t.number("angle")?);
            }
            "hither" => {
                t.next();
                t.number("hither")?;
            }
            "resolution" => {
                t.next();
                res = Some((t.count("resolution x")?, t.count("resolution y")?));
            }
            _ => break,
        }
    }
    let missing = |what: &str| SceneError::at(t.path, line, format!("view lacks `{what}`"));
    let (from, at, up) = (
        from.ok_or_else(|| missing("from"))?,
        at.ok_or_else(|| missing("at"))?,
        up.ok_or_else(|| missing("up"))?,
    );
    let angle = angle.ok_or_else(|| missing("angle"))?;
    let (nx, ny) = res.unwrap_or((512, 512));
    if nx == 0 || ny == 0 || nx > 1 << 16 || ny > 1 << 16 {
        return Err(SceneError::at(
            t.path,
            line,
            format!("absurd resolution {nx} x {ny}"),
        ));
    }
    // `angle` spans pixel centres of the top and bottom rows: widen it to the image edges.
    let half = (angle.to_radians() * 0.5).tan() * ny as f32 / (ny as f32 - 1.0).max(1.0);
    scene.camera = Camera::perspective(from, at, up, 2.0 * half.atan().to_degrees());
    scene
        .camera
        .check()
        .map_err(|e| SceneError::at(t.path, line, e))?;
    scene.resolution = Some((nx as u32, ny as u32));
    Ok(())
}

/// Whitespace-separated tokens with their 1-based line numbers (`#` starts a comment).
struct Tokens<'a> {
    items: Vec<(&'a str, usize)>,
    at: usize,
    path: &'a Path,
}

impl<'a> Tokens<'a> {
    fn new(text: &'a str, path: &'a Path) -> Self {
        let items = text
            .lines()
            .enumerate()
            .flat_map(|(i, l)| {
                l.split('#')
                    .next()
                    .unwrap_or("")
                    .split_whitespace()
                    .map(move |t| (t, i + 1))
            })
            .collect();
        Self { items, at: 0, path }
    }

    fn next(&mut self) -> Option<(&'a str, usize)> {
        let t = self.items.get(self.at).copied();
        self.at += 1;
        t
    }

    fn peek_word(&self) -> Option<&'a str> {
        self.items.get(self.at).map(|t| t.0)
    }

    fn peek_is_number(&self) -> bool {
        self.peek_word().is_some_and(|w| w.parse::<f32>().is_ok())
    }

    fn last_line(&self) -> usize {
        self.items.last().map_or(1, |t| t.1)
    }

    fn number(&mut self, what: &str) -> Result<f32, SceneError> {
        let Some((tok, line)) = self.next() else {
            return Err(SceneError::at(
                self.path,
                self.last_line(),
                format!("file ends where {what} was expected"),
            ));
        };
        match tok.parse::<f32>() {
            Ok(x) if x.is_finite() => Ok(x),
            Ok(_) => Err(SceneError::at(
                self.path,
                line,
                format!("{what} is NaN or infinite"),
            )),
            Err(_) => Err(SceneError::at(
                self.path,
                line,
                format!("expected a number for {what}, found `{tok}`"),
            )),
        }
    }

    fn vec3(&mut self, what: &str) -> Result<Vec3, SceneError> {
        Ok(Vec3::new(
            self.number(what)?,
            self.number(what)?,
            self.number(what)?,
        ))
    }

    fn count(&mut self, what: &str) -> Result<usize, SceneError> {
        let Some((tok, line)) = self.next() else {
            return Err(SceneError::at(
                self.path,
                self.last_line(),
                format!("file ends where {what} was expected"),
            ));
        };
        match tok.parse::<usize>() {
            Ok(n) if n <= 1 << 20 => Ok(n),
            _ => Err(SceneError::at(
                self.path,
                line,
                format!("expected a count for {what}, found `{tok}`"),
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_geom::Shape;

    fn parse(s: &str) -> Result<Scene, SceneError> {
        parse_nff(s, Path::new("t.nff"), "t")
    }

    const VIEW: &str = "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 64 64\n";

    #[test]
    fn every_entity() {
        let s = parse(&format!(
            "b 0.1 0.2 0.3\n{VIEW}l 1 2 3\nl 4 5 6 0.5 0.5 0.5\nf 1 0 0 0.8 0.2 30 0 0\n\
             s 0 0 0 1\nc 0 0 0 1  0 1 0 0.5\nf 1 1 1 0.5 0 100000 0.8 1.1\n\
             p 4\n0 0 0\n1 0 0\n1 1 0\n0 1 0\npp 3\n0 0 1 0 0 1\n1 0 1 0 0 1\n0 1 1 0 0 1\n"
        ))
        .unwrap();
        assert_eq!(s.background, Vec3::new(0.1, 0.2, 0.3));
        assert_eq!(s.resolution, Some((64, 64)));
        assert_eq!(s.lights.len(), 2);
        assert_eq!(s.lights[0].colour, Vec3::splat(1.0 / 2f32.sqrt()));
        assert_eq!(s.lights[1].colour, Vec3::splat(0.5));
        assert_eq!(s.shapes.len(), 5);
        assert!(matches!(s.shapes[0], Shape::Sphere(_)));
        assert!(matches!(s.shapes[1], Shape::Cone(_)));
        assert_eq!(s.material_of, vec![0, 0, 1, 1, 1]);
        assert!(s.materials[1].is_transmissive());
        assert_eq!(s.materials[1].ior, 1.1);
        assert_eq!(s.materials[0].diffuse, Vec3::new(0.8, 0.0, 0.0));
        assert!(s.vertex_normals[4].is_some() && s.vertex_normals[2].is_none());
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse(&format!("{VIEW}s 0 0 zero 1\n")).unwrap_err();
        assert_eq!(e.line, Some(8), "{e}");
        assert!(e.to_string().starts_with("t.nff:8:"), "{e}");
        let e = parse(&format!("{VIEW}f 1 1 1 1 0 0 0 0\nq 1 2 3\n")).unwrap_err();
        assert_eq!(e.line, Some(9));
        assert!(e.what.contains("unknown NFF command `q`"), "{e}");
        let e = parse(&format!("{VIEW}p 4\n0 0 0\n1 0 0\n")).unwrap_err();
        assert!(e.what.contains("file ends"), "{e}");
        let e = parse(&format!("{VIEW}s 0 0 nan 1\n")).unwrap_err();
        assert!(e.what.contains("NaN"), "{e}");
        let e = parse("s 0 0 0 1\n").unwrap_err();
        assert!(e.what.contains("no view"), "{e}");
        let e = parse("v\nfrom 0 0 0\nat 0 0 0\nup 0 1 0\nangle 45\n").unwrap_err();
        assert!(e.what.contains("looks at its own position"), "{e}");
        let e = parse(&format!("{VIEW}f 1 1 1 1 0 0 0.5 0\n")).unwrap_err();
        assert!(e.what.contains("ior"), "{e}");
    }

    #[test]
    fn empty_scene_loads_with_warnings() {
        let s = parse(VIEW).unwrap();
        assert!(s.shapes.is_empty());
        let w = s.render_warnings();
        assert!(
            w.iter().any(|w| w.contains("no geometry"))
                && w.iter().any(|w| w.contains("no lights"))
        );
    }
}
