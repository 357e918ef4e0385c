//! The Disney principled BSDF as Mitsuba 3 defines it (its `principled` plugin, after
//! Burley's 2012 and 2015 course notes): one material whose artist-friendly parameters,
//! all in [0, 1] except `eta`, blend a diffuse base with retro-reflection, sheen and a
//! fake subsurface term, a GGX specular lobe whose Fresnel mixes dielectric, tinted and
//! metallic responses, a rough dielectric transmission lobe and a GTR1 clearcoat. The
//! Mitsuba dialect creates it for `principled` (the course's simpler model,
//! [`super::Principled`], keeps that name in the lightwave dialect).
//!
//! With wo the viewing and wi the lighting direction (Mitsuba's `si.wi` and `wo`),
//! brdf = (1 − metallic)(1 − spec_trans), bsdf = (1 − metallic)·spec_trans, and
//! (αx, αy) = max(0.001, roughness²) divided and multiplied by √(1 − 0.9·anisotropic),
//! f·|cos θi| is the sum of
//!
//! - specular reflection: F·D·G/(4|cos θo|), where seen from outside
//!   F = (1 − metallic)(1 − spec_tint)·F_d + metallic·S(base_color) +
//!   (1 − metallic)·spec_tint·S(tint·R0(η)), F_d the exact dielectric Fresnel of η, S
//!   Schlick's approximation (with the refracted cosine inside a denser medium), tint the
//!   base colour over its luminance; from inside F = bsdf·F_d;
//! - specular transmission: √base_color·bsdf·(1 − F_d)·D·G·|wo·m||wi·m|/
//!   (|cos θo|(wo·m + η'wi·m)²), η' the index of the side wi is on over wo's (radiance
//!   transport);
//! - clearcoat: clearcoat/4·S(0.04)·D_GTR1(m)·G_cc·|cos θi|, GTR1's α from 0.1 to 0.001
//!   as clearcoat_gloss goes from 0 to 1, G_cc separable GGX masking with α 0.25 (the
//!   missing 1/(4 cos θo cos θi) is Mitsuba's);
//! - from outside only, diffuse with retro-reflection:
//!   brdf·base_color/π·|cos θi|·lerp((1 − Fi/2)(1 − Fo/2) + Rr(Fo + Fi + FoFi(Rr − 1)),
//!   f_ss, flatness), F· the Schlick weights (1 − cos)⁵, Rr = 2·roughness·(m·wi)²,
//!   f_ss Hanrahan–Krueger's flattened term; and sheen:
//!   sheen·(1 − metallic)·(1 − |m·wi|)⁵·lerp(1, tint, sheen_tint)·|cos θi|.
//!
//! Sampling picks the diffuse (cosine), clearcoat (GTR1 normals), transmission or
//! reflection (GGX visible normals, shared) lobe with Mitsuba's probabilities: from
//! outside proportional to brdf·r_d, clearcoat/4·r_c, r_s·bsdf·(1 − F_d) and
//! r_s·(1 − bsdf·(1 − F_d)) (the `*_sampling_rate`s r, default 1); from inside
//! transmission and reflection by F_d. The pdf is the mixture and the weight eval/pdf.
//! Values and densities match Mitsuba 3.9.1's `principled` (tested at sampled
//! directions). One difference: seen from inside a material without transmission
//! (bsdf = 0), where both are black, the density is 0 here (Mitsuba reports the
//! reflection lobe's density although it never samples there).
//!
//! ```xml
//! <bsdf type="principled">
//!     <rgb name="base_color" value="0.8,0.2,0.1"/>      <!-- default 0.5 -->
//!     <float name="roughness" value="0.3"/>             <!-- default 0.5 -->
//!     <float name="metallic" value="0.2"/>              <!-- defaults 0 from here on -->
//!     <float name="specular" value="0.6"/>              <!-- default 0.5; or eta -->
//!     <float name="spec_tint" value="0.3"/>
//!     <float name="anisotropic" value="0.5"/>
//!     <float name="sheen" value="0.3"/> <float name="sheen_tint" value="0.5"/>
//!     <float name="clearcoat" value="0.6"/> <float name="clearcoat_gloss" value="0.3"/>
//!     <float name="spec_trans" value="0.4"/> <float name="flatness" value="0"/>
//! </bsdf>
//! ```

use super::fresnel::{fresnel_dielectric_cos, schlick_weight};
use super::microfacet::{reflect, refract, Microfacet};
use super::{scalar, BsdfSample};
use crate::math::{INV_PI, PI};
use crate::sampling::warp;
use crate::texture::{TexCoord, Texture};
use glam::{FloatExt, Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct DisneyPrincipled {
    pub base_color: Arc<Texture>,
    pub roughness: Arc<Texture>,
    pub anisotropic: Arc<Texture>,
    pub metallic: Arc<Texture>,
    pub spec_trans: Arc<Texture>,
    pub spec_tint: Arc<Texture>,
    pub sheen: Arc<Texture>,
    pub sheen_tint: Arc<Texture>,
    pub flatness: Arc<Texture>,
    pub clearcoat: Arc<Texture>,
    pub clearcoat_gloss: Arc<Texture>,
    /// Interior over exterior index of refraction (from `eta`, or from `specular` s by
    /// η = 2/(1 − √(0.08 s)) − 1).
    pub eta: f32,
    pub specular_sampling_rate: f32,
    pub clearcoat_sampling_rate: f32,
    pub diffuse_sampling_rate: f32,
}

/// The parameters at one point.
struct Params {
    base: Vec3,
    roughness: f32,
    metallic: f32,
    spec_tint: f32,
    sheen: f32,
    sheen_tint: f32,
    flatness: f32,
    clearcoat: f32,
    clearcoat_gloss: f32,
    /// Weight of the opaque (diffuse) major lobe, (1 − metallic)(1 − spec_trans).
    brdf: f32,
    /// Weight of the transmissive major lobe, (1 − metallic)·spec_trans.
    bsdf: f32,
    ggx: Microfacet,
}

/// A colour over its luminance (white for black): the hue that `spec_tint` and
/// `sheen_tint` blend towards.
#[inline]
pub(super) fn tint(base: Vec3) -> Vec3 {
    let lum = crate::light::luminance(base);
    if lum > 0.0 {
        base / lum
    } else {
        Vec3::ONE
    }
}

/// The GGX distribution for `roughness` and `anisotropic`: α = max(0.001, roughness²)
/// divided (x) and multiplied (y) by √(1 − 0.9·anisotropic) (Burley 2012).
#[inline]
pub(super) fn ggx(roughness: f32, anisotropic: f32) -> Microfacet {
    let r2 = roughness * roughness;
    let aspect = (1.0 - 0.9 * anisotropic).sqrt();
    Microfacet::new((r2 / aspect).max(0.001), (r2 * aspect).max(0.001))
}

/// Lobe selection probabilities (normalised): diffuse, clearcoat, transmission,
/// reflection.
struct Choice {
    diffuse: f32,
    clearcoat: f32,
    transmission: f32,
    reflection: f32,
}

/// Schlick's Fresnel approximation with reflectance `r0` at normal incidence, for the
/// cosine `cos_i` (negative: from inside) of an interface of relative index `eta`; going
/// into the less dense medium it uses the refracted cosine (Mitsuba's `calc_schlick`).
#[inline]
pub(super) fn schlick(r0: Vec3, cos_i: f32, eta: f32) -> Vec3 {
    let eta_it = if cos_i >= 0.0 { eta } else { 1.0 / eta };
    let w = if eta_it > 1.0 {
        schlick_weight(cos_i.abs())
    } else {
        let eta_ti = 1.0 / eta_it;
        let cos_t2 = 1.0 - (1.0 - cos_i * cos_i) * (eta_ti * eta_ti);
        schlick_weight(cos_t2.max(0.0).sqrt())
    };
    r0 + (Vec3::ONE - r0) * w
}

/// Burley's diffuse with retro-reflection for |cos θo|, |cos θi| and cos θd = m·wi,
/// blended towards Hanrahan–Krueger's flattened term (a fake subsurface) by `flatness`:
/// the factor of base_color/π·|cos θi|.
#[inline]
pub(super) fn burley_diffuse(
    roughness: f32,
    flatness: f32,
    cos_o: f32,
    cos_i: f32,
    cos_d: f32,
) -> f32 {
    let fo = schlick_weight(cos_i);
    let fi = schlick_weight(cos_o);
    let rr = 2.0 * roughness * cos_d * cos_d;
    let lobe = (1.0 - 0.5 * fi) * (1.0 - 0.5 * fo) + rr * (fo + fi + fo * fi * (rr - 1.0));
    if flatness > 0.0 {
        let fss90 = 0.5 * rr;
        let fss = 1.0.lerp(fss90, fo) * 1.0.lerp(fss90, fi);
        let f_ss = 1.25 * (fss * (1.0 / (cos_i + cos_o) - 0.5) + 0.5);
        lobe.lerp(f_ss, flatness)
    } else {
        lobe
    }
}

/// The sheen's colour and angular falloff for cos θd = m·wi: (1 − |cos θd|)⁵ times
/// white tinted towards the base colour's hue by `sheen_tint`.
#[inline]
pub(super) fn sheen(base: Vec3, sheen_tint: f32, cos_d: f32) -> Vec3 {
    let colour = if sheen_tint > 0.0 {
        Vec3::ONE + (tint(base) - Vec3::ONE) * sheen_tint
    } else {
        Vec3::ONE
    };
    colour * schlick_weight(cos_d.abs())
}

/// The GTR1 (Berry) distribution of the clearcoat, D(m) for cos θm = `cos`.
#[inline]
fn gtr1(alpha: f32, cos: f32) -> f32 {
    let a2 = alpha * alpha;
    let d = (a2 - 1.0) / (PI * a2.ln() * (1.0 + (a2 - 1.0) * cos * cos));
    if d * cos > 1e-20 {
        d
    } else {
        0.0
    }
}

/// A GTR1 normal, distributed with density D(m)·cos θm.
#[inline]
fn sample_gtr1(alpha: f32, u: Vec2) -> Vec3 {
    let (sin_phi, cos_phi) = (2.0 * PI * u.x).sin_cos();
    let a2 = alpha * alpha;
    let cos2 = (1.0 - a2.powf(1.0 - u.y)) / (1.0 - a2);
    let sin = (1.0 - cos2).max(0.0).sqrt();
    Vec3::new(cos_phi * sin, sin_phi * sin, cos2.max(0.0).sqrt())
}

impl DisneyPrincipled {
    /// Mitsuba's index for a `specular` value s: η = 2/(1 − √(0.08 s)) − 1.
    pub fn eta_from_specular(specular: f32) -> f32 {
        2.0 / (1.0 - (0.08 * specular).sqrt()) - 1.0
    }

    fn params(&self, uv: TexCoord) -> Params {
        let roughness = scalar(&self.roughness, uv);
        let anisotropic = scalar(&self.anisotropic, uv);
        let metallic = scalar(&self.metallic, uv);
        let spec_trans = scalar(&self.spec_trans, uv);
        Params {
            base: self.base_color.eval(uv),
            roughness,
            metallic,
            spec_tint: scalar(&self.spec_tint, uv),
            sheen: scalar(&self.sheen, uv),
            sheen_tint: scalar(&self.sheen_tint, uv),
            flatness: scalar(&self.flatness, uv),
            clearcoat: scalar(&self.clearcoat, uv),
            clearcoat_gloss: scalar(&self.clearcoat_gloss, uv),
            brdf: (1.0 - metallic) * (1.0 - spec_trans),
            bsdf: (1.0 - metallic) * spec_trans,
            ggx: ggx(roughness, anisotropic),
        }
    }

    /// The clearcoat's GTR1 α.
    fn clearcoat_alpha(p: &Params) -> f32 {
        0.1.lerp(0.001, p.clearcoat_gloss)
    }

    /// The lobes' probabilities given the dielectric Fresnel `f` of the specular
    /// microfacet, seen from outside (`front`) or inside.
    fn choice(&self, p: &Params, front: bool, f: f32) -> Choice {
        let (diffuse, clearcoat, transmission, reflection) = if front {
            let s = self.specular_sampling_rate;
            (
                p.brdf * self.diffuse_sampling_rate,
                0.25 * p.clearcoat * self.clearcoat_sampling_rate,
                s * p.bsdf * (1.0 - f),
                s * (1.0 - p.bsdf * (1.0 - f)),
            )
        } else {
            (0.0, 0.0, 1.0 - f, f)
        };
        let total = diffuse + clearcoat + transmission + reflection;
        let inv = if total > 0.0 { 1.0 / total } else { 0.0 };
        Choice {
            diffuse: diffuse * inv,
            clearcoat: clearcoat * inv,
            transmission: transmission * inv,
            reflection: reflection * inv,
        }
    }

    /// f·|cos θi| and the density of sampling `wi`.
    fn eval_pdf(&self, p: &Params, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let (cos_o, cos_i) = (wo.z, wi.z);
        let front = cos_o > 0.0;
        // Grazing views see nothing; from inside, only a transmissive material scatters.
        if cos_o == 0.0 || (!front && p.bsdf <= 0.0) {
            return (Vec3::ZERO, 0.0);
        }
        let reflect = cos_o * cos_i > 0.0;
        let refract = cos_o * cos_i < 0.0;
        if !reflect && !refract {
            return (Vec3::ZERO, 0.0);
        }
        let eta = self.eta;
        // The index of wi's side over wo's.
        let eta_path = if front { eta } else { 1.0 / eta };
        let h = (wo + wi * if reflect { 1.0 } else { eta_path }).normalize();
        let m = if h.z < 0.0 { -h } else { h };
        let (wo_m, wi_m) = (wo.dot(m), wi.dot(m));
        let (f, _) = fresnel_dielectric_cos(wo_m, eta);
        // Both directions on the microfacet's side that faces wo's hemisphere (reflection)
        // or wi on the other (transmission).
        let side = if front { 1.0 } else { -1.0 };
        let reflect_ok = reflect && wo_m * side > 0.0 && wi_m * side > 0.0;
        let refract_ok = refract && wo_m * side > 0.0 && wi_m * side < 0.0;
        let d = p.ggx.d(m);
        let g = p.ggx.g1(wo, m) * p.ggx.g1(wi, m);

        let mut value = Vec3::ZERO;
        if reflect_ok && f > 0.0 {
            let fresnel = if front {
                let mut schlicks = p.metallic * schlick(p.base, wo_m, eta);
                if p.spec_tint > 0.0 {
                    let eta_it = if wo_m >= 0.0 { eta } else { 1.0 / eta };
                    let r0 = ((eta_it - 1.0) / (eta_it + 1.0)).powi(2);
                    schlicks +=
                        (1.0 - p.metallic) * p.spec_tint * schlick(tint(p.base) * r0, wo_m, eta);
                }
                Vec3::splat((1.0 - p.metallic) * (1.0 - p.spec_tint) * f) + schlicks
            } else {
                Vec3::splat(p.bsdf * f)
            };
            value += fresnel * (d * g / (4.0 * cos_o.abs()));
        }
        if refract_ok && p.bsdf > 0.0 && f < 1.0 {
            let denom = wo_m + eta_path * wi_m;
            // (η'² from the half-vector Jacobian) × (1/η'² for radiance).
            let t = ((1.0 - f) * d * g * wo_m * wi_m / (cos_o * denom * denom)).abs();
            let sqrt_base = p.base.max(Vec3::ZERO).to_array().map(f32::sqrt);
            value += Vec3::from(sqrt_base) * (p.bsdf * t);
        }
        if reflect_ok && front && p.clearcoat > 0.0 {
            let fcc = schlick(Vec3::splat(0.04), wo_m, eta).x;
            let dcc = gtr1(Self::clearcoat_alpha(p), m.z);
            // Separable isotropic GGX masking with α 0.25.
            let cc = Microfacet::new(0.25, 0.25);
            let gcc = cc.g1(wo, m) * cc.g1(wi, m);
            value += Vec3::splat(p.clearcoat * 0.25 * fcc * dcc * gcc * cos_i.abs());
        }
        if reflect && front && p.brdf > 0.0 {
            let (cos_o, cos_i, cos_d) = (cos_o.abs(), cos_i.abs(), m.dot(wi));
            let lobe = burley_diffuse(p.roughness, p.flatness, cos_o, cos_i, cos_d);
            value += p.base * (p.brdf * cos_i * INV_PI * lobe);
            if p.sheen > 0.0 && p.metallic < 1.0 {
                value +=
                    sheen(p.base, p.sheen_tint, cos_d) * (p.sheen * (1.0 - p.metallic) * cos_i);
            }
        }

        let choice = self.choice(p, front, f);
        // |dm/dwi| for reflection and refraction.
        let jacobian = if reflect {
            (1.0 / (4.0 * wi_m)).abs()
        } else {
            let denom = wo_m + eta_path * wi_m;
            (eta_path * eta_path * wi_m / (denom * denom)).abs()
        };
        let wo_up = wo * side;
        let mut pdf = 0.0;
        if reflect_ok {
            pdf += choice.reflection * p.ggx.pdf_visible(wo_up, m) * jacobian;
            if choice.clearcoat > 0.0 {
                let pdf_cc = m.z * gtr1(Self::clearcoat_alpha(p), m.z);
                pdf += choice.clearcoat * pdf_cc * jacobian;
            }
        }
        if reflect {
            pdf += choice.diffuse * cos_i.abs() * INV_PI;
        }
        if refract_ok {
            pdf += choice.transmission * p.ggx.pdf_visible(wo_up, m) * jacobian;
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
        let p = self.params(uv);
        let cos_o = wo.z;
        let front = cos_o > 0.0;
        if cos_o == 0.0 || (!front && p.bsdf <= 0.0) {
            return None;
        }
        let side = if front { 1.0 } else { -1.0 };
        let m = p.ggx.sample_visible(wo * side, u);
        let wo_m = wo.dot(m);
        let (f, cos_t) = fresnel_dielectric_cos(wo_m, self.eta);
        let choice = self.choice(&p, front, f);
        // As Mitsuba, a sample whose microfacet does not face both directions from the
        // right sides (or that leaves the lobe's hemisphere) is dropped.
        let reflected = |n: Vec3| {
            let wi = reflect(wo, n);
            let ok = cos_o * wi.z > 0.0 && wo.dot(n) * side > 0.0 && wi.dot(n) * side > 0.0;
            ok.then_some(wi)
        };
        let wi = if u_lobe < choice.diffuse {
            let wi = warp::square_to_cosine_hemisphere(u);
            (wi.z > 0.0).then_some(wi)?
        } else if u_lobe < choice.diffuse + choice.clearcoat {
            reflected(sample_gtr1(Self::clearcoat_alpha(&p), u))?
        } else if u_lobe < choice.diffuse + choice.clearcoat + choice.transmission {
            if f >= 1.0 || wo_m * side <= 0.0 {
                return None;
            }
            // Refract through m from wo's side of the microfacet.
            let (n, eta) = if wo_m >= 0.0 {
                (m, self.eta)
            } else {
                (-m, 1.0 / self.eta)
            };
            let wi = refract(wo, n, eta, cos_t);
            if cos_o * wi.z >= 0.0 || wi.dot(m) * side >= 0.0 {
                return None;
            }
            wi
        } else {
            reflected(m)?
        };
        let (value, pdf) = self.eval_pdf(&p, wo, wi);
        BsdfSample::from_eval(wi, value, pdf)
    }
}
