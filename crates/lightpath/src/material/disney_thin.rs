//! The thin Disney principled BSDF as Mitsuba 3 defines it (its `principledthin`
//! plugin, after Burley 2015): a sheet with no inside, such as a leaf, paper or a
//! curtain, seen the same from both sides. The Mitsuba dialect creates it for
//! `principledthin`.
//!
//! Both directions are first mirrored to the side wo is on. With wo the viewing and wi
//! the lighting direction, s = spec_trans, t = diff_trans/2 (`diff_trans` runs from 0 to
//! 2), m the half vector of wo and wi mirrored to wo's side, F_d the dielectric Fresnel
//! of `eta` at wo·m, f·|cos θi| is the sum of
//!
//! - specular reflection: s·lerp(F_d, S(tint·R0(η)), spec_tint)·D·G/(4|cos θo|), GGX with
//!   (αx, αy) from roughness and anisotropy as in [`super::DisneyPrincipled`];
//! - specular transmission, straight through the sheet (a reflection mirrored to the
//!   far side): s·base_color·(1 − F_d)·D'·G'/(4|cos θo|), D' and G' of the roughness
//!   scaled by 0.65η − 0.35;
//! - diffuse reflection with retro-reflection, flatness and sheen as in the principled
//!   BSDF, times (1 − s)(1 − t);
//! - Lambertian transmission: (1 − s)·t·base_color/π·|cos θi|.
//!
//! Sampling picks specular reflection, specular transmission, cosine reflection or
//! cosine transmission in proportion to s·r/2, s·r/2, (1 − s)(1 − t)·r and (1 − s)·t·r
//! (the four `*_sampling_rate`s r, default 1); the pdf is the mixture and the weight
//! eval/pdf. Values and densities match Mitsuba 3.9.1's `principledthin` (tested at
//! sampled directions).
//!
//! ```xml
//! <bsdf type="principledthin">
//!     <rgb name="base_color" value="0.3,0.6,0.2"/>      <!-- default 0.5 -->
//!     <float name="roughness" value="0.4"/>             <!-- default 0.5 -->
//!     <float name="diff_trans" value="0.8"/>            <!-- 0 to 2, default 0 -->
//!     <float name="spec_trans" value="0.2"/>            <!-- defaults 0 from here on -->
//!     <float name="eta" value="1.4"/>                   <!-- default 1.5 -->
//!     <float name="spec_tint" value="0.1"/> <float name="anisotropic" value="0"/>
//!     <float name="sheen" value="0.3"/> <float name="sheen_tint" value="0.5"/>
//!     <float name="flatness" value="0.2"/>
//! </bsdf>
//! ```

use super::disney_principled::{burley_diffuse, ggx, schlick, sheen, tint};
use super::fresnel::fresnel_dielectric_cos;
use super::microfacet::{reflect, Microfacet};
use super::{scalar, BsdfSample};
use crate::math::INV_PI;
use crate::sampling::warp;
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct DisneyThin {
    pub base_color: Arc<Texture>,
    pub roughness: Arc<Texture>,
    pub anisotropic: Arc<Texture>,
    pub spec_trans: Arc<Texture>,
    pub spec_tint: Arc<Texture>,
    pub sheen: Arc<Texture>,
    pub sheen_tint: Arc<Texture>,
    pub flatness: Arc<Texture>,
    /// From 0 (diffuse reflection only) to 2 (diffuse transmission only).
    pub diff_trans: Arc<Texture>,
    /// The sheet's index of refraction (relative to its surroundings).
    pub eta: Arc<Texture>,
    pub specular_reflectance_sampling_rate: f32,
    pub specular_transmittance_sampling_rate: f32,
    pub diffuse_reflectance_sampling_rate: f32,
    pub diffuse_transmittance_sampling_rate: f32,
}

/// The parameters at one point.
struct Params {
    base: Vec3,
    roughness: f32,
    anisotropic: f32,
    spec_trans: f32,
    spec_tint: f32,
    sheen: f32,
    sheen_tint: f32,
    flatness: f32,
    /// `diff_trans` / 2.
    diff_trans: f32,
    eta: f32,
}

/// The normalised lobe probabilities: specular reflection, specular transmission,
/// cosine reflection, cosine transmission.
type Choice = [f32; 4];

impl DisneyThin {
    fn params(&self, uv: TexCoord) -> Params {
        Params {
            base: self.base_color.eval(uv),
            roughness: scalar(&self.roughness, uv),
            anisotropic: scalar(&self.anisotropic, uv),
            spec_trans: scalar(&self.spec_trans, uv),
            spec_tint: scalar(&self.spec_tint, uv),
            sheen: scalar(&self.sheen, uv),
            sheen_tint: scalar(&self.sheen_tint, uv),
            flatness: scalar(&self.flatness, uv),
            diff_trans: 0.5 * scalar(&self.diff_trans, uv),
            eta: scalar(&self.eta, uv),
        }
    }

    fn choice(&self, p: &Params) -> Choice {
        let s = p.spec_trans;
        let c = [
            0.5 * s * self.specular_reflectance_sampling_rate,
            0.5 * s * self.specular_transmittance_sampling_rate,
            self.diffuse_reflectance_sampling_rate * (1.0 - s) * (1.0 - p.diff_trans),
            self.diffuse_transmittance_sampling_rate * (1.0 - s) * p.diff_trans,
        ];
        let total: f32 = c.iter().sum();
        let inv = if total > 0.0 { 1.0 / total } else { 0.0 };
        c.map(|x| x * inv)
    }

    /// The specular transmission's distribution: roughness scaled by 0.65η − 0.35.
    fn transmission_ggx(p: &Params) -> Microfacet {
        ggx((0.65 * p.eta - 0.35) * p.roughness, p.anisotropic)
    }

    /// f·|cos θi| and the density of sampling `wi`.
    fn eval_pdf(&self, p: &Params, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wo.z == 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        // Seen from wo's side: the sheet is the same from both.
        let side = if wo.z > 0.0 { 1.0 } else { -1.0 };
        let (wo, wi) = (wo * side, wi * side);
        let (cos_o, cos_i) = (wo.z, wi.z);
        let reflect = cos_i > 0.0;
        let refract = cos_i < 0.0;
        if !reflect && !refract {
            return (Vec3::ZERO, 0.0);
        }
        let m = (wo + Vec3::new(wi.x, wi.y, cos_i.abs())).normalize();
        let (wo_m, wi_m) = (wo.dot(m), wi.dot(m));
        let reflect_ok = reflect && wo_m > 0.0 && wi_m > 0.0;
        let refract_ok = refract && wo_m > 0.0 && wi_m < 0.0;
        let (s, t) = (p.spec_trans, p.diff_trans);
        let choice = self.choice(p);

        let mut value = Vec3::ZERO;
        let mut pdf = 0.0;
        if s > 0.0 && (reflect_ok || refract_ok) {
            let (f, _) = fresnel_dielectric_cos(wo_m, p.eta);
            // |dm/dwi|: the transmitted direction is a reflection mirrored.
            let jacobian = (1.0 / (4.0 * wo_m)).abs();
            if reflect_ok {
                let ggx = ggx(p.roughness, p.anisotropic);
                let fresnel = if p.spec_tint > 0.0 {
                    let r0 = ((p.eta - 1.0) / (p.eta + 1.0)).powi(2);
                    let tinted = schlick(tint(p.base) * r0, wo_m, p.eta);
                    Vec3::splat(f) + (tinted - Vec3::splat(f)) * p.spec_tint
                } else {
                    Vec3::splat(f)
                };
                let dg = ggx.d(m) * ggx.g1(wo, m) * ggx.g1(wi, m);
                value += fresnel * (s * dg / (4.0 * cos_o));
                pdf += choice[0] * ggx.pdf_visible(wo, m) * jacobian;
            } else {
                let ggx = Self::transmission_ggx(p);
                let dg = ggx.d(m) * ggx.g1(wo, m) * ggx.g1(wi, m);
                value += p.base * (s * (1.0 - f) * dg / (4.0 * cos_o));
                pdf += choice[1] * ggx.pdf_visible(wo, m) * jacobian;
            }
        }
        if reflect && s < 1.0 && t < 1.0 {
            let cos_d = m.dot(wi);
            let lobe = burley_diffuse(p.roughness, p.flatness, cos_o, cos_i, cos_d);
            let weight = (1.0 - s) * (1.0 - t);
            value += p.base * (weight * cos_i * INV_PI * lobe);
            if p.sheen > 0.0 {
                value += sheen(p.base, p.sheen_tint, cos_d) * (p.sheen * weight * cos_i);
            }
        }
        if refract && s < 1.0 && t > 0.0 {
            value += p.base * ((1.0 - s) * t * INV_PI * -cos_i);
        }
        if reflect {
            pdf += choice[2] * cos_i * INV_PI;
        } else {
            pdf += choice[3] * -cos_i * INV_PI;
        }
        (value, pdf)
    }

    pub fn eval(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_pdf(&self.params(uv), wo, wi).0
    }

    pub fn pdf(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(&self.params(uv), wo, wi).1
    }

    pub fn sample(&self, uv: TexCoord, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let p = self.params(uv);
        let side = if wo.z > 0.0 { 1.0 } else { -1.0 };
        let v = wo * side;
        let c = self.choice(&p);
        // As Mitsuba, a specular sample whose microfacet does not face both directions
        // from the right sides is dropped.
        let wi = if u_lobe < c[0] {
            let m = ggx(p.roughness, p.anisotropic).sample_visible(v, u);
            let wi = reflect(v, m);
            (wi.z > 0.0 && v.dot(m) > 0.0 && wi.dot(m) > 0.0).then_some(wi)?
        } else if u_lobe < c[0] + c[1] {
            let m = Self::transmission_ggx(&p).sample_visible(v, u);
            let r = reflect(v, m);
            let wi = Vec3::new(r.x, r.y, -r.z);
            (wi.z < 0.0 && v.dot(m) > 0.0 && wi.dot(m) < 0.0).then_some(wi)?
        } else if u_lobe < c[0] + c[1] + c[2] {
            warp::square_to_cosine_hemisphere(u)
        } else if c[3] > 0.0 {
            -warp::square_to_cosine_hemisphere(u)
        } else {
            return None;
        };
        let wi = wi * side;
        let (value, pdf) = self.eval_pdf(&p, wo, wi);
        BsdfSample::from_eval(wi, value, pdf)
    }
}
