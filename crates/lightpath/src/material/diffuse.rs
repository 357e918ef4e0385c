//! The Lambertian BSDF, f = albedo/π, reflecting on whichever side light arrives from
//! (wo and wi in the same hemisphere of the shading normal).
//!
//! ```xml
//! <bsdf type="diffuse">
//!     <texture name="albedo" type="image" filename="wood.jpg"/>
//! </bsdf>
//! ```

use super::BsdfSample;
use crate::math::INV_PI;
use crate::sampling::warp;
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct Diffuse {
    pub albedo: Arc<Texture>,
}

impl Diffuse {
    /// f·|cos θi| in the local frame.
    #[inline]
    pub fn eval(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z * wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        self.albedo.eval(uv) * INV_PI * wi.z.abs()
    }

    #[inline]
    pub fn pdf(&self, _uv: TexCoord, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z * wi.z <= 0.0 {
            return 0.0;
        }
        wi.z.abs() * INV_PI
    }

    /// Cosine-weighted sampling on wo's side; the weight is the albedo.
    #[inline]
    pub fn sample(&self, uv: TexCoord, wo: Vec3, _u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let mut wi = warp::square_to_cosine_hemisphere(u);
        if wo.z < 0.0 {
            wi.z = -wi.z;
        }
        let pdf = wi.z.abs() * INV_PI;
        if pdf <= 0.0 || wo.z == 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi,
            weight: self.albedo.eval(uv),
            pdf,
            delta: false,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    #[test]
    fn sample_matches_eval_over_pdf_and_pdf_integrates() {
        let d = Diffuse {
            albedo: Arc::new(Texture::Constant(Vec3::new(0.2, 0.5, 0.8))),
        };
        let uv = TexCoord::from(Vec2::ZERO);
        let mut rng = Pcg32::new(4, 4);
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        for _ in 0..1000 {
            let s = d
                .sample(uv, wo, 0.5, Vec2::new(rng.next_f32(), rng.next_f32()))
                .unwrap();
            assert!((d.pdf(uv, wo, s.wi) - s.pdf).abs() < 1e-5);
            if s.pdf > 1e-3 {
                assert!(
                    (d.eval(uv, wo, s.wi) / s.pdf - s.weight)
                        .abs()
                        .max_element()
                        < 1e-4
                );
            }
        }
        // The pdf integrates to 1 over the hemisphere (uniform-sphere Monte Carlo).
        let n = 200_000;
        let mut sum = 0.0;
        for _ in 0..n {
            let wi = warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            sum += d.pdf(uv, wo, wi) / warp::UNIFORM_SPHERE_PDF;
        }
        assert!((sum / n as f32 - 1.0).abs() < 0.01);
        // Reciprocity.
        let wi = Vec3::new(-0.5, 0.2, 0.6).normalize();
        assert!((d.eval(uv, wo, wi) / wi.z - d.eval(uv, wi, wo) / wo.z).length() < 1e-6);
    }
}
