//! A renderable scene: shapes with materials and optional vertex normals, lights, a camera.

use crate::{Camera, Material};
use glam::{Affine3A, Vec3, Vec3A};
use rt_geom::{Aabb, Primitive, Shape, Triangle};
use std::fmt;
use std::path::{Path, PathBuf};

/// A point light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    /// Position.
    pub position: Vec3,
    /// Intensity per channel.
    pub colour: Vec3,
}

/// Everything a render needs except the acceleration structure (which the caller builds over
/// [`Scene::shapes`], so that any structure can render any scene).
///
/// Primitive ids are indices into `shapes`; `material_of` and `vertex_normals` are indexed by
/// the same ids.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Name, for messages.
    pub name: String,
    /// The camera.
    pub camera: Camera,
    /// The image size the scene asks for (NFF's `resolution`), if any.
    pub resolution: Option<(u32, u32)>,
    /// Colour of rays that hit nothing.
    pub background: Vec3,
    /// Ambient light, multiplied by each material's ambient coefficient.
    pub ambient: Vec3,
    /// Point lights.
    pub lights: Vec<PointLight>,
    /// Materials, indexed per primitive.
    pub materials: Vec<Material>,
    /// The primitives.
    pub shapes: Vec<Shape>,
    /// Material index of each shape.
    pub material_of: Vec<u32>,
    /// Per-vertex normals of triangles with smooth shading (OBJ `vn`, NFF `pp`, lathed pieces).
    pub vertex_normals: Vec<Option<[Vec3; 3]>>,
    /// Things the loader skipped or guessed, for the user (unknown MTL statements, ...).
    pub warnings: Vec<String>,
}

/// A scene's geometry as objects placed by instances: what two-level structures are built
/// from. Flattened instance by instance, in order ([`SceneObjects::flatten_into`]), the
/// instances' shapes are the scene's [`Scene::shapes`], so a two-level structure's global
/// primitive ids index the scene's materials and normals.
#[derive(Clone, Debug, Default)]
pub struct SceneObjects {
    /// The objects, each in its own space.
    pub objects: Vec<ObjectShapes>,
    /// Where each object is placed.
    pub instances: Vec<SceneInstance>,
}

/// An object's shapes (triangles), in its own space, with their vertex normals and materials.
#[derive(Clone, Debug, Default)]
pub struct ObjectShapes {
    /// The triangles (as shapes, so structures over shapes take them).
    pub shapes: Vec<Shape>,
    /// Per shape, its vertex normals.
    pub normals: Vec<Option<[Vec3; 3]>>,
    /// Per shape, its material (unless the instance gives one).
    pub materials: Vec<u32>,
}

impl ObjectShapes {
    /// Shapes `range` of `scene`, with their normals and materials.
    pub fn from_scene(scene: &Scene, range: std::ops::Range<usize>) -> Self {
        Self {
            shapes: scene.shapes[range.clone()].to_vec(),
            normals: scene.vertex_normals[range.clone()].to_vec(),
            materials: scene.material_of[range].to_vec(),
        }
    }
}

/// An object placed in the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneInstance {
    /// Index into [`SceneObjects::objects`].
    pub object: u32,
    /// Object space to world space (orientation-preserving: triangles keep their winding).
    pub transform: Affine3A,
    /// The material of all its shapes, or `None` for the object's own.
    pub material: Option<u32>,
}

impl SceneObjects {
    /// Appends every instance's shapes to `scene`, in world space: triangles by the transform,
    /// vertex normals by its inverse transpose, with their materials. Shapes other than
    /// triangles are left out.
    pub fn flatten_into(&self, scene: &mut Scene) {
        for inst in &self.instances {
            let o = &self.objects[inst.object as usize];
            let t = inst.transform;
            let normals = t.matrix3.inverse().transpose();
            for ((shape, n), &m) in o.shapes.iter().zip(&o.normals).zip(&o.materials) {
                if let Some(tri) = shape.as_triangle() {
                    let moved = Triangle {
                        v: tri.v.map(|p| t.transform_point3(p)),
                    };
                    let n = n.map(|n| n.map(|n| Vec3::from(normals * Vec3A::from(n))));
                    scene.add(moved, inst.material.unwrap_or(m), n);
                }
            }
        }
    }

    /// The instances' triangles in world space, instance by instance (as
    /// [`SceneObjects::flatten_into`] places them).
    pub fn flattened_triangles(&self) -> Vec<Triangle> {
        let mut s = Scene::new(
            "flat",
            Camera::perspective(Vec3::Z, Vec3::ZERO, Vec3::Y, 40.0),
        );
        self.flatten_into(&mut s);
        s.triangles().unwrap_or_default()
    }
}

/// Why a scene could not be loaded or used. Names the file and the 1-based line when there is one.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    /// The file, where there is one.
    pub path: Option<PathBuf>,
    /// The line, where known.
    pub line: Option<usize>,
    /// What is wrong.
    pub what: String,
}

impl SceneError {
    /// An error with no file.
    pub fn new(what: impl Into<String>) -> Self {
        Self {
            path: None,
            line: None,
            what: what.into(),
        }
    }

    /// An error at a line of a file.
    pub fn at(path: &Path, line: usize, what: impl Into<String>) -> Self {
        Self {
            path: Some(path.to_owned()),
            line: Some(line),
            what: what.into(),
        }
    }

    /// An error about a whole file.
    pub fn in_file(path: &Path, what: impl Into<String>) -> Self {
        Self {
            path: Some(path.to_owned()),
            line: None,
            what: what.into(),
        }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (&self.path, self.line) {
            (Some(p), Some(l)) => write!(f, "{}:{l}: {}", p.display(), self.what),
            (Some(p), None) => write!(f, "{}: {}", p.display(), self.what),
            _ => f.write_str(&self.what),
        }
    }
}

impl std::error::Error for SceneError {}

impl Scene {
    /// An empty scene with this camera: black background, no lights.
    pub fn new(name: impl Into<String>, camera: Camera) -> Self {
        Self {
            name: name.into(),
            camera,
            resolution: None,
            background: Vec3::ZERO,
            ambient: Vec3::splat(0.1),
            lights: Vec::new(),
            materials: Vec::new(),
            shapes: Vec::new(),
            material_of: Vec::new(),
            vertex_normals: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// Adds a material; returns its index.
    pub fn add_material(&mut self, m: Material) -> u32 {
        self.materials.push(m);
        (self.materials.len() - 1) as u32
    }

    /// Adds a shape with a material and, for triangles, optional vertex normals.
    pub fn add(&mut self, shape: impl Into<Shape>, material: u32, normals: Option<[Vec3; 3]>) {
        self.shapes.push(shape.into());
        self.material_of.push(material);
        self.vertex_normals.push(normals);
    }

    /// Adds a triangle wound so that its normal points along `outward` (vertices and normals
    /// swapped when it does not); zero-area triangles are skipped.
    pub fn add_facing(
        &mut self,
        t: Triangle,
        outward: Vec3,
        material: u32,
        normals: Option<[Vec3; 3]>,
    ) {
        if t.is_degenerate() {
            return;
        }
        if t.cross().dot(outward) >= 0.0 {
            self.add(t, material, normals);
        } else {
            let [a, b, c] = t.v;
            self.add(
                Triangle::new(a, c, b),
                material,
                normals.map(|[na, nb, nc]| [na, nc, nb]),
            );
        }
    }

    /// Adds a planar quad `a b c d` as two triangles facing `outward`.
    pub fn add_quad(&mut self, [a, b, c, d]: [Vec3; 4], outward: Vec3, material: u32) {
        self.add_facing(Triangle::new(a, b, c), outward, material, None);
        self.add_facing(Triangle::new(a, c, d), outward, material, None);
    }

    /// Adds the axis-aligned box `[lo, hi]` as 12 triangles facing outwards (flat shaded).
    pub fn add_box(&mut self, lo: Vec3, hi: Vec3, material: u32) {
        let (centre, half) = ((lo + hi) * 0.5, (hi - lo) * 0.5);
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let n = Vec3::AXES[axis] * sign;
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let c = centre + n * half[axis];
                let (du, dv) = (Vec3::AXES[u] * half[u], Vec3::AXES[v] * half[v]);
                self.add_quad(
                    [c - du - dv, c + du - dv, c + du + dv, c - du + dv],
                    n,
                    material,
                );
            }
        }
    }

    /// The scene's shapes as triangles, when every shape is one (so that triangle-only
    /// structures can render it with the same primitive ids).
    pub fn triangles(&self) -> Option<Vec<Triangle>> {
        self.shapes
            .iter()
            .map(|s| s.as_triangle().copied())
            .collect()
    }

    /// The box around every primitive.
    pub fn bounds(&self) -> Aabb {
        self.shapes
            .iter()
            .fold(Aabb::EMPTY, |b, s| b.union(s.bounds()))
    }

    /// How far secondary rays start from the surface they leave: relative to the scene's size
    /// and to the magnitude of its coordinates (no absolute epsilon).
    pub fn ray_offset(&self) -> f32 {
        let b = self.bounds();
        if b.is_empty() || !b.is_finite() {
            return 0.0;
        }
        let size = b.extent().length();
        let magnitude = b.min.abs().max(b.max.abs()).max_element();
        1e-5 * size + 1e-6 * magnitude
    }

    /// The first problem that makes the scene unusable (bad camera, material index out of
    /// range, NaN in a light or material), as a clear message.
    pub fn check(&self) -> Result<(), SceneError> {
        self.camera.check().map_err(SceneError::new)?;
        let n = self.shapes.len();
        if self.material_of.len() != n || self.vertex_normals.len() != n {
            return Err(SceneError::new(
                "material and normal lists must match the shapes",
            ));
        }
        if let Some(&m) = self
            .material_of
            .iter()
            .find(|&&m| m as usize >= self.materials.len())
        {
            return Err(SceneError::new(format!("material index {m} out of range")));
        }
        for (i, m) in self.materials.iter().enumerate() {
            m.check()
                .map_err(|e| SceneError::new(format!("material {i}: {e}")))?;
        }
        for l in &self.lights {
            if !(l.position.is_finite() && l.colour.is_finite()) {
                return Err(SceneError::new("light with a NaN or infinite value"));
            }
        }
        if !(self.background.is_finite() && self.ambient.is_finite()) {
            return Err(SceneError::new(
                "background or ambient colour is not finite",
            ));
        }
        if let Some(i) = self.shapes.iter().position(|s| !s.is_finite()) {
            return Err(SceneError::new(format!(
                "shape {i} has a NaN or infinite coordinate"
            )));
        }
        Ok(())
    }

    /// Warnings a render of this scene deserves (no lights, no geometry) beside the loader's.
    pub fn render_warnings(&self) -> Vec<String> {
        let mut w = self.warnings.clone();
        if self.shapes.is_empty() {
            w.push(format!(
                "scene '{}' has no geometry: the image is background only",
                self.name
            ));
        }
        if self.lights.is_empty() {
            w.push(format!(
                "scene '{}' has no lights: only ambient light and reflections",
                self.name
            ));
        }
        w
    }
}
