//! Math: glam re-exports, rays, bounding boxes, orthonormal frames, transforms and the
//! floating-point error bounds that keep secondary rays off their own surface.

mod bounds;
mod float;
mod frame;
pub mod lanes;
mod ray;
mod special;
mod transform;

pub use bounds::Bounds3;
pub use float::{gamma, next_float_down, next_float_up, offset_ray_origin, round_away};
pub use frame::Frame;
pub use glam::{Mat3, Mat4, Quat, UVec2, Vec2, Vec3, Vec3A, Vec4};
pub use ray::Ray;
pub use special::{erf, erf_inv};
pub use transform::{AxisConvention, EulerOrder, Handedness, Transform};

/// π as `f32`.
pub const PI: f32 = std::f32::consts::PI;
/// 1/π.
pub const INV_PI: f32 = std::f32::consts::FRAC_1_PI;

/// `v` scaled to unit length as [`Vec3::normalize`] does it (times the reciprocal
/// length), for hot paths that compute in 4-lane [`Vec3A`]s: `Vec3A::normalize` divides
/// instead, which rounds differently, so mixing the two would change images in their
/// last bits.
#[inline(always)]
pub fn unit(v: Vec3A) -> Vec3A {
    v * v.length_recip()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `unit` and the 4-lane dot, cross and length equal `Vec3`'s bit for bit.
    #[test]
    fn vec3a_arithmetic_equals_vec3() {
        let mut rng = crate::sampling::Pcg32::new(9, 4);
        let mut v = || {
            Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 200.0 - Vec3::splat(100.0)
        };
        for _ in 0..100_000 {
            let (a, b) = (v(), v());
            let (aa, ba) = (Vec3A::from(a), Vec3A::from(b));
            assert_eq!(Vec3::from(unit(aa)), a.normalize());
            assert_eq!(Vec3::from(aa.cross(ba)), a.cross(b));
            assert_eq!(aa.dot(ba), a.dot(b));
            assert_eq!(aa.length(), a.length());
        }
    }
}
