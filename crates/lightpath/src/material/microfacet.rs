//! Microfacet distributions — GGX (Trowbridge–Reitz) and Beckmann — with the separable
//! Smith masking term, and sampling of their visible normals: Heitz 2018, "Sampling the
//! GGX Distribution of Visible Normals" (JCGT 7(4)) for GGX; for Beckmann, the slope
//! sampling of Heitz & d'Eon 2014 ("Importance Sampling Microfacet-Based BSDFs using the
//! Distribution of Visible Normals") with the numerically robust inversion Jakob
//! published for Mitsuba.
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

/// Which normal distribution a [`Microfacet`] model uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Distribution {
    /// Trowbridge–Reitz: long tails (the course's and pbrt's choice).
    #[default]
    Ggx,
    /// Beckmann–Spizzichino: a Gaussian of slopes (Mitsuba's default).
    Beckmann,
}

impl Distribution {
    pub fn from_name(name: &str) -> Option<Distribution> {
        match name {
            "ggx" => Some(Distribution::Ggx),
            "beckmann" => Some(Distribution::Beckmann),
            _ => None,
        }
    }
}

/// An anisotropic microfacet distribution with roughness `ax` along the tangent (x) and
/// `ay` along the bitangent (y).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Microfacet {
    pub ax: f32,
    pub ay: f32,
    pub distribution: Distribution,
}

impl Microfacet {
    /// An anisotropic GGX distribution.
    pub fn new(ax: f32, ay: f32) -> Microfacet {
        Microfacet {
            ax,
            ay,
            distribution: Distribution::Ggx,
        }
    }

    /// An isotropic GGX distribution.
    pub fn isotropic(alpha: f32) -> Microfacet {
        Microfacet::new(alpha, alpha)
    }

    /// The same roughness with another distribution.
    pub fn with_distribution(self, distribution: Distribution) -> Microfacet {
        Microfacet {
            distribution,
            ..self
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
        match self.distribution {
            Distribution::Ggx => {
                let c = x * x + y * y + m.z * m.z;
                INV_PI / (self.ax * self.ay * c * c)
            }
            Distribution::Beckmann => {
                let z2 = m.z * m.z;
                let v = (-(x * x + y * y) / z2).exp() * INV_PI / (self.ax * self.ay * z2 * z2);
                if v.is_finite() {
                    v
                } else {
                    0.0
                }
            }
        }
    }

    /// Smith's Λ(w).
    #[inline]
    pub fn lambda(&self, w: Vec3) -> f32 {
        let z2 = w.z * w.z;
        if z2 <= 0.0 {
            return f32::INFINITY;
        }
        let a2t2 = ((self.ax * w.x).powi(2) + (self.ay * w.y).powi(2)) / z2;
        match self.distribution {
            Distribution::Ggx => 0.5 * ((1.0 + a2t2).sqrt() - 1.0),
            Distribution::Beckmann => {
                if a2t2 <= 0.0 {
                    return 0.0;
                }
                // a = 1/(α tan θ); Λ = (erf(a) − 1)/2 + e^{−a²}/(2a√π).
                let a = (1.0 / a2t2 as f64).sqrt();
                let l = 0.5 * (crate::math::erf(a) - 1.0)
                    + (-a * a).exp() / (2.0 * a * std::f64::consts::PI.sqrt());
                l.max(0.0) as f32
            }
        }
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
        if self.distribution == Distribution::Beckmann {
            return self.sample_visible_beckmann(wo, u);
        }
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

    /// Beckmann visible normals: stretch `wo` to unit roughness, sample the slopes of
    /// the visible microfacets there, rotate and unstretch them.
    fn sample_visible_beckmann(&self, wo: Vec3, u: Vec2) -> Vec3 {
        let wi = Vec3::new(self.ax * wo.x, self.ay * wo.y, wo.z).normalize();
        let r = (wi.x * wi.x + wi.y * wi.y).sqrt();
        let (cos_phi, sin_phi) = if r > 0.0 {
            (wi.x / r, wi.y / r)
        } else {
            (1.0, 0.0)
        };
        let (sx, sy) = beckmann_visible_slopes(wi.z.clamp(-1.0, 1.0) as f64, u);
        // Rotate by φ and unstretch.
        let (sx, sy) = (
            (cos_phi as f64 * sx - sin_phi as f64 * sy) * self.ax as f64,
            (sin_phi as f64 * sx + cos_phi as f64 * sy) * self.ay as f64,
        );
        let m = Vec3::new(-sx as f32, -sy as f32, 1.0).normalize();
        if m.is_finite() {
            m
        } else {
            Vec3::Z
        }
    }
}

/// Slopes (x̃, ỹ) of the visible normals of the unit-roughness Beckmann distribution,
/// seen from a direction with cosine `cos_theta` in the x–z plane.
///
/// The x slope inverts its CDF, `C(b) = N (1 + b + tan θ e^{−erf⁻¹(b)²}/√π)` in the
/// variable `b = erf(x̃)` with `b ∈ [−1, erf(cot θ)]`, by Newton steps safeguarded with
/// bisection; the y slope is a plain Gaussian.
fn beckmann_visible_slopes(cos_theta: f64, u: Vec2) -> (f64, f64) {
    use crate::math::{erf, erf_inv};
    let inv_sqrt_pi = 1.0 / std::f64::consts::PI.sqrt();
    let ux = (u.x as f64).max(1e-6);
    let uy = (u.y as f64).max(1e-6);
    let sy = erf_inv(2.0 * uy - 1.0);
    if cos_theta > 0.9999 {
        // Seen from the normal: the visible slopes are the slopes.
        return (erf_inv(2.0 * ux - 1.0), sy);
    }
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let tan_theta = sin_theta / cos_theta;
    let cot_theta = cos_theta / sin_theta;
    // The search interval, in erf space.
    let mut lo = -1.0;
    let mut hi = erf(cot_theta);
    // A good first guess (Jakob's polynomial fit in θ).
    let theta = cos_theta.acos();
    let fit = 1.0 + theta * (-0.876 + theta * (0.4265 - 0.0594 * theta));
    let mut b = hi - (1.0 + hi) * (1.0 - ux).powf(fit);
    let norm = 1.0 / (1.0 + hi + inv_sqrt_pi * tan_theta * (-cot_theta * cot_theta).exp());
    for _ in 0..100 {
        if !(b >= lo && b <= hi) {
            b = 0.5 * (lo + hi);
        }
        let x = erf_inv(b);
        let value = norm * (1.0 + b + inv_sqrt_pi * tan_theta * (-x * x).exp()) - ux;
        let derivative = norm * (1.0 - x * tan_theta);
        if value.abs() < 1e-7 {
            break;
        }
        if value > 0.0 {
            hi = b;
        } else {
            lo = b;
        }
        b -= value / derivative;
    }
    (erf_inv(b), sy)
}

/// A microfacet reflection pair in the upper hemisphere (`wo.z > 0`, `wi.z > 0`): the
/// half vector, D·G1(wi)·G1(wo)/(4 cos θo) (f·cos θi without Fresnel or colour), and the
/// density D_wo(m)/(4 wo·m) with which VNDF sampling produces `wi`. `None` when the pair
/// cannot be reached (a back-facing half vector, or a direction on the horizon).
#[inline]
pub fn reflection(ggx: &Microfacet, wo: Vec3, wi: Vec3) -> Option<(Vec3, f32, f32)> {
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
        for ggx in [
            Microfacet::isotropic(0.5),
            Microfacet::new(0.3, 0.8),
            Microfacet::isotropic(0.5).with_distribution(Distribution::Beckmann),
            Microfacet::new(0.3, 0.8).with_distribution(Distribution::Beckmann),
        ] {
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

    /// Sampled visible normals follow `pdf_visible`: a histogram over (cos θ, φ) bins
    /// against the density integrated over each bin, by a chi-square statistic.
    #[test]
    fn visible_normal_samples_follow_their_density() {
        const NT: usize = 10;
        const NP: usize = 20;
        let n = 200_000;
        for (mf, wo) in [
            (Microfacet::isotropic(0.3), Vec3::new(0.5, 0.2, 0.6)),
            (Microfacet::new(0.2, 0.6), Vec3::new(-0.7, 0.3, 0.3)),
            (
                Microfacet::isotropic(0.3).with_distribution(Distribution::Beckmann),
                Vec3::new(0.5, 0.2, 0.6),
            ),
            (
                Microfacet::isotropic(0.8).with_distribution(Distribution::Beckmann),
                Vec3::new(0.9, 0.0, 0.1),
            ),
            (
                Microfacet::new(0.15, 0.5).with_distribution(Distribution::Beckmann),
                Vec3::new(-0.4, 0.5, 0.4),
            ),
            (
                Microfacet::isotropic(0.4).with_distribution(Distribution::Beckmann),
                Vec3::Z,
            ),
        ] {
            let wo = wo.normalize();
            let bin = |m: Vec3| {
                let t = ((m.z.clamp(0.0, 1.0)) * NT as f32) as usize;
                let p = ((m.y.atan2(m.x) + PI) / (2.0 * PI) * NP as f32) as usize;
                t.min(NT - 1) * NP + p.min(NP - 1)
            };
            let mut observed = vec![0f64; NT * NP];
            let mut rng = Pcg32::new(3, 7);
            for _ in 0..n {
                let m = mf.sample_visible(wo, Vec2::new(rng.next_f32(), rng.next_f32()));
                assert!(m.is_finite() && m.z >= 0.0, "{mf:?}: {m}");
                observed[bin(m)] += 1.0;
            }
            // Expected counts: midpoint rule on a fine grid in (cos θ, φ), where the
            // solid angle element is d(cos θ) dφ.
            let mut expected = vec![0f64; NT * NP];
            let (ft, fp) = (400, 400);
            for i in 0..ft {
                let z = (i as f32 + 0.5) / ft as f32;
                for j in 0..fp {
                    let phi = (j as f32 + 0.5) / fp as f32 * 2.0 * PI - PI;
                    let r = (1.0 - z * z).sqrt();
                    let m = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                    let da = (1.0 / ft as f32) * (2.0 * PI / fp as f32);
                    expected[bin(m)] += (mf.pdf_visible(wo, m) * da) as f64 * n as f64;
                }
            }
            let total: f64 = expected.iter().sum();
            assert!(
                (total / n as f64 - 1.0).abs() < 0.01,
                "{mf:?}: mass {total}"
            );
            // Pool bins with small expectations, then the chi-square statistic.
            let (mut chi2, mut dof, mut pool_o, mut pool_e) = (0.0, 0usize, 0.0, 0.0);
            for (o, e) in observed.iter().zip(&expected) {
                if *e < 5.0 {
                    pool_o += o;
                    pool_e += e;
                } else {
                    chi2 += (o - e) * (o - e) / e;
                    dof += 1;
                }
            }
            if pool_e > 5.0 {
                chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
                dof += 1;
            }
            // Mean dof, sd sqrt(2 dof): 5 sd above is a failure (p < 1e-6).
            let limit = dof as f64 + 5.0 * (2.0 * dof as f64).sqrt();
            assert!(
                chi2 < limit,
                "{mf:?} wo {wo}: chi2 {chi2:.1} > {limit:.1} ({dof} dof)"
            );
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
