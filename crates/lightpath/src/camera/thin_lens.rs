//! The thin-lens camera: depth of field around a focal plane, with a shaped aperture
//! (round, an N-bladed polygon, or an image mask) that shapes the bokeh.
//!
//! ```xml
//! <camera type="thinlens">
//!     <integer name="width" value="640"/>
//!     <integer name="height" value="480"/>
//!     <float name="fov" value="40"/>
//!     <float name="apertureRadius" value="0.1"/>
//!     <float name="focusDistance" value="5"/>
//!     <integer name="blades" value="6"/>          <!-- optional: polygonal aperture -->
//!     <float name="bladeRotation" value="15"/>   <!-- degrees -->
//!     <string name="apertureImage" value="heart.png"/> <!-- optional: image mask -->
//! </camera>
//! ```
//!
//! The focal plane is the plane z = `focusDistance` in camera space; every ray through a
//! given film point meets the pinhole ray through it there. `lensRadius` and
//! `focalDistance` are accepted for `apertureRadius` and `focusDistance`.

use super::{CameraSample, Perspective};
use crate::math::Ray;
use crate::sampling::{warp, Distribution2D};
use glam::{Vec2, Vec3};

/// The shape of the lens aperture, scaled to `aperture_radius`.
#[derive(Debug, Clone)]
pub enum Aperture {
    /// A disk.
    Disk,
    /// A regular polygon with `blades` corners on the unit circle, rotated by `rotation`
    /// radians.
    Polygon { blades: u32, rotation: f32 },
    /// A mask image mapped onto [-1, 1]²: points are drawn in proportion to its
    /// brightness. The image's top row lies at camera-space y = -1 (image up).
    Image(Box<Distribution2D>),
}

impl Aperture {
    /// A point on the aperture in [-1, 1]² for a uniform `u`.
    #[inline]
    pub fn sample(&self, u: Vec2) -> Vec2 {
        match self {
            Aperture::Disk => warp::square_to_uniform_disk_concentric(u),
            Aperture::Polygon { blades, rotation } => {
                warp::square_to_uniform_polygon(u, *blades, *rotation)
            }
            Aperture::Image(d) => {
                let (p, _) = d.sample(u);
                // Image row 0 is the top of the mask: camera-space -y.
                Vec2::new(2.0 * p.x - 1.0, 2.0 * p.y - 1.0)
            }
        }
    }
}

#[derive(Debug, Clone)]
pub struct ThinLens {
    /// The pinhole camera through the lens centre (resolution, transform, field of view).
    pub pinhole: Perspective,
    pub aperture_radius: f32,
    pub focus_distance: f32,
    pub aperture: Aperture,
}

impl ThinLens {
    #[inline]
    pub fn generate_ray(&self, sample: &CameraSample) -> Ray {
        let d = self.pinhole.camera_direction(sample.film);
        let to = &self.pinhole.render_from_camera;
        if self.aperture_radius <= 0.0 {
            return Ray::new(to.point(Vec3::ZERO), to.vector(d).normalize());
        }
        // d has z = 1, so the focal point is d scaled to the focus distance.
        let focus = d * self.focus_distance;
        let lens = self.aperture.sample(sample.lens) * self.aperture_radius;
        let origin = Vec3::new(lens.x, lens.y, 0.0);
        Ray::new(to.point(origin), to.vector(focus - origin).normalize())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::FovAxis;
    use crate::math::Transform;
    use crate::sampling::Pcg32;
    use glam::UVec2;

    fn lens(aperture: Aperture) -> ThinLens {
        let to = Transform::look_at(Vec3::new(1.0, 2.0, -3.0), Vec3::ZERO, Vec3::Y).unwrap();
        ThinLens {
            pinhole: Perspective::new(UVec2::new(64, 48), 50.0, FovAxis::X, to),
            aperture_radius: 0.2,
            focus_distance: 4.0,
            aperture,
        }
    }

    #[test]
    fn rays_converge_on_the_focal_plane() {
        for aperture in [
            Aperture::Disk,
            Aperture::Polygon {
                blades: 6,
                rotation: 0.3,
            },
        ] {
            let cam = lens(aperture);
            let to = cam.pinhole.render_from_camera;
            let mut rng = Pcg32::new(1, 2);
            for _ in 0..100 {
                let film = Vec2::new(rng.next_f32() * 64.0, rng.next_f32() * 48.0);
                let pin = cam.pinhole.camera_direction(film) * cam.focus_distance;
                let target = to.point(pin);
                let mut origins = Vec::new();
                for _ in 0..8 {
                    let r = cam.generate_ray(&CameraSample {
                        film,
                        lens: Vec2::new(rng.next_f32(), rng.next_f32()),
                    });
                    // Where the ray meets the focal plane (camera z = focus distance).
                    let o = to.inverse().point(r.origin);
                    let d = to.inverse().vector(r.direction);
                    let t = (cam.focus_distance - o.z) / d.z;
                    assert!((to.point(o + d * t) - target).length() < 1e-4);
                    assert!(o.z.abs() < 1e-5 && Vec2::new(o.x, o.y).length() <= 0.2 + 1e-5);
                    origins.push(o);
                }
                // The origins are spread over the lens.
                assert!(origins.iter().any(|o| (*o - origins[0]).length() > 1e-3));
            }
        }
    }

    #[test]
    fn image_aperture_follows_the_mask() {
        // A 2x2 mask with only the top-right texel lit: all lens points in x > 0, y < 0.
        let d = Distribution2D::new(&[0.0, 1.0, 0.0, 0.0], 2, 2);
        let cam = lens(Aperture::Image(Box::new(d)));
        let mut rng = Pcg32::new(3, 4);
        for _ in 0..200 {
            let p = cam
                .aperture
                .sample(Vec2::new(rng.next_f32(), rng.next_f32()));
            assert!(p.x >= 0.0 && p.y <= 0.0, "{p}");
        }
    }
}
