//! lightpath: a physically based ray tracer.
//!
//! The data path: [`io::load_scene`] reads a scene file into a [`scene::Scene`] (shapes
//! in acceleration structures, a camera), an [`integrator::Integrator`] and a
//! [`sampling::Sampler`]; [`render::Renderer`] renders it on all cores into a
//! [`film::Image`], written by [`io::image::write_image`].
//!
//! The library never prints: it reports progress through a callback and errors through
//! [`Error`], which names the file, line and column of bad input.

pub mod accel;
pub mod camera;
mod cpu;
mod error;
pub mod film;
pub mod geometry;
pub mod integrator;
pub mod io;
pub mod light;
pub mod material;
pub mod math;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod texture;

pub use cpu::{limit_simd_tier, simd_tier, SimdTier};
pub use error::{Error, Location, Result};

/// The types most programs need.
pub mod prelude {
    pub use crate::accel::AccelKind;
    pub use crate::camera::{Camera, CameraSample, FovAxis, Perspective};
    pub use crate::film::Image;
    pub use crate::geometry::{Shape, Sphere, SurfaceInteraction, TriangleMesh};
    pub use crate::io::{load_scene, LoadOptions, LoadedScene};
    pub use crate::math::{Bounds3, Ray, Transform, Vec2, Vec3};
    pub use crate::render::Renderer;
    pub use crate::scene::{Scene, SceneBuilder};
    pub use crate::{Error, Result};
}
