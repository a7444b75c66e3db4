//! Cameras: perspective (with an optional thin lens) and orthographic.

use glam::Vec3;
use rt_geom::Ray;

/// How the image plane maps to rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Rays from the eye; `vfov_deg` is the full vertical field of view, from the top edge of
    /// the image to the bottom edge.
    Perspective {
        /// Vertical field of view in degrees.
        vfov_deg: f32,
    },
    /// Parallel rays along the view direction; `height` is the height of the view in world units.
    Orthographic {
        /// Height of the view in scene units.
        height: f32,
    },
}

/// Depth of field: rays start on a disc of radius `aperture` around the eye and meet on the
/// plane at `focus_distance` along the view direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinLens {
    /// Lens diameter (0: a pinhole).
    pub aperture: f32,
    /// Distance of the plane in focus.
    pub focus_distance: f32,
}

/// A camera at `eye` looking at `look_at`. Image right is `(look_at - eye) x up` (right-handed),
/// image up is perpendicular to the view direction in the plane of `up`; pixels are square.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye point.
    pub eye: Vec3,
    /// The point the camera looks at.
    pub look_at: Vec3,
    /// Up direction.
    pub up: Vec3,
    /// Perspective or orthographic.
    pub projection: Projection,
    /// Depth of field, if any.
    pub lens: Option<ThinLens>,
}

/// A camera set up for one image size: what generating a ray needs.
#[derive(Clone, Copy, Debug)]
pub struct CameraFrame {
    eye: Vec3,
    forward: Vec3,
    /// Image right and up, scaled to half the image's width and height on the plane at
    /// distance 1 (perspective) or in world units (orthographic).
    right: Vec3,
    up: Vec3,
    width: f32,
    height: f32,
    projection: Projection,
    lens: Option<ThinLens>,
    /// Unit right and up, for the lens disc.
    unit_right: Vec3,
    unit_up: Vec3,
}

impl Camera {
    /// A pinhole perspective camera with a vertical field of view in degrees.
    pub fn perspective(eye: Vec3, look_at: Vec3, up: Vec3, vfov_deg: f32) -> Self {
        Self {
            eye,
            look_at,
            up,
            projection: Projection::Perspective { vfov_deg },
            lens: None,
        }
    }

    /// An orthographic camera whose view is `height` tall.
    pub fn orthographic(eye: Vec3, look_at: Vec3, up: Vec3, height: f32) -> Self {
        Self {
            eye,
            look_at,
            up,
            projection: Projection::Orthographic { height },
            lens: None,
        }
    }

    /// Depth of field (perspective cameras only).
    pub fn with_thin_lens(mut self, aperture: f32, focus_distance: f32) -> Self {
        self.lens = Some(ThinLens {
            aperture,
            focus_distance,
        });
        self
    }

    /// A clear description of what makes the camera unusable, if anything.
    pub fn check(&self) -> Result<(), String> {
        if !(self.eye.is_finite() && self.look_at.is_finite() && self.up.is_finite()) {
            return Err("camera position, look-at point and up must be finite".into());
        }
        let forward = self.look_at - self.eye;
        if forward.length_squared() == 0.0 {
            return Err("camera looks at its own position".into());
        }
        if forward.cross(self.up).length_squared() == 0.0 {
            return Err("camera up direction is zero or along the view direction".into());
        }
        match self.projection {
            Projection::Perspective { vfov_deg } if !(vfov_deg > 0.0 && vfov_deg < 180.0) => {
                return Err(format!(
                    "field of view must lie in (0, 180) degrees, got {vfov_deg}"
                ));
            }
            Projection::Orthographic { height } if !(height > 0.0 && height.is_finite()) => {
                return Err(format!(
                    "orthographic view height must be positive, got {height}"
                ));
            }
            _ => {}
        }
        if let Some(l) = self.lens {
            if matches!(self.projection, Projection::Orthographic { .. }) {
                return Err("a thin lens needs a perspective camera".into());
            }
            let aperture_ok = l.aperture >= 0.0 && l.aperture.is_finite();
            let focus_ok = l.focus_distance > 0.0 && l.focus_distance.is_finite();
            if !aperture_ok || !focus_ok {
                return Err(format!(
                    "thin lens needs aperture >= 0 and focus distance > 0, got {} and {}",
                    l.aperture, l.focus_distance
                ));
            }
        }
        Ok(())
    }

    /// The camera for a `width x height` image (call [`Camera::check`] first).
    pub fn frame(&self, width: u32, height: u32) -> CameraFrame {
        let forward = (self.look_at - self.eye).normalize();
        let unit_right = forward.cross(self.up).normalize();
        let unit_up = unit_right.cross(forward);
        let aspect = width as f32 / height.max(1) as f32;
        let half_h = match self.projection {
            Projection::Perspective { vfov_deg } => (vfov_deg.to_radians() * 0.5).tan(),
            Projection::Orthographic { height } => height * 0.5,
        };
        CameraFrame {
            eye: self.eye,
            forward,
            right: unit_right * half_h * aspect,
            up: unit_up * half_h,
            width: width as f32,
            height: height as f32,
            projection: self.projection,
            lens: self.lens,
            unit_right,
            unit_up,
        }
    }
}

impl CameraFrame {
    /// The ray through image point `(x, y)`, in pixels from the top-left corner of the image
    /// (`(0.5, 0.5)` is the centre of the first pixel); `lens` is a point of the unit square
    /// that picks a point of the lens (ignored without a thin lens).
    pub fn ray(&self, x: f32, y: f32, lens: (f32, f32)) -> Ray {
        let sx = 2.0 * x / self.width - 1.0;
        let sy = 1.0 - 2.0 * y / self.height;
        match self.projection {
            Projection::Orthographic { .. } => {
                Ray::new(self.eye + self.right * sx + self.up * sy, self.forward)
            }
            Projection::Perspective { .. } => {
                let dir = self.forward + self.right * sx + self.up * sy;
                match self.lens {
                    Some(l) if l.aperture > 0.0 => {
                        let focus = self.eye + dir * l.focus_distance;
                        let (dx, dy) = concentric_disc(lens.0, lens.1);
                        let origin =
                            self.eye + (self.unit_right * dx + self.unit_up * dy) * l.aperture;
                        Ray::new(origin, focus - origin)
                    }
                    _ => Ray::new(self.eye, dir),
                }
            }
        }
    }
}

/// Shirley & Chiu's concentric map from the unit square to the unit disc.
fn concentric_disc(u: f32, v: f32) -> (f32, f32) {
    let (a, b) = (2.0 * u - 1.0, 2.0 * v - 1.0);
    if a == 0.0 && b == 0.0 {
        return (0.0, 0.0);
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, std::f32::consts::FRAC_PI_4 * (b / a))
    } else {
        (
            b,
            std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (a / b),
        )
    };
    (r * phi.cos(), r * phi.sin())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn perspective_centre_and_edges() {
        let cam = Camera::perspective(Vec3::ZERO, -Vec3::Z, Vec3::Y, 90.0);
        cam.check().unwrap();
        let f = cam.frame(200, 100);
        let centre = f.ray(100.0, 50.0, (0.5, 0.5));
        assert_eq!(centre.dir(), -Vec3::Z);
        // Top edge: 45 degrees up. Right edge: twice as far right (aspect 2).
        let top = f.ray(100.0, 0.0, (0.5, 0.5)).dir();
        assert_relative_eq!(top.y, 1.0, max_relative = 1e-6);
        let right = f.ray(200.0, 50.0, (0.5, 0.5)).dir();
        // Looking down -z with y up, image right is +x.
        assert_relative_eq!(right.x, 2.0, max_relative = 1e-6);
    }

    #[test]
    fn orthographic_rays_are_parallel() {
        let cam = Camera::orthographic(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 4.0);
        let f = cam.frame(10, 10);
        let a = f.ray(0.0, 0.0, (0.0, 0.0));
        let b = f.ray(10.0, 10.0, (0.0, 0.0));
        assert_eq!(a.dir(), b.dir());
        assert_relative_eq!(a.origin().y, 2.0);
        assert_relative_eq!(b.origin().x, 2.0);
    }

    #[test]
    fn thin_lens_rays_meet_on_the_focus_plane() {
        let cam = Camera::perspective(Vec3::ZERO, -Vec3::Z, Vec3::Y, 60.0).with_thin_lens(0.3, 4.0);
        cam.check().unwrap();
        let f = cam.frame(64, 64);
        let a = f.ray(10.0, 20.0, (0.1, 0.9));
        let b = f.ray(10.0, 20.0, (0.8, 0.3));
        assert_ne!(a.origin(), b.origin());
        let pa = a.at((-4.0 - a.origin().z) / a.dir().z);
        let pb = b.at((-4.0 - b.origin().z) / b.dir().z);
        assert!(pa.abs_diff_eq(pb, 1e-5), "{pa} {pb}");
    }

    #[test]
    fn bad_cameras_are_explained() {
        let ok = Camera::perspective(Vec3::ZERO, -Vec3::Z, Vec3::Y, 60.0);
        let bad = [
            Camera {
                look_at: Vec3::ZERO,
                ..ok
            },
            Camera { up: Vec3::Z, ..ok },
            Camera {
                eye: Vec3::NAN,
                ..ok
            },
            Camera::perspective(Vec3::ZERO, -Vec3::Z, Vec3::Y, 180.0),
            Camera::orthographic(Vec3::ZERO, -Vec3::Z, Vec3::Y, 0.0),
            ok.with_thin_lens(-1.0, 1.0),
        ];
        for c in bad {
            assert!(c.check().is_err(), "{c:?}");
        }
    }
}
