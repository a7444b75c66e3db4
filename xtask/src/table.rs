//! One benchmark record, one table row: the columns `bench` prints and `bench --report` writes
//! in `index.md`, formatted in one place.

use serde::Serialize;

/// One measurement: a structure on a scene with a ray set and a thread count.
#[derive(Clone, Debug, Serialize)]
pub struct Record {
    pub accel: String,
    pub scene: String,
    /// The ray set: `primary`, `shadow` or `diffuse`.
    pub rays: String,
    pub threads: usize,
    pub build_ms: f64,
    /// Median over the repetitions.
    pub mrays_s: f64,
    pub bytes: usize,
    /// `mrays_s` over the faster of `obvhs` and `obvhs-cwbvh` on the same scene, rays, threads.
    pub ratio_vs_obvhs: Option<f64>,
    /// `mrays_s` over Embree's on the same scene, rays, threads (with the `embree` feature).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ratio_vs_embree: Option<f64>,
    /// `mrays_s` over Embree's in its default (not robust) mode, `embree-fast`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ratio_vs_embree_fast: Option<f64>,
    pub ray_count: usize,
    pub hits: usize,
    /// Primitives in the scene.
    pub prims: usize,
    pub sah_cost: Option<f32>,
    /// Box (node, cell) and primitive tests per ray, in a counting build (`bench --count`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tests_per_ray: Option<(f64, f64)>,
}

/// Column titles; with `embree`, two more columns: the ratios to Embree's robust and default
/// modes; with `counted`, two more: box and primitive tests per ray.
pub fn headers(embree: bool, counted: bool) -> Vec<&'static str> {
    let mut h = vec![
        "structure",
        "scene",
        "rays",
        "threads",
        "build ms",
        "Mrays/s",
        "vs obvhs",
        "B/prim",
        "MiB",
        "SAH",
    ];
    if embree {
        h.extend(["vs embree", "vs embree-fast"]);
    }
    if counted {
        h.extend(["boxes/ray", "prims/ray"]);
    }
    h
}

/// The cells of `r`'s row, in [`headers`] order.
pub fn cells(r: &Record, embree: bool, counted: bool) -> Vec<String> {
    let ratio = |x: Option<f64>| x.map_or("-".into(), |x| format!("{x:.2}x"));
    let mut c = vec![
        r.accel.clone(),
        r.scene.clone(),
        r.rays.clone(),
        r.threads.to_string(),
        format!("{:.1}", r.build_ms),
        format!("{:.2}", r.mrays_s),
        ratio(r.ratio_vs_obvhs),
        format!("{:.1}", r.bytes as f64 / r.prims.max(1) as f64),
        format!("{:.1}", r.bytes as f64 / (1 << 20) as f64),
        r.sah_cost.map_or("-".into(), |x| format!("{x:.1}")),
    ];
    if embree {
        c.extend([ratio(r.ratio_vs_embree), ratio(r.ratio_vs_embree_fast)]);
    }
    if counted {
        let (boxes, prims) = r.tests_per_ray.map_or(("-".into(), "-".into()), |(b, p)| {
            (format!("{b:.1}"), format!("{p:.1}"))
        });
        c.extend([boxes, prims]);
    }
    c
}

/// Whether any record has test counts (a counting build).
fn with_counts(records: &[Record]) -> bool {
    records.iter().any(|r| r.tests_per_ray.is_some())
}

/// Whether any record has an Embree ratio (then every table gets the columns).
fn with_embree(records: &[Record]) -> bool {
    records
        .iter()
        .any(|r| r.ratio_vs_embree.is_some() || r.ratio_vs_embree_fast.is_some())
}

/// Columns that hold names (left-aligned); the others are numbers.
const NAME_COLUMNS: usize = 3;

/// The records as aligned text, one line each under a title line.
pub fn text(records: &[Record]) -> String {
    let (embree, counted) = (with_embree(records), with_counts(records));
    let rows: Vec<Vec<String>> = std::iter::once(
        headers(embree, counted)
            .iter()
            .map(|h| h.to_string())
            .collect(),
    )
    .chain(records.iter().map(|r| cells(r, embree, counted)))
    .collect();
    let widths: Vec<usize> = (0..rows[0].len())
        .map(|c| rows.iter().map(|r| r[c].len()).max().unwrap_or(0))
        .collect();
    let mut out = String::new();
    for row in rows {
        let line: Vec<String> = row
            .iter()
            .zip(&widths)
            .enumerate()
            .map(|(c, (cell, &w))| {
                if c < NAME_COLUMNS {
                    format!("{cell:<w$}")
                } else {
                    format!("{cell:>w$}")
                }
            })
            .collect();
        out.push_str(line.join("  ").trim_end());
        out.push('\n');
    }
    out
}

/// The records as a Markdown table.
pub fn markdown(records: &[Record]) -> String {
    let (embree, counted) = (with_embree(records), with_counts(records));
    let h = headers(embree, counted);
    let align: Vec<&str> = (0..h.len())
        .map(|c| if c < NAME_COLUMNS { "---" } else { "---:" })
        .collect();
    let mut out = format!("| {} |\n|{}|\n", h.join(" | "), align.join("|"));
    for r in records {
        out.push_str(&format!("| {} |\n", cells(r, embree, counted).join(" | ")));
    }
    out
}
