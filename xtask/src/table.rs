//! One benchmark record, one table row: the columns `bench` prints and `bench --report` writes
//! in `index.md`, formatted in one place.

use serde::{Deserialize, Serialize};

/// One measurement: a structure on a scene with a ray set and a thread count.
#[derive(Clone, Debug, Serialize, Deserialize)]
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
    /// `mrays_s` over `obvhs-cwbvh` (obvhs with its own triangle test) on the same scene, rays,
    /// threads.
    pub ratio_vs_obvhs: Option<f64>,
    /// `mrays_s` over Embree's on the same scene, rays, threads (with the `embree` feature).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ratio_vs_embree: Option<f64>,
    /// `mrays_s` over Embree's in its default (not robust) mode: the faster of its high-quality
    /// (`embree-fast`) and medium (`embree-medium`) builds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ratio_vs_embree_fast: Option<f64>,
    /// `mrays_s` over tinybvh's `BVH8_CPU` (with the `tinybvh` feature, in an AVX2 build).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ratio_vs_tinybvh: Option<f64>,
    pub ray_count: usize,
    pub hits: usize,
    /// Primitives in the scene.
    pub prims: usize,
    pub sah_cost: Option<f32>,
    /// Box (node, cell) and primitive tests per ray, in a counting build (`bench --count`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tests_per_ray: Option<(f64, f64)>,
}

/// The optional columns a table has.
#[derive(Clone, Copy, Debug)]
pub struct Columns {
    /// The ratios to Embree's robust and default modes.
    pub embree: bool,
    /// The ratio to tinybvh.
    pub tinybvh: bool,
    /// Box and primitive tests per ray.
    pub counted: bool,
}

impl Columns {
    /// The columns some record of `records` fills (then every row gets them).
    pub fn of(records: &[Record]) -> Self {
        Self {
            embree: records
                .iter()
                .any(|r| r.ratio_vs_embree.is_some() || r.ratio_vs_embree_fast.is_some()),
            tinybvh: records.iter().any(|r| r.ratio_vs_tinybvh.is_some()),
            counted: records.iter().any(|r| r.tests_per_ray.is_some()),
        }
    }
}

/// Column titles, the optional ones where `cols` has them.
pub fn headers(cols: Columns) -> Vec<&'static str> {
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
    if cols.embree {
        h.extend(["vs embree", "vs embree default"]);
    }
    if cols.tinybvh {
        h.push("vs tinybvh");
    }
    if cols.counted {
        h.extend(["boxes/ray", "prims/ray"]);
    }
    h
}

/// The cells of `r`'s row, in [`headers`] order.
pub fn cells(r: &Record, cols: Columns) -> Vec<String> {
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
    if cols.embree {
        c.extend([ratio(r.ratio_vs_embree), ratio(r.ratio_vs_embree_fast)]);
    }
    if cols.tinybvh {
        c.push(ratio(r.ratio_vs_tinybvh));
    }
    if cols.counted {
        let (boxes, prims) = r.tests_per_ray.map_or(("-".into(), "-".into()), |(b, p)| {
            (format!("{b:.1}"), format!("{p:.1}"))
        });
        c.extend([boxes, prims]);
    }
    c
}

/// Columns that hold names (left-aligned); the others are numbers.
const NAME_COLUMNS: usize = 3;

/// The records as aligned text, one line each under a title line.
pub fn text(records: &[Record]) -> String {
    let cols = Columns::of(records);
    let rows: Vec<Vec<String>> =
        std::iter::once(headers(cols).iter().map(|h| h.to_string()).collect())
            .chain(records.iter().map(|r| cells(r, cols)))
            .collect();
    aligned(&rows, NAME_COLUMNS)
}

/// `rows` (a title row first) as aligned text: the first `names` columns left-aligned, the
/// others (numbers) right-aligned.
pub fn aligned(rows: &[Vec<String>], names: usize) -> String {
    let widths: Vec<usize> = (0..rows.first().map_or(0, Vec::len))
        .map(|c| rows.iter().map(|r| r[c].len()).max().unwrap_or(0))
        .collect();
    let mut out = String::new();
    for row in rows {
        let line: Vec<String> = row
            .iter()
            .zip(&widths)
            .enumerate()
            .map(|(c, (cell, &w))| {
                if c < names {
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
    let cols = Columns::of(records);
    let h = headers(cols);
    let align: Vec<&str> = (0..h.len())
        .map(|c| if c < NAME_COLUMNS { "---" } else { "---:" })
        .collect();
    let mut out = format!("| {} |\n|{}|\n", h.join(" | "), align.join("|"));
    for r in records {
        out.push_str(&format!("| {} |\n", cells(r, cols).join(" | ")));
    }
    out
}
