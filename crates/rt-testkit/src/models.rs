//! The shared test meshes (`../shared/models`: bunny, dragon, sponza, teapot). They are never
//! copied into the repository; tests that need them skip, saying so, when they are absent,
//! unless `RT_REQUIRE_SHARED=1` (CI sets it), which turns every such skip into a failure.

use rt_geom::{Mesh, MeshError};
use std::path::PathBuf;

/// The standard meshes, smallest first.
pub const MODEL_NAMES: [&str; 4] = ["teapot", "bunny", "sponza", "dragon"];

/// The models directory: `$RT_MODELS` if set, else `shared/models` or `../shared/models` found
/// from the workspace root upwards.
pub fn models_dir() -> Option<PathBuf> {
    if let Some(dir) = std::env::var_os("RT_MODELS") {
        let dir = PathBuf::from(dir);
        return dir.is_dir().then_some(dir);
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    for base in [root.clone(), root.join("..")] {
        let dir = base.join("shared/models");
        if dir.join("teapot.obj").is_file() {
            return dir.canonicalize().ok();
        }
    }
    None
}

/// Path of a standard model, if the shared models are present.
pub fn model_path(name: &str) -> Option<PathBuf> {
    let p = models_dir()?.join(format!("{name}.obj"));
    p.is_file().then_some(p)
}

/// Whether `RT_REQUIRE_SHARED=1`: the shared meshes and scenes must be there.
pub fn shared_required() -> bool {
    std::env::var("RT_REQUIRE_SHARED").is_ok_and(|v| v == "1")
}

/// Says that a test skips `what` (shared data it did not find); panics instead when
/// `RT_REQUIRE_SHARED=1`, so that a run that must have the data cannot pass without it.
pub fn skip(what: &str) {
    let message = format!("skipping: {what}");
    if shared_required() {
        panic!("{message}, and RT_REQUIRE_SHARED=1 requires it");
    }
    eprintln!("{message}");
}

/// Loads a standard model; `Ok(None)` (after [`skip`]) when the shared models are absent.
pub fn load_model(name: &str) -> Result<Option<Mesh>, MeshError> {
    match model_path(name) {
        Some(p) => rt_geom::load_obj(p).map(Some),
        None => {
            skip(&format!(
                "model {name} not found (looked in $RT_MODELS and ../shared/models)"
            ));
            Ok(None)
        }
    }
}

/// The standard SPD scenes of `../shared/scenes/spd` (NFF), at the SPD's benchmark sizes.
pub const SPD_NAMES: [&str; 9] = [
    "balls", "gears", "mount", "rings", "teapot", "tetra", "tree", "lattice", "shells",
];

/// Path of an SPD scene (`../shared/scenes/spd/NAME.nff`, or `$RT_SPD/NAME.nff`), if present.
pub fn spd_path(name: &str) -> Option<PathBuf> {
    let dir = match std::env::var_os("RT_SPD") {
        Some(dir) => PathBuf::from(dir),
        None => models_dir()?.join("../scenes/spd"),
    };
    let p = dir.join(format!("{name}.nff"));
    p.is_file().then_some(p)
}
