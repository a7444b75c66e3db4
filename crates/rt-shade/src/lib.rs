//! # rt-shade: Whitted ray tracing and path tracing with any rt structure
//!
//! A scene is shapes ([`rt_geom::Shape`]: triangles, spheres, cones) with materials, lights and
//! a camera; the caller builds any [`Accel`](rt_geom::Accel) over [`Scene::shapes`] (or over
//! [`Scene::triangles`] for triangle-only structures) and calls [`render()`].
//!
//! | module | what it holds |
//! |---|---|
//! | [`camera`] | [`Camera`]: perspective (thin lens optional) and orthographic |
//! | [`material`] | [`Material`]: Lambert, Phong highlight, reflection, refraction, per channel |
//! | [`scene`] | [`Scene`], [`PointLight`], [`SceneError`], [`SceneObjects`] (objects and instances) |
//! | [`whitted`] | the Whitted integrator ([`Whitted`]), its ray rules, [`RayStats`] |
//! | [`path`] | path tracing ([`PathOptions`]): diffuse bounces, point lights sampled, emitters, Russian roulette |
//! | [`wavefront`] | the same rules level by level over a tile's rays, each level's shadow, reflected and refracted rays traced as groups ([`Queries`]) |
//! | [`render`](mod@render) | parallel tiles, supersampling, [`Image`] and PNG output |
//! | [`chess`](mod@chess) | the built-in scene: a reflective board and 32 lathed pieces, some glass; flat, per piece, or instanced ([`ChessForm`]) |
//! | [`nff`] | Haines' NFF (the SPD scenes) |
//! | [`obj`] | OBJ with MTL materials |
//! | [`triangulate`](mod@triangulate) | ear clipping of concave polygons |
//!
//! ```
//! use rt_geom::BruteForce;
//! use rt_shade::{RenderOptions, chess, render};
//!
//! let scene = chess();
//! let tris = scene.triangles().expect("the chess scene is all triangles");
//! let accel = BruteForce::build(&tris).expect("finite scene");
//! let options = RenderOptions { width: 8, height: 6, ..RenderOptions::default() };
//! let out = render(&scene, &accel, &options, &|_| {}).expect("valid scene and options");
//! assert_eq!(out.stats.eye_rays, 48);
//! assert_eq!(out.image.pixels.len(), 48);
//! ```

#![warn(missing_docs)]

pub mod camera;
pub mod chess;
pub mod material;
pub mod nff;
pub mod obj;
pub mod path;
pub mod render;
pub mod scene;
pub mod triangulate;
pub mod wavefront;
pub mod whitted;

pub use camera::{Camera, CameraFrame, Projection, ThinLens};
pub use chess::{ChessForm, chess, chess_lamp, chess_moving, chess_objects};
pub use material::Material;
pub use nff::{load_nff, parse_nff, parse_nff_bytes};
pub use obj::{load_obj_scene, parse_mtl, parse_obj_scene};
pub use path::PathOptions;
pub use render::{
    Image, Integrator, Packets, RenderOptions, Rendered, render, render_with_packets, write_png,
};
pub use scene::{ObjectShapes, PointLight, Scene, SceneError, SceneInstance, SceneObjects};
pub use triangulate::triangulate;
pub use wavefront::{Queries, SingleRays};
pub use whitted::{MAX_DEPTH, RayStats, ShadeOptions, Whitted};

/// Loads a scene by name: `chess` or `chess-lamp` (built in), or a path ending in `.obj` or
/// `.nff`.
pub fn load_scene(name: &str) -> Result<Scene, SceneError> {
    let path = std::path::Path::new(name);
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match (name, ext.as_deref()) {
        ("chess", _) => Ok(chess()),
        ("chess-lamp", _) => Ok(chess_lamp()),
        (_, Some("obj")) => load_obj_scene(path),
        (_, Some("nff")) => load_nff(path),
        _ => Err(SceneError::new(format!(
            "unknown scene '{name}': use chess, chess-lamp, a .obj file or a .nff file"
        ))),
    }
}
