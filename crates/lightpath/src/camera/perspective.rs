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
use crate::math::lanes::F32x16 as F;
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

/// [`Perspective::generate_ray`] for sixteen film points at once (see
/// [`Perspective::pinhole_lanes`]).
#[derive(Debug, Clone, Copy)]
pub struct PinholeLanes {
    /// Every ray's origin.
    pub origin: Vec3,
    resolution: Vec2,
    half_extents: Vec2,
    /// The render-from-camera transform's first three columns.
    axes: [Vec3; 3],
}

impl PinholeLanes {
    /// The unit directions of the rays through sixteen film points (`film[0]`: x,
    /// `film[1]`: y): lane by lane the bits of [`Perspective::generate_ray`]'s, by the
    /// same operations in the same order (those of `normalized_film`, glam's
    /// `transform_vector3` and `normalize`), no multiply-adds fused.
    #[inline(always)]
    pub fn directions(&self, film: [F; 2]) -> [F; 3] {
        let n = [
            (2.0 * film[0] / self.resolution.x - 1.0) * self.half_extents.x,
            (2.0 * film[1] / self.resolution.y - 1.0) * self.half_extents.y,
        ];
        let [x, y, z] = self.axes;
        // `x·nx`, plus `y·ny`, plus `z·1` (`z` itself).
        let d = [
            n[1] * y.x + n[0] * x.x + z.x,
            n[1] * y.y + n[0] * x.y + z.y,
            n[1] * y.z + n[0] * x.z + z.z,
        ];
        let recip = 1.0 / (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        [d[0] * recip, d[1] * recip, d[2] * recip]
    }
}

impl Perspective {
    /// The camera's rays as [`PinholeLanes`] computes them, sixteen at a time.
    pub fn pinhole_lanes(&self) -> PinholeLanes {
        let m = &self.render_from_camera;
        PinholeLanes {
            origin: m.point(Vec3::ZERO),
            resolution: self.resolution.as_vec2(),
            half_extents: self.half_extents,
            axes: [
                m.matrix().x_axis.truncate(),
                m.matrix().y_axis.truncate(),
                m.matrix().z_axis.truncate(),
            ],
        }
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
    fn pinhole_lanes_equal_generate_ray() {
        use crate::sampling::Pcg32;
        let mut rng = Pcg32::new(3, 9);
        for (res, fov, axis) in [
            (UVec2::new(400, 300), 90.0, FovAxis::X),
            (UVec2::new(256, 256), 19.5, FovAxis::Y),
            (UVec2::new(7, 1000), 150.0, FovAxis::Diagonal),
        ] {
            for look in [
                Transform::IDENTITY,
                Transform::look_at(
                    Vec3::new(0.3, -5.0, 1.2),
                    Vec3::new(0.1, 0.2, -0.3),
                    Vec3::new(0.0, 0.0, -1.0),
                )
                .unwrap(),
                Transform::look_at(Vec3::new(-2.0, 1.0, 4.0), Vec3::ZERO, Vec3::Y).unwrap(),
            ] {
                let cam = Perspective::new(res, fov, axis, look);
                let lanes = cam.pinhole_lanes();
                for _ in 0..200 {
                    let [mut fx, mut fy] = [F::ZERO; 2];
                    for (x, y) in fx.0.iter_mut().zip(fy.0.iter_mut()) {
                        *x = rng.next_f32() * res.x as f32;
                        *y = rng.next_f32() * res.y as f32;
                    }
                    let mut film = [fx, fy];
                    // Pixel corners and centres too.
                    film[0][0] = 0.0;
                    film[1][1] = res.y as f32 / 2.0;
                    film[0][2] = res.x as f32 / 2.0;
                    let d = lanes.directions(film);
                    for i in 0..16 {
                        let want = cam.generate_ray(&sample(film[0][i], film[1][i]));
                        assert_eq!(
                            lanes.origin.to_array().map(f32::to_bits),
                            want.origin.to_array().map(f32::to_bits)
                        );
                        let got = [d[0][i], d[1][i], d[2][i]];
                        assert_eq!(
                            got.map(f32::to_bits),
                            want.direction.to_array().map(f32::to_bits),
                            "film ({}, {})",
                            film[0][i],
                            film[1][i]
                        );
                    }
                }
            }
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
