//! The orthographic camera: parallel rays along +z from an image plane whose half-width
//! on the `fovAxis` is `size` scene units (scale it with the transform as well).
//!
//! ```xml
//! <camera type="orthographic">
//!     <integer name="width" value="512"/>
//!     <integer name="height" value="512"/>
//!     <float name="size" value="2"/>
//!     <transform><lookat origin="0,0,-10" target="0,0,0" up="0,1,0"/></transform>
//! </camera>
//! ```

use super::{normalized_film, CameraSample, FovAxis};
use crate::math::{Ray, Transform};
use glam::{UVec2, Vec2, Vec3};

#[derive(Debug, Clone)]
pub struct Orthographic {
    pub resolution: UVec2,
    pub render_from_camera: Transform,
    /// Half-extents of the image plane in camera space.
    pub half_extents: Vec2,
}

impl Orthographic {
    pub fn new(resolution: UVec2, size: f32, axis: FovAxis, render_from_camera: Transform) -> Self {
        let (w, h) = (resolution.x as f32, resolution.y as f32);
        let half_extents = match axis {
            FovAxis::X => Vec2::new(size, size * h / w),
            FovAxis::Y => Vec2::new(size * w / h, size),
            FovAxis::Diagonal => {
                let d = (w * w + h * h).sqrt();
                Vec2::new(size * w / d, size * h / d)
            }
        };
        Orthographic {
            resolution,
            render_from_camera,
            half_extents,
        }
    }

    #[inline]
    pub fn generate_ray(&self, sample: &CameraSample) -> Ray {
        let n = normalized_film(sample.film, self.resolution) * self.half_extents;
        Ray::new(
            self.render_from_camera.point(Vec3::new(n.x, n.y, 0.0)),
            self.render_from_camera.vector(Vec3::Z).normalize(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rays_are_parallel_and_span_the_plane() {
        let t = Transform::rotate(Vec3::Y, 30.0).unwrap();
        let cam = Orthographic::new(UVec2::new(200, 100), 2.0, FovAxis::X, t);
        let a = cam.generate_ray(&CameraSample {
            film: Vec2::new(0.0, 0.0),
            lens: Vec2::ZERO,
        });
        let b = cam.generate_ray(&CameraSample {
            film: Vec2::new(200.0, 100.0),
            lens: Vec2::ZERO,
        });
        let c = cam.generate_ray(&CameraSample {
            film: Vec2::new(100.0, 50.0),
            lens: Vec2::ZERO,
        });
        assert!((a.direction - b.direction).length() < 1e-6);
        assert!((a.direction - t.vector(Vec3::Z)).length() < 1e-6);
        assert!(c.origin.length() < 1e-6);
        // Corners at (-2, -1) and (2, 1) in camera space.
        let ia = t.inverse().point(a.origin);
        let ib = t.inverse().point(b.origin);
        assert!((ia - Vec3::new(-2.0, -1.0, 0.0)).length() < 1e-5);
        assert!((ib - Vec3::new(2.0, 1.0, 0.0)).length() < 1e-5);
    }
}
