//! The course's `camera` integrator: each ray's direction as a colour, `(d + 1) / 2`,
//! under a grid of black lines where the ray's line meets the plane z = 1 in render
//! space (lines every 0.1 units, 0.01 wide, mirrored about the axes so the axes come out
//! twice as thick), so camera position, orientation and field of view can be checked at
//! a glance.
//!
//! ```xml
//! <integrator type="camera">
//!     <scene>...</scene>
//! </integrator>
//! ```

use crate::math::Ray;
use crate::sampling::Sampler;
use glam::Vec3;

#[derive(Debug, Clone, Default)]
pub struct CameraDirection;

/// Lines per unit on the z = 1 plane.
const LINES_PER_UNIT: f32 = 10.0;
/// Line width as a fraction of the spacing.
const LINE_WIDTH: f32 = 0.1;

impl CameraDirection {
    pub fn li(&self, ray: &Ray, _sampler: &mut Sampler) -> Vec3 {
        let d = ray.direction.normalize();
        // Where the ray's line meets z = 1 (behind the origin too). A ray parallel to the
        // plane gives no finite point and no line.
        let t = (1.0 - ray.origin.z) / d.z;
        let on_plane = ray.origin + d * t;
        for c in [on_plane.x, on_plane.y] {
            if c.is_finite() && (c.abs() * LINES_PER_UNIT).fract() < LINE_WIDTH {
                return Vec3::ZERO;
            }
        }
        (d + Vec3::ONE) * 0.5
    }
}
