//! The Whitted integrator's rules: local shading with shadow rays, perfect reflection,
//! refraction by Snell's law, total internal reflection, cut-offs by depth and by weight. The
//! rays are traced level by level over groups of rays by [`crate::wavefront`], which holds
//! the entry points ([`Whitted::eye`], [`Whitted::shade_group`]).
//!
//! Ray rules (what published Whitted statistics assume): the eye ray has depth 1; a shadow ray
//! is cast only towards a light in front of the surface (on the side of the shading normal that
//! faces the ray); a surface with reflected or transmitted light spawns a reflection ray; a
//! transmitting surface spawns a refraction ray, except under total internal reflection, where
//! its weight goes to the reflection ray; no ray is spawned beyond `max_depth`, nor when its
//! weight is below `min_weight` in every channel.

use crate::{Material, Scene};
use glam::Vec3;
use rt_geom::{Accel, FilteredAccel, Hit, Masked, Ray, SkipPrim};
use std::ops::AddAssign;

/// Counts of the rays a render cast.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct RayStats {
    /// Eye (primary) rays.
    pub eye_rays: u64,
    /// Eye rays that hit a surface.
    pub eye_hits: u64,
    /// Reflection rays.
    pub reflected: u64,
    /// Refraction rays.
    pub refracted: u64,
    /// Shadow rays.
    pub shadow: u64,
    /// Diffuse bounces (path tracing).
    pub diffuse: u64,
}

impl RayStats {
    /// Every ray cast.
    pub fn total(&self) -> u64 {
        self.eye_rays + self.reflected + self.refracted + self.shadow + self.diffuse
    }
}

impl AddAssign for RayStats {
    fn add_assign(&mut self, o: Self) {
        self.eye_rays += o.eye_rays;
        self.eye_hits += o.eye_hits;
        self.reflected += o.reflected;
        self.refracted += o.refracted;
        self.shadow += o.shadow;
        self.diffuse += o.diffuse;
    }
}

/// The integrator's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadeOptions {
    /// Deepest ray (the eye ray is depth 1). Default 5.
    pub max_depth: u32,
    /// Secondary rays whose weight (the product of the coefficients along the path) is below
    /// this in every channel are not cast. Default 0: every ray the rules ask for is cast.
    pub min_weight: f32,
    /// Weight reflection and refraction of transmitting surfaces by the dielectric Fresnel
    /// equations (off: the material's coefficients as given, the classic model).
    pub fresnel: bool,
    /// Cast shadow rays (off: every light lights every surface facing it, no shadow ray cast:
    /// with `max_depth` 1, eye rays alone, for interactive previews). Whitted shading only.
    pub shadows: bool,
}

impl Default for ShadeOptions {
    fn default() -> Self {
        Self {
            max_depth: 5,
            min_weight: 0.0,
            fresnel: false,
            shadows: true,
        }
    }
}

impl ShadeOptions {
    /// Checks every field; the error names the first one out of range.
    pub fn check(&self) -> Result<(), String> {
        if !(1..=MAX_DEPTH).contains(&self.max_depth) {
            return Err(format!(
                "maximum depth must lie in 1..={MAX_DEPTH} (1: the eye ray only), got {}",
                self.max_depth
            ));
        }
        if !(self.min_weight >= 0.0 && self.min_weight.is_finite()) {
            return Err(format!(
                "minimum weight must be finite and >= 0, got {}",
                self.min_weight
            ));
        }
        Ok(())
    }
}

/// The deepest ray [`ShadeOptions::max_depth`] allows. Shading recurses once per bounce, and
/// a transmissive surface casts two rays per hit, so rays per pixel can grow as `2^depth`
/// (`min_weight` prunes them).
pub const MAX_DEPTH: u32 = 32;

/// Traces rays through a scene with an acceleration structure built over its shapes.
pub struct Whitted<'a> {
    scene: &'a Scene,
    accel: &'a dyn Accel,
    /// The structure's filtered queries, where it has them: rays leaving a triangle skip it,
    /// and shadow rays skip surfaces that cast no shadow.
    filtered: Option<&'a dyn FilteredAccel>,
    /// Per primitive, its ray mask when some surface casts no shadow: [`SHADOW`] unless its
    /// material casts none.
    masks: Option<Vec<u32>>,
    options: ShadeOptions,
    offset: f32,
}

/// The ray-mask bit of shadow rays, and of the surfaces that block them.
const SHADOW: u32 = 1;

/// The surface at a hit, oriented towards the incoming ray.
pub(crate) struct Surface<'a> {
    pub(crate) point: Vec3,
    /// Geometric normal, on the side the ray came from.
    pub(crate) geometric: Vec3,
    /// Shading normal (interpolated where the scene has vertex normals), same side.
    pub(crate) shading: Vec3,
    /// Whether the ray hit the outside (the side the geometric normal points to).
    pub(crate) entering: bool,
    /// The primitive hit.
    pub(crate) prim: u32,
    /// A bound on the rounding error of `point` (relative to the numbers that made it).
    pub(crate) error: f32,
    pub(crate) material: &'a Material,
}

impl<'a> Whitted<'a> {
    /// An integrator over `scene`, tracing through `accel`. Where `accel` has filtered queries
    /// ([`Accel::filtered`], every rt structure), a ray leaving a triangle starts on it and
    /// skips it (a planar surface cannot be met again), and shadow rays skip the surfaces
    /// that cast none; through a structure without them, every ray leaving a surface starts
    /// off it ([`Scene::ray_offset`]) and every surface casts shadows ([`crate::render()`]
    /// refuses such a pair when some surface casts none).
    pub fn new(scene: &'a Scene, accel: &'a dyn Accel, options: ShadeOptions) -> Self {
        let shadowless = scene.materials.iter().any(|m| !m.casts_shadow);
        let masks = shadowless.then(|| {
            let mask = |&m: &u32| match scene.materials[m as usize].casts_shadow {
                true => SHADOW,
                false => !SHADOW,
            };
            scene.material_of.iter().map(mask).collect()
        });
        Self {
            scene,
            accel,
            filtered: accel.filtered(),
            masks,
            options,
            offset: scene.ray_offset(),
        }
    }

    /// Whether shadow rays go ray by ray through the filtered queries, with the surfaces
    /// that cast no shadow masked out (a packet path skips only the primitive a ray leaves).
    pub(crate) fn masked_shadows(&self) -> bool {
        self.masks.is_some() && self.filtered.is_some()
    }

    /// Whether each shadow ray of `rays` (leaving the primitives of `leaving`) is blocked by a
    /// surface that casts shadows, ray by ray through the filtered queries.
    pub(crate) fn occluded_masked(&self, rays: &[Ray], leaving: &[Option<u32>], out: &mut [bool]) {
        let (Some(accel), Some(masks)) = (self.filtered, &self.masks) else {
            return;
        };
        for ((ray, &leaves), o) in rays.iter().zip(leaving).zip(out) {
            let mut filter = Masked {
                prims: masks,
                instances: &[],
                ray: SHADOW,
                inner: SkipPrim(leaves.unwrap_or(u32::MAX)),
            };
            *o = accel.occluded_filtered(ray, &mut filter);
        }
    }

    /// The structure the integrator traces through.
    pub(crate) fn accel(&self) -> &'a dyn Accel {
        self.accel
    }

    pub(crate) fn scene(&self) -> &'a Scene {
        self.scene
    }

    pub(crate) fn options(&self) -> &ShadeOptions {
        &self.options
    }

    /// The chain of refracted rays that follows `ray` through transmitting surfaces (each ray
    /// as spawned: origin moved off the surface), up to `max` of them; it ends at a miss, an
    /// opaque surface or total internal reflection. For tests and debugging.
    pub fn refraction_chain(&self, ray: &Ray, max: usize) -> Vec<Ray> {
        let mut out = Vec::new();
        let mut ray = *ray;
        let mut next_skip = None;
        while out.len() < max {
            let Some(hit) = self.intersect_leaving(&ray, next_skip) else {
                break;
            };
            let d = ray.dir().normalize();
            let s = self.surface(&ray, &hit, d);
            if !s.material.is_transmissive() {
                break;
            }
            let eta = if s.entering {
                1.0 / s.material.ior
            } else {
                s.material.ior
            };
            let Some(t) = refract(d, &s, eta) else { break };
            let spawn = self.leave(&s, t);
            ray = spawn.ray(t, f32::INFINITY);
            out.push(ray);
            next_skip = spawn.leaving;
        }
        out
    }

    /// The closest hit of a ray that leaves primitive `leaving`, which it skips.
    pub(crate) fn intersect_leaving(&self, ray: &Ray, leaving: Option<u32>) -> Option<Hit> {
        match (leaving, self.filtered) {
            (Some(prim), Some(accel)) => accel.intersect_leaving(ray, prim),
            _ => self.accel.intersect(ray),
        }
    }

    pub(crate) fn surface(&self, ray: &Ray, hit: &Hit, d: Vec3) -> Surface<'a> {
        let i = hit.prim as usize;
        let point = ray.at(hit.t);
        let shape = &self.scene.shapes[i];
        let mut geometric = shape.normal_at(point);
        let mut shading = self.scene.vertex_normals[i]
            .map(|[n0, n1, n2]| {
                (n0 * (1.0 - hit.u - hit.v) + n1 * hit.u + n2 * hit.v).normalize_or_zero()
            })
            .filter(|n| *n != Vec3::ZERO)
            .unwrap_or(geometric);
        let entering = geometric.dot(d) < 0.0;
        if !entering {
            geometric = -geometric;
            shading = -shading;
        }
        if shading.dot(geometric) <= 0.0 {
            shading = geometric;
        }
        Surface {
            point,
            geometric,
            shading,
            entering,
            prim: hit.prim,
            error: rounding_error(ray, hit.t, point),
            material: &self.scene.materials[self.scene.material_of[i] as usize],
        }
    }

    /// Where a ray leaving the surface in direction `dir` starts. A triangle, which a ray
    /// leaving it cannot meet again, is skipped through the filtered queries and the ray starts
    /// at the hit point itself, ignoring only hits within the hit point's rounding error (of
    /// neighbouring triangles, through a shared edge). From a curved surface (a refracted ray
    /// must meet its sphere again), or through a structure without filtered queries, the ray
    /// starts off the surface, on the side `dir` goes.
    pub(crate) fn leave(&self, s: &Surface, dir: Vec3) -> Spawn {
        let planar = self.scene.shapes[s.prim as usize].as_triangle().is_some();
        if planar && self.filtered.is_some() {
            return Spawn {
                origin: s.point,
                leaving: Some(s.prim),
                near: s.error,
            };
        }
        let side = if dir.dot(s.geometric) >= 0.0 {
            1.0
        } else {
            -1.0
        };
        let magnitude = s.point.abs().max_element();
        Spawn {
            origin: s.point + s.geometric * (side * (self.offset + magnitude * 1e-6)),
            leaving: None,
            near: 0.0,
        }
    }
}

/// Where a ray leaving a surface starts: its origin, the primitive it skips, and the distance
/// from the origin within which it ignores hits.
pub(crate) struct Spawn {
    pub(crate) origin: Vec3,
    pub(crate) leaving: Option<u32>,
    near: f32,
}

impl Spawn {
    /// The ray in direction `dir`, over `[near, tmax]` in units of `dir`'s length.
    pub(crate) fn ray(&self, dir: Vec3, tmax: f32) -> Ray {
        Ray::segment(self.origin, dir, self.near / dir.length(), tmax)
    }
}

/// A bound on the rounding error of the hit point `ray.at(t)`: a few units in the last place
/// of the numbers it is made of (the origin, the path `t * dir`, the point), with the hit
/// test's own error in `t` folded in.
fn rounding_error(ray: &Ray, t: f32, point: Vec3) -> f32 {
    let scale = ray.origin().abs().max_element()
        + t * ray.dir().abs().max_element()
        + point.abs().max_element();
    16.0 * f32::EPSILON * scale
}

/// Mirror direction about the shading normal; about the geometric normal when the shading
/// normal would send the ray into the surface.
pub(crate) fn mirror(d: Vec3, s: &Surface) -> Vec3 {
    let about = |n: Vec3| d - n * (2.0 * d.dot(n));
    let r = about(s.shading);
    if r.dot(s.geometric) > 0.0 {
        r
    } else {
        about(s.geometric)
    }
}

/// Snell's law: the refracted direction for relative index `eta` (incident over transmitted),
/// or `None` under total internal reflection. Uses the shading normal, or the geometric one when
/// the shading normal would keep the ray on the incoming side.
pub(crate) fn refract(d: Vec3, s: &Surface, eta: f32) -> Option<Vec3> {
    let through = |n: Vec3| {
        let cos_i = -d.dot(n);
        let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
        (k >= 0.0).then(|| (d * eta + n * (eta * cos_i - k.sqrt())).normalize())
    };
    let t = through(s.shading)?;
    if t.dot(s.geometric) < 0.0 {
        Some(t)
    } else {
        through(s.geometric)
    }
}

/// Unpolarised dielectric Fresnel reflectance from the cosines of the incident and transmitted
/// angles and the relative index `eta = n_i / n_t`.
pub(crate) fn fresnel(cos_i: f32, cos_t: f32, eta: f32) -> f32 {
    let (ci, ct) = (cos_i.abs(), cos_t.abs());
    let rs = (eta * ci - ct) / (eta * ci + ct);
    let rp = (ci - eta * ct) / (ci + eta * ct);
    (0.5 * (rs * rs + rp * rp)).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn flat(n: Vec3) -> Surface<'static> {
        static M: std::sync::OnceLock<Material> = std::sync::OnceLock::new();
        Surface {
            point: Vec3::ZERO,
            geometric: n,
            shading: n,
            entering: true,
            prim: 0,
            error: 0.0,
            material: M.get_or_init(Material::default),
        }
    }

    #[test]
    fn snell_and_total_internal_reflection() {
        let s = flat(Vec3::Y);
        // 45 degrees into glass (1.5): sin t = sin 45 / 1.5.
        let d = Vec3::new(1.0, -1.0, 0.0).normalize();
        let t = refract(d, &s, 1.0 / 1.5).unwrap();
        assert_relative_eq!(t.x, (0.5f32).sqrt() / 1.5, max_relative = 1e-6);
        assert!(t.y < 0.0);
        // Leaving glass at 45 degrees: beyond the critical angle asin(1/1.5) = 41.8 degrees.
        assert!(refract(d, &s, 1.5).is_none());
        // Just under the critical angle it still refracts, grazing.
        let crit = (1.0f32 / 1.5).asin() - 0.001;
        let d = Vec3::new(crit.sin(), -crit.cos(), 0.0);
        assert!(refract(d, &s, 1.5).unwrap().x > 0.99);
    }

    #[test]
    fn fresnel_limits() {
        // Normal incidence on glass: ((1 - 1.5) / (1 + 1.5))^2 = 0.04.
        assert_relative_eq!(fresnel(1.0, 1.0, 1.0 / 1.5), 0.04, max_relative = 1e-5);
        // Grazing: everything is reflected.
        assert!(fresnel(1e-4, 0.74, 1.0 / 1.5) > 0.99);
    }

    #[test]
    fn mirror_reflects_about_the_normal() {
        let s = flat(Vec3::Y);
        let r = mirror(Vec3::new(1.0, -2.0, 0.5), &s);
        assert_eq!(r, Vec3::new(1.0, 2.0, 0.5));
    }
}
