//! Chooses one light for next-event estimation, in proportion to power × weight.

use super::Light;
use crate::math::Bounds3;
use crate::sampling::Distribution1D;

#[derive(Debug, Clone)]
pub struct LightSampler {
    distribution: Option<Distribution1D>,
    /// Selection probability per light.
    probabilities: Vec<f32>,
}

impl LightSampler {
    /// `weights[i]` scales light `i`'s power; weight 0 removes it from sampling.
    pub fn new(lights: &[Light], weights: &[f32], bounds: &Bounds3) -> LightSampler {
        let values: Vec<f32> = lights
            .iter()
            .zip(weights)
            .map(|(l, &w)| {
                let p = l.power(bounds);
                // A light with no measurable power (e.g. black) is still picked if weighted.
                w.max(0.0) * if p.is_finite() && p > 0.0 { p } else { 0.0 }
            })
            .collect();
        let total: f32 = values.iter().sum();
        if total <= 0.0 {
            return LightSampler {
                distribution: None,
                probabilities: vec![0.0; lights.len()],
            };
        }
        let probabilities = values.iter().map(|v| v / total).collect();
        LightSampler {
            distribution: Some(Distribution1D::new(&values)),
            probabilities,
        }
    }

    /// Picks a light: (index, probability).
    #[inline]
    pub fn sample(&self, u: f32) -> Option<(usize, f32)> {
        let d = self.distribution.as_ref()?;
        if let [p] = self.probabilities[..] {
            // One light (the distribution's only cell).
            return Some((0, p));
        }
        let i = d.sample_discrete(u);
        Some((i, self.probabilities[i]))
    }

    /// The distribution [`LightSampler::sample`] picks from (`None`: it picks nothing).
    pub(crate) fn distribution(&self) -> Option<&Distribution1D> {
        self.distribution.as_ref()
    }

    pub fn probability(&self, light: usize) -> f32 {
        self.probabilities[light]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::PointLight;
    use glam::Vec3;

    #[test]
    fn probabilities_follow_power_and_sum_to_one() {
        let lights: Vec<Light> = [1.0f32, 3.0, 0.5, 2.0]
            .iter()
            .map(|&i| {
                Light::Point(PointLight {
                    position: Vec3::ZERO,
                    intensity: Vec3::splat(i),
                })
            })
            .collect();
        let s = LightSampler::new(&lights, &[1.0, 1.0, 0.0, 1.0], &Bounds3::EMPTY);
        let total: f32 = (0..4).map(|i| s.probability(i)).sum();
        assert!((total - 1.0).abs() < 1e-6);
        assert_eq!(s.probability(2), 0.0);
        assert!((s.probability(1) - 0.5).abs() < 1e-6);
        let mut counts = [0usize; 4];
        let n = 60_000;
        for k in 0..n {
            let (i, p) = s.sample((k as f32 + 0.5) / n as f32).unwrap();
            assert_eq!(p, s.probability(i));
            counts[i] += 1;
        }
        assert_eq!(counts[2], 0);
        assert!((counts[1] as f32 / n as f32 - 0.5).abs() < 0.01);
    }
}
