//! The Lambertian BSDF, f = albedo/π, reflecting on whichever side light arrives from
//! (wo and wi in the same hemisphere of the shading normal).
//!
//! ```xml
//! <bsdf type="diffuse">
//!     <texture name="albedo" type="image" filename="wood.jpg"/>
//! </bsdf>
//! ```

use crate::math::INV_PI;
use crate::sampling::warp;
use crate::texture::Texture;
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct Diffuse {
    pub albedo: Arc<Texture>,
}

impl Diffuse {
    #[inline]
    pub fn eval(&self, uv: Vec2, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z * wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        self.albedo.eval(uv) * INV_PI * wi.z.abs()
    }

    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z * wi.z <= 0.0 {
            return 0.0;
        }
        wi.z.abs() * INV_PI
    }

    /// Cosine-weighted sampling on wo's side; the weight is the albedo.
    #[inline]
    pub fn sample(&self, uv: Vec2, wo: Vec3, u: Vec2) -> Option<(Vec3, Vec3, f32)> {
        let mut wi = warp::square_to_cosine_hemisphere(u);
        if wo.z < 0.0 {
            wi.z = -wi.z;
        }
        let pdf = wi.z.abs() * INV_PI;
        if pdf <= 0.0 || wo.z == 0.0 {
            return None;
        }
        Some((wi, self.albedo.eval(uv), pdf))
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
        let mut rng = Pcg32::new(4, 4);
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        for _ in 0..1000 {
            let (wi, w, pdf) = d
                .sample(Vec2::ZERO, wo, Vec2::new(rng.next_f32(), rng.next_f32()))
                .unwrap();
            assert!((d.pdf(wo, wi) - pdf).abs() < 1e-5);
            if pdf > 1e-3 {
                assert!((d.eval(Vec2::ZERO, wo, wi) / pdf - w).abs().max_element() < 1e-4);
            }
        }
        // The pdf integrates to 1 over the hemisphere (uniform-sphere Monte Carlo).
        let n = 200_000;
        let mut sum = 0.0;
        for _ in 0..n {
            let wi = warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            sum += d.pdf(wo, wi) / warp::UNIFORM_SPHERE_PDF;
        }
        assert!((sum / n as f32 - 1.0).abs() < 0.01);
        // Reciprocity.
        let wi = Vec3::new(-0.5, 0.2, 0.6).normalize();
        assert!(
            (d.eval(Vec2::ZERO, wo, wi) / wi.z - d.eval(Vec2::ZERO, wi, wo) / wo.z).length() < 1e-6
        );
    }
}
