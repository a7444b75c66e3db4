//! Rendering an image: tiles traced in parallel (rayon), by the Whitted rules or by path
//! tracing ([`Integrator`]), supersampling on a regular grid, thin-lens samples from a hash of
//! the pixel (so every render of a scene is the same, bit for bit, whatever the thread count),
//! PNG output.

use crate::path::PathOptions;
use crate::wavefront::{Queries, SingleRays};
use crate::{RayStats, Scene, SceneError, ShadeOptions, Whitted};
use glam::Vec3;
use rayon::prelude::*;
use rt_geom::{Accel, Hit, Ray};
use std::path::Path;
use std::time::Instant;

/// Side of the square tiles the image is cut into.
pub const TILE: u32 = 16;

/// Largest image rendered (pixels), and largest supersampling grid side.
pub const MAX_PIXELS: u64 = 1 << 28;
/// Upper limit of supersamples per pixel axis.
pub const MAX_SAMPLES_PER_AXIS: u32 = 16;

/// What to render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Supersampling: `n x n` eye rays per pixel on a regular grid, averaged. Default 1.
    pub samples_per_axis: u32,
    /// Shading options.
    pub shade: ShadeOptions,
    /// Whitted's rules, or path tracing (which ignores `samples_per_axis`: it jitters its own
    /// samples in each pixel).
    pub integrator: Integrator,
}

/// How a pixel's colour is computed.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Integrator {
    /// The Whitted rules ([`crate::whitted`]): shadow rays, mirror and refracted rays.
    #[default]
    Whitted,
    /// Path tracing ([`crate::path`]): diffuse light bounced too, Monte Carlo.
    Path(PathOptions),
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            samples_per_axis: 1,
            shade: ShadeOptions::default(),
            integrator: Integrator::Whitted,
        }
    }
}

impl RenderOptions {
    /// Checks every field; the error names the first one out of range.
    pub fn check(&self) -> Result<(), String> {
        if self.width == 0 || self.height == 0 {
            return Err(format!(
                "image size must be positive, got {}x{}",
                self.width, self.height
            ));
        }
        if self.width as u64 * self.height as u64 > MAX_PIXELS {
            return Err(format!(
                "image of {}x{} pixels is larger than the limit of {MAX_PIXELS}",
                self.width, self.height
            ));
        }
        if !(1..=MAX_SAMPLES_PER_AXIS).contains(&self.samples_per_axis) {
            return Err(format!(
                "samples per axis must lie in 1..={MAX_SAMPLES_PER_AXIS}, got {}",
                self.samples_per_axis
            ));
        }
        self.shade.check()?;
        match &self.integrator {
            Integrator::Whitted => Ok(()),
            Integrator::Path(p) => p.check(),
        }
    }

    /// Number of tiles (the units of progress).
    pub fn tiles(&self) -> u64 {
        self.width.div_ceil(TILE) as u64 * self.height.div_ceil(TILE) as u64
    }
}

/// A linear RGB image, row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB per pixel, row by row from the top.
    pub pixels: Vec<Vec3>,
}

impl Image {
    /// 8 bits per channel (RGB, row by row), clamped to [0, 1] (no gamma: the classic
    /// model's linear output).
    pub fn to_rgb8(&self) -> Vec<u8> {
        let q = |x: f32| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
        self.pixels
            .iter()
            .flat_map(|c| [q(c.x), q(c.y), q(c.z)])
            .collect()
    }

    /// Writes the image as an 8-bit PNG.
    pub fn save_png(&self, path: &Path) -> Result<(), String> {
        write_png(path, self.width, self.height, &self.to_rgb8())
    }
}

/// Writes 8-bit RGB pixels (row by row, `3 * width * height` bytes) as a PNG, creating missing
/// folders.
pub fn write_png(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<(), String> {
    let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    if rgb.len() != 3 * width as usize * height as usize {
        return Err(err(&"pixel buffer does not match the image size"));
    }
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| err(&e))?;
    }
    let file = std::fs::File::create(path).map_err(|e| err(&e))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| err(&e))?;
    writer.write_image_data(rgb).map_err(|e| err(&e))?;
    writer.finish().map_err(|e| err(&e))
}

/// A finished render.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// The picture.
    pub image: Image,
    /// Rays traced, by kind.
    pub stats: RayStats,
    /// Wall-clock seconds of tracing (the structure's build not included).
    pub seconds: f64,
}

/// A packet path: groups of up to [`TILE`]² rays at once (a tile's eye rays, its shadow rays
/// to one light, its reflected or refracted rays of one bounce), such as
/// `rt_packet::PacketAccel::intersect_group` and `occluded_group`, each ray skipping the
/// primitive it leaves (`leaving`, as [`Queries`] gives it: `rt_packet::LeavingGroups`). It
/// must answer what the structure's queries answer, ray by ray.
#[derive(Clone, Copy)]
pub struct Packets<'a> {
    /// Closest hits of a group.
    pub intersect: &'a (dyn Fn(&[Ray], &[Option<u32>], &mut [Option<Hit>]) + Sync),
    /// Whether each ray of a group is blocked.
    pub occluded: &'a (dyn Fn(&[Ray], &[Option<u32>], &mut [bool]) + Sync),
}

impl Queries for Packets<'_> {
    fn intersect(&self, rays: &[Ray], leaving: &[Option<u32>], out: &mut [Option<Hit>]) {
        (self.intersect)(rays, leaving, out)
    }

    fn occluded(&self, rays: &[Ray], leaving: &[Option<u32>], out: &mut [bool]) {
        (self.occluded)(rays, leaving, out)
    }
}

/// Renders `scene` with `accel`, which must have been built over `scene.shapes` (or the same
/// triangles in the same order). `progress` is called with 1 after each finished tile. A
/// scene with surfaces that cast no shadow needs a structure with filtered queries
/// ([`Accel::filtered`]).
pub fn render(
    scene: &Scene,
    accel: &dyn Accel,
    options: &RenderOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Rendered, SceneError> {
    render_with_packets(scene, accel, None, options, progress)
}

/// [`render`], with every group of a tile's rays traced by `packets`: the eye rays (one 16x16
/// packet per tile at one sample per pixel), then level by level the shadow rays to each light
/// and the reflected and refracted rays (see [`crate::wavefront`]). The image is the same as
/// [`render`]'s, bit for bit.
pub fn render_with_packets(
    scene: &Scene,
    accel: &dyn Accel,
    packets: Option<Packets<'_>>,
    options: &RenderOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Rendered, SceneError> {
    options.check().map_err(SceneError::new)?;
    scene.check()?;
    if accel.filtered().is_none() && scene.materials.iter().any(|m| !m.casts_shadow) {
        return Err(SceneError::new(
            "this scene has surfaces that cast no shadow, which shadow rays skip through a ray \
             mask: the structure has no filtered queries"
                .to_string(),
        ));
    }
    let start = Instant::now();
    let (w, h) = (options.width, options.height);
    let frame = scene.camera.frame(w, h);
    let whitted = Whitted::new(scene, accel, options.shade);
    let n = options.samples_per_axis;
    let tiles: Vec<(u32, u32)> = (0..h.div_ceil(TILE))
        .flat_map(|ty| (0..w.div_ceil(TILE)).map(move |tx| (tx * TILE, ty * TILE)))
        .collect();
    let done: Vec<(Vec<Vec3>, RayStats)> = tiles
        .par_iter()
        .map(|&(x0, y0)| {
            let mut stats = RayStats::default();
            let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
            let single = SingleRays(accel);
            let queries: &dyn Queries = match &packets {
                Some(p) => p,
                None => &single,
            };
            if let Integrator::Path(path) = &options.integrator {
                let out = whitted.path_tile(&frame, (x0, y0, x1, y1), path, queries, &mut stats);
                progress(1);
                return (out, stats);
            }
            // The tile's eye rays, sample by sample (pixels row-major within each sample), so
            // that each group of TILE^2 rays is one image tile.
            let mut rays = Vec::with_capacity(((x1 - x0) * (y1 - y0) * n * n) as usize);
            for sy in 0..n {
                for sx in 0..n {
                    for y in y0..y1 {
                        for x in x0..x1 {
                            let px = x as f32 + (sx as f32 + 0.5) / n as f32;
                            let py = y as f32 + (sy as f32 + 0.5) / n as f32;
                            let lens = lens_sample(x, y, sy * n + sx);
                            rays.push(frame.ray(px, py, lens));
                        }
                    }
                }
            }
            let colours = whitted.shade_group(&rays, None, queries, &mut stats);
            let pixels = ((x1 - x0) * (y1 - y0)) as usize;
            let mut out = vec![Vec3::ZERO; pixels];
            // Summed in the order of the samples.
            for (k, c) in colours.into_iter().enumerate() {
                out[k % pixels] += c;
            }
            for c in &mut out {
                *c /= (n * n) as f32;
            }
            progress(1);
            (out, stats)
        })
        .collect();
    let mut pixels = vec![Vec3::ZERO; (w as usize) * (h as usize)];
    let mut stats = RayStats::default();
    for (&(x0, y0), (tile, s)) in tiles.iter().zip(done) {
        stats += s;
        let tw = (x0 + TILE).min(w) - x0;
        for (row, chunk) in tile.chunks(tw as usize).enumerate() {
            let at = (y0 as usize + row) * w as usize + x0 as usize;
            pixels[at..at + chunk.len()].copy_from_slice(chunk);
        }
    }
    Ok(Rendered {
        image: Image {
            width: w,
            height: h,
            pixels,
        },
        stats,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// A point of the unit square for the lens, from a hash of the pixel and sample (PCG-style).
fn lens_sample(x: u32, y: u32, s: u32) -> (f32, f32) {
    let mut h = (x as u64) << 40 ^ (y as u64) << 16 ^ s as u64;
    let mut next = || {
        h = h
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((h >> 40) as u32) as f32 / (1u32 << 24) as f32
    };
    (next(), next())
}
