//! Triangle meshes from Wavefront OBJ (through `tobj`).
//!
//! Primitive ids follow the file: faces in file order across all objects and groups, polygons
//! fan-triangulated as `(v0, vi, vi+1)`. Zero-area triangles are kept (ids stay stable); the
//! kernels never report them as hits.

use crate::{Aabb, Triangle};
use glam::Vec3;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// An indexed triangle mesh with its OBJ objects/groups as ranges of triangles.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles as vertex indices, in file order.
    pub indices: Vec<[u32; 3]>,
    /// Objects and groups of the file, in file order, as ranges of triangle ids.
    pub groups: Vec<MeshGroup>,
}

/// A named range of triangles (an OBJ `o` or `g`).
#[derive(Clone, Debug, PartialEq)]
pub struct MeshGroup {
    /// The object or group name from the file.
    pub name: String,
    /// Its triangles in [`Mesh::indices`].
    pub triangles: Range<usize>,
}

impl Mesh {
    /// The triangles, by id.
    pub fn triangles(&self) -> Vec<Triangle> {
        self.indices
            .iter()
            .map(|&[a, b, c]| {
                Triangle::new(
                    self.positions[a as usize],
                    self.positions[b as usize],
                    self.positions[c as usize],
                )
            })
            .collect()
    }

    /// The box around every vertex.
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(self.positions.iter().copied())
    }

    /// Triangles with zero area (kept, never hit).
    pub fn degenerate_count(&self) -> usize {
        self.triangles()
            .iter()
            .filter(|t| t.is_degenerate())
            .count()
    }
}

/// Why an OBJ file could not be loaded. Every variant names the file; `line` is 1-based.
#[derive(Debug)]
pub enum MeshError {
    /// The file could not be read.
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A line that is not valid OBJ (bad number, bad face, ...).
    Malformed {
        /// The file.
        path: PathBuf,
        /// The line, where known.
        line: Option<usize>,
        /// What is wrong.
        what: String,
    },
    /// A vertex with a NaN or infinite coordinate.
    NonFinite {
        /// The file.
        path: PathBuf,
        /// The line, where known.
        line: Option<usize>,
    },
    /// A face refers to a vertex, texture coordinate or normal that does not exist.
    IndexOutOfRange {
        /// The file.
        path: PathBuf,
        /// The line, where known.
        line: Option<usize>,
    },
    /// The file holds no face.
    NoTriangles {
        /// The file.
        path: PathBuf,
    },
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let at = |path: &Path, line: &Option<usize>| match line {
            Some(l) => format!("{}:{l}", path.display()),
            None => path.display().to_string(),
        };
        match self {
            MeshError::Io { path, source } => write!(f, "{}: {source}", path.display()),
            MeshError::Malformed { path, line, what } => {
                write!(f, "{}: malformed OBJ: {what}", at(path, line))
            }
            MeshError::NonFinite { path, line } => {
                write!(
                    f,
                    "{}: vertex with a NaN or infinite coordinate",
                    at(path, line)
                )
            }
            MeshError::IndexOutOfRange { path, line } => {
                write!(
                    f,
                    "{}: face refers to a vertex, texture coordinate or normal that does not exist",
                    at(path, line)
                )
            }
            MeshError::NoTriangles { path } => write!(f, "{}: no faces in file", path.display()),
        }
    }
}

impl std::error::Error for MeshError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            MeshError::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

impl MeshError {
    /// The file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            MeshError::Io { path, .. }
            | MeshError::Malformed { path, .. }
            | MeshError::NonFinite { path, .. }
            | MeshError::IndexOutOfRange { path, .. }
            | MeshError::NoTriangles { path } => path,
        }
    }
}

/// Loads an OBJ file (positions and faces; materials, normals and texture coordinates are not
/// read here).
pub fn load_obj(path: impl AsRef<Path>) -> Result<Mesh, MeshError> {
    let path = path.as_ref();
    let text = std::fs::read(path).map_err(|source| MeshError::Io {
        path: path.to_owned(),
        source,
    })?;
    parse_obj(&text, path)
}

/// Parses OBJ text; `path` only names the source in errors.
pub fn parse_obj(text: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    // tobj resolves an out-of-range texture or normal index past the end of its arrays
    // (wrapping arithmetic): such faces are errors here, before it reads them.
    if let Some(line) = first_bad_face(text, true) {
        return Err(MeshError::IndexOutOfRange {
            path: path.to_owned(),
            line: Some(line),
        });
    }
    let mut reader = std::io::BufReader::new(text);
    let loaded = tobj::load_obj_buf(&mut reader, &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    });
    let models = match loaded {
        Ok((models, _materials)) => models,
        Err(e) => return Err(diagnose(text, path, e)),
    };
    let mut mesh = Mesh::default();
    for model in models {
        let m = &model.mesh;
        let base = mesh.positions.len() as u32;
        let first = mesh.indices.len();
        mesh.positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2])),
        );
        mesh.indices.extend(
            m.indices
                .chunks_exact(3)
                .map(|t| [base + t[0], base + t[1], base + t[2]]),
        );
        mesh.groups.push(MeshGroup {
            name: model.name,
            triangles: first..mesh.indices.len(),
        });
    }
    if mesh.positions.iter().any(|p| !p.is_finite()) {
        // tobj renumbers vertices per object: find the first non-finite `v` line of the file.
        return Err(MeshError::NonFinite {
            path: path.to_owned(),
            line: first_line(text, |kw, rest| kw == "v" && !vertex_is_finite(rest)),
        });
    }
    if mesh.indices.is_empty() {
        return Err(MeshError::NoTriangles {
            path: path.to_owned(),
        });
    }
    Ok(mesh)
}

/// Turns a `tobj` error into one that names the line, by scanning the text for the first line
/// that shows that error.
fn diagnose(text: &[u8], path: &Path, e: tobj::LoadError) -> MeshError {
    use tobj::LoadError as E;
    let path = path.to_owned();
    match e {
        E::FaceVertexOutOfBounds => MeshError::IndexOutOfRange {
            line: first_bad_face(text, true),
            path,
        },
        E::PositionParseError => MeshError::Malformed {
            line: first_line(text, |kw, rest| kw == "v" && !vertex_parses(rest)),
            path,
            what: "vertex position needs 3 numbers".into(),
        },
        E::FaceParseError | E::InvalidPolygon => MeshError::Malformed {
            line: first_bad_face(text, false),
            path,
            what: "face needs vertex indices".into(),
        },
        E::NormalParseError => MeshError::Malformed {
            line: first_line(text, |kw, rest| kw == "vn" && !vertex_parses(rest)),
            path,
            what: "normal needs 3 numbers".into(),
        },
        E::TexcoordParseError => MeshError::Malformed {
            line: first_line(text, |kw, _| kw == "vt"),
            path,
            what: "texture coordinate".into(),
        },
        E::ReadError | E::UnrecognizedCharacter => MeshError::Malformed {
            line: text
                .split(|&b| b == b'\n')
                .position(|l| std::str::from_utf8(l).is_err())
                .map(|i| i + 1),
            path,
            what: "not UTF-8 text".into(),
        },
        other => MeshError::Malformed {
            line: None,
            path,
            what: other.to_string(),
        },
    }
}

/// 1-based number of the first line whose keyword and rest satisfy `bad`.
fn first_line(text: &[u8], mut bad: impl FnMut(&str, &str) -> bool) -> Option<usize> {
    for (i, line) in String::from_utf8_lossy(text).lines().enumerate() {
        let line = line.trim();
        let (kw, rest) = line.split_once(char::is_whitespace).unwrap_or((line, ""));
        if bad(kw, rest.trim()) {
            return Some(i + 1);
        }
    }
    None
}

fn vertex_parses(rest: &str) -> bool {
    let n: Vec<_> = rest.split_whitespace().collect();
    n.len() >= 3 && n.iter().all(|x| x.parse::<f32>().is_ok())
}

fn vertex_is_finite(rest: &str) -> bool {
    rest.split_whitespace()
        .take(3)
        .all(|x| x.parse::<f32>().is_ok_and(f32::is_finite))
}

/// The first face with an unparsable vertex index (`range_only == false`) or the first face,
/// line or point with an index of a vertex, texture coordinate or normal that does not exist
/// (`range_only == true`; OBJ indices are 1-based, negative ones count back from the last
/// defined so far).
fn first_bad_face(text: &[u8], range_only: bool) -> Option<usize> {
    const KINDS: [&str; 3] = ["v", "vt", "vn"];
    let mut total = [0i64; 3];
    first_line(text, |kw, _| {
        if let Some(k) = KINDS.iter().position(|&x| x == kw) {
            total[k] += 1;
        }
        false
    });
    let mut so_far = [0i64; 3];
    first_line(text, |kw, rest| {
        if let Some(k) = KINDS.iter().position(|&x| x == kw) {
            so_far[k] += 1;
            return false;
        }
        // Lines and points are ignored, but tobj resolves their indices too.
        if kw != "f" && !(range_only && (kw == "l" || kw == "p")) {
            return false;
        }
        if !range_only {
            let idx: Vec<Option<i64>> = rest
                .split_whitespace()
                .map(|c| c.split('/').next().and_then(|s| s.parse().ok()))
                .collect();
            return idx.len() < 3 || idx.iter().any(Option::is_none);
        }
        rest.split_whitespace().any(|corner| {
            corner.split('/').enumerate().any(|(k, s)| {
                let Ok(i) = s.parse::<i64>() else {
                    return false;
                };
                let abs = if i < 0 {
                    so_far[k.min(2)].saturating_add(1).saturating_add(i)
                } else {
                    i
                };
                abs < 1 || abs > total[k.min(2)]
            })
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<Mesh, MeshError> {
        parse_obj(s.as_bytes(), Path::new("test.obj"))
    }

    /// Relative texture and normal indices before the first ones defined (found by fuzzing:
    /// tobj wraps them around).
    #[test]
    fn texture_and_normal_indices_out_of_range_are_errors() {
        for (text, line) in [
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/-3 3\n", 5),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2//1 3//1\nvn 0 0 1\nf 1//2 2//1 3//1\n",
                6,
            ),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/0 2/1 3/1\n", 5),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nl 1//-31 2\nf 1 2 3\n",
                5,
            ),
        ] {
            match parse(text) {
                Err(MeshError::IndexOutOfRange { line: l, .. }) => {
                    assert_eq!(l, Some(line), "{text}")
                }
                other => panic!("{text}: {other:?}"),
            }
        }
    }

    #[test]
    fn fan_triangulation_and_groups_in_file_order() {
        let m = parse(
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\n\
             o first\nf 1 2 3 4\ng second\nf 1 2 5\nf 5 4 1\n",
        )
        .unwrap();
        assert_eq!(m.indices.len(), 4);
        let t = m.triangles();
        // Quad fan: (v0, v1, v2), (v0, v2, v3).
        assert_eq!(t[0].v, [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)]);
        assert_eq!(t[1].v, [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y]);
        assert_eq!(t[2].v, [Vec3::ZERO, Vec3::X, Vec3::Z]);
        assert_eq!(t[3].v, [Vec3::Z, Vec3::Y, Vec3::ZERO]);
        assert_eq!(m.groups.len(), 2);
        assert_eq!(m.groups[0].name, "first");
        assert_eq!(m.groups[0].triangles, 0..2);
        assert_eq!(m.groups[1].triangles, 2..4);
    }

    #[test]
    fn pentagon_fans_from_first_vertex() {
        let m = parse("v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nf 1 2 3 4 5\n").unwrap();
        let ids: Vec<_> = m
            .indices
            .iter()
            .map(|t| t.map(|i| m.positions[i as usize]))
            .collect();
        assert_eq!(ids.len(), 3);
        for (k, t) in ids.iter().enumerate() {
            assert_eq!(t[0], Vec3::ZERO);
            assert_eq!(t[1], m.positions[m.indices[k][1] as usize]);
        }
        assert_eq!(ids[2][2], Vec3::Y);
    }

    #[test]
    fn degenerate_triangles_are_kept() {
        let m = parse("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n").unwrap();
        assert_eq!(m.indices.len(), 2);
        assert_eq!(m.degenerate_count(), 1);
    }

    #[test]
    fn errors_name_file_and_line() {
        let e = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n").unwrap_err();
        assert!(
            matches!(e, MeshError::IndexOutOfRange { line: Some(4), .. }),
            "{e}"
        );
        assert!(e.to_string().starts_with("test.obj:4:"), "{e}");

        let e = parse("v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n").unwrap_err();
        assert!(
            matches!(e, MeshError::Malformed { line: Some(2), .. }),
            "{e}"
        );

        let e = parse("v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n").unwrap_err();
        assert!(
            matches!(e, MeshError::NonFinite { line: Some(3), .. }),
            "{e}"
        );

        let e = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n").unwrap_err();
        assert!(
            matches!(e, MeshError::Malformed { line: Some(4), .. }),
            "{e}"
        );

        assert!(matches!(
            parse("").unwrap_err(),
            MeshError::NoTriangles { .. }
        ));
        assert!(matches!(
            parse("# nothing\nv 1 2 3\n").unwrap_err(),
            MeshError::NoTriangles { .. }
        ));

        let e = load_obj("/definitely/not/here.obj").unwrap_err();
        assert!(matches!(e, MeshError::Io { .. }));
        assert!(e.to_string().contains("/definitely/not/here.obj"));
    }
}
