//! Materials: the coefficients of Whitted's shading model, per colour channel.

use glam::Vec3;

/// How a surface answers light. Every coefficient is per colour channel (RGB, linear).
///
/// The colour seen along a ray that hits the surface is
///
/// ```text
/// emit + ambient * scene.ambient
///   + sum over visible lights of (diffuse * I * max(0, n.l) + specular * I * max(0, r.v)^shininess)
///   + reflect * (colour along the reflected ray) + transmit * (colour along the refracted ray)
/// ```
///
/// where `I` is the light's colour and `n`, `l`, `r`, `v` are unit vectors (Whitted 1980 with
/// Phong's highlight).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Lambert coefficient `kd` times the surface colour.
    pub diffuse: Vec3,
    /// Coefficient of the scene's ambient light.
    pub ambient: Vec3,
    /// Phong highlight coefficient (zero: no highlight).
    pub specular: Vec3,
    /// Phong exponent.
    pub shininess: f32,
    /// Weight of the perfectly reflected ray.
    pub reflect: Vec3,
    /// Weight of the refracted ray (zero: opaque).
    pub transmit: Vec3,
    /// Index of refraction of the inside (the outside is 1); used when `transmit` is not zero.
    pub ior: f32,
    /// Light the surface gives off (radiance, the same in every direction): added where a ray
    /// meets it, by Whitted's rules and the path tracer alike. Zero for every built-in surface
    /// but emitters.
    pub emit: Vec3,
    /// Whether the surface blocks shadow rays (a lamp's bulb around its light does not: shadow
    /// rays leave it untested through a ray mask).
    pub casts_shadow: bool,
}

impl Default for Material {
    /// Matte light grey.
    fn default() -> Self {
        Self::matte(Vec3::splat(0.8))
    }
}

impl Material {
    /// A Lambert surface of this colour, with the same ambient response.
    pub fn matte(colour: Vec3) -> Self {
        Self {
            diffuse: colour,
            ambient: colour,
            specular: Vec3::ZERO,
            shininess: 1.0,
            reflect: Vec3::ZERO,
            transmit: Vec3::ZERO,
            ior: 1.0,
            emit: Vec3::ZERO,
            casts_shadow: true,
        }
    }

    /// With a Phong highlight.
    pub fn with_highlight(mut self, specular: f32, shininess: f32) -> Self {
        self.specular = Vec3::splat(specular);
        self.shininess = shininess;
        self
    }

    /// With a reflected ray of this weight.
    pub fn with_reflection(mut self, weight: f32) -> Self {
        self.reflect = Vec3::splat(weight);
        self
    }

    /// With a refracted ray of this weight (per channel) and this index of refraction.
    pub fn with_transmission(mut self, weight: Vec3, ior: f32) -> Self {
        self.transmit = weight;
        self.ior = ior;
        self
    }

    /// Giving off this radiance.
    pub fn with_emission(mut self, radiance: Vec3) -> Self {
        self.emit = radiance;
        self
    }

    /// Casting no shadow: shadow rays pass through the surface.
    pub fn without_shadow(mut self) -> Self {
        self.casts_shadow = false;
        self
    }

    /// Whether the surface spawns a refracted ray.
    pub fn is_transmissive(&self) -> bool {
        self.transmit.max_element() > 0.0
    }

    /// The classic rule: a surface with specular or transmitted light spawns a reflection ray.
    pub fn spawns_reflection(&self) -> bool {
        self.reflect.max_element() > 0.0 || self.is_transmissive()
    }

    /// A clear description of the first coefficient that is NaN, infinite or negative.
    pub fn check(&self) -> Result<(), String> {
        let fields = [
            ("diffuse", self.diffuse),
            ("ambient", self.ambient),
            ("specular", self.specular),
            ("reflect", self.reflect),
            ("transmit", self.transmit),
            ("emit", self.emit),
        ];
        for (name, v) in fields {
            if !v.is_finite() || v.min_element() < 0.0 {
                return Err(format!("{name} must be finite and not negative, got {v}"));
            }
        }
        if !(self.shininess.is_finite() && self.shininess >= 0.0) {
            return Err(format!(
                "shininess must be finite and not negative, got {}",
                self.shininess
            ));
        }
        if self.is_transmissive() && !(self.ior.is_finite() && self.ior > 0.0) {
            return Err(format!(
                "index of refraction must be positive, got {}",
                self.ior
            ));
        }
        Ok(())
    }
}
