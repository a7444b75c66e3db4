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

/// Traces one eye ray through the centre of each pixel of the `options`-sized view of
/// `scene` with `accel`, counting its tests: the map of those of `kind` with its legend, the
/// eye rays (and hits) cast, and the tests summed. Needs the counting build.
pub fn heatmap(
    scene: &Scene,
    accel: &dyn Accel,
    options: &RenderOptions,
    kind: Heatmap,
) -> Result<(Rendered, counters::Counts), String> {
    if !counters::ENABLED {
        return Err("--heatmap needs the counting build (feature counters)".into());
    }
    let start = std::time::Instant::now();
    let (width, height) = (options.width, options.height);
    let frame = scene.camera.frame(width, height);
    let per_pixel: Vec<(bool, counters::Counts)> = (0..height)
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
        .collect();
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

    #[test]
    fn the_legend_names_its_ticks() {
        let strip = legend(200, 500);
        assert_eq!(strip.len(), 200 * LEGEND as usize);
        // Some dots of the labels are drawn, white, under the bar.
        assert!(strip[8 * 200..].contains(&rt_geom::Vec3::ONE));
    }
}
