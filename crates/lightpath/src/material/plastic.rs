//! Smooth plastic: a diffuse base under a smooth dielectric coating, after Mitsuba 3's
//! `plastic`. A delta specular lobe reflects with weight `specularReflectance`·F(cos θo);
//! the rest enters the coating, scatters diffusely, and leaves with
//!
//! f·cos θi = diff·(1 − F(cos θo))·(1 − F(cos θi))/η² · cos θi/π,
//!
//! where the internal reflections at the coating are summed as diff = ρ/(1 − F_dr,int)
//! (`nonlinear="false"`, the default: the texture's colour is preserved) or
//! ρ/(1 − ρ·F_dr,int) (`nonlinear="true"`: the colour saturates as in real varnish).
//! F_dr,int is the coating's hemispherical reflectance from inside, computed numerically.
//! With ρ = 1 and specular 1 the material is energy conserving (the η² law of
//! hemispherical transmittance). The specular lobe is picked with probability
//! F·s/(F·s + (1 − F)·(1 − s)), s = mean(specular)/(mean(diffuse) + mean(specular)).
//! One-sided: black when wo or wi is below the shading normal (wrap it in `twosided`).
//!
//! ```xml
//! <bsdf type="plastic">
//!     <texture name="diffuseReflectance" type="constant" value="0.1,0.3,0.7"/>
//!     <float name="ior" value="1.5"/>
//!     <texture name="specularReflectance" type="constant" value="1"/>   <!-- optional -->
//!     <boolean name="nonlinear" value="false"/>                         <!-- optional -->
//! </bsdf>
//! ```

use super::fresnel::{fresnel_dielectric, fresnel_diffuse_reflectance};
use super::{valid_pdf, BsdfSample};
use crate::math::INV_PI;
use crate::sampling::warp;
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct Plastic {
    pub diffuse: Arc<Texture>,
    pub specular: Arc<Texture>,
    /// Interior index over exterior index.
    pub eta: f32,
    pub nonlinear: bool,
    /// Hemispherical Fresnel reflectance of the coating seen from inside.
    fdr_int: f32,
    /// Weight steering samples to the specular lobe.
    specular_sampling_weight: f32,
}

impl Plastic {
    pub fn new(
        diffuse: Arc<Texture>,
        specular: Arc<Texture>,
        ior: f32,
        nonlinear: bool,
    ) -> Plastic {
        let d_mean = diffuse.average().dot(Vec3::splat(1.0 / 3.0)).max(0.0);
        let s_mean = specular.average().dot(Vec3::splat(1.0 / 3.0)).max(0.0);
        let total = d_mean + s_mean;
        Plastic {
            diffuse,
            specular,
            eta: ior,
            nonlinear,
            fdr_int: fresnel_diffuse_reflectance(1.0 / ior),
            specular_sampling_weight: if total > 0.0 { s_mean / total } else { 0.5 },
        }
    }

    /// Probability of picking the specular lobe given F(cos θo).
    #[inline]
    fn prob_specular(&self, f_o: f32) -> f32 {
        let ps = f_o * self.specular_sampling_weight;
        let pd = (1.0 - f_o) * (1.0 - self.specular_sampling_weight);
        if ps + pd > 0.0 {
            ps / (ps + pd)
        } else {
            1.0
        }
    }

    /// The diffuse base's colour after the internal reflections.
    #[inline]
    fn base(&self, uv: TexCoord) -> Vec3 {
        let rho = self.diffuse.eval(uv);
        if self.nonlinear {
            rho / (Vec3::ONE - rho * self.fdr_int)
        } else {
            rho / (1.0 - self.fdr_int)
        }
    }

    /// The non-delta (diffuse) part: f·cos θi.
    pub fn eval(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let f_o = fresnel_dielectric(wo.z, self.eta);
        let f_i = fresnel_dielectric(wi.z, self.eta);
        self.base(uv) * ((1.0 - f_o) * (1.0 - f_i) / (self.eta * self.eta) * wi.z * INV_PI)
    }

    /// Density of the diffuse lobe's directions (the specular lobe is a delta).
    pub fn pdf(&self, _uv: TexCoord, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let f_o = fresnel_dielectric(wo.z, self.eta);
        (1.0 - self.prob_specular(f_o)) * wi.z * INV_PI
    }

    pub fn sample(&self, uv: TexCoord, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let f_o = fresnel_dielectric(wo.z, self.eta);
        let p_spec = self.prob_specular(f_o);
        if u_lobe < p_spec {
            return Some(BsdfSample {
                wi: Vec3::new(-wo.x, -wo.y, wo.z),
                weight: self.specular.eval(uv) * (f_o / p_spec),
                pdf: p_spec,
                delta: true,
            });
        }
        let wi = warp::square_to_cosine_hemisphere(u);
        let pdf = (1.0 - p_spec) * wi.z * INV_PI;
        if !valid_pdf(pdf) {
            return None;
        }
        let f_i = fresnel_dielectric(wi.z, self.eta);
        let weight =
            self.base(uv) * ((1.0 - f_o) * (1.0 - f_i) / (self.eta * self.eta * (1.0 - p_spec)));
        Some(BsdfSample {
            wi,
            weight,
            pdf,
            delta: false,
        })
    }
}
