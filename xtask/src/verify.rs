//! `cargo xtask verify`: every registered structure against brute force on the conformance
//! scenes, and, when `../shared/models` exists, on the standard meshes with camera, shadow and
//! diffuse rays (against brute force on small meshes, against obvhs on large ones). Packet
//! paths are checked on the same rays against their own structure's single rays, exactly.

use crate::registry::{self, AccelEntry};
use crate::run;
use rayon::prelude::*;
use rt_geom::{Accel, BruteForce, Triangle, TriangleKernel};
use rt_testkit::conformance::{self, MollerTrumbore, Report};
use rt_testkit::{RaySets, TestRay, models, scenes};
use std::time::Instant;

#[derive(Clone, Debug, Default)]
pub struct VerifyOptions {
    /// Fewer rays and only the small meshes.
    pub quick: bool,
    /// Comma-separated structure names (all when `None`).
    pub accels: Option<String>,
}

/// One line of the verify table.
#[derive(Clone, Debug)]
pub struct Row {
    pub accel: &'static str,
    pub scene: String,
    pub build_ms: f64,
    pub report: Result<Report, String>,
    /// On the meshes, with the `embree` feature: `(rays that disagree with Embree, rays)`,
    /// disagreeing meaning hit against miss, or `t` off by more than 1e-4 relative.
    pub vs_embree: Option<(usize, usize)>,
}

impl Row {
    pub fn ok(&self) -> bool {
        self.report.as_ref().is_ok_and(Report::is_ok)
    }
}

/// Largest mesh verified against brute force; larger ones are verified against obvhs.
const BRUTE_REFERENCE_MAX: usize = 10_000;

/// Runs everything; prints the table; `Ok(true)` when nothing disagrees.
pub fn verify(opts: &VerifyOptions) -> Result<bool, String> {
    let entries = registry::select(opts.accels.as_deref())?;
    let mut rows = conformance_rows(&entries);
    match models::models_dir() {
        Some(dir) => {
            eprintln!("meshes from {}", dir.display());
            let names: &[&str] = if opts.quick {
                &["teapot", "bunny"]
            } else {
                &models::MODEL_NAMES
            };
            for name in names {
                if let Some(mesh) = models::load_model(name).map_err(|e| e.to_string())? {
                    rows.extend(mesh_rows(name, &mesh.triangles(), &entries, opts.quick)?);
                }
            }
        }
        None if models::shared_required() => {
            return Err(
                "../shared/models not found (set RT_MODELS), and RT_REQUIRE_SHARED=1 \
                        requires the meshes"
                    .into(),
            );
        }
        None => {
            eprintln!(
                "note: ../shared/models not found (set RT_MODELS): meshes skipped; camera, shadow \
                 and diffuse rays through a procedural sphere-20k instead"
            );
            let sphere = scenes::tessellated_sphere(20_000, rt_geom::Vec3::ZERO, 1.0);
            rows.extend(mesh_rows("sphere-20k", &sphere, &entries, opts.quick)?);
        }
    }
    print_table(&rows);
    let bad = rows.iter().filter(|r| !r.ok()).count();
    if bad > 0 {
        println!("\n{bad} of {} rows disagree. Reproducers:", rows.len());
        for r in rows.iter().filter(|r| !r.ok()) {
            match &r.report {
                Err(e) => println!("  {} {}: {e}", r.accel, r.scene),
                Ok(rep) => {
                    for m in rep.mismatches.iter().take(3) {
                        println!("  {}: {m}", r.accel);
                    }
                }
            }
        }
    } else {
        println!("\nall {} rows agree: 0 mismatches", rows.len());
    }
    Ok(bad == 0)
}

fn conformance_rows(entries: &[&'static AccelEntry]) -> Vec<Row> {
    let scenes = scenes::conformance_triangle_scenes();
    // Single rays against brute force; packet paths against their own single rays.
    let jobs: Vec<_> = entries
        .iter()
        .filter(|e| e.conformance)
        .flat_map(|e| {
            let single = e.packet_only.is_none().then_some(false);
            let packets = e.packets.is_some().then_some(true);
            single.into_iter().chain(packets).map(move |p| (*e, p))
        })
        .flat_map(|(e, packets)| scenes.iter().map(move |s| (e, packets, s)))
        .collect();
    let pb = run::bar(jobs.len() as u64, "conformance");
    let rows = jobs
        .par_iter()
        .map(|(entry, packets, scene)| {
            pb.set_message(format!("{} {}", entry.name, scene.name));
            let start = Instant::now();
            let report = if *packets {
                let reference = BruteForce::build(&scene.prims).map_err(|e| e.to_string());
                reference.and_then(|reference| {
                    let seed = 0x5eed ^ scene.prims.len() as u64;
                    let rays =
                        rt_testkit::rays::conformance_rays(&scene.prims, &reference, 400, seed);
                    packet_report(&scene.name, &scene.prims, &rays, entry)
                })
            } else {
                entry.check_triangle_scene(scene)
            };
            pb.inc(1);
            Row {
                accel: entry.name,
                scene: row_scene(&scene.name, *packets),
                build_ms: start.elapsed().as_secs_f64() * 1e3,
                report,
                vs_embree: None,
            }
        })
        .collect();
    pb.finish_and_clear();
    rows
}

/// The scene column of a row: packet rows say so.
fn row_scene(scene: &str, packets: bool) -> String {
    if packets {
        format!("{scene} [packets]")
    } else {
        scene.to_string()
    }
}

/// Group sizes of the packet check, cycled in file order: full and partial packets of every
/// size the packet paths pick (4, 16, 64, 256 lanes), single rays, odd sizes.
const PACKET_GROUPS: [usize; 7] = [256, 64, 16, 4, 1, 37, 200];

/// An entry's packet path against its own single rays, exactly (every field of every hit, and
/// every occluded answer), with `rays` traced as groups of [`PACKET_GROUPS`] sizes.
pub(crate) fn packet_report(
    scene: &str,
    tris: &[Triangle],
    rays: &[TestRay],
    entry: &AccelEntry,
) -> Result<Report, String> {
    let build = entry.packets.ok_or("no packet path")?;
    let packets = build(tris).map_err(|e| e.to_string())?;
    let single = (entry.build)(tris).map_err(|e| e.to_string())?;
    let mut groups = Vec::new();
    let mut start = 0;
    for size in PACKET_GROUPS.iter().cycle() {
        if start >= rays.len() {
            break;
        }
        let end = (start + size).min(rays.len());
        groups.push(start..end);
        start = end;
    }
    let reports: Vec<Report> = groups
        .par_iter()
        .map(|g| {
            let group: Vec<rt_geom::Ray> = rays[g.clone()].iter().map(|t| t.ray).collect();
            let mut hits = vec![None; group.len()];
            let mut blocked = vec![false; group.len()];
            packets.intersect_packet_group(&group, &mut hits);
            packets.occluded_packet_group(&group, &mut blocked);
            let mut report = Report {
                scene: scene.to_string(),
                rays: group.len(),
                ..Report::default()
            };
            for (k, test) in rays[g.clone()].iter().enumerate() {
                let expected = single.intersect(&test.ray);
                report.hits += expected.is_some() as usize;
                let query = if hits[k] != expected {
                    "packet intersect"
                } else if blocked[k] != single.occluded(&test.ray) {
                    "packet occluded"
                } else {
                    continue;
                };
                report.mismatch_count += 1;
                report.mismatches.push(conformance::Mismatch {
                    scene: scene.to_string(),
                    kind: test.kind,
                    query,
                    ray: test.ray,
                    expected,
                    got: hits[k],
                });
            }
            report
        })
        .collect();
    Ok(reports.into_iter().fold(Report::default(), |mut a, b| {
        if a.scene.is_empty() {
            a.scene = b.scene.clone();
        }
        a.merge(b);
        a
    }))
}

/// Rows of a mesh (a shared model, or a procedural stand-in) traced with the standard camera,
/// shadow and diffuse ray sets.
fn mesh_rows(
    name: &str,
    tris: &[Triangle],
    entries: &[&'static AccelEntry],
    quick: bool,
) -> Result<Vec<Row>, String> {
    let tris = tris.to_vec();
    let small = tris.len() <= BRUTE_REFERENCE_MAX;
    let pb = run::spinner(format!("{name}: building the reference"));
    let reference: Box<dyn Accel> = if small {
        Box::new(BruteForce::build(&tris).map_err(|e| e.to_string())?)
    } else {
        (registry::find("obvhs").expect("obvhs is registered").build)(&tris)
            .map_err(|e| e.to_string())?
    };
    let size = if quick { 64 } else { 192 };
    pb.set_message(format!("{name}: reference rays"));
    let rays = RaySets::generate(name, &tris, reference.as_ref(), size, size, 7).tagged();
    let expected: Vec<_> = rays
        .par_iter()
        .map(|r| reference.intersect(&r.ray))
        .collect();
    // Entries on Möller–Trumbore's kernel: brute force with it on small meshes, rt's BVH2
    // over triangles on that kernel (its own structure and walk) on large ones.
    let mt: Vec<MollerTrumbore> = tris.iter().copied().map(MollerTrumbore).collect();
    let expected_mt: Option<Vec<_>> = entries
        .iter()
        .any(|e| e.kernel == TriangleKernel::MollerTrumbore)
        .then(|| -> Result<_, String> {
            pb.set_message(format!("{name}: the Möller–Trumbore reference"));
            let reference: Box<dyn Accel> = if small {
                Box::new(BruteForce::build(&mt).map_err(|e| e.to_string())?)
            } else {
                let params = rt_accel_bvh::BvhParams::balanced();
                Box::new(rt_accel_bvh::Bvh::build(&mt, params).map_err(|e| e.to_string())?)
            };
            Ok(rays
                .par_iter()
                .map(|r| reference.intersect(&r.ray))
                .collect())
        })
        .transpose()?;
    // Embree's answers on the same rays, when it is registered.
    let embree_hits: Option<Vec<Option<rt_geom::Hit>>> = match registry::find("embree") {
        Some(e) => {
            pb.set_message(format!("{name}: Embree's answers"));
            let embree = (e.build)(&tris).map_err(|e| e.to_string())?;
            Some(rays.par_iter().map(|r| embree.intersect(&r.ray)).collect())
        }
        None => None,
    };
    pb.finish_and_clear();
    let scene = format!(
        "{name} ({} vs {})",
        tris.len(),
        if small { "brute" } else { "obvhs" }
    );
    let scene_mt = format!(
        "{name} ({} vs {}, Möller–Trumbore)",
        tris.len(),
        if small { "brute" } else { "bvh" }
    );
    let mut rows = Vec::new();
    for entry in entries {
        if tris.len() > entry.bench_max_prims {
            continue; // brute force as a subject on a large mesh: O(n) per ray, not verified
        }
        if entry.packets.is_some() {
            let pb = run::spinner(format!("{name}: {} packets", entry.name));
            let start = Instant::now();
            let report = packet_report(&scene, &tris, &rays, entry);
            pb.finish_and_clear();
            rows.push(Row {
                accel: entry.name,
                scene: row_scene(&scene, true),
                build_ms: start.elapsed().as_secs_f64() * 1e3,
                report,
                vs_embree: None,
            });
        }
        if entry.packet_only.is_some() {
            continue; // its single rays are another entry's
        }
        let pb = run::spinner(format!("{name}: {}", entry.name));
        let start = Instant::now();
        let built = (entry.build)(&tris);
        let build_ms = start.elapsed().as_secs_f64() * 1e3;
        let mut vs_embree = None;
        let report = built.map_err(|e| e.to_string()).and_then(|accel| {
            accel.validate()?;
            if let Some(theirs) = &embree_hits {
                vs_embree = Some((disagreements(&rays, theirs, accel.as_ref()), rays.len()));
            }
            Ok(match &expected_mt {
                Some(expected) if entry.kernel == TriangleKernel::MollerTrumbore => {
                    compare_parallel(&scene_mt, &mt, &rays, expected, accel.as_ref(), entry)
                }
                _ => compare_parallel(&scene, &tris, &rays, &expected, accel.as_ref(), entry),
            })
        });
        pb.finish_and_clear();
        let on_mt = entry.kernel == TriangleKernel::MollerTrumbore && expected_mt.is_some();
        rows.push(Row {
            accel: entry.name,
            scene: if on_mt {
                scene_mt.clone()
            } else {
                scene.clone()
            },
            build_ms,
            report,
            vs_embree,
        });
    }
    Ok(rows)
}

fn compare_parallel<P: rt_geom::Primitive>(
    scene: &str,
    tris: &[P],
    rays: &[TestRay],
    expected: &[Option<rt_geom::Hit>],
    accel: &dyn Accel,
    entry: &AccelEntry,
) -> Report {
    rays.par_chunks(2048)
        .zip(expected.par_chunks(2048))
        .map(|(r, e)| conformance::compare_with_expected(scene, tris, r, e, accel, entry.tolerance))
        .reduce(Report::default, |mut a, b| {
            if a.scene.is_empty() {
                a.scene = b.scene.clone();
            }
            a.merge(b);
            a
        })
}

/// Rays on which `accel` and Embree's answers differ: hit against miss, or `t` more than 1e-4
/// relative apart.
fn disagreements(rays: &[TestRay], embree: &[Option<rt_geom::Hit>], accel: &dyn Accel) -> usize {
    rays.par_iter()
        .zip(embree)
        .filter(|(r, theirs)| match (accel.intersect(&r.ray), theirs) {
            (None, None) => false,
            (Some(a), Some(b)) => (a.t - b.t).abs() > 1e-4 * b.t.abs().max(1e-30),
            _ => true,
        })
        .count()
}

fn print_table(rows: &[Row]) {
    println!(
        "{:<18} {:<32} {:>8} {:>8} {:>10} {:>9} {:>10} {:>10}",
        "accel", "scene", "rays", "hits", "mismatches", "tolerated", "max|dt|", "ms"
    );
    for r in rows {
        match &r.report {
            Ok(rep) => println!(
                "{:<18} {:<32} {:>8} {:>8} {:>10} {:>9} {:>10.3e} {:>10.1}",
                r.accel,
                r.scene,
                rep.rays,
                rep.hits,
                rep.mismatch_count,
                rep.tolerated,
                rep.max_dt,
                r.build_ms
            ),
            Err(e) => println!("{:<18} {:<32} ERROR: {e}", r.accel, r.scene),
        }
    }
    let with_embree: Vec<&Row> = rows.iter().filter(|r| r.vs_embree.is_some()).collect();
    if !with_embree.is_empty() {
        println!("\nagreement with Embree on the meshes (hit/miss, t within 1e-4 relative):");
        println!(
            "{:<18} {:<32} {:>8} {:>12} {:>9}",
            "accel", "scene", "rays", "disagreeing", "agree %"
        );
        for r in with_embree {
            let (bad, n) = r.vs_embree.unwrap_or_default();
            println!(
                "{:<18} {:<32} {:>8} {:>12} {:>9.4}",
                r.accel,
                r.scene,
                n,
                bad,
                100.0 * (n - bad) as f64 / n.max(1) as f64
            );
        }
    }
}
