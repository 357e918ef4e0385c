//! Math: glam re-exports, rays, bounding boxes, orthonormal frames, transforms and the
//! floating-point error bounds that keep secondary rays off their own surface.

mod bounds;
mod float;
mod frame;
mod ray;
mod special;
mod transform;

pub use bounds::Bounds3;
pub use float::{gamma, next_float_down, next_float_up, offset_ray_origin};
pub use frame::Frame;
pub use glam::{Mat3, Mat4, Quat, Vec2, Vec3, Vec3A, Vec4};
pub use ray::Ray;
pub use special::{erf, erf_inv};
pub use transform::{AxisConvention, EulerOrder, Handedness, Transform};

/// π as `f32`.
pub const PI: f32 = std::f32::consts::PI;
/// 1/π.
pub const INV_PI: f32 = std::f32::consts::FRAC_1_PI;
