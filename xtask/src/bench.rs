//! `cargo xtask bench`: build time, throughput, memory and SAH cost of every structure on every
//! scene and ray set, per thread count, beside obvhs measured in the same run.

use crate::registry::{self, AccelEntry};
use crate::run;
pub use crate::table::Record;
use rt_geom::{Accel, Ray, Triangle, Vec3};
use rt_testkit::{RaySets, models, scenes};
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub quick: bool,
    pub accels: Option<String>,
    pub scenes: Option<String>,
    pub json: Option<PathBuf>,
    pub threads: Vec<usize>,
}

/// The scenes `bench` knows: the shared meshes and procedural ones.
pub fn scene_names() -> Vec<&'static str> {
    let mut v: Vec<&str> = models::MODEL_NAMES.to_vec();
    v.extend(["soup-100k", "sphere-200k", "stadium-100k"]);
    v
}

/// A `bench` scene by name; `Ok(None)` when it is a shared mesh and the shared models are absent.
pub fn load_scene(name: &str) -> Result<Option<Vec<Triangle>>, String> {
    Ok(Some(match name {
        "soup-100k" => scenes::random_soup(100_000, 11),
        "soup-20k" => scenes::random_soup(20_000, 11),
        "sphere-200k" => scenes::tessellated_sphere(200_000, Vec3::ZERO, 1.0),
        // A dense teapot in a large sparse stadium: the case uniform grids are known to lose.
        "stadium-100k" => scenes::teapot_in_stadium(100_000),
        _ if models::MODEL_NAMES.contains(&name) => {
            match models::load_model(name).map_err(|e| e.to_string())? {
                Some(m) => m.triangles(),
                None => return Ok(None),
            }
        }
        _ => {
            return Err(format!(
                "unknown scene '{name}'; known: {}",
                scene_names().join(", ")
            ));
        }
    }))
}

fn default_scenes(quick: bool) -> Vec<&'static str> {
    let have_models = models::models_dir().is_some();
    match (quick, have_models) {
        (true, true) => vec!["teapot"],
        (true, false) => vec!["soup-20k"],
        (false, true) => vec!["teapot", "bunny", "sponza", "dragon"],
        (false, false) => vec!["soup-100k", "sphere-200k"],
    }
}

/// The peers every bench measures in the same run (those registered: Embree's two modes only
/// with the `embree` feature), so that every ratio has its reference.
const PEERS: [&str; 5] = [
    "obvhs-cwbvh",
    "embree",
    "embree-fast",
    "embree-medium",
    "tinybvh",
];

/// Time budget of one timed repetition; larger ray sets are subsampled to fit it.
const REP_BUDGET: Duration = Duration::from_millis(1500);

pub fn bench(opts: &BenchOptions) -> Result<Vec<Record>, String> {
    let entries = registry::select(opts.accels.as_deref())?;
    eprintln!("measuring the {}", crate::native::build_description());
    let scene_list: Vec<String> = match &opts.scenes {
        Some(s) => s.split(',').map(|x| x.trim().to_string()).collect(),
        None => default_scenes(opts.quick)
            .iter()
            .map(|s| s.to_string())
            .collect(),
    };
    let (size, reps) = if opts.quick {
        (128, Reps::QUICK)
    } else {
        (1024, Reps::FULL)
    };
    let pools: Vec<_> = opts
        .threads
        .iter()
        .map(|&t| run::pool(t).map(|p| (t, p)))
        .collect::<Result<_, _>>()?;
    // The peers are always measured: every ratio is against one of them, in the same run
    // (obvhs; Embree and tinybvh when their features register them).
    let mut measured: Vec<&AccelEntry> = entries.clone();
    for name in PEERS {
        if let Some(e) = registry::find(name) {
            if name == "tinybvh" && !cfg!(target_feature = "avx2") {
                eprintln!(
                    "tinybvh left out: tinybvh-rs runs BVH8_CPU only in AVX2 builds (--native)"
                );
                continue;
            }
            if !measured.iter().any(|m| m.name == name) {
                measured.push(e);
            }
        }
    }
    eprintln!(
        "bench: {} structures x {} scenes x 3 ray sets x threads {:?}; {size}x{size} camera, median of {}",
        measured.len(),
        scene_list.len(),
        opts.threads,
        reps.count
    );
    let mut records = Vec::new();
    for scene in &scene_list {
        let Some(tris) = load_scene(scene)? else {
            continue;
        };
        let reference_entry = registry::find("obvhs").expect("registered");
        let pb = run::spinner(format!("{scene}: rays from the reference"));
        let reference = (reference_entry.build)(&tris).map_err(|e| e.to_string())?;
        let sets = RaySets::generate(scene, &tris, reference.as_ref(), size, size, 3);
        drop(reference);
        pb.finish_and_clear();
        let runnable: Vec<_> = measured
            .iter()
            .filter(|e| tris.len() <= e.bench_max_prims)
            .collect();
        let pb = run::bar((runnable.len() * 3 * pools.len()) as u64, scene.clone());
        // Every structure is built (and its packets measured) first; the single rays are then
        // timed round by round, each round every structure in turn, so that all of them
        // meet the same moments of a shared machine (its load swings over seconds, and a
        // ratio between two structures timed minutes apart carries those swings).
        let mut singles = Vec::new();
        for entry in runnable {
            pb.set_message(format!("{} build", entry.name));
            let start = Instant::now();
            // Built in the largest pool: parallel builders (and Embree's device) use its threads.
            let build_pool = &pools.last().expect("at least one thread count").1;
            let accel = build_pool
                .install(|| (entry.build)(&tris))
                .map_err(|e| format!("{}: {e}", entry.name))?;
            let build_ms = start.elapsed().as_secs_f64() * 1e3;
            let stats = accel.stats();
            // One measurement of this structure on this scene (ratios are filled in later).
            let record = Measured {
                accel: entry.name,
                scene,
                build_ms,
                bytes: stats.bytes,
                sah_cost: stats.sah_cost,
                prims: tris.len(),
            };
            // Structures with a packet path: primary rays as image tiles, and the shadow and
            // diffuse rays of those tiles' pixels (`primary-WxH`, `shadow-WxH`, `diffuse-WxH`
            // records beside the single-ray ones; incoherent groups fall back to single rays).
            if let Some(build_packets) = entry.packets {
                let packets = build_pool
                    .install(|| build_packets(&tris))
                    .map_err(|e| format!("{}: {e}", entry.name))?;
                let sides: &[usize] = if opts.quick {
                    &[8]
                } else {
                    &rt_packet::TILE_SIDES
                };
                for &side in sides {
                    let tiles = rt_packet::tiles(size, size, side, side);
                    let shadow_tiles = sets.secondary_groups(&tiles);
                    for (set, rays, groups) in [
                        ("primary", &sets.primary, &tiles),
                        ("shadow", &sets.shadow, &shadow_tiles),
                        ("diffuse", &sets.diffuse, &shadow_tiles),
                    ] {
                        let occluded = set == "shadow";
                        for (threads, pool) in &pools {
                            pb.set_message(format!(
                                "{} {set} {side}x{side} packets x{threads}",
                                entry.name
                            ));
                            let (rate, hits) = measure_packets(
                                packets.as_ref(),
                                rays,
                                groups,
                                occluded,
                                pool,
                                reps,
                            );
                            let name = format!("{set}-{side}x{side}");
                            records.push(record.record(name, *threads, rate, hits, rays.len()));
                        }
                    }
                }
            }
            if entry.packet_only.is_some() {
                pb.inc((RaySets::NAMES.len() * pools.len()) as u64);
                continue;
            }
            singles.push((record, accel));
        }
        for set in RaySets::NAMES {
            let rays = sets.by_name(set).expect("known set");
            let occluded = set == "shadow";
            for (threads, pool) in &pools {
                pb.set_message(format!(
                    "{set} x{threads}, {} structures in turn",
                    singles.len()
                ));
                let accels: Vec<&dyn Accel> = singles.iter().map(|(_, a)| a.as_ref()).collect();
                for ((record, accel), (rate, hits, count)) in singles
                    .iter()
                    .zip(measure_in_turn(&accels, rays, occluded, pool, reps))
                {
                    let mut r = record.record(set.to_string(), *threads, rate, hits, count);
                    r.tests_per_ray = count_tests(accel.as_ref(), rays, occluded);
                    records.push(r);
                    pb.inc(1);
                }
            }
        }
        pb.finish_and_clear();
    }
    fill_ratios(&mut records);
    records
        .retain(|r| entries.iter().any(|e| e.name == r.accel) || PEERS.contains(&r.accel.as_str()));
    print_table(&records);
    print_packet_table(&records);
    if opts.quick {
        eprintln!(
            "--quick is a smoke test (128x128 rays): its figures are not comparable with a full \
             run's; run without --quick to compare structures"
        );
    }
    if let Some(path) = &opts.json {
        let text = serde_json::to_string_pretty(&records).map_err(|e| e.to_string())?;
        std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))?;
        eprintln!("wrote {} records to {}", records.len(), path.display());
    }
    Ok(records)
}

/// In a counting build, box and primitive tests per ray over (up to 65536 of) `rays`, traced
/// on this thread after the timed runs; `None` otherwise.
fn count_tests(accel: &dyn Accel, rays: &[Ray], occluded: bool) -> Option<(f64, f64)> {
    if !rt_geom::counters::ENABLED || rays.is_empty() {
        return None;
    }
    let sample: Vec<Ray> = rays
        .iter()
        .step_by(rays.len().div_ceil(65536))
        .copied()
        .collect();
    rt_geom::counters::take();
    for r in &sample {
        if occluded {
            accel.occluded(r);
        } else {
            accel.intersect(r);
        }
    }
    let c = rt_geom::counters::take();
    let n = sample.len() as f64;
    Some((c.nodes as f64 / n, c.prims as f64 / n))
}

/// What a record says of a structure besides its speed.
struct Measured<'a> {
    accel: &'a str,
    scene: &'a str,
    build_ms: f64,
    bytes: usize,
    sah_cost: Option<f32>,
    prims: usize,
}

impl Measured<'_> {
    /// The record of one measurement (ratios are filled in later).
    fn record(
        &self,
        rays: String,
        threads: usize,
        mrays_s: f64,
        hits: usize,
        ray_count: usize,
    ) -> Record {
        Record {
            accel: self.accel.to_string(),
            scene: self.scene.to_string(),
            rays,
            threads,
            build_ms: self.build_ms,
            mrays_s,
            bytes: self.bytes,
            ratio_vs_obvhs: None,
            ratio_vs_embree: None,
            ratio_vs_embree_fast: None,
            ratio_vs_tinybvh: None,
            ray_count,
            hits,
            prims: self.prims,
            sah_cost: self.sah_cost,
            tests_per_ray: None,
        }
    }
}

/// Median Mrays/s of each of `accels` over `reps.count` rounds, each round every structure
/// timed in turn (the order rotated from round to round) after one warm-up each; sets too
/// slow for a structure's time budget are subsampled evenly for it. Returns per structure
/// `(mrays_s, hits, rays per run)`.
fn measure_in_turn(
    accels: &[&dyn Accel],
    rays: &[Ray],
    occluded: bool,
    pool: &rayon::ThreadPool,
    reps: Reps,
) -> Vec<(f64, usize, usize)> {
    if rays.is_empty() {
        return vec![(0.0, 0, 0); accels.len()];
    }
    let probe = &rays[..rays.len().min(4096)];
    // Per structure: its rays (all, or an even subset), its warm-up's hits, passes per timing.
    let plans: Vec<(Vec<Ray>, usize, u32)> = accels
        .iter()
        .map(|&accel| {
            let (_, t) = run::trace_count(accel, probe, occluded, pool);
            let per_ray = t.as_secs_f64() / probe.len() as f64;
            let fit = (REP_BUDGET.as_secs_f64() / per_ray.max(1e-12)) as usize;
            let stride = if fit < rays.len() {
                rays.len().div_ceil(fit.max(256))
            } else {
                1
            };
            let subset: Vec<Ray> = rays.iter().step_by(stride).copied().collect();
            let (hits, warm) = run::trace_count(accel, &subset, occluded, pool);
            (subset, hits, passes_for(reps, warm))
        })
        .collect();
    let mut times = vec![Vec::with_capacity(reps.count); accels.len()];
    for round in 0..reps.count {
        for k in 0..accels.len() {
            let i = (k + round) % accels.len();
            let (subset, _, passes) = &plans[i];
            let t: Duration = (0..*passes)
                .map(|_| run::trace_count(accels[i], subset, occluded, pool).1)
                .sum();
            times[i].push(t / *passes);
        }
    }
    plans
        .iter()
        .zip(times)
        .map(|((subset, hits, _), t)| {
            let time = run::median(t);
            (run::mrays_per_s(subset.len(), time), *hits, subset.len())
        })
        .collect()
}

/// How a figure is timed: the median of `count` repetitions, each at least `min` long (a small
/// ray set is traced several times per repetition, so that thread wake-up and timer
/// resolution do not dominate its figure).
#[derive(Clone, Copy, Debug)]
struct Reps {
    count: usize,
    min: Duration,
}

impl Reps {
    /// A measurement.
    const FULL: Reps = Reps {
        count: 5,
        min: Duration::from_millis(200),
    };
    /// `--quick`, a smoke test: one short repetition.
    const QUICK: Reps = Reps {
        count: 1,
        min: Duration::from_millis(20),
    };
}

/// Runs `pass` once to warm up, then `reps.count` timed repetitions of as many passes as fill
/// `reps.min`; returns the median time of one pass and the warm-up's hit count.
fn median_pass(reps: Reps, mut pass: impl FnMut() -> (usize, Duration)) -> (Duration, usize) {
    let (hits, warm) = pass();
    let passes = passes_for(reps, warm);
    let times = (0..reps.count)
        .map(|_| (0..passes).map(|_| pass().1).sum::<Duration>() / passes)
        .collect();
    (run::median(times), hits)
}

/// Passes per timed repetition for a pass that took `warm`: enough to fill `reps.min`.
fn passes_for(reps: Reps, warm: Duration) -> u32 {
    (reps.min.as_secs_f64() / warm.as_secs_f64().max(1e-9))
        .ceil()
        .clamp(1.0, 10_000.0) as u32
}

/// Median Mrays/s of rays traced as packets (one per group of ray indices, gathered into
/// slices before the timing as a renderer makes its rays tile by tile), closest hit or
/// (`occluded`) any hit, counting hits as the single-ray measurement does.
fn measure_packets(
    accel: &dyn rt_packet::PacketAccel,
    rays: &[Ray],
    groups: &[Vec<usize>],
    occluded: bool,
    pool: &rayon::ThreadPool,
    reps: Reps,
) -> (f64, usize) {
    let grouped = run::GroupedRays::new(rays, groups);
    let (time, hits) = median_pass(reps, || {
        run::trace_packets_count(accel, &grouped, occluded, pool)
    });
    (run::mrays_per_s(grouped.ray_count(), time), hits)
}

fn fill_ratios(records: &mut [Record]) {
    // The best rate among the references named by `is_ref`, per scene, rays and threads.
    let best = |records: &[Record], is_ref: fn(&str) -> bool| -> Vec<Option<f64>> {
        records
            .iter()
            .map(|r| {
                records
                    .iter()
                    .filter(|o| {
                        // Packet records (`primary-8x8`) against the references' single rays.
                        let set = r.rays.split('-').next().unwrap_or(&r.rays);
                        is_ref(&o.accel)
                            && o.scene == r.scene
                            && o.rays == set
                            && o.threads == r.threads
                    })
                    .map(|o| o.mrays_s)
                    .fold(None, |a: Option<f64>, x| Some(a.map_or(x, |a| a.max(x))))
                    .filter(|b| *b > 0.0)
                    .map(|b| r.mrays_s / b)
            })
            .collect()
    };
    // obvhs with its own triangle test; Embree as its users run it: default flags, the faster
    // of its high and medium (default) builds.
    let obvhs = best(records, |a| a == "obvhs-cwbvh");
    let embree = best(records, |a| a == "embree");
    let embree_fast = best(records, |a| a == "embree-fast" || a == "embree-medium");
    let tinybvh = best(records, |a| a == "tinybvh");
    for (i, r) in records.iter_mut().enumerate() {
        r.ratio_vs_obvhs = obvhs[i];
        r.ratio_vs_embree = embree[i];
        r.ratio_vs_embree_fast = embree_fast[i];
        r.ratio_vs_tinybvh = tinybvh[i];
    }
}

/// Mrays/s of `accel` on `r`'s scene and threads for the ray set `rays`, if measured.
fn rate_of(records: &[Record], accel: &str, r: &Record, rays: &str) -> Option<f64> {
    records
        .iter()
        .find(|o| {
            o.accel == accel && o.scene == r.scene && o.threads == r.threads && o.rays == rays
        })
        .map(|o| o.mrays_s)
}

/// A packet record (`primary-16x16`, ...) against the same structure's single rays on the same
/// set: `x single` (for a packet path over another entry's structure, such as `kd-mlrta`, that
/// entry's single rays).
pub fn packet_speedup(records: &[Record], r: &Record) -> Option<f64> {
    let (set, _) = r.rays.split_once('-')?;
    let single_of = registry::find(&r.accel)
        .and_then(|e| e.packet_only)
        .unwrap_or(&r.accel);
    rate_of(records, single_of, r, set).map(|s| r.mrays_s / s.max(1e-9))
}

/// The packet records against the same structure's single rays (and, for a packet path over
/// another entry's structure, against that entry's packets on the same tiles).
pub fn print_packet_table(records: &[Record]) {
    let packets: Vec<&Record> = records.iter().filter(|r| r.rays.contains('-')).collect();
    if packets.is_empty() {
        return;
    }
    println!(
        "\npackets: {:<18} {:<12} {:<15} {:>3} {:>9} {:>9} {:>9} {:>10}",
        "accel", "scene", "rays", "thr", "Mrays/s", "x single", "vs obvhs", "x plain"
    );
    let ratio = |x: Option<f64>| x.map_or("-".into(), |x| format!("{x:.2}x"));
    for r in packets {
        let base = registry::find(&r.accel).and_then(|e| e.packet_only);
        let plain = base.and_then(|b| rate_of(records, b, r, &r.rays));
        println!(
            "         {:<18} {:<12} {:<15} {:>3} {:>9.2} {:>9} {:>9} {:>10}",
            r.accel,
            r.scene,
            r.rays,
            r.threads,
            r.mrays_s,
            ratio(packet_speedup(records, r)),
            ratio(r.ratio_vs_obvhs),
            ratio(plain.map(|p| r.mrays_s / p)),
        );
    }
}

/// The single-ray and packet records as aligned text on stdout.
pub fn print_table(records: &[Record]) {
    print!("{}", crate::table::text(records));
}
