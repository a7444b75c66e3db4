//! Path tracing on the same scenes and structures as the Whitted integrator: every surface's
//! diffuse light too, gathered from random bounces (global illumination), the incoherent rays
//! that decide which structure wins.
//!
//! Each path starts at a jittered point of its pixel and, at every surface it meets:
//! - adds the surface's emission ([`Material::emit`](crate::Material::emit));
//! - adds each point light in front of it unless a shadow ray is blocked (next-event
//!   estimation), as Whitted's diffuse term `diffuse * I * cos` (a point light gives irradiance
//!   `pi * I * cos` at any distance, the classic model's lights);
//! - goes on along one lobe, picked with probability proportional to its weight (the mean of
//!   its channels): the diffuse lobe (a cosine-distributed direction about the shading normal:
//!   the Lambert BRDF `diffuse / pi`), the mirror direction, or the refracted one (total
//!   internal reflection and, with [`ShadeOptions::fresnel`](crate::ShadeOptions::fresnel),
//!   Fresnel's split as in Whitted's rules);
//! - after [`PathOptions::roulette_after`] bounces, survives Russian roulette with probability
//!   `min(0.95, max channel of its throughput)`, its throughput divided by it.
//!
//! A path that leaves the scene adds the background colour (a uniform sky). Point lights are
//! met only through their shadow rays and emitters only by the bounces, so nothing is counted
//! twice and the estimate is unbiased up to [`PathOptions::max_bounces`].
//! Random numbers come from a hash of the seed, the pixel and the sample: an image repeats for
//! a seed whatever the threads. A tile's paths advance together, bounce by bounce, each
//! bounce's rays one group for [`Queries`] (a packet path takes the eye rays as packets).

use crate::wavefront::{Queries, in_groups};
use crate::whitted::{Whitted, mirror};
use crate::{CameraFrame, RayStats};
use glam::Vec3;
use rt_geom::Hit;

/// The path tracer's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathOptions {
    /// Paths per pixel. Default 16.
    pub samples: u32,
    /// Longest path, in bounces after the eye ray: a cap that Russian roulette all but never
    /// reaches (a path of albedo 0.8 survives 64 bounces with probability 0.8^61). Default 64.
    pub max_bounces: u32,
    /// Bounces before Russian roulette may end a path. Default 3.
    pub roulette_after: u32,
    /// The seed of every path's random numbers.
    pub seed: u64,
}

/// Most paths per pixel [`PathOptions::check`] accepts.
pub const MAX_SAMPLES: u32 = 1 << 16;

impl Default for PathOptions {
    fn default() -> Self {
        Self {
            samples: 16,
            max_bounces: 64,
            roulette_after: 3,
            seed: 0,
        }
    }
}

impl PathOptions {
    /// Checks every field; the error names the first one out of range.
    pub fn check(&self) -> Result<(), String> {
        if !(1..=MAX_SAMPLES).contains(&self.samples) {
            return Err(format!(
                "paths per pixel must lie in 1..={MAX_SAMPLES}, got {}",
                self.samples
            ));
        }
        if self.max_bounces > 1024 {
            return Err(format!(
                "bounces must lie in 0..=1024, got {}",
                self.max_bounces
            ));
        }
        Ok(())
    }
}

/// A small generator per path (SplitMix64): seeded by a hash of the seed, the pixel and the
/// sample.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PathRng(u64);

impl PathRng {
    pub(crate) fn new(seed: u64, x: u32, y: u32, sample: u32) -> Self {
        let mut r = PathRng(seed ^ 0x9e37_79b9_7f4a_7c15);
        for k in [x, y, sample] {
            r.0 ^= r.next() ^ k as u64;
        }
        r
    }

    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    pub(crate) fn f32(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// A cosine-distributed unit direction about the unit normal `n` (Malley's method: a uniform
/// point of the unit disc lifted to the hemisphere), from two uniform numbers.
pub(crate) fn cosine_direction(n: Vec3, u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let phi = std::f32::consts::TAU * u2;
    let (x, y) = (r * phi.cos(), r * phi.sin());
    let z = (1.0 - u1).max(0.0).sqrt();
    // An orthonormal basis about `n` without a branch on its direction (Duff et al. 2017).
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let s = Vec3::new(b, sign + n.y * n.y * a, -n.y);
    t * x + s * y + n * z
}

/// A path on its way: the pixel it adds to, what it carries, its random numbers.
#[derive(Clone, Copy)]
struct Path {
    pixel: u32,
    throughput: Vec3,
    bounces: u32,
    rng: PathRng,
}

/// The mean of a colour's channels: how likely a lobe of that weight is picked.
fn weight(c: Vec3) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

impl Whitted<'_> {
    /// The mean radiance of `options.samples` paths through each pixel of the tile
    /// `x0..x1, y0..y1` of `frame` (row by row), each bounce's rays traced as groups through
    /// `queries`.
    pub fn path_tile(
        &self,
        frame: &CameraFrame,
        (x0, y0, x1, y1): (u32, u32, u32, u32),
        options: &PathOptions,
        queries: &dyn Queries,
        stats: &mut RayStats,
    ) -> Vec<Vec3> {
        let scene = self.scene();
        let tw = x1 - x0;
        let mut out = vec![Vec3::ZERO; (tw * (y1 - y0)) as usize];
        for sample in 0..options.samples {
            let mut rays = Vec::with_capacity(out.len());
            let mut leaving: Vec<Option<u32>> = Vec::new();
            let mut paths = Vec::with_capacity(out.len());
            for y in y0..y1 {
                for x in x0..x1 {
                    let mut rng = PathRng::new(options.seed, x, y, sample);
                    let (px, py) = (x as f32 + rng.f32(), y as f32 + rng.f32());
                    let lens = (rng.f32(), rng.f32());
                    rays.push(frame.ray(px, py, lens));
                    paths.push(Path {
                        pixel: (y - y0) * tw + (x - x0),
                        throughput: Vec3::ONE,
                        bounces: 0,
                        rng,
                    });
                }
            }
            stats.eye_rays += rays.len() as u64;
            while !rays.is_empty() {
                let mut hits: Vec<Option<Hit>> = vec![None; rays.len()];
                in_groups(&rays, &leaving, &mut hits, |r, l, o| {
                    queries.intersect(r, l, o)
                });
                let n = rays.len();
                let (mut next_rays, mut next_leaving, mut next_paths) = (
                    Vec::with_capacity(n),
                    Vec::with_capacity(n),
                    Vec::with_capacity(n),
                );
                let (mut shadow_rays, mut shadow_leaving, mut shadow_light) =
                    (Vec::new(), Vec::new(), Vec::new());
                for ((ray, mut path), hit) in rays.iter().zip(paths).zip(hits) {
                    let Some(hit) = hit else {
                        out[path.pixel as usize] += path.throughput * scene.background;
                        continue;
                    };
                    if path.bounces == 0 {
                        stats.eye_hits += 1;
                    }
                    let d = ray.dir().normalize();
                    let s = self.surface(ray, &hit, d);
                    let m = s.material;
                    out[path.pixel as usize] += path.throughput * m.emit;
                    if m.diffuse.max_element() > 0.0 {
                        for light in &scene.lights {
                            let Some((ray, leaving, cos, _)) = self.shadow_ray(&s, light.position)
                            else {
                                continue;
                            };
                            stats.shadow += 1;
                            let lit = path.throughput * m.diffuse * light.colour * cos;
                            shadow_rays.push(ray);
                            shadow_leaving.push(leaving);
                            shadow_light.push((path.pixel, lit));
                        }
                    }
                    if path.bounces >= options.max_bounces {
                        continue;
                    }
                    // The lobes and their weights, total internal reflection and Fresnel's
                    // split applied as the Whitted rules apply them.
                    let (kr, kt, transmitted) = self.reflect_and_transmit(d, &s);
                    let weights = [weight(m.diffuse), weight(kr), weight(kt)];
                    let total: f32 = weights.iter().sum();
                    if !(total > 0.0) {
                        continue;
                    }
                    let u = path.rng.f32() * total;
                    let mut lobe = if u < weights[0] {
                        0
                    } else if u < weights[0] + weights[1] {
                        1
                    } else {
                        2
                    };
                    if weights[lobe] <= 0.0 {
                        // `u` rounded up to `total`: the last lobe that has a weight.
                        lobe = (0..3).rev().find(|&k| weights[k] > 0.0).unwrap_or(0);
                    }
                    let (dir, k) = match (lobe, transmitted) {
                        (0, _) => {
                            let dir = cosine_direction(s.shading, path.rng.f32(), path.rng.f32());
                            if !(dir.dot(s.geometric) > 0.0) {
                                // Below the surface (a shading normal tilted from the
                                // geometric one): the path ends.
                                continue;
                            }
                            stats.diffuse += 1;
                            (dir, m.diffuse)
                        }
                        (1, _) => {
                            stats.reflected += 1;
                            (mirror(d, &s), kr)
                        }
                        (_, Some(t)) => {
                            stats.refracted += 1;
                            (t, kt)
                        }
                        (_, None) => continue,
                    };
                    path.throughput *= k * (total / weights[lobe]);
                    path.bounces += 1;
                    if path.bounces > options.roulette_after {
                        let q = path.throughput.max_element().min(0.95);
                        if !(path.rng.f32() < q) {
                            continue;
                        }
                        path.throughput /= q;
                    }
                    let spawn = self.leave(&s, dir);
                    next_rays.push(spawn.ray(dir, f32::INFINITY));
                    next_leaving.push(spawn.leaving);
                    next_paths.push(path);
                }
                let blocked = self.shadows_blocked(&shadow_rays, &shadow_leaving, queries);
                for (&(pixel, lit), blocked) in shadow_light.iter().zip(blocked) {
                    if !blocked {
                        out[pixel as usize] += lit;
                    }
                }
                (rays, leaving, paths) = (next_rays, next_leaving, next_paths);
            }
        }
        for c in &mut out {
            *c /= options.samples as f32;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_directions_are_unit_above_the_normal_and_cosine_distributed() {
        let mut rng = PathRng::new(7, 1, 2, 3);
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.5, 0.8).normalize(),
        ] {
            let (mut mean_cos, count) = (0.0f64, 20_000);
            for _ in 0..count {
                let d = cosine_direction(n, rng.f32(), rng.f32());
                assert!((d.length() - 1.0).abs() < 1e-5, "{d}");
                assert!(d.dot(n) >= -1e-6, "{d} below {n}");
                mean_cos += d.dot(n) as f64;
            }
            // E[cos] under the cosine density is 2/3 (standard error about 0.0017).
            let mean = mean_cos / count as f64;
            assert!((mean - 2.0 / 3.0).abs() < 0.01, "{n}: {mean}");
        }
    }

    #[test]
    fn random_numbers_repeat_per_seed_pixel_and_sample() {
        let draw = |seed, x, y, s| {
            let mut r = PathRng::new(seed, x, y, s);
            [r.f32(), r.f32(), r.f32()]
        };
        assert_eq!(draw(1, 2, 3, 4), draw(1, 2, 3, 4));
        for other in [
            draw(2, 2, 3, 4),
            draw(1, 3, 3, 4),
            draw(1, 2, 4, 4),
            draw(1, 2, 3, 5),
        ] {
            assert_ne!(draw(1, 2, 3, 4), other);
        }
        let mut r = PathRng::new(0, 0, 0, 0);
        let mean = (0..100_000).map(|_| r.f32() as f64).sum::<f64>() / 100_000.0;
        assert!((mean - 0.5).abs() < 0.005, "{mean}");
    }
}
