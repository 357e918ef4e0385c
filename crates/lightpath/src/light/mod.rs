//! Lights that next-event estimation samples directly, and the environment seen by rays
//! that leave the scene.
//!
//! ```xml
//! <light type="point" position="0,-3,-10" power="1000"/>          <!-- or intensity -->
//! <light type="directional" direction="-0.8,-2,-1" intensity="2.6,2.1,1.9"/>
//! <light type="spot" position="0,-3,0" direction="0,1,0" intensity="50" cutoffAngle="30" beamWidth="20"/>
//! <light type="envmap" weight="1">
//!     <texture type="image" filename="sky.hdr"/>
//!     <transform><rotate axis="0,1,0" angle="-50"/></transform>
//! </light>
//! ```
//!
//! Every light has a `weight` (default 1) that scales how often next-event estimation
//! picks it; a light with weight 0 is never sampled directly (an environment with weight
//! 0 is still seen by rays that escape).

mod area;
mod environment;
mod sampler;

pub(crate) use area::FlatTriangleSample;
pub use area::{AreaLight, Emission};
pub use environment::Environment;
pub use sampler::LightSampler;

use crate::math::{Bounds3, PI};
use glam::Vec3;

/// A light sample as seen from a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightSample {
    /// Unit direction from the point towards the light.
    pub wi: Vec3,
    /// Distance to the light along `wi` (infinite for distant lights).
    pub distance: f32,
    /// Incident radiance divided by the solid-angle density (for delta lights, the
    /// irradiance-like contribution).
    pub weight: Vec3,
    /// Solid-angle density (0 for delta lights, which MIS cannot weight).
    pub pdf: f32,
}

/// A point light.
#[derive(Debug, Clone, PartialEq)]
pub struct PointLight {
    pub position: Vec3,
    /// Radiant intensity (W/sr); `power` in a scene file is divided by 4π.
    pub intensity: Vec3,
}

/// A light from one direction, infinitely far away.
#[derive(Debug, Clone, PartialEq)]
pub struct DirectionalLight {
    /// Unit direction towards the light.
    pub direction: Vec3,
    /// Irradiance on a surface facing the light.
    pub intensity: Vec3,
}

/// A spot light: a point light restricted to a cone, with full intensity inside
/// `cos_falloff_start`, dark outside `cos_cutoff`, and a falloff of shape `profile`
/// between.
#[derive(Debug, Clone, PartialEq)]
pub struct SpotLight {
    pub position: Vec3,
    /// Unit direction the spot points to.
    pub direction: Vec3,
    pub intensity: Vec3,
    pub cos_falloff_start: f32,
    pub cos_cutoff: f32,
    pub profile: SpotProfile,
}

/// The shape of a spot light's falloff between its beam and its cutoff.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SpotProfile {
    /// A smoothstep of the cosine (pbrt, the lightwave course).
    #[default]
    SmoothstepCosine,
    /// Linear in the angle from the axis (Mitsuba's `spot`).
    LinearAngle,
    /// The square of the linear ramp in cosine (glTF's `KHR_lights_punctual`).
    SquaredCosine,
}

impl SpotLight {
    /// Intensity scale for a unit direction leaving the light.
    pub fn falloff(&self, w: Vec3) -> f32 {
        let c = w.dot(self.direction);
        if c >= self.cos_falloff_start {
            return 1.0;
        }
        if c <= self.cos_cutoff {
            return 0.0;
        }
        let t = (c - self.cos_cutoff) / (self.cos_falloff_start - self.cos_cutoff);
        match self.profile {
            SpotProfile::SmoothstepCosine => t * t * (3.0 - 2.0 * t),
            SpotProfile::SquaredCosine => t * t,
            SpotProfile::LinearAngle => {
                let (cutoff, beam) = (self.cos_cutoff.acos(), self.cos_falloff_start.acos());
                ((cutoff - c.min(1.0).acos()) / (cutoff - beam)).clamp(0.0, 1.0)
            }
        }
    }
}

/// Light from a point with intensity `intensity` arriving at `p` (inverse-square law).
fn point_sample(position: Vec3, intensity: Vec3, p: Vec3) -> Option<LightSample> {
    let d = position - p;
    let r2 = d.length_squared();
    if r2 == 0.0 {
        return None;
    }
    let r = r2.sqrt();
    Some(LightSample {
        wi: d / r,
        distance: r,
        weight: intensity / r2,
        pdf: 0.0,
    })
}

/// A light of any kind.
#[derive(Debug, Clone)]
pub enum Light {
    Point(PointLight),
    Directional(DirectionalLight),
    Spot(SpotLight),
    Environment(Environment),
    Area(AreaLight),
}

/// Luminance of linear sRGB.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

impl Light {
    /// Samples light arriving at `p`; `u_prim` picks a part of a shape made of a few (a
    /// cuboid's face, a cylinder's side or cap), `u` the point on it. Triangle meshes
    /// pick their triangle with `u.x` and reuse it inside the triangle instead, so that a
    /// stratified `u` stays stratified over the whole mesh.
    #[inline(always)]
    pub fn sample(&self, p: Vec3, u_prim: f32, u: glam::Vec2) -> Option<LightSample> {
        match self {
            Light::Point(l) => point_sample(l.position, l.intensity, p),
            Light::Spot(l) => {
                let mut ls = point_sample(l.position, l.intensity, p)?;
                let scale = l.falloff(-ls.wi);
                if scale == 0.0 {
                    return None;
                }
                ls.weight *= scale;
                Some(ls)
            }
            Light::Directional(l) => Some(LightSample {
                wi: l.direction,
                distance: f32::INFINITY,
                weight: l.intensity,
                pdf: 0.0,
            }),
            Light::Environment(e) => e.sample(u),
            Light::Area(a) => a.sample(p, u_prim, u),
        }
    }

    /// Approximate emitted power, for choosing lights in proportion to it. Distant lights
    /// use the scene's bounding sphere.
    pub fn power(&self, scene_bounds: &Bounds3) -> f32 {
        let radius = if scene_bounds.is_empty() {
            1.0
        } else {
            scene_bounds.diagonal().length() * 0.5
        };
        match self {
            Light::Point(l) => 4.0 * PI * luminance(l.intensity),
            Light::Spot(l) => {
                2.0 * PI
                    * luminance(l.intensity)
                    * (1.0 - 0.5 * (l.cos_falloff_start + l.cos_cutoff))
            }
            Light::Directional(l) => PI * radius * radius * luminance(l.intensity),
            Light::Environment(e) => 4.0 * PI * PI * radius * radius * luminance(e.average()),
            Light::Area(a) => a.power(),
        }
    }

    /// Whether rays that sample the BSDF can reach this light (then its next-event
    /// estimates are weighted by MIS against theirs): the environment and area lights
    /// that are scene geometry; not delta lights, nor area lights outside the scene.
    pub fn reachable_by_rays(&self) -> bool {
        match self {
            Light::Environment(_) => true,
            Light::Area(a) => a.placed,
            _ => false,
        }
    }
}
