//! The report's PNG plots (plotters on an RGB buffer, encoded by `image`).

use crate::bench::Record;
use crate::sweep::SweepRecord;
use plotters::prelude::*;
use std::path::Path;

/// The font plot text is drawn with: DejaVu Sans cut down to the characters the plots use
/// (`assets/DejaVuSans-subset.ttf`, its licence beside it), carried in the binary so that a
/// fresh machine with no system fonts still gets labelled plots.
const PLOT_FONT: &[u8] = include_bytes!("../../assets/DejaVuSans-subset.ttf");

/// Registers the embedded plot font (DejaVu Sans, cut down) as plotters' "sans-serif" (once
/// per process is enough; again is harmless).
pub fn register_font() -> bool {
    plotters::style::register_font("sans-serif", FontStyle::Normal, PLOT_FONT).is_ok()
}

const SIZE: (u32, u32) = (1000, 600);

/// A tick label: 1k, 250k, 1M; 0.5, 12, 300.
pub(super) fn short(v: f64) -> String {
    if v >= 1e6 {
        format!("{}M", trim(v / 1e6))
    } else if v >= 1e3 {
        format!("{}k", trim(v / 1e3))
    } else {
        trim(v)
    }
}

pub(super) fn trim(v: f64) -> String {
    let s = format!("{v:.2}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Draws into an RGB buffer with plotters and writes it as PNG.
pub(super) fn png(
    path: &Path,
    draw: impl FnOnce(DrawingArea<BitMapBackend, plotters::coord::Shift>) -> Result<(), String>,
) -> Result<(), String> {
    let mut buf = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        draw(root.clone())?;
        root.present().map_err(|e| e.to_string())?;
    }
    rt_shade::write_png(path, SIZE.0, SIZE.1, &buf)
}

pub(super) fn colour(i: usize) -> RGBColor {
    const P: [RGBColor; 12] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
        RGBColor(0, 0, 0),
        RGBColor(110, 70, 0),
    ];
    P[i % P.len()]
}

pub(super) fn names<'a>(it: impl Iterator<Item = &'a str>) -> Vec<&'a str> {
    let mut v: Vec<&str> = Vec::new();
    for n in it {
        if !v.contains(&n) {
            v.push(n);
        }
    }
    v
}

/// Family colour of a structure name (bvh, bvlist, kd, bsp, grid, octree, obvhs, brute).
pub(super) fn family_colour(name: &str) -> RGBColor {
    const FAMILIES: [&str; 8] = [
        "bvlist", "bvh", "kd", "bsp", "grid", "octree", "obvhs", "brute",
    ];
    colour(
        FAMILIES
            .iter()
            .position(|f| name.starts_with(f))
            .unwrap_or(9),
    )
}

/// One panel per scene: primary-ray throughput per structure, fastest on top, bars coloured by
/// family and labelled with the structure's name.
pub(super) fn plot_throughput(
    path: &Path,
    records: &[Record],
    threads: usize,
) -> Result<(), String> {
    let rs: Vec<&Record> = records
        .iter()
        .filter(|r| r.threads == threads && r.rays == "primary")
        .collect();
    let scenes = names(rs.iter().map(|r| r.scene.as_str()));
    png(path, |root| {
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        let root = root
            .titled(
                &format!("primary rays, {threads} thread(s): Mrays/s"),
                ("sans-serif", 22),
            )
            .map_err(e)?;
        let panels = root.split_evenly((1, scenes.len().max(1)));
        for (panel, scene) in panels.iter().zip(&scenes) {
            let mut bars: Vec<&&Record> = rs.iter().filter(|r| r.scene == *scene).collect();
            bars.sort_by(|a, b| b.mrays_s.total_cmp(&a.mrays_s));
            let top = bars.first().map_or(1.0, |r| r.mrays_s).max(0.1) * 1.15;
            let n = bars.len().max(1);
            let mut chart = ChartBuilder::on(panel)
                .caption(*scene, ("sans-serif", 18))
                .margin(8)
                .x_label_area_size(25)
                .y_label_area_size(5)
                .build_cartesian_2d(0.0..top, 0.0..n as f64)
                .map_err(e)?;
            chart
                .configure_mesh()
                .disable_y_mesh()
                .y_labels(0)
                .x_label_formatter(&|x| short(*x))
                .draw()
                .map_err(e)?;
            for (k, r) in bars.iter().enumerate() {
                let y = (n - 1 - k) as f64;
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(0.0, y + 0.12), (r.mrays_s, y + 0.88)],
                        family_colour(&r.accel).mix(0.75).filled(),
                    )))
                    .map_err(e)?;
                chart
                    .draw_series(std::iter::once(Text::new(
                        format!("{} {:.2}", r.accel, r.mrays_s),
                        (top * 0.01, y + 0.78),
                        ("sans-serif", 11),
                    )))
                    .map_err(e)?;
            }
        }
        Ok(())
    })
}

/// Build time against primary-ray throughput on the largest scene, one labelled point per
/// structure.
pub(super) fn plot_tradeoff(path: &Path, records: &[Record], threads: usize) -> Result<(), String> {
    let largest = records
        .iter()
        .max_by_key(|r| r.prims)
        .map(|r| r.scene.clone())
        .unwrap_or_default();
    let rs: Vec<&Record> = records
        .iter()
        .filter(|r| r.threads == threads && r.rays == "primary" && r.scene == largest)
        .collect();
    let max_x = rs.iter().map(|r| r.build_ms).fold(1.0, f64::max) * 2.0;
    let min_x = rs
        .iter()
        .map(|r| r.build_ms)
        .fold(f64::INFINITY, f64::min)
        .clamp(0.01, max_x)
        / 1.5;
    let max_y = rs.iter().map(|r| r.mrays_s).fold(0.1, f64::max) * 1.1;
    png(path, |root| {
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!(
                    "{largest}: build time against primary-ray throughput (up and left is better)"
                ),
                ("sans-serif", 20),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d((min_x..max_x).log_scale(), 0.0..max_y)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("build ms (log)")
            .y_desc("Mrays/s")
            .x_label_formatter(&|x| short(*x))
            .draw()
            .map_err(e)?;
        for r in &rs {
            let p = (r.build_ms.max(min_x), r.mrays_s);
            let c = family_colour(&r.accel);
            chart
                .draw_series(std::iter::once(Circle::new(p, 5, c.filled())))
                .map_err(e)?;
            chart
                .draw_series(std::iter::once(Text::new(
                    r.accel.clone(),
                    p,
                    ("sans-serif", 11),
                )))
                .map_err(e)?;
        }
        Ok(())
    })
}

/// Packets against single rays: one panel per scene and ray set (primary, shadow), the speed-up
/// over the same structure's single rays against the tile size, a line per packet path.
pub(super) fn plot_packets(path: &Path, records: &[Record], threads: usize) -> Result<(), String> {
    const SETS: [&str; 2] = ["primary", "shadow"];
    let sides = rt_packet::TILE_SIDES;
    let points = |scene: &str, set: &str, accel: &str| -> Vec<(f64, f64)> {
        sides
            .iter()
            .enumerate()
            .filter_map(|(k, side)| {
                let rays = format!("{set}-{side}x{side}");
                let r = records.iter().find(|r| {
                    r.threads == threads && r.scene == scene && r.accel == accel && r.rays == rays
                })?;
                Some((k as f64, crate::bench::packet_speedup(records, r)?))
            })
            .collect()
    };
    let packet_records = || {
        records
            .iter()
            .filter(|r| r.threads == threads && r.rays.contains('-'))
    };
    let scenes = names(packet_records().map(|r| r.scene.as_str()));
    let accels = names(packet_records().map(|r| r.accel.as_str()));
    let top = packet_records()
        .filter_map(|r| crate::bench::packet_speedup(records, r))
        .fold(1.0, f64::max)
        * 1.15;
    png(path, |root| {
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        let root = root
            .titled(
                &format!("packets, {threads} thread(s): x the same structure's single rays"),
                ("sans-serif", 22),
            )
            .map_err(e)?;
        let panels = root.split_evenly((SETS.len(), scenes.len().max(1)));
        for (k, panel) in panels.iter().enumerate() {
            let (set, scene) = (
                SETS[k / scenes.len().max(1)],
                scenes[k % scenes.len().max(1)],
            );
            let mut chart = ChartBuilder::on(panel)
                .caption(format!("{scene}, {set}"), ("sans-serif", 16))
                .margin(8)
                .x_label_area_size(22)
                .y_label_area_size(32)
                .build_cartesian_2d(-0.2..sides.len() as f64 - 0.8, 0.0..top)
                .map_err(e)?;
            chart
                .configure_mesh()
                .x_labels(sides.len())
                .x_label_formatter(&|x| {
                    let s = sides[(x.round().max(0.0) as usize).min(sides.len() - 1)];
                    format!("{s}x{s}")
                })
                .draw()
                .map_err(e)?;
            // No gain below this line.
            chart
                .draw_series(LineSeries::new(
                    [(-0.2, 1.0), (sides.len() as f64 - 0.8, 1.0)],
                    BLACK.mix(0.4),
                ))
                .map_err(e)?;
            for (i, accel) in accels.iter().enumerate() {
                let line = points(scene, set, accel);
                if line.is_empty() {
                    continue;
                }
                let c = colour(i);
                chart
                    .draw_series(LineSeries::new(line.clone(), c.stroke_width(2)))
                    .map_err(e)?
                    .label(*accel)
                    .legend(move |(x, y)| {
                        PathElement::new([(x, y), (x + 16, y)], c.stroke_width(2))
                    });
                chart
                    .draw_series(line.iter().map(|p| Circle::new(*p, 3, c.filled())))
                    .map_err(e)?;
            }
            if k > 0 {
                // One legend, in the first panel.
                continue;
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK.mix(0.3))
                .label_font(("sans-serif", 11))
                .draw()
                .map_err(e)?;
        }
        Ok(())
    })
}

/// Log-log: time per ray and build time against N, with reference slopes.
pub(super) fn plot_sweep(path: &Path, sweep: &[SweepRecord], family: &str) -> Result<(), String> {
    let rs: Vec<&SweepRecord> = sweep.iter().filter(|r| r.family == family).collect();
    if rs.is_empty() {
        return Err(format!("no {family} records"));
    }
    let accels = names(rs.iter().map(|r| r.accel.as_str()));
    let (n0, n1) = (
        rs.iter().map(|r| r.n).min().unwrap_or(1) as f64,
        rs.iter().map(|r| r.n).max().unwrap_or(2) as f64,
    );
    png(path, |root| {
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        let (left, right) = root.split_horizontally(SIZE.0 / 2);
        for (area, what) in [(left, "ns per ray"), (right, "build ms")] {
            let value = |r: &SweepRecord| {
                if what == "build ms" {
                    r.build_ms
                } else {
                    r.ns_per_ray
                }
            };
            let vals: Vec<f64> = rs.iter().map(|r| value(r)).filter(|v| *v > 0.0).collect();
            let lo = vals.iter().copied().fold(f64::INFINITY, f64::min).max(1e-3) / 2.0;
            let hi = vals.iter().copied().fold(0.0, f64::max).max(lo * 4.0) * 2.0;
            let mut chart = ChartBuilder::on(&area)
                .caption(format!("{family}: {what} against N"), ("sans-serif", 20))
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(55)
                .build_cartesian_2d((n0 / 1.2..n1 * 1.2).log_scale(), (lo..hi).log_scale())
                .map_err(e)?;
            chart
                .configure_mesh()
                .x_desc("N triangles")
                .y_desc(what)
                .x_label_formatter(&|x| short(*x))
                .y_label_formatter(&|y| short(*y))
                .draw()
                .map_err(e)?;
            for (ai, accel) in accels.iter().enumerate() {
                let pts: Vec<(f64, f64)> = rs
                    .iter()
                    .filter(|r| r.accel == *accel && value(r) > 0.0)
                    .map(|r| (r.n as f64, value(r)))
                    .collect();
                chart
                    .draw_series(LineSeries::new(pts.clone(), colour(ai).stroke_width(2)))
                    .map_err(e)?
                    .label(*accel)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 16, y)], colour(ai).stroke_width(2))
                    });
                chart
                    .draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour(ai).filled())))
                    .map_err(e)?;
            }
            // Reference slopes from the geometric mean of the values at the smallest N.
            let first: Vec<f64> = rs
                .iter()
                .filter(|r| r.n as f64 == n0)
                .map(|r| value(r))
                .filter(|v| *v > 0.0)
                .collect();
            let mid = (first.iter().map(|v| v.ln()).sum::<f64>() / first.len().max(1) as f64).exp();
            for (label, f) in [
                ("~ N", Box::new(|n: f64| n / n0) as Box<dyn Fn(f64) -> f64>),
                ("~ N^(1/3)", Box::new(|n: f64| (n / n0).cbrt())),
                ("~ log N", Box::new(|n: f64| n.ln() / n0.ln())),
            ] {
                let pts: Vec<(f64, f64)> = (0..=20)
                    .map(|i| n0 * (n1 / n0).powf(i as f64 / 20.0))
                    .map(|n| (n, mid * f(n)))
                    .collect();
                chart
                    .draw_series(LineSeries::new(pts, BLACK.mix(0.35).stroke_width(1)))
                    .map_err(e)?
                    .label(label)
                    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], BLACK.mix(0.35)));
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .label_font(("sans-serif", 12))
                .draw()
                .map_err(e)?;
        }
        Ok(())
    })
}
