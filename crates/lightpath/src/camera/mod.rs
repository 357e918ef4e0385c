//! Cameras: they turn a film position (and a lens position) into a ray in render space.
//!
//! Camera space follows the course's convention: the camera looks along +z, +x is image
//! right and +y is image *down*. Normalised film coordinates run from -1 at the left/top
//! edge to +1 at the right/bottom edge.

mod fisheye;
mod orthographic;
mod perspective;
mod realistic;
mod thin_lens;

pub use fisheye::{Fisheye, FisheyeMapping};
pub use orthographic::Orthographic;
pub use perspective::{Perspective, PinholeLanes};
pub use realistic::{FlareSampling, Realistic, RealisticOptions, LAMBDA_D};
pub use thin_lens::{Aperture, ThinLens};

use crate::math::{Ray, Transform};
use glam::{UVec2, Vec2, Vec3};

/// Which image axis a field of view applies to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FovAxis {
    #[default]
    X,
    Y,
    Diagonal,
}

impl FovAxis {
    pub fn from_name(name: &str) -> Option<FovAxis> {
        match name {
            "x" => Some(FovAxis::X),
            "y" => Some(FovAxis::Y),
            "diagonal" | "diag" => Some(FovAxis::Diagonal),
            _ => None,
        }
    }

    /// The half-extents of the image plane at distance 1 for a field of view of
    /// `fov_degrees` on this axis.
    pub fn half_extents(self, fov_degrees: f32, resolution: UVec2) -> Vec2 {
        let t = (fov_degrees.to_radians() * 0.5).tan();
        let (w, h) = (resolution.x as f32, resolution.y as f32);
        match self {
            FovAxis::X => Vec2::new(t, t * h / w),
            FovAxis::Y => Vec2::new(t * w / h, t),
            FovAxis::Diagonal => {
                let d = (w * w + h * h).sqrt();
                Vec2::new(t * w / d, t * h / d)
            }
        }
    }
}

/// What a camera needs to make one ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraSample {
    /// Position on the film in raster coordinates: (0, 0) is the top-left corner of the
    /// image, (width, height) the bottom-right.
    pub film: Vec2,
    /// A point in [0, 1)² for the lens.
    pub lens: Vec2,
}

/// A camera of any kind.
#[derive(Debug, Clone)]
pub enum Camera {
    Perspective(Perspective),
    Orthographic(Orthographic),
    Fisheye(Fisheye),
    ThinLens(ThinLens),
    Realistic(Box<Realistic>),
}

impl Camera {
    /// Image size in pixels.
    pub fn resolution(&self) -> UVec2 {
        match self {
            Camera::Perspective(c) => c.resolution,
            Camera::Orthographic(c) => c.resolution,
            Camera::Fisheye(c) => c.resolution,
            Camera::ThinLens(c) => c.pinhole.resolution,
            Camera::Realistic(c) => c.resolution,
        }
    }

    pub fn render_from_camera(&self) -> &Transform {
        match self {
            Camera::Perspective(c) => &c.render_from_camera,
            Camera::Orthographic(c) => &c.render_from_camera,
            Camera::Fisheye(c) => &c.render_from_camera,
            Camera::ThinLens(c) => &c.pinhole.render_from_camera,
            Camera::Realistic(c) => &c.render_from_camera,
        }
    }

    /// Whether [`CameraSample::lens`] shapes the ray (only cameras with a lens have an
    /// aperture to sample); the others leave the sampler's dimensions for the path.
    #[inline]
    pub fn uses_lens_sample(&self) -> bool {
        matches!(self, Camera::ThinLens(_) | Camera::Realistic(_))
    }

    /// Whether [`Camera::sample_ray`] uses its `u_path` (a realistic camera's wavelength
    /// and path through the lens, when it has dispersion or flare).
    #[inline]
    pub fn uses_path_sample(&self) -> bool {
        match self {
            Camera::Realistic(c) => c.uses_path_sample(),
            _ => false,
        }
    }

    /// The ray for a film sample and its RGB weight: 1 except for a realistic camera,
    /// whose weight carries the lens' exposure, falloff, wavelength and path (see
    /// [`Realistic`]). `u_path` is used where [`Camera::uses_path_sample`].
    #[inline(always)]
    pub fn sample_ray(&self, sample: &CameraSample, u_path: Vec2) -> Option<(Ray, Vec3)> {
        match self {
            Camera::Realistic(c) => c.sample_ray(sample, u_path),
            _ => self.generate_ray(sample).map(|r| (r, Vec3::ONE)),
        }
    }

    /// The ray for a film sample, in render space with a unit direction; `None` where the
    /// camera sees nothing (outside a fisheye's image circle, or blocked inside a lens).
    /// A realistic camera's ray takes the middle of the path sample; renderers use
    /// [`Camera::sample_ray`] for its weight.
    #[inline(always)]
    pub fn generate_ray(&self, sample: &CameraSample) -> Option<Ray> {
        match self {
            Camera::Perspective(c) => Some(c.generate_ray(sample)),
            Camera::Orthographic(c) => Some(c.generate_ray(sample)),
            Camera::Fisheye(c) => c.generate_ray(sample),
            Camera::ThinLens(c) => Some(c.generate_ray(sample)),
            Camera::Realistic(c) => c.sample_ray(sample, Vec2::splat(0.5)).map(|r| r.0),
        }
    }
}

/// Raster position to normalised film coordinates in [-1, 1]².
#[inline]
pub(crate) fn normalized_film(film: Vec2, resolution: UVec2) -> Vec2 {
    Vec2::new(
        2.0 * film.x / resolution.x as f32 - 1.0,
        2.0 * film.y / resolution.y as f32 - 1.0,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_extents_per_axis() {
        let r = UVec2::new(400, 300);
        let x = FovAxis::X.half_extents(90.0, r);
        assert!((x.x - 1.0).abs() < 1e-6 && (x.y - 0.75).abs() < 1e-6);
        let y = FovAxis::Y.half_extents(90.0, r);
        assert!((y.y - 1.0).abs() < 1e-6 && (y.x - 4.0 / 3.0).abs() < 1e-6);
        let d = FovAxis::Diagonal.half_extents(90.0, r);
        assert!((d.length() - 1.0).abs() < 1e-6);
    }
}
