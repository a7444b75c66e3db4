//! Whitted shading level by level over a group of eye rays (a tile): the eye rays' hits, then
//! every shadow ray of the level to each light as one group, then the reflected rays and the
//! refracted rays of the level as groups, and so on down the tree; colours are combined
//! bottom-up at the end. Each group goes to a [`Queries`] at once, so a packet path traces
//! the coherent ones (a tile's shadow rays to one light, its mirror bounces off a flat board)
//! as packets. Every colour is computed with the operations, in the order, of the recursive
//! rules ([`crate::whitted`]), so the image is the same bit for bit whatever traces the rays.

use crate::whitted::{Surface, Whitted, fresnel, mirror, refract};
use crate::{Material, RayStats};
use glam::Vec3;
use rt_geom::{Accel, FilteredAccel, Hit, Ray};

/// Groups of rays answered at once: closest hits, and whether each ray is blocked. Each ray
/// may leave a primitive, `leaving[i]` (`None`: it leaves none; an empty slice: no ray does),
/// which it skips. Answers must be those of the structure's `intersect` and `occluded` ray by
/// ray, or [`FilteredAccel::intersect_leaving`] and `occluded_leaving` where a ray leaves a
/// primitive (the integrator gives primitives to leave only through a structure with
/// filtered queries).
pub trait Queries: Sync {
    /// Closest hit of each ray into `out` (same length).
    fn intersect(&self, rays: &[Ray], leaving: &[Option<u32>], out: &mut [Option<Hit>]);
    /// Whether each ray is blocked, into `out` (same length).
    fn occluded(&self, rays: &[Ray], leaving: &[Option<u32>], out: &mut [bool]);
}

/// Ray by ray through a structure (its filtered queries for a ray that leaves a primitive).
pub struct SingleRays<'a>(pub &'a dyn Accel);

impl SingleRays<'_> {
    /// The structure's filtered queries for ray `i`, and the primitive it leaves, if any.
    fn leaving(&self, leaving: &[Option<u32>], i: usize) -> Option<(&dyn FilteredAccel, u32)> {
        let prim = leaving.get(i).copied().flatten()?;
        Some((self.0.filtered()?, prim))
    }
}

impl Queries for SingleRays<'_> {
    fn intersect(&self, rays: &[Ray], leaving: &[Option<u32>], out: &mut [Option<Hit>]) {
        for (i, (r, o)) in rays.iter().zip(out).enumerate() {
            *o = match self.leaving(leaving, i) {
                Some((accel, prim)) => accel.intersect_leaving(r, prim),
                None => self.0.intersect(r),
            };
        }
    }

    fn occluded(&self, rays: &[Ray], leaving: &[Option<u32>], out: &mut [bool]) {
        for (i, (r, o)) in rays.iter().zip(out).enumerate() {
            *o = match self.leaving(leaving, i) {
                Some((accel, prim)) => accel.occluded_leaving(r, prim),
                None => self.0.occluded(r),
            };
        }
    }
}

/// A ray waiting to be traced (the ray itself is kept apart, so that a level's rays are one
/// slice for the queries), and where its colour goes.
#[derive(Clone, Copy)]
struct Pending {
    depth: u32,
    weight: Vec3,
    /// The node whose reflection (`false`) or refraction (`true`) this ray is.
    parent: Option<(usize, bool)>,
}

/// The rays of one level, the primitive each leaves, and what each one is.
struct Level {
    rays: Vec<Ray>,
    leaving: Vec<Option<u32>>,
    pending: Vec<Pending>,
}

impl Level {
    fn with_capacity(n: usize) -> Self {
        Self {
            rays: Vec::with_capacity(n),
            leaving: Vec::with_capacity(n),
            pending: Vec::with_capacity(n),
        }
    }

    fn push(&mut self, (ray, leaving): (Ray, Option<u32>), pending: Pending) {
        self.rays.push(ray);
        self.leaving.push(leaving);
        self.pending.push(pending);
    }

    fn append(&mut self, other: &mut Level) {
        self.rays.append(&mut other.rays);
        self.leaving.append(&mut other.leaving);
        self.pending.append(&mut other.pending);
    }
}

/// A light's shadow rays of a level, the primitive each leaves, and what each adds when
/// unblocked.
struct Shadows {
    rays: Vec<Ray>,
    leaving: Vec<Option<u32>>,
    lit: Vec<Lit>,
}

/// A traced ray: its colour (the background, or the surface's local light, then the
/// children's light added), and its children with their coefficients.
struct Node {
    colour: Vec3,
    reflected: Option<(Vec3, usize)>,
    refracted: Option<(Vec3, usize)>,
}

/// What a surface's lights need: its shading normal, the direction to the viewer, its
/// material.
struct Lighting<'s> {
    node: usize,
    shading: Vec3,
    view: Vec3,
    material: &'s Material,
}

/// A light in front of a surface (an index into the level's [`Lighting`]), whose contribution
/// is added unless its shadow ray is blocked (computed then, as the recursive rules compute
/// it).
struct Lit {
    surface: u32,
    cos: f32,
    l: Vec3,
}

/// The cosine at surface `s`'s shading normal of the direction to a light at `light`, and
/// that unit direction; `None` for a light behind the surface.
fn toward(s: &Surface, light: Vec3) -> Option<(f32, Vec3)> {
    let l = (light - s.point).normalize_or_zero();
    let cos = s.shading.dot(l);
    (cos > 0.0).then_some((cos, l))
}

impl Whitted<'_> {
    /// The shadow ray from surface `s` to a light at `light` (and the primitive it leaves),
    /// the cosine at the shading normal and the unit direction to the light; `None` for a
    /// light behind the surface.
    pub(crate) fn shadow_ray(
        &self,
        s: &Surface,
        light: Vec3,
    ) -> Option<(Ray, Option<u32>, f32, Vec3)> {
        let (cos, l) = toward(s, light)?;
        let spawn = self.leave(s, light - s.point);
        let ray = spawn.ray(light - spawn.origin, 1.0f32.next_down());
        Some((ray, spawn.leaving, cos, l))
    }

    /// The weights of the reflected and the refracted ray at surface `s` hit along the unit
    /// direction `d`, and the refracted direction: total internal reflection gives the
    /// transmitted weight to the reflection, and with [`ShadeOptions::fresnel`] Fresnel's
    /// equations split it.
    pub(crate) fn reflect_and_transmit(&self, d: Vec3, s: &Surface) -> (Vec3, Vec3, Option<Vec3>) {
        let m = s.material;
        let (mut kr, mut kt) = (m.reflect, m.transmit);
        if !m.is_transmissive() {
            return (kr, kt, None);
        }
        let eta = if s.entering { 1.0 / m.ior } else { m.ior };
        match refract(d, s, eta) {
            None => (kr + kt, Vec3::ZERO, None),
            Some(t) => {
                if self.options().fresnel {
                    let f = fresnel(s.shading.dot(-d), t.dot(-s.shading), eta);
                    kr += kt * f;
                    kt *= 1.0 - f;
                }
                (kr, kt, Some(t))
            }
        }
    }

    /// Whether each shadow ray (leaving the primitives of `leaving`) is blocked: through the
    /// filtered queries with the surfaces that cast no shadow masked out where the scene has
    /// such, else as groups through `queries`.
    pub(crate) fn shadows_blocked(
        &self,
        rays: &[Ray],
        leaving: &[Option<u32>],
        queries: &dyn Queries,
    ) -> Vec<bool> {
        let mut blocked = vec![false; rays.len()];
        if self.masked_shadows() {
            self.occluded_masked(rays, leaving, &mut blocked);
        } else {
            in_groups(rays, leaving, &mut blocked, |r, l, o| {
                queries.occluded(r, l, o)
            });
        }
        blocked
    }

    /// The colour seen along an eye ray.
    pub fn eye(&self, ray: &Ray, stats: &mut RayStats) -> Vec3 {
        self.shade_group(
            std::slice::from_ref(ray),
            None,
            &SingleRays(self.accel()),
            stats,
        )[0]
    }

    /// The colour seen along an eye ray whose closest hit is known already (traced in a
    /// packet): the same as [`Self::eye`] when `hit` is `accel.intersect(ray)`.
    pub fn eye_with_hit(&self, ray: &Ray, hit: Option<Hit>, stats: &mut RayStats) -> Vec3 {
        let queries = SingleRays(self.accel());
        self.shade_group(std::slice::from_ref(ray), Some(vec![hit]), &queries, stats)[0]
    }

    /// The colour along each eye ray of `rays` (closest hits in `hits` when already traced,
    /// for example as a packet: one per ray, else they are traced here), tracing every other
    /// ray as groups through `queries`.
    pub fn shade_group(
        &self,
        rays: &[Ray],
        hits: Option<Vec<Option<Hit>>>,
        queries: &dyn Queries,
        stats: &mut RayStats,
    ) -> Vec<Vec3> {
        stats.eye_rays += rays.len() as u64;
        let scene = self.scene();
        let options = self.options();
        let mut nodes: Vec<Node> = Vec::with_capacity(rays.len());
        let eye = Pending {
            depth: 1,
            weight: Vec3::ONE,
            parent: None,
        };
        let mut level = Level {
            rays: rays.to_vec(),
            leaving: Vec::new(),
            pending: vec![eye; rays.len()],
        };
        let mut hits = hits.filter(|h| h.len() == rays.len());
        while !level.rays.is_empty() {
            let level_hits = hits.take().unwrap_or_else(|| {
                let mut out = vec![None; level.rays.len()];
                in_groups(&level.rays, &level.leaving, &mut out, |r, l, o| {
                    queries.intersect(r, l, o)
                });
                out
            });
            // Per light, the shadow rays of the level and what each adds when unblocked.
            let n = level.rays.len();
            let mut shadow: Vec<Shadows> = scene
                .lights
                .iter()
                .map(|_| Shadows {
                    rays: Vec::with_capacity(n),
                    leaving: Vec::with_capacity(n),
                    lit: Vec::with_capacity(n),
                })
                .collect();
            // At most one reflected and one refracted ray per hit, the refracted appended to the
            // reflected at the end: no vector grows as it fills.
            let (mut reflected, mut refracted) =
                (Level::with_capacity(2 * n), Level::with_capacity(n));
            let mut surfaces: Vec<Lighting> = Vec::with_capacity(n);
            for ((ray, p), hit) in level.rays.iter().zip(&level.pending).zip(level_hits) {
                let node = nodes.len();
                if let Some((parent, refr)) = p.parent {
                    let child = if refr {
                        &mut nodes[parent].refracted
                    } else {
                        &mut nodes[parent].reflected
                    };
                    if let Some((_, slot)) = child {
                        *slot = node;
                    }
                }
                let Some(hit) = hit else {
                    nodes.push(Node {
                        colour: scene.background,
                        reflected: None,
                        refracted: None,
                    });
                    continue;
                };
                if p.depth == 1 {
                    stats.eye_hits += 1;
                }
                let d = ray.dir().normalize();
                let s = self.surface(ray, &hit, d);
                let m = s.material;
                let view = -d;
                let surface = surfaces.len() as u32;
                surfaces.push(Lighting {
                    node,
                    shading: s.shading,
                    view,
                    material: m,
                });
                for (light, shadows) in scene.lights.iter().zip(&mut shadow) {
                    if !options.shadows {
                        if let Some((cos, l)) = toward(&s, light.position) {
                            shadows.lit.push(Lit { surface, cos, l });
                        }
                        continue;
                    }
                    let Some((ray, leaving, cos, l)) = self.shadow_ray(&s, light.position) else {
                        continue;
                    };
                    stats.shadow += 1;
                    shadows.rays.push(ray);
                    shadows.leaving.push(leaving);
                    shadows.lit.push(Lit { surface, cos, l });
                }
                let mut out = Node {
                    colour: m.emit + m.ambient * scene.ambient,
                    reflected: None,
                    refracted: None,
                };
                if p.depth < options.max_depth {
                    let (kr, kt, transmitted) = self.reflect_and_transmit(d, &s);
                    // The reflected ray, then the refracted one, each where its weight counts.
                    let reflected_dir = m.spawns_reflection().then(|| mirror(d, &s));
                    for (dir, k, refr) in [(reflected_dir, kr, false), (transmitted, kt, true)] {
                        let w = p.weight * k;
                        let Some(dir) = dir.filter(|_| w.max_element() >= options.min_weight)
                        else {
                            continue;
                        };
                        let (count, slot, next) = if refr {
                            (&mut stats.refracted, &mut out.refracted, &mut refracted)
                        } else {
                            (&mut stats.reflected, &mut out.reflected, &mut reflected)
                        };
                        *count += 1;
                        *slot = Some((k, usize::MAX));
                        let pending = Pending {
                            depth: p.depth + 1,
                            weight: w,
                            parent: Some((node, refr)),
                        };
                        let spawn = self.leave(&s, dir);
                        next.push((spawn.ray(dir, f32::INFINITY), spawn.leaving), pending);
                    }
                }
                nodes.push(out);
            }
            // Each light's shadow rays as groups; a node adds its lights in the lights' order.
            for (light, shadows) in scene.lights.iter().zip(&shadow) {
                let blocked = match options.shadows {
                    true => self.shadows_blocked(&shadows.rays, &shadows.leaving, queries),
                    false => vec![false; shadows.lit.len()],
                };
                for (lit, blocked) in shadows.lit.iter().zip(blocked) {
                    if blocked {
                        continue;
                    }
                    let s = &surfaces[lit.surface as usize];
                    let (m, cos) = (s.material, lit.cos);
                    let colour = &mut nodes[s.node].colour;
                    *colour += m.diffuse * light.colour * cos;
                    if m.specular.max_element() > 0.0 {
                        let r = s.shading * (2.0 * cos) - lit.l;
                        *colour +=
                            m.specular * light.colour * r.dot(s.view).max(0.0).powf(m.shininess);
                    }
                }
            }
            reflected.append(&mut refracted);
            level = reflected;
        }
        // Children follow their parents: a reverse sweep combines each node's children first,
        // reflection then refraction, as the recursive rules add them.
        for i in (0..nodes.len()).rev() {
            let mut colour = nodes[i].colour;
            if let Some((kr, child)) = nodes[i].reflected {
                colour += kr * nodes[child].colour;
            }
            if let Some((kt, child)) = nodes[i].refracted {
                colour += kt * nodes[child].colour;
            }
            nodes[i].colour = colour;
        }
        nodes[..rays.len()].iter().map(|n| n.colour).collect()
    }
}

/// Largest group handed to [`Queries`] at once: a 16x16 tile.
pub const GROUP: usize = 256;

/// `query` over `rays` (each leaving the primitive of `leaving`, or none if it is empty) in
/// groups of at most [`GROUP`], each group's `leaving` empty where no ray of it leaves one.
pub(crate) fn in_groups<T>(
    rays: &[Ray],
    leaving: &[Option<u32>],
    out: &mut [T],
    query: impl Fn(&[Ray], &[Option<u32>], &mut [T]),
) {
    for (k, (r, o)) in rays.chunks(GROUP).zip(out.chunks_mut(GROUP)).enumerate() {
        let l = leaving.get(k * GROUP..k * GROUP + r.len()).unwrap_or(&[]);
        let none = l.iter().all(Option::is_none);
        query(r, if none { &[] } else { l }, o);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ShadeOptions, chess};
    use rt_accel_bvh::{Bvh, BvhParams};

    #[test]
    fn a_group_shades_each_ray_as_alone() {
        let scene = chess();
        let accel = Bvh::build(&scene.shapes, BvhParams::balanced()).unwrap();
        let w = Whitted::new(&scene, &accel, ShadeOptions::default());
        let frame = scene.camera.frame(64, 48);
        let rays: Vec<Ray> = (0..48)
            .flat_map(|y| (0..64).map(move |x| (x, y)))
            .map(|(x, y)| frame.ray(x as f32 + 0.5, y as f32 + 0.5, (0.5, 0.5)))
            .collect();
        let (mut group, mut alone) = (RayStats::default(), RayStats::default());
        let together = w.shade_group(&rays, None, &SingleRays(&accel), &mut group);
        let one_by_one: Vec<Vec3> = rays.iter().map(|r| w.eye(r, &mut alone)).collect();
        assert_eq!(together, one_by_one);
        assert_eq!(group, alone);
        assert!(group.refracted > 0 && group.reflected > 0 && group.shadow > 0);
        // Hits given: used when one per ray, ignored otherwise.
        let hits: Vec<Option<Hit>> = rays.iter().map(|r| accel.intersect(r)).collect();
        let mut s = RayStats::default();
        assert_eq!(
            w.shade_group(&rays, Some(hits), &SingleRays(&accel), &mut s),
            together
        );
        let short = Some(vec![None; 3]);
        assert_eq!(
            w.shade_group(&rays, short, &SingleRays(&accel), &mut s),
            together
        );
    }
}
