//! The GGX (Trowbridge–Reitz) microfacet distribution with the separable Smith masking
//! term, and sampling of its visible normals (Heitz 2018, "Sampling the GGX Distribution
//! of Visible Normals", JCGT 7(4)).
//!
//! Everything works in the local shading frame (normal = +z) with the viewing direction
//! `wo` in the upper hemisphere: the materials mirror their directions there first.

use super::valid_pdf;
use crate::math::{INV_PI, PI};
use glam::{Vec2, Vec3};

/// The course's roughness remapping: α = max(1e-3, roughness²).
#[inline]
pub fn roughness_to_alpha(roughness: f32) -> f32 {
    (roughness * roughness).max(1e-3)
}

/// Mirrors `v` about the normal: 2(v·n)n − v.
#[inline]
pub fn reflect(v: Vec3, n: Vec3) -> Vec3 {
    2.0 * v.dot(n) * n - v
}

/// Refracts `wo` (on the side `n` points to, wo·n > 0) through a surface with normal `n`
/// and relative index `eta` = η(far side)/η(wo's side), given the transmitted cosine
/// `cos_t` (from the Fresnel computation; > 0). The result points away from `n`'s side.
#[inline]
pub fn refract(wo: Vec3, n: Vec3, eta: f32, cos_t: f32) -> Vec3 {
    let cos_o = wo.dot(n);
    (cos_o / eta - cos_t) * n - wo / eta
}

/// An anisotropic GGX distribution with roughness `ax` along the tangent (x) and `ay`
/// along the bitangent (y).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ggx {
    pub ax: f32,
    pub ay: f32,
}

impl Ggx {
    pub fn new(ax: f32, ay: f32) -> Ggx {
        Ggx { ax, ay }
    }

    pub fn isotropic(alpha: f32) -> Ggx {
        Ggx {
            ax: alpha,
            ay: alpha,
        }
    }

    /// The normal distribution D(m) (zero below the surface).
    #[inline]
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let x = m.x / self.ax;
        let y = m.y / self.ay;
        let c = x * x + y * y + m.z * m.z;
        INV_PI / (self.ax * self.ay * c * c)
    }

    /// Smith's Λ(w).
    #[inline]
    pub fn lambda(&self, w: Vec3) -> f32 {
        let z2 = w.z * w.z;
        if z2 <= 0.0 {
            return f32::INFINITY;
        }
        let a2t2 = ((self.ax * w.x).powi(2) + (self.ay * w.y).powi(2)) / z2;
        0.5 * ((1.0 + a2t2).sqrt() - 1.0)
    }

    /// Smith's masking G1(w, m) = 1/(1 + Λ(w)), zero when `w` sees the back of the
    /// microfacet `m` (w·m and w·n of different signs).
    #[inline]
    pub fn g1(&self, w: Vec3, m: Vec3) -> f32 {
        if w.dot(m) * w.z * m.z <= 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + self.lambda(w))
    }

    /// The density of visible normals D_wo(m) = G1(wo, m)·max(0, wo·m)·D(m)/wo.z, for
    /// `wo` in the upper hemisphere.
    #[inline]
    pub fn pdf_visible(&self, wo: Vec3, m: Vec3) -> f32 {
        if wo.z <= 0.0 {
            return 0.0;
        }
        self.g1(wo, m) * wo.dot(m).max(0.0) * self.d(m) / wo.z
    }

    /// A visible normal for `wo` (upper hemisphere), distributed with
    /// [`pdf_visible`](Self::pdf_visible) (Heitz 2018, listing 1).
    pub fn sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
        // Stretch the view direction to the hemisphere configuration.
        let vh = Vec3::new(self.ax * wo.x, self.ay * wo.y, wo.z).normalize();
        // An orthonormal basis around it.
        let lensq = vh.x * vh.x + vh.y * vh.y;
        let t1 = if lensq > 0.0 {
            Vec3::new(-vh.y, vh.x, 0.0) / lensq.sqrt()
        } else {
            Vec3::X
        };
        let t2 = vh.cross(t1);
        // A point on the projected area: a disk whose lower half is squashed.
        let r = u.x.sqrt();
        let phi = 2.0 * PI * u.y;
        let p1 = r * phi.cos();
        let p2 = r * phi.sin();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * p2;
        // Reproject onto the hemisphere and unstretch.
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        Vec3::new(self.ax * nh.x, self.ay * nh.y, nh.z.max(0.0)).normalize()
    }
}

/// A microfacet reflection pair in the upper hemisphere (`wo.z > 0`, `wi.z > 0`): the
/// half vector, D·G1(wi)·G1(wo)/(4 cos θo) (f·cos θi without Fresnel or colour), and the
/// density D_wo(m)/(4 wo·m) with which VNDF sampling produces `wi`. `None` when the pair
/// cannot be reached (a back-facing half vector, or a direction on the horizon).
#[inline]
pub fn reflection(ggx: &Ggx, wo: Vec3, wi: Vec3) -> Option<(Vec3, f32, f32)> {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return None;
    }
    let m = (wo + wi).normalize_or_zero();
    if m.z <= 0.0 {
        return None;
    }
    let d = ggx.d(m);
    let g1o = ggx.g1(wo, m);
    let g1i = ggx.g1(wi, m);
    let value = d * g1o * g1i / (4.0 * wo.z);
    let pdf = d * g1o / (4.0 * wo.z);
    if !valid_pdf(pdf) {
        return None;
    }
    Some((m, value, pdf))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{warp, Pcg32};

    /// ∫ D(m) cos θm dm = 1 and ∫ D_wo(m) dm = 1, by uniform-sphere Monte Carlo.
    #[test]
    fn ggx_is_normalised_and_visible_normals_integrate_to_one() {
        let mut rng = Pcg32::new(9, 1);
        for ggx in [Ggx::isotropic(0.5), Ggx::new(0.3, 0.8)] {
            let wo = Vec3::new(0.4, -0.3, 0.6).normalize();
            let n = 400_000;
            let (mut proj, mut vis) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let m = warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
                proj += (ggx.d(m) * m.z.max(0.0) / warp::UNIFORM_SPHERE_PDF) as f64;
                vis += (ggx.pdf_visible(wo, m) / warp::UNIFORM_SPHERE_PDF) as f64;
            }
            assert!((proj / n as f64 - 1.0).abs() < 0.01, "{}", proj / n as f64);
            assert!((vis / n as f64 - 1.0).abs() < 0.01, "{}", vis / n as f64);
        }
    }

    #[test]
    fn refraction_obeys_snell() {
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let eta = 1.5;
        let (_, cos_t) = super::super::fresnel::fresnel_dielectric_cos(wo.z, eta);
        let wi = refract(wo, Vec3::Z, eta, cos_t);
        assert!((wi.length() - 1.0).abs() < 1e-6);
        assert!((wi.x.abs() * eta - wo.x).abs() < 1e-6 && wi.z < 0.0 && wi.x < 0.0);
    }
}
