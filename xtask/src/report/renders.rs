//! The SPD scenes rendered with every structure that holds spheres and cones.

use super::SPD_ACCELS;

/// One SPD scene rendered with one structure.
pub struct SpdRow {
    pub scene: String,
    pub prims: usize,
    pub accel: String,
    pub size: u32,
    pub build_ms: f64,
    pub seconds: f64,
    pub rays: u64,
}

/// Renders every SPD scene present with each of [`SPD_ACCELS`] (on all cores).
pub(super) fn spd_renders(quick: bool) -> Result<Vec<SpdRow>, String> {
    // The full report adds the larger sizes of balls, tetra and mount (the same scenes with 9,
    // 16 to 64 and 16 times the primitives): a scaling series on real scenes.
    let names: Vec<&str> = if quick {
        vec!["balls", "gears", "tree"]
    } else {
        let mut v = rt_testkit::models::SPD_NAMES.to_vec();
        v.extend([
            "balls-size5",
            "balls-size6",
            "tetra-size8",
            "tetra-size9",
            "mount-size8",
        ]);
        v
    };
    let size = if quick { 96 } else { 256 };
    let accels = crate::registry::select(Some(SPD_ACCELS))?;
    let found: Vec<_> = names
        .iter()
        .filter_map(|n| rt_testkit::models::spd_path(n).map(|p| (*n, p)))
        .collect();
    let pb = crate::run::bar((found.len() * accels.len()) as u64, "SPD renders");
    let mut rows = Vec::new();
    for (name, path) in found {
        let scene = rt_shade::load_nff(&path).map_err(|e| e.to_string())?;
        let options = rt_shade::RenderOptions {
            width: size,
            height: size,
            ..Default::default()
        };
        for entry in &accels {
            pb.set_message(format!("{name} {}", entry.name));
            let start = std::time::Instant::now();
            let accel = entry.build_any(&scene.shapes)?;
            let build_ms = start.elapsed().as_secs_f64() * 1e3;
            let out = rt_shade::render(&scene, accel.as_ref(), &options, &|_| {})
                .map_err(|e| e.to_string())?;
            rows.push(SpdRow {
                scene: name.to_string(),
                prims: scene.shapes.len(),
                accel: entry.name.to_string(),
                size,
                build_ms,
                seconds: out.seconds,
                rays: out.stats.total(),
            });
            pb.inc(1);
        }
    }
    pb.finish_and_clear();
    Ok(rows)
}
