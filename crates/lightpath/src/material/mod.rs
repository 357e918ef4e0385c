//! Materials: they turn a surface interaction into a BSDF, evaluated and sampled in the
//! local shading frame (normal = +z, tangent = dp/du made orthogonal to the normal).
//! `eval` returns f·|cos θi|; `sample` returns a direction with its weight
//! f·|cos θi|/pdf. Directions point away from the surface: `wo` toward the viewer, `wi`
//! toward the light. Transport is of radiance (camera paths): refraction into a medium of
//! relative index η scales by 1/η².
//!
//! Delta lobes (mirrors, smooth glass, plastic's coating) are invisible to `eval` and
//! `pdf`; their samples carry `delta: true`, and their `pdf` is the discrete probability
//! of having picked the lobe. Integrators must not apply MIS to such samples.
//!
//! Each variant's struct exposes `eval`/`pdf`/`sample` in the local frame (taking the
//! texture coordinates `uv`), and [`Material`] has the same as `*_local`.
//!
//! ```xml
//! <bsdf type="diffuse"><texture name="albedo" type="constant" value="0.8"/></bsdf>
//! <bsdf type="conductor"><texture name="reflectance" type="constant" value="1,0.7,0.3"/></bsdf>
//! <bsdf type="roughconductor"><texture name="reflectance" type="constant" value="0.9"/><float name="roughness" value="0.2"/></bsdf>
//! <bsdf type="dielectric"><float name="ior" value="1.5"/></bsdf>
//! <bsdf type="roughdielectric"><float name="ior" value="1.5"/><float name="roughness" value="0.3"/></bsdf>
//! <bsdf type="thindielectric"><float name="ior" value="1.5"/></bsdf>
//! <bsdf type="plastic"><texture name="diffuseReflectance" type="constant" value="0.2,0.4,0.8"/><float name="ior" value="1.5"/></bsdf>
//! <!-- Mitsuba dialect only: -->
//! <bsdf type="roughplastic"><rgb name="diffuse_reflectance" value="0.2,0.4,0.8"/><float name="alpha" value="0.1"/></bsdf>
//! <bsdf type="principled"><texture name="baseColor" type="constant" value="0.8,0.1,0.1"/><float name="roughness" value="0.4"/>
//!     <float name="metallic" value="0"/><float name="specular" value="0.5"/></bsdf>
//! <bsdf type="twosided"><bsdf type="plastic"/></bsdf>
//! <bsdf type="blend"><float name="weight" value="0.3"/><bsdf type="diffuse"/><bsdf type="conductor"/></bsdf>
//! <bsdf type="normalmap"><texture name="normal" type="image" filename="n.png" linear="true"/><bsdf type="diffuse"/></bsdf>
//! <!-- Mitsuba dialect only: a height field's luminance tilts the normal -->
//! <bsdf type="bumpmap"><texture name="h" type="bitmap"><string name="filename" value="h.png"/></texture>
//!     <float name="scale" value="0.05"/><bsdf type="roughplastic"/></bsdf>
//! <bsdf type="hair"><float name="eumelanin" value="1.3"/></bsdf>
//! <!-- Mitsuba dialect only: Mitsuba's Disney BSDFs (`principled` there is this one) -->
//! <bsdf type="principled"><rgb name="base_color" value="0.8,0.2,0.1"/><float name="clearcoat" value="0.5"/></bsdf>
//! <bsdf type="principledthin"><float name="diff_trans" value="0.8"/></bsdf>
//! ```
//!
//! Scalar parameters (roughness, metallic, ...) may be `<float>`s or textures; a texture
//! gives its first channel, as lightwave's `Texture::scalar` does. See each module for
//! the exact model.

mod blend;
mod bumpmap;
mod conductor;
mod dielectric;
mod diffuse;
mod disney_principled;
mod disney_thin;
pub mod fresnel;
mod hair;
pub mod microfacet;
mod normalmap;
mod onesided;
mod plastic;
mod principled;
mod rough_conductor;
mod rough_dielectric;
mod rough_plastic;
mod thin_dielectric;
mod twosided;

#[cfg(test)]
mod tests;

pub use blend::Blend;
pub use bumpmap::BumpMap;
pub use conductor::{ComplexIor, Conductor};
pub use dielectric::Dielectric;
pub use diffuse::Diffuse;
pub use disney_principled::DisneyPrincipled;
pub use disney_thin::DisneyThin;
pub use hair::{sigma_a_from_color, sigma_a_from_melanin, Hair, HairAbsorption, HairParameters};
pub use normalmap::NormalMap;
pub use onesided::OneSided;
pub use plastic::Plastic;
pub use principled::Principled;
pub use rough_conductor::RoughConductor;
pub use rough_dielectric::RoughDielectric;
pub use rough_plastic::RoughPlastic;
pub use thin_dielectric::ThinDielectric;
pub use twosided::TwoSided;

use crate::geometry::SurfaceInteraction;
use crate::math::Frame;
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3, Vec3A};

/// A sampled direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BsdfSample {
    /// Incident direction (render space from [`Material::sample`], local from the
    /// `*_local` methods).
    pub wi: Vec3,
    /// f·|cos θi| / pdf.
    pub weight: Vec3,
    /// Solid-angle density of `wi` (for a delta lobe, the discrete probability of
    /// choosing it).
    pub pdf: f32,
    /// True when `wi` comes from a delta (specular) lobe: `eval`/`pdf` cannot find it
    /// and MIS must not weight it.
    pub delta: bool,
}

impl BsdfSample {
    /// The non-delta sample of `wi` whose f·|cos θi| is `value` and density `pdf`: weight
    /// value/pdf, or `None` where the density is not usable ([`valid_pdf`]).
    #[inline]
    pub(crate) fn from_eval(wi: Vec3, value: Vec3, pdf: f32) -> Option<BsdfSample> {
        valid_pdf(pdf).then(|| BsdfSample {
            wi,
            weight: value / pdf,
            pdf,
            delta: false,
        })
    }
}

/// A material of any kind.
#[derive(Debug, Clone)]
pub enum Material {
    Diffuse(Diffuse),
    Conductor(Conductor),
    RoughConductor(RoughConductor),
    Dielectric(Dielectric),
    RoughDielectric(RoughDielectric),
    ThinDielectric(ThinDielectric),
    Plastic(Plastic),
    RoughPlastic(RoughPlastic),
    Principled(Principled),
    /// Mitsuba 3's `principled` (Burley's Disney BSDF).
    DisneyPrincipled(DisneyPrincipled),
    /// Mitsuba 3's `principledthin` (Burley's thin-sheet Disney BSDF).
    DisneyThin(DisneyThin),
    TwoSided(TwoSided),
    OneSided(OneSided),
    Blend(Blend),
    NormalMap(NormalMap),
    /// Applied by [`Bsdf::new`], which has the surface's dp/du and dp/dv: where the
    /// local-frame methods meet one (nested where `Bsdf::new` does not look, which the
    /// scene readers reject), they use the inner BSDF unperturbed.
    BumpMap(BumpMap),
    Hair(Hair),
}

/// A frame with normal `n` whose first axis is `tangent` made orthogonal to `n`
/// (Gram–Schmidt); falls back to [`Frame::from_normal`] when the tangent is (nearly)
/// parallel to `n`, zero or not finite.
#[inline]
pub fn frame_from_normal_and_tangent(n: Vec3, tangent: Vec3) -> Frame {
    // In 4-lane arithmetic: the same operations as with `Vec3`, bit for bit.
    let (na, tangent) = (Vec3A::from(n), Vec3A::from(tangent));
    let t = tangent - na * na.dot(tangent);
    let len2 = t.length_squared();
    if len2.is_finite() && len2 > 1e-8 * tangent.length_squared() && len2 > 0.0 {
        let s = t / len2.sqrt();
        Frame {
            s: s.into(),
            t: na.cross(s).into(),
            n,
        }
    } else {
        Frame::from_normal(n)
    }
}

/// The shading frame of an interaction: the shading normal with dp/du as the tangent.
#[inline]
pub fn shading_frame(si: &SurfaceInteraction) -> Frame {
    frame_from_normal_and_tangent(si.shading_n, si.dpdu)
}

/// The shadowing term of Conty Estevez, Lecocq and Stein (2019, "A Microfacet-Based
/// Shadowing Function to Solve the Bump Terminator Problem") that Mitsuba's `bumpmap` and
/// `normalmap` apply by default: a Smith G1 of GGX roughness α² = min(tan²θn / 8, 1),
/// θn the tilt of the perturbed normal, for a direction at θ from the unperturbed one.
/// Given cos θn and cos θ.
#[inline]
pub(crate) fn terminator_shadowing(cos_n: f32, cos_w: f32) -> f32 {
    let tan2 = |c: f32| {
        let c2 = c * c;
        (1.0 - c2).max(0.0) / c2
    };
    let alpha2 = (0.125 * tan2(cos_n)).min(1.0);
    if alpha2 == 0.0 {
        return 1.0;
    }
    let g = 2.0 / (1.0 + (1.0 + alpha2 * tan2(cos_w)).sqrt());
    if g.is_finite() {
        g
    } else {
        0.0
    }
}

/// A scalar parameter from a texture: its first channel (lightwave's `scalar`).
#[inline]
pub(crate) fn scalar(t: &Texture, uv: TexCoord) -> f32 {
    t.eval(uv).x
}

/// A usable density: positive and finite (false for NaN).
#[inline]
pub(crate) fn valid_pdf(pdf: f32) -> bool {
    pdf > 0.0 && pdf.is_finite()
}

/// Mirrors a direction through the tangent plane.
#[inline]
pub(crate) fn mirror_z(v: Vec3) -> Vec3 {
    Vec3::new(v.x, v.y, -v.z)
}

/// Mirrors (wo, wi) together so that wo is in the upper hemisphere.
#[inline]
pub(crate) fn mirror_to_upper(wo: Vec3, wi: Vec3) -> (Vec3, Vec3) {
    if wo.z < 0.0 {
        (mirror_z(wo), mirror_z(wi))
    } else {
        (wo, wi)
    }
}

/// A material set up at one surface point: its shading frame, texture coordinates and
/// the outgoing direction in that frame, computed once and shared by every evaluation
/// and sample at the point (next-event estimation and the continuation of a path).
#[derive(Debug, Clone, Copy)]
pub struct Bsdf<'a> {
    pub material: &'a Material,
    pub frame: Frame,
    pub uv: TexCoord,
    /// The outgoing direction in the local frame.
    pub wo: Vec3,
    /// Under a bump map: the unperturbed shading normal in the local (perturbed) frame.
    /// A direction on different sides of it and of the perturbed normal carries nothing.
    pub guard: Option<Vec3>,
    /// Under a bump map with terminator shadowing: its cosine of the perturbed normal's
    /// tilt (Conty Estevez et al. 2019); 1 (no shadowing) otherwise.
    pub shadowing_cos: f32,
}

impl<'a> Bsdf<'a> {
    /// The BSDF of `material` at `si` for the render-space outgoing direction `wo`.
    #[inline]
    pub fn new(material: &'a Material, si: &SurfaceInteraction, wo: Vec3) -> Self {
        let bumped = match material {
            Material::BumpMap(_) => true,
            Material::TwoSided(t) => {
                matches!(*t.inner, Material::BumpMap(_))
                    || matches!(t.back.as_deref(), Some(Material::BumpMap(_)))
            }
            _ => false,
        };
        if bumped {
            if let Some(bsdf) = Self::bumped(material, si, wo) {
                return bsdf;
            }
        }
        let frame = shading_frame(si);
        Bsdf {
            material,
            frame,
            uv: si.tex(),
            wo: frame.to_local(wo),
            guard: None,
            shadowing_cos: 1.0,
        }
    }

    /// A bump map's BSDF, outermost or inside a two-sided one: the nested material in the
    /// perturbed frame. `None` for materials without a bump map there.
    #[inline(never)]
    fn bumped(material: &'a Material, si: &SurfaceInteraction, wo: Vec3) -> Option<Self> {
        let bsdf = |b: &'a BumpMap, frame: Frame, n: Vec3| {
            let guard = frame.to_local(n);
            Bsdf {
                material: &b.inner,
                frame,
                uv: si.tex(),
                wo: frame.to_local(wo),
                guard: Some(guard),
                shadowing_cos: if b.shadowing { guard.z } else { 1.0 },
            }
        };
        let n = si.shading_n;
        let mirror = |v: Vec3| v - n * (2.0 * v.dot(n));
        match material {
            Material::BumpMap(b) => Some(bsdf(b, b.frame(si, wo), n)),
            Material::TwoSided(t) => {
                // As `TwoSided` does in the local frame: seen from behind, the back's
                // BSDF with both directions mirrored through the (unperturbed) tangent
                // plane, here by mirroring the frame instead.
                let back = wo.dot(n) < 0.0;
                let side = if back {
                    t.back.as_deref().unwrap_or(&t.inner)
                } else {
                    &t.inner
                };
                let Material::BumpMap(b) = side else {
                    return None;
                };
                if !back {
                    return Some(bsdf(b, b.frame(si, wo), n));
                }
                let f = b.frame(si, mirror(wo));
                let mirrored = Frame {
                    s: mirror(f.s),
                    t: mirror(f.t),
                    n: mirror(f.n),
                };
                Some(bsdf(b, mirrored, -n))
            }
            _ => None,
        }
    }

    /// Whether a local `wi` is on the same side of the perturbed and the unperturbed
    /// surface (always, without a bump map).
    #[inline(always)]
    fn passes_guard(&self, wi: Vec3) -> bool {
        match self.guard {
            None => true,
            Some(g) => wi.z * wi.dot(g) > 0.0,
        }
    }

    /// A render-space direction in the local frame.
    #[inline]
    pub fn to_local(&self, w: Vec3) -> Vec3 {
        self.frame.to_local(w)
    }

    /// f(wo, wi)·|cos θi| for a local `wi` (see [`Bsdf::to_local`]).
    #[inline]
    pub fn eval_local(&self, wi: Vec3) -> Vec3 {
        // One inlined copy of the material's evaluation; a bump map's side guard and
        // shadowing out of line.
        let weight = match self.guard {
            None => 1.0,
            Some(_) => self.bump_weight(wi),
        };
        if weight == 0.0 {
            return Vec3::ZERO;
        }
        self.material.eval_local(self.uv, self.wo, wi) * weight
    }

    /// Under a bump map: 0 for a `wi` on different sides of the perturbed and the
    /// unperturbed surface, else its terminator shadowing.
    #[inline(never)]
    fn bump_weight(&self, wi: Vec3) -> f32 {
        match self.guard {
            Some(g) if wi.z * wi.dot(g) > 0.0 => {
                terminator_shadowing(self.shadowing_cos, wi.dot(g))
            }
            Some(_) => 0.0,
            None => 1.0,
        }
    }

    /// The density of a local `wi`.
    #[inline]
    pub fn pdf_local(&self, wi: Vec3) -> f32 {
        if !self.passes_guard(wi) {
            return 0.0;
        }
        self.material.pdf_local(self.uv, self.wo, wi)
    }

    /// f(wo, wi)·|cos θi| for a render-space unit `wi`.
    #[inline]
    pub fn eval(&self, wi: Vec3) -> Vec3 {
        self.eval_local(self.to_local(wi))
    }

    /// Density with which `sample` picks the render-space `wi`.
    #[inline]
    pub fn pdf(&self, wi: Vec3) -> f32 {
        self.pdf_local(self.to_local(wi))
    }

    /// Samples a render-space incident direction: `u_lobe` picks a lobe, `u` the
    /// direction in it.
    #[inline]
    pub fn sample(&self, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let mut bs = self.material.sample_local(self.uv, self.wo, u_lobe, u)?;
        if !valid_pdf(bs.pdf) || !bs.weight.is_finite() {
            return None;
        }
        if self.guard.is_some() {
            // The side guard (0) and the terminator shadowing in one.
            let weight = self.bump_weight(bs.wi);
            if weight == 0.0 {
                return None;
            }
            bs.weight *= weight;
        }
        bs.wi = self.frame.to_world(bs.wi);
        Some(bs)
    }
}

impl Material {
    /// The material at `si` seen from the render-space direction `wo`, ready for
    /// several evaluations and samples.
    #[inline]
    pub fn bsdf(&self, si: &SurfaceInteraction, wo: Vec3) -> Bsdf<'_> {
        Bsdf::new(self, si, wo)
    }

    /// f(wo, wi)·|cos θi| for render-space unit directions.
    pub fn eval(&self, si: &SurfaceInteraction, wo: Vec3, wi: Vec3) -> Vec3 {
        self.bsdf(si, wo).eval(wi)
    }

    /// Density with which `sample` picks `wi` (0 for directions only delta lobes reach).
    pub fn pdf(&self, si: &SurfaceInteraction, wo: Vec3, wi: Vec3) -> f32 {
        self.bsdf(si, wo).pdf(wi)
    }

    /// Samples an incident direction: `u_lobe` picks a lobe, `u` the direction in it.
    pub fn sample(
        &self,
        si: &SurfaceInteraction,
        wo: Vec3,
        u_lobe: f32,
        u: Vec2,
    ) -> Option<BsdfSample> {
        self.bsdf(si, wo).sample(u_lobe, u)
    }

    /// f·|cos θi| in the local shading frame.
    #[inline(always)]
    pub fn eval_local(&self, uv: impl Into<TexCoord>, wo: Vec3, wi: Vec3) -> Vec3 {
        let uv = uv.into();
        // Diffuse, also one-sided (Mitsuba's), inline at the caller (the common case);
        // the rest behind a call.
        match self {
            Material::Diffuse(m) => m.eval(uv, wo, wi),
            Material::OneSided(m) => match &*m.inner {
                Material::Diffuse(d) => OneSided::eval_with(wo, wi, || d.eval(uv, wo, wi)),
                _ => self.eval_local_other(uv, wo, wi),
            },
            _ => self.eval_local_other(uv, wo, wi),
        }
    }

    #[inline(never)]
    fn eval_local_other(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> Vec3 {
        match self {
            Material::Diffuse(m) => m.eval(uv, wo, wi),
            Material::Conductor(m) => m.eval(uv, wo, wi),
            Material::RoughConductor(m) => m.eval(uv, wo, wi),
            Material::Dielectric(m) => m.eval(uv, wo, wi),
            Material::RoughDielectric(m) => m.eval(uv, wo, wi),
            Material::ThinDielectric(m) => m.eval(uv, wo, wi),
            Material::Plastic(m) => m.eval(uv, wo, wi),
            Material::RoughPlastic(m) => m.eval(uv, wo, wi),
            Material::Principled(m) => m.eval(uv, wo, wi),
            Material::DisneyPrincipled(m) => m.eval(uv, wo, wi),
            Material::DisneyThin(m) => m.eval(uv, wo, wi),
            Material::TwoSided(m) => m.eval(uv, wo, wi),
            Material::OneSided(m) => m.eval(uv, wo, wi),
            Material::Blend(m) => m.eval(uv, wo, wi),
            Material::NormalMap(m) => m.eval(uv, wo, wi),
            Material::BumpMap(m) => m.inner.eval_local(uv, wo, wi),
            Material::Hair(m) => m.eval(uv, wo, wi),
        }
    }

    /// The sampling density in the local shading frame.
    #[inline(always)]
    pub fn pdf_local(&self, uv: impl Into<TexCoord>, wo: Vec3, wi: Vec3) -> f32 {
        let uv = uv.into();
        // Diffuse, also one-sided, inline at the caller; the rest behind a call.
        match self {
            Material::Diffuse(m) => m.pdf(uv, wo, wi),
            Material::OneSided(m) => match &*m.inner {
                Material::Diffuse(d) => OneSided::pdf_with(wo, wi, || d.pdf(uv, wo, wi)),
                _ => self.pdf_local_other(uv, wo, wi),
            },
            _ => self.pdf_local_other(uv, wo, wi),
        }
    }

    #[inline(never)]
    fn pdf_local_other(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> f32 {
        match self {
            Material::Diffuse(m) => m.pdf(uv, wo, wi),
            Material::Conductor(m) => m.pdf(uv, wo, wi),
            Material::RoughConductor(m) => m.pdf(uv, wo, wi),
            Material::Dielectric(m) => m.pdf(uv, wo, wi),
            Material::RoughDielectric(m) => m.pdf(uv, wo, wi),
            Material::ThinDielectric(m) => m.pdf(uv, wo, wi),
            Material::Plastic(m) => m.pdf(uv, wo, wi),
            Material::RoughPlastic(m) => m.pdf(uv, wo, wi),
            Material::Principled(m) => m.pdf(uv, wo, wi),
            Material::DisneyPrincipled(m) => m.pdf(uv, wo, wi),
            Material::DisneyThin(m) => m.pdf(uv, wo, wi),
            Material::TwoSided(m) => m.pdf(uv, wo, wi),
            Material::OneSided(m) => m.pdf(uv, wo, wi),
            Material::Blend(m) => m.pdf(uv, wo, wi),
            Material::NormalMap(m) => m.pdf(uv, wo, wi),
            Material::BumpMap(m) => m.inner.pdf_local(uv, wo, wi),
            Material::Hair(m) => m.pdf(uv, wo, wi),
        }
    }

    /// Samples in the local shading frame (`wi` is local too).
    #[inline(always)]
    pub fn sample_local(
        &self,
        uv: impl Into<TexCoord>,
        wo: Vec3,
        u_lobe: f32,
        u: Vec2,
    ) -> Option<BsdfSample> {
        let uv = uv.into();
        // Diffuse, also one-sided, inline at the caller; the rest behind a call.
        match self {
            Material::Diffuse(m) => m.sample(uv, wo, u_lobe, u),
            Material::OneSided(m) => match &*m.inner {
                Material::Diffuse(d) => OneSided::sample_with(wo, || d.sample(uv, wo, u_lobe, u)),
                _ => self.sample_local_other(uv, wo, u_lobe, u),
            },
            _ => self.sample_local_other(uv, wo, u_lobe, u),
        }
    }

    #[inline(never)]
    fn sample_local_other(
        &self,
        uv: TexCoord,
        wo: Vec3,
        u_lobe: f32,
        u: Vec2,
    ) -> Option<BsdfSample> {
        match self {
            Material::Diffuse(m) => m.sample(uv, wo, u_lobe, u),
            Material::Conductor(m) => m.sample(uv, wo, u_lobe, u),
            Material::RoughConductor(m) => m.sample(uv, wo, u_lobe, u),
            Material::Dielectric(m) => m.sample(uv, wo, u_lobe, u),
            Material::RoughDielectric(m) => m.sample(uv, wo, u_lobe, u),
            Material::ThinDielectric(m) => m.sample(uv, wo, u_lobe, u),
            Material::Plastic(m) => m.sample(uv, wo, u_lobe, u),
            Material::RoughPlastic(m) => m.sample(uv, wo, u_lobe, u),
            Material::Principled(m) => m.sample(uv, wo, u_lobe, u),
            Material::DisneyPrincipled(m) => m.sample(uv, wo, u_lobe, u),
            Material::DisneyThin(m) => m.sample(uv, wo, u_lobe, u),
            Material::TwoSided(m) => m.sample(uv, wo, u_lobe, u),
            Material::OneSided(m) => m.sample(uv, wo, u_lobe, u),
            Material::Blend(m) => m.sample(uv, wo, u_lobe, u),
            Material::NormalMap(m) => m.sample(uv, wo, u_lobe, u),
            Material::BumpMap(m) => m.inner.sample_local(uv, wo, u_lobe, u),
            Material::Hair(m) => m.sample(uv, wo, u_lobe, u),
        }
    }

    /// The material's colour at `uv` (a `Vec2` or a [`TexCoord`]), as denoisers' albedo buffers want it: the
    /// diffuse or base colour (diffuse, plastic, principled), the reflectance tint of
    /// conductors, the transmittance tint of dielectrics; two-sided and normal-mapped
    /// materials give their inner material's, a blend mixes its two by its weight. Not
    /// a directional reflectance: no Fresnel, no roughness.
    pub fn albedo(&self, uv: impl Into<TexCoord>) -> Vec3 {
        let uv = uv.into();
        match self {
            Material::Diffuse(m) => m.albedo.eval(uv),
            Material::Conductor(m) => m.reflectance.eval(uv),
            Material::RoughConductor(m) => m.reflectance.eval(uv),
            Material::Dielectric(m) => m.transmittance.eval(uv),
            Material::RoughDielectric(m) => m.transmittance.eval(uv),
            Material::ThinDielectric(m) => m.transmittance.eval(uv),
            Material::Plastic(m) => m.diffuse.eval(uv),
            Material::RoughPlastic(m) => m.diffuse.eval(uv),
            Material::Principled(m) => m.base_color.eval(uv),
            Material::DisneyPrincipled(m) => m.base_color.eval(uv),
            Material::DisneyThin(m) => m.base_color.eval(uv),
            Material::TwoSided(m) => m.inner.albedo(uv),
            Material::OneSided(m) => m.inner.albedo(uv),
            Material::NormalMap(m) => m.inner.albedo(uv),
            Material::BumpMap(m) => m.inner.albedo(uv),
            Material::Hair(m) => m.albedo(uv),
            Material::Blend(m) => {
                let w = scalar(&m.weight, uv);
                m.first.albedo(uv) * (1.0 - w) + m.second.albedo(uv) * w
            }
        }
    }

    /// True when every lobe is a delta (a mirror or smooth glass): next-event estimation
    /// is useless there.
    #[inline(always)]
    pub fn is_delta(&self) -> bool {
        // The wrappers' recursion stays behind a call, so the rest inlines.
        match self {
            Material::Conductor(_) | Material::Dielectric(_) | Material::ThinDielectric(_) => true,
            Material::RoughDielectric(m) => m.is_pass_through(),
            Material::Diffuse(_)
            | Material::RoughConductor(_)
            | Material::Plastic(_)
            | Material::RoughPlastic(_)
            | Material::Principled(_)
            | Material::DisneyPrincipled(_)
            | Material::DisneyThin(_)
            | Material::Hair(_) => false,
            // One-sided diffuse (Mitsuba's) without the call.
            Material::OneSided(m) if matches!(*m.inner, Material::Diffuse(_)) => false,
            Material::TwoSided(_)
            | Material::OneSided(_)
            | Material::NormalMap(_)
            | Material::BumpMap(_)
            | Material::Blend(_) => self.is_delta_wrapped(),
        }
    }

    #[inline(never)]
    fn is_delta_wrapped(&self) -> bool {
        match self {
            Material::TwoSided(m) => m.is_delta(),
            Material::OneSided(m) => m.inner.is_delta(),
            Material::NormalMap(m) => m.inner.is_delta(),
            Material::BumpMap(m) => m.inner.is_delta(),
            Material::Blend(m) => m.first.is_delta() && m.second.is_delta(),
            _ => self.is_delta(),
        }
    }
}
