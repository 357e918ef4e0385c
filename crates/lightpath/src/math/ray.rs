//! A ray with its valid parameter range.

use glam::Vec3;

/// A ray `origin + t * direction` for `t` in `[t_min, t_max]`.
///
/// `t` is measured in units of `direction`, which need not be unit length (object-space
/// rays of scaled instances are not).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub direction: Vec3,
    pub t_min: f32,
    pub t_max: f32,
}

impl Ray {
    /// A ray over `[0, ∞)`.
    #[inline]
    pub fn new(origin: Vec3, direction: Vec3) -> Self {
        Ray {
            origin,
            direction,
            t_min: 0.0,
            t_max: f32::INFINITY,
        }
    }

    /// A ray over `[t_min, t_max]`.
    #[inline]
    pub fn with_range(origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Self {
        Ray {
            origin,
            direction,
            t_min,
            t_max,
        }
    }

    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.direction * t
    }
}
