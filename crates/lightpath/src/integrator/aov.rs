//! Arbitrary output variables: geometric quantities of the first hit, for debugging and
//! for the course's tests.
//!
//! ```xml
//! <integrator type="aov" variable="normals">   <!-- or rawnormals, distance, uv, albedo, bvh -->
//!     <scene>...</scene>
//! </integrator>
//! <integrator type="aov" variable="bvh" scale="100">...</integrator>
//! <integrator type="normals" remap="false">...</integrator>   <!-- lightwave's names -->
//! <integrator type="albedo">...</integrator>
//! ```
//!
//! | variable     | value                                                           | miss      |
//! |--------------|-----------------------------------------------------------------|-----------|
//! | `normals`    | shading normal mapped to colour, `(n + 1) / 2`                  | 0.5       |
//! | `rawnormals` | shading normal `n`                                              | 0         |
//! | `distance`   | distance from the ray origin to the hit                         | 0         |
//! | `uv`         | texture coordinates `(u, v, 0)`                                 | 0         |
//! | `albedo`     | the material's colour (as a denoiser's feature buffer)          | 0         |
//! | `bvh`        | `(nodes visited, primitives tested, 0) / scale`                 | counts    |
//!
//! lightwave's `normals` integrator is `normals` (`remap="false"`: `rawnormals`), its
//! `albedo` integrator `albedo`.
//!
//! [`AovLayer`] and [`first_hit`] are the layers `lightpath render --aov` writes into
//! the EXR beside the image (see [`crate::render::Renderer::render_aovs`]).

use crate::accel::RayStats;
use crate::math::Ray;
use crate::scene::Scene;
use glam::Vec3;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AovVariable {
    Normals,
    /// The shading normal itself, not remapped (lightwave's `normals` integrator with
    /// `remap="false"`).
    RawNormals,
    Distance,
    Uv,
    Albedo,
    Bvh,
}

impl AovVariable {
    pub const NAMES: &'static [&'static str] =
        &["normals", "rawnormals", "distance", "uv", "albedo", "bvh"];

    pub fn from_name(name: &str) -> Option<AovVariable> {
        match name {
            "normals" => Some(AovVariable::Normals),
            "rawnormals" => Some(AovVariable::RawNormals),
            "distance" => Some(AovVariable::Distance),
            "uv" => Some(AovVariable::Uv),
            "albedo" => Some(AovVariable::Albedo),
            "bvh" => Some(AovVariable::Bvh),
            _ => None,
        }
    }
}

#[derive(Debug, Clone)]
pub struct Aov {
    pub variable: AovVariable,
    /// Divisor of the `bvh` counters.
    pub scale: f32,
}

impl Aov {
    pub fn li(&self, scene: &Scene, ray: &Ray, stats: &mut RayStats) -> Vec3 {
        let mut ray_stats = RayStats::default();
        let hit = scene.intersect_with_stats(ray, &mut ray_stats);
        stats.nodes_visited += ray_stats.nodes_visited;
        stats.prims_tested += ray_stats.prims_tested;
        match self.variable {
            AovVariable::Normals => match hit {
                Some(si) => (si.shading_n + Vec3::ONE) * 0.5,
                None => Vec3::splat(0.5),
            },
            AovVariable::RawNormals => hit.map_or(Vec3::ZERO, |si| si.shading_n),
            AovVariable::Albedo => hit.map_or(Vec3::ZERO, |si| {
                scene
                    .material(&si)
                    .map_or(Vec3::ZERO, |m| m.albedo(si.tex()))
            }),
            AovVariable::Distance => {
                hit.map_or(Vec3::ZERO, |si| Vec3::splat(si.t * ray.direction.length()))
            }
            AovVariable::Uv => hit.map_or(Vec3::ZERO, |si| Vec3::new(si.uv.x, si.uv.y, 0.0)),
            AovVariable::Bvh => {
                Vec3::new(
                    ray_stats.nodes_visited as f32,
                    ray_stats.prims_tested as f32,
                    0.0,
                ) / self.scale
            }
        }
    }
}

/// An extra layer written beside the image (`lightpath render --aov albedo,normal,depth`),
/// from the first hit of each camera sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AovLayer {
    /// The hit material's colour ([`crate::material::Material::albedo`]); 0 for misses
    /// and surfaces without a material.
    Albedo,
    /// The shading normal in render space (as interpolated, before normal maps); 0 for
    /// misses.
    Normal,
    /// The distance from the camera ray's origin to the hit; averaged over the samples
    /// that hit, +inf where none does.
    Depth,
}

impl AovLayer {
    pub const NAMES: &'static [&'static str] = &["albedo", "normal", "depth"];

    pub fn from_name(name: &str) -> Option<AovLayer> {
        match name {
            "albedo" => Some(AovLayer::Albedo),
            "normal" => Some(AovLayer::Normal),
            "depth" => Some(AovLayer::Depth),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            AovLayer::Albedo => "albedo",
            AovLayer::Normal => "normal",
            AovLayer::Depth => "depth",
        }
    }

    /// The layer's EXR channel names.
    pub fn channels(self) -> &'static [&'static str] {
        match self {
            AovLayer::Albedo => &["albedo.R", "albedo.G", "albedo.B"],
            AovLayer::Normal => &["normal.X", "normal.Y", "normal.Z"],
            AovLayer::Depth => &["depth.Z"],
        }
    }
}

/// What the AOV layers record about a camera ray's first hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FirstHit {
    pub albedo: Vec3,
    /// Unit shading normal in render space.
    pub normal: Vec3,
    /// Distance from the ray's origin.
    pub depth: f32,
}

/// The first hit of a camera ray, `None` for a miss.
pub fn first_hit(scene: &Scene, ray: &Ray) -> Option<FirstHit> {
    let si = scene.intersect(ray)?;
    let albedo = scene
        .material(&si)
        .map_or(Vec3::ZERO, |m| m.albedo(si.tex()));
    Some(FirstHit {
        albedo,
        normal: si.shading_n,
        depth: si.t * ray.direction.length(),
    })
}
