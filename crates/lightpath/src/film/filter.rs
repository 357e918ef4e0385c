//! Pixel reconstruction filters, applied by filter importance sampling.
//!
//! A pixel's value is the filter-weighted average of the radiance around its centre,
//! `∫ f(x) L(x) dx / ∫ f(x) dx`. For a filter that is never negative that average is
//! estimated without bias by drawing the camera sample's offset from the pixel centre
//! with density `f / ∫ f` and averaging the radiance of the samples with equal weights
//! (pbrt-v4's filter importance sampling). Mitsuba splats each sample into every pixel
//! in the filter's reach instead; both converge to the same image.
//!
//! In a Mitsuba 3 scene:
//! ```xml
//! <film type="hdrfilm">
//!     <rfilter type="gaussian"><float name="stddev" value="0.5"/></rfilter>
//! </film>
//! ```

use crate::math::{erf, erf_inv};
use glam::Vec2;

/// A separable pixel filter, `f(x, y) = f₁(x) f₁(y)`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Filter {
    /// Constant over the pixel: a sample lands uniformly inside it.
    #[default]
    Box,
    /// `max(0, 1 − |x|/radius)`: Mitsuba's `tent` (radius 1 by default).
    Tent { radius: f32 },
    /// A Gaussian of standard deviation `stddev`, cut at `radius` (Mitsuba's `gaussian`:
    /// stddev 0.5, radius 4·stddev). Build it with [`Filter::gaussian`] or
    /// [`Filter::gaussian_cut`], which also fill in `edge`.
    Gaussian {
        stddev: f32,
        radius: f32,
        /// `erf(radius / (stddev·√2))`: the normal CDF's range over a pixel whose filter
        /// the film does not cut, kept so that most samples need no `erf` of their own.
        edge: f64,
    },
}

impl Filter {
    /// Mitsuba's Gaussian filter for a standard deviation.
    pub fn gaussian(stddev: f32) -> Filter {
        Filter::gaussian_cut(stddev, 4.0 * stddev)
    }

    /// A Gaussian of standard deviation `stddev` cut at `radius`.
    pub fn gaussian_cut(stddev: f32, radius: f32) -> Filter {
        Filter::Gaussian {
            stddev,
            radius,
            edge: erf(radius as f64 / (stddev as f64 * std::f64::consts::SQRT_2)),
        }
    }

    /// How far from the pixel centre the filter reaches, in pixels.
    pub fn radius(&self) -> f32 {
        match *self {
            Filter::Box => 0.5,
            Filter::Tent { radius } | Filter::Gaussian { radius, .. } => radius,
        }
    }

    /// Where a camera sample lands in pixel `(x, y)`'s neighbourhood, in film
    /// coordinates (pixel `(x, y)` covers `[x, x+1) × [y, y+1)`), for a uniform `u`.
    ///
    /// Samples stay on the film of size `resolution`: near the border the filter is cut
    /// at the film's edge and renormalised (Mitsuba's `hdrfilm` without `sample_border`),
    /// so border pixels do not see past the image.
    #[inline]
    pub fn film_position(&self, pixel: Vec2, u: Vec2, resolution: Vec2) -> Vec2 {
        match *self {
            // Kept as `pixel + u` so box-filtered images do not change by rounding.
            Filter::Box => pixel + u,
            _ => {
                let centre = pixel + Vec2::splat(0.5);
                let r = self.radius();
                // The offsets that stay on the film, per axis.
                let lo = (-centre).max(Vec2::splat(-r));
                let hi = (resolution - centre).min(Vec2::splat(r));
                centre
                    + Vec2::new(
                        self.sample_1d(u.x, lo.x, hi.x),
                        self.sample_1d(u.y, lo.y, hi.y),
                    )
            }
        }
    }

    /// An offset from the pixel centre in `[lo, hi]` drawn with density ∝ f₁ there (the
    /// inverse of the profile's CDF, restricted to the interval).
    fn sample_1d(&self, u: f32, lo: f32, hi: f32) -> f32 {
        let (u, lo, hi) = (u as f64, lo as f64, hi as f64);
        let x = match *self {
            Filter::Box => lo + u * (hi - lo),
            Filter::Tent { radius } => {
                let r = radius as f64;
                // The triangle's CDF on [-r, r] and its inverse.
                let cdf = |x: f64| {
                    if x <= 0.0 {
                        (x + r).powi(2) / (2.0 * r * r)
                    } else {
                        1.0 - (r - x).powi(2) / (2.0 * r * r)
                    }
                };
                let p = cdf(lo) + u * (cdf(hi) - cdf(lo));
                if p < 0.5 {
                    r * ((2.0 * p).sqrt() - 1.0)
                } else {
                    r * (1.0 - (2.0 - 2.0 * p).max(0.0).sqrt())
                }
            }
            Filter::Gaussian {
                stddev,
                radius,
                edge,
            } => {
                // The normal CDF is (1 + erf(x/(σ√2)))/2; invert it between lo and hi.
                let s = stddev as f64 * std::f64::consts::SQRT_2;
                let r = radius as f64;
                let a = if lo == -r { -edge } else { erf(lo / s) };
                let b = if hi == r { edge } else { erf(hi / s) };
                s * erf_inv(a + u * (b - a))
            }
        };
        (x.clamp(lo, hi)) as f32
    }

    /// The filter's value at an offset from the pixel centre (for tests and plots).
    pub fn eval(&self, offset: Vec2) -> f32 {
        let f = |x: f32| match *self {
            Filter::Box => (x.abs() <= 0.5) as u32 as f32,
            Filter::Tent { radius } => (1.0 - x.abs() / radius).max(0.0),
            Filter::Gaussian { stddev, radius, .. } => {
                if x.abs() > radius {
                    0.0
                } else {
                    (-x * x / (2.0 * stddev * stddev)).exp()
                }
            }
        };
        f(offset.x) * f(offset.y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples follow the filter: a histogram of sampled offsets against the filter's
    /// normalised profile (chi-square-like relative check per bin).
    #[test]
    fn sampled_offsets_follow_the_filter() {
        for filter in [
            Filter::Tent { radius: 1.0 },
            Filter::Tent { radius: 1.5 },
            Filter::gaussian(0.5),
            Filter::gaussian_cut(0.3, 0.6),
        ] {
            let r = filter.radius();
            const BINS: usize = 20;
            const N: usize = 200_000;
            let mut hist = [0usize; BINS];
            for i in 0..N {
                let u = (i as f32 + 0.5) / N as f32;
                let x = filter.sample_1d(u, -r, r);
                assert!(x.abs() <= r, "{filter:?}: offset {x} beyond radius");
                let b = (((x + r) / (2.0 * r)) * BINS as f32) as usize;
                hist[b.min(BINS - 1)] += 1;
            }
            // Expected mass per bin by integrating the 1D profile.
            let f1 = |x: f32| filter.eval(Vec2::new(x, 0.0));
            let mut expected = [0.0f64; BINS];
            let steps = 200;
            for (b, e) in expected.iter_mut().enumerate() {
                let (a, w) = (-r + 2.0 * r * b as f32 / BINS as f32, 2.0 * r / BINS as f32);
                *e = (0..steps)
                    .map(|k| f1(a + w * (k as f32 + 0.5) / steps as f32) as f64)
                    .sum::<f64>();
            }
            let total: f64 = expected.iter().sum();
            for b in 0..BINS {
                let e = expected[b] / total * N as f64;
                let o = hist[b] as f64;
                assert!(
                    (o - e).abs() <= 0.01 * N as f64 / BINS as f64 + 0.02 * e,
                    "{filter:?} bin {b}: {o} samples, expected {e:.0}"
                );
            }
        }
    }

    /// Near the film's border the samples stay on the film and follow the filter cut
    /// there: in a corner pixel, the fraction of samples in the pixel itself matches the
    /// filter's mass over that pixel relative to its mass on the film.
    #[test]
    fn border_pixels_sample_only_the_film() {
        let res = Vec2::new(4.0, 3.0);
        for filter in [Filter::Tent { radius: 1.5 }, Filter::gaussian(0.5)] {
            let n = 100_000;
            let mut inside_pixel = 0;
            for i in 0..n {
                let u = Vec2::new(
                    (i as f32 + 0.5) / n as f32,
                    ((i * 7919) % n) as f32 / n as f32,
                );
                let p = filter.film_position(Vec2::new(3.0, 0.0), u, res);
                assert!(p.x >= 0.0 && p.x <= 4.0 && p.y >= 0.0 && p.y <= 3.0, "{p}");
                if p.x >= 3.0 && p.y <= 1.0 {
                    inside_pixel += 1;
                }
            }
            // Expected: the filter's mass over the pixel over its mass on the film.
            let mass = |x0: f32, x1: f32, y0: f32, y1: f32| {
                let steps = 400;
                let mut m = 0.0f64;
                for a in 0..steps {
                    for b in 0..steps {
                        let x = x0 + (x1 - x0) * (a as f32 + 0.5) / steps as f32;
                        let y = y0 + (y1 - y0) * (b as f32 + 0.5) / steps as f32;
                        m += filter.eval(Vec2::new(x - 3.5, y - 0.5)) as f64
                            * ((x1 - x0) * (y1 - y0)) as f64;
                    }
                }
                m
            };
            let r = filter.radius();
            let film = mass(3.5 - r, 4.0, 0.0, 0.5 + r);
            let expected = mass(3.0, 4.0, 0.0, 1.0) / film;
            let observed = inside_pixel as f64 / n as f64;
            assert!(
                (observed - expected).abs() < 0.01,
                "{filter:?}: {observed} of the samples in the pixel, expected {expected}"
            );
        }
    }

    #[test]
    fn box_keeps_samples_inside_the_pixel() {
        let res = Vec2::new(8.0, 8.0);
        let p = Filter::Box.film_position(Vec2::new(3.0, 4.0), Vec2::new(0.25, 0.75), res);
        assert_eq!(p, Vec2::new(3.25, 4.75));
    }
}
