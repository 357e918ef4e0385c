//! The environment: radiance arriving from infinitely far away in every direction, from
//! a constant colour or a latitude-longitude image, sampled in proportion to its
//! brightness.
//!
//! Direction `d` (in the light's space, after the inverse of its transform) maps to
//! `u = (atan2(-d.z, d.x) + π) / 2π` and `v = acos(d.y) / π`, and the image texture's own
//! lookup (v up the image) applies: +y is the image's bottom row.
//!
//! ```xml
//! <light type="envmap" weight="1">
//!     <texture type="image" filename="sky.hdr" exposure="0.7"/>
//!     <transform><rotate axis="0,1,0" angle="-50"/></transform>
//! </light>
//! ```

use super::{luminance, LightSample};
use crate::math::{Transform, PI};
use crate::sampling::{warp, Distribution2D};
use crate::texture::Texture;
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct Environment {
    pub texture: Arc<Texture>,
    pub render_from_light: Transform,
    /// Sampling distribution over the image, rows from the top, for image textures.
    distribution: Option<Distribution2D>,
}

impl Environment {
    pub fn new(texture: Arc<Texture>, render_from_light: Transform) -> Environment {
        let distribution = match &*texture {
            Texture::Image(t) => {
                let (w, h) = (t.image.width as usize, t.image.height as usize);
                // Luminance times sin θ of the row centre, so the density is uniform in
                // solid angle where the image is uniform.
                let mut values = vec![0.0f32; w * h];
                for y in 0..h {
                    let v = 1.0 - (y as f32 + 0.5) / h as f32;
                    let sin_theta = (PI * v).sin();
                    for x in 0..w {
                        values[y * w + x] =
                            luminance(t.image.get(x as u32, y as u32)).max(0.0) * sin_theta;
                    }
                }
                Some(Distribution2D::new(&values, w, h))
            }
            _ => None,
        };
        Environment {
            texture,
            render_from_light,
            distribution,
        }
    }

    /// Radiance arriving along the ray direction `d` (pointing away from the scene).
    pub fn eval(&self, d: Vec3) -> Vec3 {
        self.texture.eval(Self::direction_to_uv(self.local(d)))
    }

    fn local(&self, d: Vec3) -> Vec3 {
        self.render_from_light.inverse().vector(d).normalize()
    }

    fn direction_to_uv(d: Vec3) -> Vec2 {
        let u = ((-d.z).atan2(d.x) + PI) / (2.0 * PI);
        // θ = acos(d.y), in the form that stays accurate near the poles.
        let v = (d.x * d.x + d.z * d.z).sqrt().atan2(d.y) / PI;
        Vec2::new(u, v)
    }

    fn uv_to_direction(uv: Vec2) -> Vec3 {
        let phi = 2.0 * PI * uv.x - PI;
        let theta = PI * uv.y;
        let s = theta.sin();
        Vec3::new(s * phi.cos(), theta.cos(), -s * phi.sin())
    }

    /// Samples a direction; `weight` is radiance / pdf.
    pub fn sample(&self, u: Vec2) -> Option<LightSample> {
        let (local, pdf) = match &self.distribution {
            Some(dist) => {
                let (p, pdf_image) = dist.sample(u);
                // p.y counts rows from the top; v runs from the bottom.
                let uv = Vec2::new(p.x, 1.0 - p.y);
                let sin_theta = (PI * uv.y).sin();
                if pdf_image <= 0.0 || sin_theta <= 0.0 {
                    return None;
                }
                (
                    Self::uv_to_direction(uv),
                    pdf_image / (2.0 * PI * PI * sin_theta),
                )
            }
            None => (warp::square_to_uniform_sphere(u), warp::UNIFORM_SPHERE_PDF),
        };
        let wi = self.render_from_light.vector(local).normalize();
        let radiance = self.eval(wi);
        Some(LightSample {
            wi,
            distance: f32::INFINITY,
            weight: radiance / pdf,
            pdf,
        })
    }

    /// Solid-angle density of sampling `wi`.
    pub fn pdf(&self, wi: Vec3) -> f32 {
        match &self.distribution {
            Some(dist) => {
                let uv = Self::direction_to_uv(self.local(wi));
                let sin_theta = (PI * uv.y).sin();
                if sin_theta <= 0.0 {
                    return 0.0;
                }
                dist.pdf(Vec2::new(uv.x, 1.0 - uv.y)) / (2.0 * PI * PI * sin_theta)
            }
            None => warp::UNIFORM_SPHERE_PDF,
        }
    }

    pub fn average(&self) -> Vec3 {
        self.texture.average()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::Image;
    use crate::sampling::Pcg32;
    use crate::texture::{BorderMode, FilterMode, ImageTexture};

    fn env() -> Environment {
        let mut img = Image::new(16, 8);
        for y in 0..8 {
            for x in 0..16 {
                img.set(x, y, Vec3::splat(((x * 7 + y * 3) % 5) as f32 + 0.1));
            }
        }
        let tex = Texture::Image(ImageTexture {
            image: Arc::new(img),
            border: BorderMode::Repeat,
            filter: FilterMode::Nearest,
            exposure: 1.0,
        });
        Environment::new(
            Arc::new(tex),
            Transform::rotate(Vec3::new(1.0, 2.0, 0.5), 40.0).unwrap(),
        )
    }

    #[test]
    fn uv_mapping_round_trips() {
        let mut rng = Pcg32::new(8, 8);
        for _ in 0..1000 {
            let uv = Vec2::new(rng.next_f32(), rng.next_f32() * 0.98 + 0.01);
            let back = Environment::direction_to_uv(Environment::uv_to_direction(uv));
            assert!((back - uv).abs().max_element() < 1e-4, "{uv} {back}");
        }
    }

    #[test]
    fn pdf_integrates_to_one_and_matches_sampling() {
        let e = env();
        let mut rng = Pcg32::new(1, 9);
        let n = 400_000;
        let mut integral = 0.0f64;
        for _ in 0..n {
            let w = warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            integral += (e.pdf(w) / warp::UNIFORM_SPHERE_PDF) as f64;
        }
        assert!(
            (integral / n as f64 - 1.0).abs() < 0.01,
            "{}",
            integral / n as f64
        );
        for _ in 0..1000 {
            let s = e.sample(Vec2::new(rng.next_f32(), rng.next_f32())).unwrap();
            let pdf = e.pdf(s.wi);
            assert!(
                (pdf - s.pdf).abs() <= 1e-3 * s.pdf.max(1.0),
                "{pdf} vs {}",
                s.pdf
            );
        }
    }

    #[test]
    fn importance_sampling_estimates_the_integral() {
        // ∫ L dω estimated by sampling equals the uniform estimate.
        let e = env();
        let mut rng = Pcg32::new(3, 1);
        let n = 200_000;
        let (mut is, mut uni) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let s = e.sample(Vec2::new(rng.next_f32(), rng.next_f32())).unwrap();
            is += luminance(s.weight) as f64;
            let w = warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            uni += (luminance(e.eval(w)) / warp::UNIFORM_SPHERE_PDF) as f64;
        }
        let (is, uni) = (is / n as f64, uni / n as f64);
        assert!((is - uni).abs() / uni < 0.02, "{is} vs {uni}");
    }
}
