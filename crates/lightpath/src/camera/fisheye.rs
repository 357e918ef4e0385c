//! The fisheye camera: a circular image whose radius maps to the angle from the optical
//! axis by one of four classic projections. The image circle fills the shorter image
//! side; rays outside it are black. `fov` is the full angle across the circle, up to 360°
//! for the equidistant and equisolid mappings (which then see all around), below 360°
//! for stereographic, and at most 180° for the orthographic mapping.
//!
//! ```xml
//! <camera type="fisheye">
//!     <integer name="width" value="512"/>
//!     <integer name="height" value="512"/>
//!     <string name="mapping" value="equisolid"/>  <!-- equidistant, equisolid, orthographic, stereographic -->
//!     <float name="fov" value="180"/>
//! </camera>
//! ```

use super::{normalized_film, CameraSample};
use crate::math::{Ray, Transform};
use glam::{UVec2, Vec2, Vec3};

/// How the image radius `r` relates to the angle `θ` from the optical axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FisheyeMapping {
    /// r ∝ θ
    Equidistant,
    /// r ∝ 2 sin(θ/2) (equal area)
    Equisolid,
    /// r ∝ sin θ
    Orthographic,
    /// r ∝ 2 tan(θ/2) (conformal)
    Stereographic,
}

impl FisheyeMapping {
    pub const NAMES: &'static [&'static str] =
        &["equidistant", "equisolid", "orthographic", "stereographic"];

    pub fn from_name(name: &str) -> Option<FisheyeMapping> {
        match name {
            "equidistant" => Some(FisheyeMapping::Equidistant),
            "equisolid" => Some(FisheyeMapping::Equisolid),
            "orthographic" => Some(FisheyeMapping::Orthographic),
            "stereographic" => Some(FisheyeMapping::Stereographic),
            _ => None,
        }
    }

    /// Radius for angle θ (unit focal length).
    pub fn radius(self, theta: f32) -> f32 {
        match self {
            FisheyeMapping::Equidistant => theta,
            FisheyeMapping::Equisolid => 2.0 * (theta * 0.5).sin(),
            FisheyeMapping::Orthographic => theta.sin(),
            FisheyeMapping::Stereographic => 2.0 * (theta * 0.5).tan(),
        }
    }

    /// Angle for radius r (unit focal length).
    pub fn angle(self, r: f32) -> f32 {
        match self {
            FisheyeMapping::Equidistant => r,
            FisheyeMapping::Equisolid => 2.0 * (r * 0.5).clamp(-1.0, 1.0).asin(),
            FisheyeMapping::Orthographic => r.clamp(-1.0, 1.0).asin(),
            FisheyeMapping::Stereographic => 2.0 * (r * 0.5).atan(),
        }
    }

    /// The largest field of view (degrees) the mapping can show.
    pub fn max_fov(self) -> f32 {
        match self {
            FisheyeMapping::Equidistant | FisheyeMapping::Equisolid => 360.0,
            FisheyeMapping::Orthographic => 180.0,
            FisheyeMapping::Stereographic => 359.0,
        }
    }
}

#[derive(Debug, Clone)]
pub struct Fisheye {
    pub resolution: UVec2,
    pub render_from_camera: Transform,
    pub mapping: FisheyeMapping,
    /// Full field of view across the image circle, in degrees.
    pub fov_degrees: f32,
    /// Image-circle radius in mapping units (`radius(fov / 2)`).
    radius_max: f32,
}

impl Fisheye {
    /// A fisheye camera; `Err` if the field of view is out of the mapping's range.
    pub fn new(
        resolution: UVec2,
        mapping: FisheyeMapping,
        fov_degrees: f32,
        render_from_camera: Transform,
    ) -> Result<Self, String> {
        if !(fov_degrees > 0.0 && fov_degrees <= mapping.max_fov()) {
            return Err(format!(
                "fisheye fov {fov_degrees} is outside (0, {}] for this mapping",
                mapping.max_fov()
            ));
        }
        let radius_max = mapping.radius(fov_degrees.to_radians() * 0.5);
        Ok(Fisheye {
            resolution,
            render_from_camera,
            mapping,
            fov_degrees,
            radius_max,
        })
    }

    /// The camera-space unit direction through a film point, or `None` outside the image
    /// circle.
    pub fn camera_direction(&self, film: Vec2) -> Option<Vec3> {
        let (w, h) = (self.resolution.x as f32, self.resolution.y as f32);
        // Unit circle inscribed in the shorter side.
        let n = normalized_film(film, self.resolution) * Vec2::new(w, h) / w.min(h);
        let r = n.length();
        if r > 1.0 {
            return None;
        }
        let theta = self.mapping.angle(r * self.radius_max);
        let (sin_t, cos_t) = theta.sin_cos();
        let (cos_p, sin_p) = if r > 0.0 {
            (n.x / r, n.y / r)
        } else {
            (1.0, 0.0)
        };
        Some(Vec3::new(sin_t * cos_p, sin_t * sin_p, cos_t))
    }

    pub fn generate_ray(&self, sample: &CameraSample) -> Option<Ray> {
        let d = self.camera_direction(sample.film)?;
        Some(Ray::new(
            self.render_from_camera.point(Vec3::ZERO),
            self.render_from_camera.vector(d).normalize(),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(cam: &Fisheye, x: f32, y: f32) -> Option<Vec3> {
        cam.camera_direction(Vec2::new(x, y))
    }

    #[test]
    fn centre_edge_and_outside() {
        for &m in &[
            FisheyeMapping::Equidistant,
            FisheyeMapping::Equisolid,
            FisheyeMapping::Orthographic,
            FisheyeMapping::Stereographic,
        ] {
            let cam = Fisheye::new(UVec2::new(300, 200), m, 180.0, Transform::IDENTITY).unwrap();
            assert!((at(&cam, 150.0, 100.0).unwrap() - Vec3::Z).length() < 1e-6);
            // The circle touches the top edge: straight "up" (-y), 90° off axis.
            let top = at(&cam, 150.0, 0.0).unwrap();
            assert!(
                (top.angle_between(Vec3::Z).to_degrees() - 90.0).abs() < 1e-3,
                "{m:?}"
            );
            assert!(top.y < -0.99);
            // Corners are outside the image circle.
            assert!(at(&cam, 0.0, 0.0).is_none());
            assert!(cam
                .generate_ray(&CameraSample {
                    film: Vec2::new(299.0, 1.0),
                    lens: Vec2::ZERO
                })
                .is_none());
        }
    }

    #[test]
    fn angle_per_mapping_at_half_radius() {
        // Half way to the edge of a 180° circle.
        let expected = [
            (FisheyeMapping::Equidistant, 45.0f32),
            (
                FisheyeMapping::Equisolid,
                2.0 * (0.5 * 2.0 * 45f32.to_radians().sin() / 2.0)
                    .asin()
                    .to_degrees(),
            ),
            (FisheyeMapping::Orthographic, 30.0),
            (
                FisheyeMapping::Stereographic,
                2.0 * (0.5f32).atan().to_degrees(),
            ),
        ];
        for (m, deg) in expected {
            let cam = Fisheye::new(UVec2::new(200, 200), m, 180.0, Transform::IDENTITY).unwrap();
            let d = at(&cam, 150.0, 100.0).unwrap();
            assert!(
                (d.angle_between(Vec3::Z).to_degrees() - deg).abs() < 1e-3,
                "{m:?}: {}",
                d.angle_between(Vec3::Z).to_degrees()
            );
            assert!(d.x > 0.0 && d.y.abs() < 1e-6);
        }
    }

    #[test]
    fn full_sphere_sees_behind() {
        let cam = Fisheye::new(
            UVec2::new(200, 200),
            FisheyeMapping::Equidistant,
            360.0,
            Transform::IDENTITY,
        )
        .unwrap();
        let edge = at(&cam, 200.0, 100.0).unwrap();
        assert!((edge - (-Vec3::Z)).length() < 1e-3);
        assert!(Fisheye::new(
            UVec2::new(2, 2),
            FisheyeMapping::Orthographic,
            200.0,
            Transform::IDENTITY
        )
        .is_err());
    }
}
