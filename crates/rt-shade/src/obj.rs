//! OBJ scenes with MTL materials. Geometry goes through `rt_geom::parse_obj` (tobj; the same
//! triangles and ids as every other rt tool, errors that name the line), vertex normals and
//! `usemtl` through a second tobj pass, and MTL files through the small reader here, whose
//! errors name the line.
//!
//! MTL to [`Material`]: `Kd` diffuse, `Ka` ambient (default: `Kd`), `Ks` highlight with
//! exponent `Ns`; `illum` 3 to 7 add a reflected ray of weight `Ks`; dissolve `d < 1` (or
//! `Tr > 0`) adds a refracted ray of weight `1 - d` with index `Ni`; `Ke` the light the surface
//! gives off ([`Material::emit`]: an area light for the path tracer, a glow for Whitted's
//! rules). Statements rt does not use (textures, ...) are reported once per keyword as
//! warnings.

use crate::{Camera, Material, PointLight, Scene, SceneError};
use glam::Vec3;
use rt_geom::parse_obj;
use std::cell::RefCell;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// Loads an OBJ file and the MTL files it names (relative to its folder).
pub fn load_obj_scene(path: &Path) -> Result<Scene, SceneError> {
    let text = std::fs::read(path).map_err(|e| SceneError::in_file(path, e.to_string()))?;
    parse_obj_scene(&text, path, &|mtl| std::fs::read_to_string(mtl))
}

/// Parses OBJ text as a scene; `path` names the source in errors and its folder is where MTL
/// files are looked up, each read by `read_mtl` (a missing one is a warning, default materials
/// are used).
pub fn parse_obj_scene(
    text: &[u8],
    path: &Path,
    read_mtl: &dyn Fn(&Path) -> std::io::Result<String>,
) -> Result<Scene, SceneError> {
    let mesh = match parse_obj(text, path) {
        Ok(mesh) => mesh,
        // A file without faces is a scene without geometry: background, with a warning.
        Err(rt_geom::MeshError::NoTriangles { .. }) => rt_geom::Mesh::default(),
        Err(e) => return Err(SceneError::new(e.to_string())),
    };
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();

    let library = RefCell::new(MtlLibrary::default());
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let loaded = tobj::load_obj_buf(&mut std::io::BufReader::new(text), &options, |mtl| {
        library.borrow_mut().load(&dir.join(mtl), read_mtl);
        let lib = library.borrow();
        let placeholders = vec![tobj::Material::default(); lib.materials.len()];
        Ok((placeholders, lib.by_name.clone()))
    });
    let (models, _) = loaded.map_err(|e| SceneError::in_file(path, e.to_string()))?;
    let library = library.into_inner();
    if let Some(e) = library.error {
        return Err(e);
    }

    let view = default_view(&mesh.bounds());
    let mut scene = Scene::new(name, view.0);
    scene.background = Vec3::new(0.1, 0.1, 0.12);
    scene.lights = view.1;
    scene.warnings = library.warnings;
    scene.materials = library.materials;
    let fallback = scene.add_material(Material::default());
    let triangles = mesh.triangles();
    // tobj fills a face without normals with some other vertex's normal: find which faces
    // really have them.
    let mut with_normals = triangles_with_normals(text);
    if with_normals.len() != triangles.len() {
        scene
            .warnings
            .push("could not match normals to faces: flat shading".into());
        with_normals = vec![false; triangles.len()];
    }
    let mut next = 0;
    for model in &models {
        let m = &model.mesh;
        let material = m.material_id.map_or(fallback, |i| i as u32);
        let has_normals = !m.normals.is_empty() && m.normal_indices.len() == m.indices.len();
        let normal = |k: usize| {
            let i = m.normal_indices[k] as usize * 3;
            Vec3::new(m.normals[i], m.normals[i + 1], m.normals[i + 2]).normalize_or_zero()
        };
        for (f, _) in m.indices.chunks_exact(3).enumerate() {
            let normals =
                has_normals.then(|| [normal(3 * f), normal(3 * f + 1), normal(3 * f + 2)]);
            let normals = normals.filter(|n| {
                with_normals[next] && n.iter().all(|v| v.is_finite() && *v != Vec3::ZERO)
            });
            scene.add(triangles[next], material, normals);
            next += 1;
        }
    }
    if next != triangles.len() {
        return Err(SceneError::in_file(
            path,
            "faces read twice disagree (internal error)",
        ));
    }
    if models.iter().any(|m| m.mesh.material_id.is_none()) && !library.by_name.is_empty() {
        scene
            .warnings
            .push("faces without a known material use the default".into());
    }
    scene
        .check()
        .map_err(|e| SceneError::in_file(path, e.what))?;
    Ok(scene)
}

/// Per triangle (faces in file order, fan-triangulated), whether every corner of its face names
/// a normal (`v//vn` or `v/vt/vn`).
fn triangles_with_normals(text: &[u8]) -> Vec<bool> {
    let mut out = Vec::new();
    for line in String::from_utf8_lossy(text).lines() {
        let line = line.trim_start();
        let Some(rest) = line.strip_prefix("f ").or_else(|| line.strip_prefix("f\t")) else {
            continue;
        };
        let corners: Vec<&str> = rest
            .split('#')
            .next()
            .unwrap_or("")
            .split_whitespace()
            .collect();
        let has = corners
            .iter()
            .all(|c| c.split('/').nth(2).is_some_and(|n| !n.is_empty()));
        out.extend(std::iter::repeat_n(has, corners.len().saturating_sub(2)));
    }
    out
}

/// A camera in front of the box (looking down -z, y up) that frames it with a 45-degree field
/// of view, and two lights: one over the camera, one to the side.
pub fn default_view(bounds: &rt_geom::Aabb) -> (Camera, Vec<PointLight>) {
    let (centre, radius) = if bounds.is_empty() {
        (Vec3::ZERO, 1.0)
    } else {
        (bounds.center(), (bounds.extent().length() * 0.5).max(1e-6))
    };
    let dist = radius / (22.5f32).to_radians().sin() * 1.05;
    let dir = Vec3::new(0.25, 0.3, 1.0).normalize();
    let eye = centre + dir * dist;
    let lights = vec![
        PointLight {
            position: eye + Vec3::Y * radius * 2.0,
            colour: Vec3::splat(0.7),
        },
        PointLight {
            position: centre + Vec3::new(-2.0, 1.5, 0.5) * radius * 2.0,
            colour: Vec3::splat(0.4),
        },
    ];
    (Camera::perspective(eye, centre, Vec3::Y, 45.0), lights)
}

/// Materials read from MTL files, by name.
#[derive(Default)]
struct MtlLibrary {
    materials: Vec<Material>,
    by_name: HashMap<String, usize>,
    warnings: Vec<String>,
    error: Option<SceneError>,
}

impl MtlLibrary {
    fn load(&mut self, path: &Path, read: &dyn Fn(&Path) -> std::io::Result<String>) {
        if self.error.is_some() {
            return;
        }
        match read(path) {
            Err(e) => self
                .warnings
                .push(format!("{}: {e}; default materials used", path.display())),
            Ok(text) => match parse_mtl(&text, path) {
                Ok((mats, warnings)) => {
                    for (name, m) in mats {
                        self.by_name.insert(name, self.materials.len());
                        self.materials.push(m);
                    }
                    self.warnings.extend(warnings);
                }
                Err(e) => self.error = Some(e),
            },
        }
    }
}

/// Parses MTL text into named materials and warnings (statements not used, per keyword).
pub fn parse_mtl(
    text: &str,
    path: &Path,
) -> Result<(Vec<(String, Material)>, Vec<String>), SceneError> {
    #[derive(Default)]
    struct Raw {
        kd: Option<Vec3>,
        ka: Option<Vec3>,
        ks: Option<Vec3>,
        ke: Option<Vec3>,
        ns: Option<f32>,
        ni: Option<f32>,
        d: Option<f32>,
        illum: Option<u32>,
    }
    let mut out: Vec<(String, Raw)> = Vec::new();
    let mut ignored: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    for (i, line) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = line.split('#').next().unwrap_or("").trim();
        let Some((kw, rest)) = line
            .split_once(char::is_whitespace)
            .or((!line.is_empty()).then_some((line, "")))
        else {
            continue;
        };
        let rest = rest.trim();
        let err = |what: String| SceneError::at(path, line_no, what);
        let nums = |n: usize| -> Result<Vec<f32>, SceneError> {
            let v: Vec<f32> = rest
                .split_whitespace()
                .map(|t| {
                    t.parse::<f32>()
                        .map_err(|_| err(format!("`{kw}` expects numbers, found `{t}`")))
                })
                .collect::<Result<_, _>>()?;
            if v.len() < n {
                return Err(err(format!(
                    "`{kw}` needs {n} number(s), found {}",
                    v.len()
                )));
            }
            if v.iter().any(|x| !x.is_finite() || *x < 0.0) {
                return Err(err(format!("`{kw}` needs finite numbers >= 0")));
            }
            Ok(v)
        };
        let colour = |v: Vec<f32>| match v.len() {
            1 => Ok(Vec3::splat(v[0])),
            3 => Ok(Vec3::new(v[0], v[1], v[2])),
            n => Err(err(format!("`{kw}` needs 1 or 3 numbers, found {n}"))),
        };
        if kw == "newmtl" {
            if rest.is_empty() {
                return Err(err("`newmtl` needs a name".into()));
            }
            out.push((rest.to_string(), Raw::default()));
            continue;
        }
        let known = ["Kd", "Ka", "Ks", "Ke", "Ns", "Ni", "d", "Tr", "illum"];
        if !known.contains(&kw) {
            ignored.entry(kw.to_string()).or_insert((line_no, 0)).1 += 1;
            continue;
        }
        let Some((_, raw)) = out.last_mut() else {
            return Err(err(format!("`{kw}` before any `newmtl`")));
        };
        match kw {
            "Kd" => raw.kd = Some(colour(nums(1)?)?),
            "Ka" => raw.ka = Some(colour(nums(1)?)?),
            "Ks" => raw.ks = Some(colour(nums(1)?)?),
            "Ke" => raw.ke = Some(colour(nums(1)?)?),
            "Ns" => raw.ns = Some(nums(1)?[0]),
            "Ni" => raw.ni = Some(nums(1)?[0]),
            "d" => raw.d = Some(nums(1)?[0].min(1.0)),
            "Tr" => raw.d = Some(1.0 - nums(1)?[0].min(1.0)),
            _ => {
                raw.illum =
                    Some(rest.parse().map_err(|_| {
                        err(format!("`illum` expects a model number, found `{rest}`"))
                    })?)
            }
        }
    }
    let warnings = ignored
        .into_iter()
        .map(|(kw, (line, n))| {
            let more = if n > 1 {
                format!(" (and {} more lines)", n - 1)
            } else {
                String::new()
            };
            format!(
                "{}:{line}: `{kw}` is not used by rt-shade{more}",
                path.display()
            )
        })
        .collect();
    let materials = out
        .into_iter()
        .map(|(name, r)| {
            let kd = r.kd.unwrap_or(Vec3::splat(0.8));
            let ks = r.ks.unwrap_or(Vec3::ZERO);
            let mut m = Material::matte(kd);
            m.ambient = r.ka.unwrap_or(kd);
            m.specular = ks;
            m.shininess = r.ns.unwrap_or(1.0);
            m.emit = r.ke.unwrap_or(Vec3::ZERO);
            if matches!(r.illum, Some(3..=7)) {
                m.reflect = ks;
            }
            let d = r.d.unwrap_or(1.0);
            if d < 1.0 {
                m.transmit = Vec3::splat(1.0 - d);
                m.ior = r.ni.filter(|&n| n > 0.0).unwrap_or(1.0);
            }
            (name, m)
        })
        .collect();
    Ok((materials, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mtl_materials_and_warnings() {
        let (mats, warnings) = parse_mtl(
            "# c\nnewmtl glass\nKd 0.1 0.1 0.1\nKs 0.9 0.9 0.9\nNs 200\nNi 1.5\nd 0.2\nillum 7\n\
             map_Kd a.png\nnewmtl red\nKd 1 0 0\nKe 2 1.5 0\nmap_Kd b.png\n",
            Path::new("m.mtl"),
        )
        .unwrap();
        assert_eq!(mats.len(), 2);
        let g = &mats[0].1;
        assert_eq!(mats[0].0, "glass");
        assert!(g.is_transmissive() && (g.ior - 1.5).abs() < 1e-6);
        assert_eq!(g.reflect, Vec3::splat(0.9));
        assert!((g.transmit.x - 0.8).abs() < 1e-6);
        assert_eq!(mats[1].1.diffuse, Vec3::X);
        assert_eq!(mats[1].1.reflect, Vec3::ZERO);
        assert_eq!(
            (g.emit, mats[1].1.emit),
            (Vec3::ZERO, Vec3::new(2.0, 1.5, 0.0))
        );
        assert_eq!(
            warnings,
            vec!["m.mtl:9: `map_Kd` is not used by rt-shade (and 1 more lines)"]
        );
    }

    #[test]
    fn mtl_errors_name_the_line() {
        let e = parse_mtl("newmtl a\nKd 1 x 0\n", Path::new("m.mtl")).unwrap_err();
        assert_eq!(e.to_string(), "m.mtl:2: `Kd` expects numbers, found `x`");
        let e = parse_mtl("Kd 1 1 1\n", Path::new("m.mtl")).unwrap_err();
        assert_eq!(e.line, Some(1));
        let e = parse_mtl("newmtl a\nNs nan\n", Path::new("m.mtl")).unwrap_err();
        assert_eq!(e.line, Some(2));
        let e = parse_mtl("newmtl a\nillum x\n", Path::new("m.mtl")).unwrap_err();
        assert_eq!(e.line, Some(2));
    }

    #[test]
    fn obj_with_mtl_normals_and_materials() {
        let dir = std::env::temp_dir().join(format!("rt-shade-obj-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(
            dir.join("m.mtl"),
            "newmtl red\nKd 1 0 0\nnewmtl mirror\nKs 1 1 1\nillum 3\n",
        )
        .unwrap();
        std::fs::write(
            dir.join("s.obj"),
            "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\n\
             usemtl red\nf 1//1 2//1 3//1\nusemtl mirror\nf 1 3 4\nusemtl nothing\nf 1 2 4\n",
        )
        .unwrap();
        let s = load_obj_scene(&dir.join("s.obj")).unwrap();
        assert_eq!(s.shapes.len(), 3);
        assert_eq!(s.materials[s.material_of[0] as usize].diffuse, Vec3::X);
        assert_eq!(s.materials[s.material_of[1] as usize].reflect, Vec3::ONE);
        assert_eq!(
            s.material_of[2] as usize,
            s.materials.len() - 1,
            "unknown material: default"
        );
        assert_eq!(s.vertex_normals[0], Some([Vec3::Z; 3]));
        assert_eq!(s.vertex_normals[1], None);
        // A broken MTL names its line; a missing one is a warning.
        std::fs::write(dir.join("m.mtl"), "newmtl red\nKd 1 0\n").unwrap();
        let e = load_obj_scene(&dir.join("s.obj")).unwrap_err();
        assert!(
            e.to_string()
                .ends_with("m.mtl:2: `Kd` needs 1 or 3 numbers, found 2"),
            "{e}"
        );
        std::fs::remove_file(dir.join("m.mtl")).unwrap();
        let s = load_obj_scene(&dir.join("s.obj")).unwrap();
        assert!(
            s.warnings.iter().any(|w| w.contains("m.mtl")),
            "{:?}",
            s.warnings
        );
        std::fs::write(dir.join("empty.obj"), "# nothing here\nv 0 0 0\n").unwrap();
        let empty = load_obj_scene(&dir.join("empty.obj")).unwrap();
        assert!(empty.shapes.is_empty());
        assert!(
            empty
                .render_warnings()
                .iter()
                .any(|w| w.contains("no geometry"))
        );
        let e = load_obj_scene(&dir.join("none.obj")).unwrap_err();
        assert!(e.to_string().contains("none.obj"));
        std::fs::remove_dir_all(&dir).ok();
    }
}
