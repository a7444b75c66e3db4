//! `render --heatmap boxes|prims`: the cost of each pixel's eye ray as a picture. The tests
//! are the counters `--count` reads (`rt_geom::counters`, the counting build); each count
//! goes through a logarithmic scale onto a perceptual colour ramp (viridis), with a legend
//! strip under the image that names the counts at its ticks.

use rayon::prelude::*;
use rt_geom::{Accel, counters};
use rt_shade::{Image, RayStats, RenderOptions, Rendered, Scene};

/// What a heatmap counts per eye ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Heatmap {
    /// Bounding-volume tests: BVH child boxes, kd-tree and octree nodes, grid cells.
    Boxes,
    /// Primitive tests.
    Prims,
}

/// Height in pixels of the legend strip.
const LEGEND: u32 = 22;

/// Each pixel's eye ray (through its centre) of a `width` x `height` view of `scene` through
/// `accel`: whether it hit, and the tests it took. Needs the counting build.
fn count_eye_rays(
    scene: &Scene,
    accel: &dyn Accel,
    (width, height): (u32, u32),
) -> Result<Vec<(bool, counters::Counts)>, String> {
    if !counters::ENABLED {
        return Err("heatmaps need the counting build (feature counters)".into());
    }
    let frame = scene.camera.frame(width, height);
    Ok((0..height)
        .into_par_iter()
        .flat_map_iter(|y| {
            let frame = &frame;
            (0..width).map(move |x| {
                let ray = frame.ray(x as f32 + 0.5, y as f32 + 0.5, (0.5, 0.5));
                counters::take();
                let hit = accel.intersect(&ray).is_some();
                (hit, counters::take())
            })
        })
        .collect())
}

/// Traces one eye ray through the centre of each pixel of the `options`-sized view of
/// `scene` with `accel`, counting its tests: the map of those of `kind` with its legend, the
/// eye rays (and hits) cast, and the tests summed. Needs the counting build.
pub fn heatmap(
    scene: &Scene,
    accel: &dyn Accel,
    options: &RenderOptions,
    kind: Heatmap,
) -> Result<(Rendered, counters::Counts), String> {
    let start = std::time::Instant::now();
    let (width, height) = (options.width, options.height);
    let per_pixel = count_eye_rays(scene, accel, (width, height))?;
    let count = |c: &counters::Counts| match kind {
        Heatmap::Boxes => c.nodes,
        Heatmap::Prims => c.prims,
    };
    let max = per_pixel
        .iter()
        .map(|(_, c)| count(c))
        .max()
        .unwrap_or(0)
        .max(1);
    let mut pixels: Vec<_> = per_pixel
        .iter()
        .map(|(_, c)| ramp(scale(count(c), max)))
        .collect();
    pixels.extend(legend(width, max));
    let mut total = counters::Counts::default();
    for (_, c) in &per_pixel {
        total += *c;
    }
    let stats = RayStats {
        eye_rays: per_pixel.len() as u64,
        eye_hits: per_pixel.iter().filter(|(hit, _)| *hit).count() as u64,
        ..RayStats::default()
    };
    let image = Image {
        width,
        height: height + LEGEND,
        pixels,
    };
    let seconds = start.elapsed().as_secs_f64();
    Ok((
        Rendered {
            image,
            stats,
            seconds,
        },
        total,
    ))
}

/// The structures [`figure`] compares, as the lecture does: the fastest BVH, the kd-tree, the
/// hierarchical grid, the octree, bounding boxes per chess piece (`--objects pieces`, each
/// piece tested by brute force inside its box), and brute force.
pub const FIGURE_ACCELS: [&str; 6] = ["bvh8-tri", "kd", "grid2", "octree", "pieces", "brute"];

/// One figure of every structure of [`FIGURE_ACCELS`] on the chess scene and on sponza (when
/// `../shared/models` has it; seen from inside, as the benchmarks' sponza rays are): per
/// panel the tests (box and primitive together) of each pixel's eye ray on one shared
/// logarithmic scale, the mean box and primitive tests per ray under it, one legend. Panels
/// are `size` pixels; returns a line per panel with its means.
pub fn figure(size: (u32, u32), out: &std::path::Path) -> Result<Vec<String>, String> {
    if size.0 == 0 || size.1 == 0 {
        return Err(format!(
            "panels of {}x{} pixels hold nothing",
            size.0, size.1
        ));
    }
    let (chess, pieces) = rt_shade::chess_objects(rt_shade::ChessForm::Pieces);
    let mut rows = vec![(chess, Some(pieces))];
    if let Some(path) = rt_testkit::models::model_path("sponza") {
        let mut sponza = rt_shade::load_obj_scene(&path).map_err(|e| e.to_string())?;
        // From inside, as the benchmarks' sponza rays look.
        let v = rt_testkit::View::standard("sponza", &sponza.bounds());
        sponza.camera = rt_shade::Camera::perspective(v.eye, v.target, v.up, v.fov_y);
        rows.push((sponza, None));
    }
    // Per row and column: the per-pixel tests, or none (no pieces in the scene).
    let mut panels: Vec<Vec<Option<Vec<counters::Counts>>>> = Vec::new();
    let mut lines = Vec::new();
    for (scene, objects) in &rows {
        let mut row = Vec::new();
        for name in FIGURE_ACCELS {
            let accel: Box<dyn Accel> = match (name, objects) {
                ("pieces", Some(objects)) => {
                    let brute = crate::registry::find("brute").ok_or("no brute entry")?;
                    crate::render::build_two_level(brute, objects)?
                }
                ("pieces", None) => {
                    row.push(None);
                    continue;
                }
                _ => crate::registry::find(name)
                    .ok_or_else(|| crate::registry::unknown(name))?
                    .build_any(&scene.shapes)?,
            };
            let counts: Vec<_> = count_eye_rays(scene, accel.as_ref(), size)?
                .into_iter()
                .map(|(_, c)| c)
                .collect();
            let (boxes, prims) = means(&counts);
            lines.push(format!(
                "{} {name}: {boxes:.1} box tests, {prims:.1} primitive tests per eye ray",
                scene.name
            ));
            row.push(Some(counts));
        }
        panels.push(row);
    }
    let max = panels
        .iter()
        .flatten()
        .flatten()
        .flatten()
        .map(|c| c.nodes + c.prims)
        .max()
        .unwrap_or(0)
        .max(1);
    draw_figure(out, size, &rows, &panels, max)?;
    Ok(lines)
}

/// The mean box and primitive tests of a panel's rays.
fn means(counts: &[counters::Counts]) -> (f64, f64) {
    let n = counts.len().max(1) as f64;
    let sum = |f: fn(&counters::Counts) -> u64| counts.iter().map(f).sum::<u64>() as f64 / n;
    (sum(|c| c.nodes), sum(|c| c.prims))
}

/// Lays the panels out in rows (scenes) and columns (structures), names and means under
/// each, the legend at the bottom, and writes the PNG.
fn draw_figure(
    out: &std::path::Path,
    (pw, ph): (u32, u32),
    rows: &[(Scene, Option<rt_shade::SceneObjects>)],
    panels: &[Vec<Option<Vec<counters::Counts>>>],
    max: u64,
) -> Result<(), String> {
    use plotters::prelude::*;
    crate::report::register_font();
    let (pad, label) = (8u32, 30u32);
    let cols = FIGURE_ACCELS.len() as u32;
    let width = cols * (pw + pad) + pad;
    let height = rows.len() as u32 * (ph + label + pad) + pad + LEGEND + 16;
    let mut rgb = vec![255u8; (width * height * 3) as usize];
    let mut put = |x: u32, y: u32, c: rt_geom::Vec3| {
        let at = ((y * width + x) * 3) as usize;
        for (k, v) in c.to_array().into_iter().enumerate() {
            rgb[at + k] = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
        }
    };
    let origin = |r: u32, c: u32| (pad + c * (pw + pad), pad + r * (ph + label + pad));
    for (r, row) in panels.iter().enumerate() {
        for (c, panel) in row.iter().enumerate() {
            let (x0, y0) = origin(r as u32, c as u32);
            for (i, count) in panel.iter().flatten().enumerate() {
                let (x, y) = (i as u32 % pw, i as u32 / pw);
                put(x0 + x, y0 + y, ramp(scale(count.nodes + count.prims, max)));
            }
            if panel.is_none() {
                for y in 0..ph {
                    for x in 0..pw {
                        put(x0 + x, y0 + y, rt_geom::Vec3::splat(0.9));
                    }
                }
            }
        }
    }
    let strip = legend(width - 2 * pad, max);
    let ly = height - LEGEND - 16;
    for (i, &c) in strip.iter().enumerate() {
        let (x, y) = (i as u32 % (width - 2 * pad), i as u32 / (width - 2 * pad));
        put(pad + x, ly + y, c);
    }
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
        let text = |s: &str, x: u32, y: u32, root: &DrawingArea<_, _>| {
            root.draw(&Text::new(
                s.to_string(),
                (x as i32, y as i32),
                ("sans-serif", 13),
            ))
            .map_err(|e| e.to_string())
        };
        for (r, row) in panels.iter().enumerate() {
            for (c, panel) in row.iter().enumerate() {
                let (x0, y0) = origin(r as u32, c as u32);
                let name = FIGURE_ACCELS[c];
                let caption = match panel {
                    Some(counts) => {
                        let (b, p) = means(counts);
                        format!("{name}: {b:.0} box + {p:.0} prim")
                    }
                    None => format!("{name}: no pieces"),
                };
                text(
                    &format!("{} / {caption}", rows[r].0.name),
                    x0,
                    y0 + ph + 6,
                    &root,
                )?;
            }
        }
        text(
            "tests per eye ray (box + primitive), log scale",
            pad,
            height - 14,
            &root,
        )?;
        root.present().map_err(|e| e.to_string())?;
    }
    rt_shade::write_png(out, width, height, &rgb)
}

/// `count` on the logarithmic scale up to `max`: 0 for none, 1 for `max`.
fn scale(count: u64, max: u64) -> f32 {
    ((1.0 + count as f64).ln() / (1.0 + max as f64).ln()) as f32
}

/// The viridis ramp (its colours at eight even stops), linear in between; `v` in [0, 1].
fn ramp(v: f32) -> rt_geom::Vec3 {
    const STOPS: [[f32; 3]; 8] = [
        [0.267, 0.005, 0.329],
        [0.275, 0.194, 0.497],
        [0.213, 0.359, 0.552],
        [0.153, 0.498, 0.558],
        [0.122, 0.633, 0.531],
        [0.288, 0.761, 0.428],
        [0.626, 0.854, 0.223],
        [0.993, 0.906, 0.144],
    ];
    let x = v.clamp(0.0, 1.0) * (STOPS.len() - 1) as f32;
    let i = (x as usize).min(STOPS.len() - 2);
    let f = x - i as f32;
    let (a, b) = (
        rt_geom::Vec3::from(STOPS[i]),
        rt_geom::Vec3::from(STOPS[i + 1]),
    );
    a + (b - a) * f
}

/// The legend strip: the ramp across the width, and under it the counts at 0, the powers of
/// ten below `max`, and `max`, each at its place on the scale.
fn legend(width: u32, max: u64) -> Vec<rt_geom::Vec3> {
    let (w, h) = (width as usize, LEGEND as usize);
    let mut strip = vec![rt_geom::Vec3::splat(0.08); w * h];
    let bar = 8;
    for x in 0..w {
        let c = ramp(x as f32 / (w - 1).max(1) as f32);
        for y in 1..bar {
            strip[y * w + x] = c;
        }
    }
    let mut ticks = vec![0];
    let mut p = 10;
    while p < max {
        ticks.push(p);
        p *= 10;
    }
    ticks.push(max);
    let mut free_from = 0;
    for t in ticks {
        let label = t.to_string();
        let label_w = label.len() * 8;
        let at = (scale(t, max) * (w - 1) as f32) as usize;
        let left = at
            .saturating_sub(label_w / 2)
            .min(w.saturating_sub(label_w));
        if left < free_from && t != max {
            continue;
        }
        for y in bar..bar + 2 {
            strip[y * w + at.min(w - 1)] = rt_geom::Vec3::ONE;
        }
        for (k, ch) in label.bytes().enumerate() {
            draw_digit(&mut strip, w, left + k * 8, bar + 3, ch - b'0');
        }
        free_from = left + label_w + 4;
    }
    strip
}

/// Digit `d` (3x5 dots, each drawn 2x2) in white with its top left at `(x, y)`.
fn draw_digit(strip: &mut [rt_geom::Vec3], w: usize, x: usize, y: usize, d: u8) {
    const FONT: [u16; 10] = [
        0o75557, 0o26227, 0o71747, 0o71717, 0o55711, 0o74717, 0o74757, 0o71111, 0o75757, 0o75717,
    ];
    let rows = FONT[d as usize % 10];
    for row in 0..5 {
        let bits = (rows >> (3 * (4 - row))) & 7;
        for col in 0..3 {
            if bits & (4 >> col) == 0 {
                continue;
            }
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (px, py) = (x + 2 * col + dx, y + 2 * row + dy);
                if px < w && py < LEGEND as usize {
                    strip[py * w + px] = rt_geom::Vec3::ONE;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_and_the_ramp_run_from_none_to_the_most() {
        assert_eq!(scale(0, 100), 0.0);
        assert_eq!(scale(100, 100), 1.0);
        assert!(scale(9, 100) < scale(10, 100));
        assert_eq!(ramp(0.0), rt_geom::Vec3::new(0.267, 0.005, 0.329));
        assert_eq!(ramp(1.0), rt_geom::Vec3::new(0.993, 0.906, 0.144));
        // Brighter as the count grows (viridis rises in lightness).
        let lum = |c: rt_geom::Vec3| 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
        assert!((1..=20).all(|i| lum(ramp(i as f32 / 20.0)) > lum(ramp((i - 1) as f32 / 20.0))));
    }

    /// The figure's layout: panels, captions and legend in a PNG of the size it computes, a
    /// missing panel grey.
    #[test]
    fn the_figure_lays_out_every_panel() {
        let scene = rt_shade::chess();
        let (pw, ph) = (20, 10);
        let panel = |n: u64| {
            let c = counters::Counts { nodes: n, prims: 1 };
            Some(vec![c; (pw * ph) as usize])
        };
        let mut row: Vec<_> = (0..FIGURE_ACCELS.len() as u64).map(panel).collect();
        row[4] = None;
        let out = std::env::temp_dir().join(format!("rt-figure-{}.png", std::process::id()));
        let rows = [(scene, None)];
        draw_figure(&out, (pw, ph), &rows, &[row], 6).unwrap();
        let png = std::fs::read(&out).unwrap();
        assert_eq!(&png[1..4], b"PNG");
        // Width and height in the header: six panels and their gaps; one row, the legend.
        let be = |at: usize| u32::from_be_bytes(png[at..at + 4].try_into().unwrap());
        assert_eq!(
            (be(16), be(20)),
            (6 * (pw + 8) + 8, ph + 30 + 8 + 8 + LEGEND + 16)
        );
        let _ = std::fs::remove_file(&out);
    }

    #[test]
    fn the_legend_names_its_ticks() {
        let strip = legend(200, 500);
        assert_eq!(strip.len(), 200 * LEGEND as usize);
        // Some dots of the labels are drawn, white, under the bar.
        assert!(strip[8 * 200..].contains(&rt_geom::Vec3::ONE));
    }
}
