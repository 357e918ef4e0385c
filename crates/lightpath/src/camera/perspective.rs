//! The pinhole perspective camera.
//!
//! ```xml
//! <camera type="perspective">
//!     <integer name="width" value="640"/>
//!     <integer name="height" value="480"/>
//!     <string name="fovAxis" value="x"/>   <!-- x, y or diagonal -->
//!     <float name="fov" value="40"/>       <!-- degrees -->
//!     <transform><lookat origin="0,-5,1" target="0,0,0" up="0,0,-1"/></transform>
//! </camera>
//! ```

use super::{normalized_film, CameraSample, FovAxis};
use crate::math::{Ray, Transform};
use glam::{UVec2, Vec2, Vec3};

#[derive(Debug, Clone)]
pub struct Perspective {
    pub resolution: UVec2,
    pub render_from_camera: Transform,
    /// Half-extents of the image plane at z = 1.
    pub half_extents: Vec2,
}

impl Perspective {
    pub fn new(
        resolution: UVec2,
        fov_degrees: f32,
        fov_axis: FovAxis,
        render_from_camera: Transform,
    ) -> Self {
        Perspective {
            resolution,
            render_from_camera,
            half_extents: fov_axis.half_extents(fov_degrees, resolution),
        }
    }

    /// The camera-space direction (not normalised, z = 1) through a film point.
    #[inline]
    pub fn camera_direction(&self, film: Vec2) -> Vec3 {
        let n = normalized_film(film, self.resolution) * self.half_extents;
        Vec3::new(n.x, n.y, 1.0)
    }

    #[inline]
    pub fn generate_ray(&self, sample: &CameraSample) -> Ray {
        let d = self.camera_direction(sample.film);
        Ray::new(
            self.render_from_camera.point(Vec3::ZERO),
            self.render_from_camera.vector(d).normalize(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(x: f32, y: f32) -> CameraSample {
        CameraSample {
            film: Vec2::new(x, y),
            lens: Vec2::splat(0.5),
        }
    }

    #[test]
    fn centre_and_corners() {
        let cam = Perspective::new(UVec2::new(400, 300), 90.0, FovAxis::X, Transform::IDENTITY);
        let c = cam.generate_ray(&sample(200.0, 150.0));
        assert!((c.direction - Vec3::Z).length() < 1e-6);
        assert_eq!(c.origin, Vec3::ZERO);
        // Top-left corner looks towards (-x, -y, +z); bottom-left towards (-x, +y, +z).
        let tl = cam.generate_ray(&sample(0.0, 0.0)).direction;
        assert!((tl - Vec3::new(-1.0, -0.75, 1.0).normalize()).length() < 1e-6);
        let bl = cam.generate_ray(&sample(0.0, 300.0)).direction;
        assert!((bl - Vec3::new(-1.0, 0.75, 1.0).normalize()).length() < 1e-6);
        // The horizontal field of view is 90°.
        let r = cam.generate_ray(&sample(400.0, 150.0)).direction;
        assert!((r.angle_between(Vec3::Z).to_degrees() - 45.0).abs() < 1e-4);
    }

    #[test]
    fn vertical_fov_and_transform() {
        let to = Transform::translate(Vec3::new(1.0, 2.0, 3.0));
        let cam = Perspective::new(UVec2::new(400, 300), 20.0, FovAxis::Y, to);
        let top = cam.generate_ray(&sample(200.0, 0.0));
        assert_eq!(top.origin, Vec3::new(1.0, 2.0, 3.0));
        assert!((top.direction.angle_between(Vec3::Z).to_degrees() - 10.0).abs() < 1e-4);
    }
}
