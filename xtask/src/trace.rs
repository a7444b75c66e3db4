//! `cargo xtask trace`: a mesh, a ray file and a structure in; a hit file and one timing line
//! out. `cargo xtask rays` writes the standard ray sets of a mesh as ray files.

use crate::rayfile::{self, HitRecord};
use crate::registry;
use crate::run;
use rt_geom::load_obj;
use rt_testkit::RaySets;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct TraceOptions {
    pub mesh: PathBuf,
    pub rays: PathBuf,
    pub accel: String,
    pub occluded: bool,
    pub threads: usize,
    pub repeat: usize,
    /// Trace `(w, h)` tiles of a row-major image `width` pixels wide as packets.
    pub packet: Option<(usize, usize)>,
    pub width: Option<usize>,
    /// Also time each ray queried twice in a row ([`TraceSummary::warm_mrays_s`]).
    pub warm: bool,
    pub out: Option<PathBuf>,
}

/// What a trace did; [`TraceSummary::line`] is the last line `trace` prints.
#[derive(Clone, Debug, PartialEq)]
pub struct TraceSummary {
    pub rays: usize,
    pub hits: usize,
    /// Rays with a zero-length or non-finite direction, a non-finite origin or a NaN interval:
    /// traced as misses.
    pub invalid: usize,
    pub build_ms: f64,
    /// Median over the repetitions.
    pub trace_ms: f64,
    pub mrays_s: f64,
    /// With [`TraceOptions::warm`]: the rate of a ray's second query in a row (its nodes and
    /// leaves cached, its branches just seen), from the medians of the passes that query each
    /// ray twice and of those that query it once.
    pub warm_mrays_s: Option<f64>,
}

impl TraceSummary {
    pub fn line(&self) -> String {
        let warm = self
            .warm_mrays_s
            .map_or(String::new(), |w| format!(" warm_mrays_s={w:.3}"));
        format!(
            "rays={} hits={} build_ms={:.3} trace_ms={:.3} mrays_s={:.3}{warm}",
            self.rays, self.hits, self.build_ms, self.trace_ms, self.mrays_s
        )
    }
}

/// The most timed repetitions `trace` runs.
pub const MAX_REPEAT: usize = 1000;

/// Builds the structure over the mesh, traces the ray file `repeat` times (timed), and
/// writes the hits of the last pass when `out` is given (creating its folder).
pub fn trace(opts: &TraceOptions) -> Result<TraceSummary, String> {
    let entry = registry::find(&opts.accel).ok_or_else(|| registry::unknown(&opts.accel))?;
    if !(1..=MAX_REPEAT).contains(&opts.repeat) {
        return Err(format!(
            "--repeat must lie in 1..={MAX_REPEAT}, got {}",
            opts.repeat
        ));
    }
    let pool = run::pool(opts.threads)?;
    if let Some(dir) = opts.out.as_ref().and_then(|p| p.parent()) {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        }
    }
    let rays = rayfile::read_rays(&opts.rays)?;
    let mesh = load_obj(&opts.mesh).map_err(|e| e.to_string())?;
    let tris = mesh.triangles();
    let invalid = rays.iter().filter(|r| !r.is_valid()).count();
    if invalid > 0 {
        eprintln!(
            "warning: {invalid} of {} rays have a zero-length or non-finite direction, a non-finite origin or a NaN interval: traced as misses",
            rays.len()
        );
    }
    let pb = run::spinner(format!(
        "building {} over {} triangles",
        entry.name,
        tris.len()
    ));
    let start = Instant::now();
    let mut out = vec![HitRecord::MISS; rays.len()];
    let mut twice = Vec::new();
    let (build_ms, times): (f64, Vec<_>) = match opts.packet {
        None => {
            let accel =
                (entry.build)(&tris).map_err(|e| format!("{}: {e}", opts.mesh.display()))?;
            let build_ms = start.elapsed().as_secs_f64() * 1e3;
            pb.finish_and_clear();
            let trace = |runs, out: &mut [HitRecord]| {
                run::trace_into(accel.as_ref(), &rays, opts.occluded, runs, &pool, out)
            };
            let mut times = Vec::new();
            for _ in 0..opts.repeat {
                times.push(trace(1, &mut out));
                if opts.warm {
                    twice.push(trace(2, &mut out));
                }
            }
            (build_ms, times)
        }
        Some(_) if opts.warm => return Err("--warm times single rays, not --packet".into()),
        Some((w, h)) => {
            let packets = packet_tiles(entry, (w, h), opts.width, rays.len())?;
            let build = entry.packets.expect("checked by packet_tiles");
            let accel = build(&tris).map_err(|e| format!("{}: {e}", opts.mesh.display()))?;
            let build_ms = start.elapsed().as_secs_f64() * 1e3;
            pb.finish_and_clear();
            let times = (0..opts.repeat)
                .map(|_| {
                    run::trace_packets_into(
                        accel.as_ref(),
                        &rays,
                        &packets,
                        opts.occluded,
                        &pool,
                        &mut out,
                    )
                })
                .collect();
            (build_ms, times)
        }
    };
    let trace_time = run::median(times);
    // The second query of each pair: twice's time less once's.
    let warm_mrays_s = (!twice.is_empty()).then(|| {
        let second = run::median(twice).saturating_sub(trace_time);
        run::mrays_per_s(rays.len(), second)
    });
    if let Some(path) = &opts.out {
        rayfile::write_hits(path, &out)?;
    }
    Ok(TraceSummary {
        rays: rays.len(),
        hits: out.iter().filter(|h| h.is_hit()).count(),
        invalid,
        build_ms,
        trace_ms: trace_time.as_secs_f64() * 1e3,
        mrays_s: run::mrays_per_s(rays.len(), trace_time),
        warm_mrays_s,
    })
}

/// The packets (ray indices) of `--packet WxH --width N`, after checking the options.
fn packet_tiles(
    entry: &registry::AccelEntry,
    (w, h): (usize, usize),
    width: Option<usize>,
    rays: usize,
) -> Result<Vec<Vec<usize>>, String> {
    if entry.packets.is_none() {
        let with: Vec<_> = registry::REGISTRY
            .iter()
            .filter(|e| e.packets.is_some())
            .map(|e| e.name)
            .collect();
        return Err(format!(
            "{} has no packet path; these do: {}",
            entry.name,
            with.join(", ")
        ));
    }
    if w == 0 || h == 0 || w * h > rt_packet::MAX_GROUP {
        return Err(format!(
            "--packet {w}x{h}: tiles need 1 to {} rays",
            rt_packet::MAX_GROUP
        ));
    }
    let width = width.ok_or("--packet needs --width (pixels per image row)")?;
    if width == 0 {
        return Err("--width must be at least 1".into());
    }
    // Whole rows form the image and go in tiles; rays after the last whole row (other ray sets
    // of the file) go in file order, `w * h` per packet.
    let rows = rays / width;
    let mut groups = rt_packet::tiles(width, rows, w, h);
    let tail: Vec<usize> = (rows * width..rays).collect();
    groups.extend(tail.chunks(w * h).map(<[usize]>::to_vec));
    Ok(groups)
}

#[derive(Clone, Debug)]
pub struct RaysOptions {
    pub mesh: PathBuf,
    /// `primary`, `shadow`, `diffuse` or `all` (concatenated in that order).
    pub set: String,
    pub size: usize,
    pub out: PathBuf,
}

/// Writes a standard ray set of a mesh (camera of the mesh's standard view, named by its file
/// stem; shadow and diffuse rays from the camera hits, found with obvhs). Returns the ray count.
pub fn write_standard_rays(opts: &RaysOptions) -> Result<usize, String> {
    if opts.size == 0 || opts.size > 16384 {
        return Err(format!("--size {} out of range 1..=16384", opts.size));
    }
    let mesh = load_obj(&opts.mesh).map_err(|e| e.to_string())?;
    let tris = mesh.triangles();
    let name = opts
        .mesh
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let reference =
        (registry::find("obvhs").expect("registered").build)(&tris).map_err(|e| e.to_string())?;
    let sets = RaySets::generate(&name, &tris, reference.as_ref(), opts.size, opts.size, 1);
    let rays = match opts.set.as_str() {
        "all" => [&sets.primary[..], &sets.shadow, &sets.diffuse].concat(),
        s => sets
            .by_name(s)
            .ok_or_else(|| format!("unknown ray set '{s}': primary, shadow, diffuse or all"))?
            .to_vec(),
    };
    rayfile::write_rays(&opts.out, &rays)?;
    Ok(rays.len())
}
