//! Pixel reconstruction filters, applied by filter importance sampling.
//!
//! A pixel's value is the filter-weighted average of the radiance around its centre,
//! `∫ f(x) L(x) dx / ∫ f(x) dx`. For a filter that is never negative that average is
//! estimated without bias by drawing the camera sample's offset from the pixel centre
//! with density `f / ∫ f` and averaging the radiance of the samples with equal weights
//! (pbrt-v4's filter importance sampling). Mitsuba splats each sample into every pixel
//! in the filter's reach instead; both converge to the same image.
//!
//! Filters with negative lobes (Mitchell–Netravali, Catmull–Rom, Lanczos), and filters
//! made of constant steps as Mitsuba's film applies them ([`Filter::with_steps`]), are
//! sampled from a table of `|f|` instead, and each sample carries the weight
//! `f(x) / (p(x) ∫f)` ([`Filter::film_sample`]), whose sign follows the lobe it landed
//! in: the weighted average is still an unbiased estimate of `∫ f L / ∫ f`. The
//! samples of filters that are never negative all weigh 1.
//!
//! In a Mitsuba 3 scene:
//! ```xml
//! <film type="hdrfilm">
//!     <rfilter type="gaussian"><float name="stddev" value="0.5"/></rfilter>
//! </film>
//! ```

use crate::math::{erf, erf_inv};
use glam::Vec2;
use std::sync::Arc;

/// A separable pixel filter, `f(x, y) = f₁(x) f₁(y)`.
#[derive(Debug, Clone, PartialEq, Default)]
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
    /// The Mitchell–Netravali cubic with parameters `b` and `c`, radius 2 (Mitsuba's
    /// `mitchell`, B = C = 1/3; its `catmullrom` is B = 0, C = ½). Build it with
    /// [`Filter::mitchell`].
    Mitchell { b: f32, c: f32, table: Arc<Profile> },
    /// `sinc(x)·sinc(x/lobes)` for `|x| < lobes` (Mitsuba's `lanczos`, 3 lobes). Build it
    /// with [`Filter::lanczos`].
    Lanczos { lobes: u32, table: Arc<Profile> },
    /// `filter` made constant over `steps` steps per radius on either side (see
    /// [`Filter::with_steps`]).
    Stepped {
        filter: Arc<Filter>,
        steps: u32,
        table: Arc<Profile>,
    },
}

/// The steps per radius of the tables through which Mitsuba 3 applies its filters
/// (`eval_discretized`: the value at each step's inner end, probed in Mitsuba 3.9.1).
pub const MITSUBA_FILTER_STEPS: u32 = 31;

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

    /// The Mitchell–Netravali filter (Mitsuba's `mitchell`: `b` = `c` = 1/3).
    pub fn mitchell(b: f32, c: f32) -> Filter {
        Filter::Mitchell {
            b,
            c,
            table: Arc::new(Profile::new(2.0, 0, |x| mitchell(b as f64, c as f64, x))),
        }
    }

    /// The Catmull–Rom spline: Mitchell–Netravali with B = 0, C = ½.
    pub fn catmull_rom() -> Filter {
        Filter::mitchell(0.0, 0.5)
    }

    /// The Lanczos filter of `lobes` lobes (at least 1).
    pub fn lanczos(lobes: u32) -> Filter {
        let lobes = lobes.max(1);
        Filter::Lanczos {
            lobes,
            table: Arc::new(Profile::new(lobes as f64, 0, |x| lanczos(lobes as f64, x))),
        }
    }

    /// The filter made constant over `steps` steps per radius on either side, each
    /// taking the value at its end nearer the centre: how Mitsuba 3 applies its filters
    /// ([`MITSUBA_FILTER_STEPS`]), which differs visibly from the exact filter (Lanczos
    /// at 0.75 pixels: 0.366 against 0.270; a Gaussian is widened by about half a step).
    /// Sampled from a table whose bins do not straddle the steps. The box, already
    /// constant, a stepped filter, and `steps` 0 are returned unchanged.
    pub fn with_steps(self, steps: u32) -> Filter {
        if steps == 0 || matches!(self, Filter::Box | Filter::Stepped { .. }) {
            return self;
        }
        let r = self.radius() as f64;
        let table = Arc::new(Profile::new(r, steps, |x| {
            self.profile(quantise(x, r, steps))
        }));
        Filter::Stepped {
            filter: Arc::new(self),
            steps,
            table,
        }
    }

    /// How far from the pixel centre the filter reaches, in pixels.
    pub fn radius(&self) -> f32 {
        match self {
            Filter::Box => 0.5,
            Filter::Tent { radius } | Filter::Gaussian { radius, .. } => *radius,
            Filter::Mitchell { .. } => 2.0,
            Filter::Lanczos { lobes, .. } => *lobes as f32,
            Filter::Stepped { filter, .. } => filter.radius(),
        }
    }

    /// The profile `f₁` at an offset, in double precision.
    fn profile(&self, x: f64) -> f64 {
        match *self {
            Filter::Stepped {
                ref filter, steps, ..
            } => filter.profile(quantise(x, filter.radius() as f64, steps)),
            Filter::Box => f64::from(u8::from(x.abs() <= 0.5)),
            Filter::Tent { radius } => (1.0 - x.abs() / radius as f64).max(0.0),
            Filter::Gaussian { stddev, radius, .. } => {
                if x.abs() > radius as f64 {
                    0.0
                } else {
                    (-x * x / (2.0 * (stddev as f64).powi(2))).exp()
                }
            }
            Filter::Mitchell { b, c, .. } => mitchell(b as f64, c as f64, x),
            Filter::Lanczos { lobes, .. } => lanczos(lobes as f64, x),
        }
    }

    /// Where a camera sample lands in pixel `(x, y)`'s neighbourhood, in film
    /// coordinates (pixel `(x, y)` covers `[x, x+1) × [y, y+1)`), for a uniform `u`.
    ///
    /// Samples stay on the film of size `resolution`: near the border the filter is cut
    /// at the film's edge and renormalised (Mitsuba's `hdrfilm` without `sample_border`),
    /// so border pixels do not see past the image.
    ///
    /// Returns the position and the sample's weight: 1 for the filters that are never
    /// negative, `f / (p ∫f)` for those with negative lobes (see the module docs).
    #[inline]
    pub fn film_sample(&self, pixel: Vec2, u: Vec2, resolution: Vec2) -> (Vec2, f32) {
        match self {
            // Kept as `pixel + u` so box-filtered images do not change by rounding.
            Filter::Box => (pixel + u, 1.0),
            _ => {
                let centre = pixel + Vec2::splat(0.5);
                let r = self.radius();
                // The offsets that stay on the film, per axis.
                let lo = (-centre).max(Vec2::splat(-r));
                let hi = (resolution - centre).min(Vec2::splat(r));
                let (x, wx) = self.sample_1d(u.x, lo.x, hi.x);
                let (y, wy) = self.sample_1d(u.y, lo.y, hi.y);
                (centre + Vec2::new(x, y), wx * wy)
            }
        }
    }

    /// An offset from the pixel centre in `[lo, hi]` drawn with density ∝ f₁ there (the
    /// inverse of the profile's CDF, restricted to the interval), or for the filters
    /// with negative lobes ∝ a table of |f₁|, and its weight.
    fn sample_1d(&self, u: f32, lo: f32, hi: f32) -> (f32, f32) {
        let (u, lo, hi) = (u as f64, lo as f64, hi as f64);
        let table = match self {
            Filter::Mitchell { table, .. }
            | Filter::Lanczos { table, .. }
            | Filter::Stepped { table, .. } => table,
            _ => return (self.sample_positive(u, lo, hi), 1.0),
        };
        let (x, pdf) = table.sample(u, lo, hi);
        if table.never_negative {
            // Drawn with density exactly ∝ f (constant steps in whole bins).
            return (x as f32, 1.0);
        }
        let weight = self.profile(x) / (pdf * table.integral(lo, hi, |x| self.profile(x)));
        (
            x as f32,
            if weight.is_finite() {
                weight as f32
            } else {
                0.0
            },
        )
    }

    /// [`Filter::sample_1d`] for the filters that are never negative.
    fn sample_positive(&self, u: f64, lo: f64, hi: f64) -> f32 {
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
            Filter::Mitchell { .. } | Filter::Lanczos { .. } | Filter::Stepped { .. } => {
                unreachable!("sampled from their tables")
            }
        };
        (x.clamp(lo, hi)) as f32
    }

    /// The filter's value at an offset from the pixel centre (for tests and plots).
    pub fn eval(&self, offset: Vec2) -> f32 {
        (self.profile(offset.x as f64) * self.profile(offset.y as f64)) as f32
    }
}

/// `|x|` moved to the inner end of its step, for `steps` (at least 1) steps per `radius`.
fn quantise(x: f64, radius: f64, steps: u32) -> f64 {
    let s = steps as f64;
    (x.abs() * s / radius).floor() * radius / s
}

/// The Mitchell–Netravali cubic (Mitchell and Netravali 1988, as Mitsuba 3 writes it).
fn mitchell(b: f64, c: f64, x: f64) -> f64 {
    let x = x.abs();
    let v = if x < 1.0 {
        (12.0 - 9.0 * b - 6.0 * c) * x * x * x
            + (-18.0 + 12.0 * b + 6.0 * c) * x * x
            + (6.0 - 2.0 * b)
    } else if x < 2.0 {
        (-b - 6.0 * c) * x * x * x
            + (6.0 * b + 30.0 * c) * x * x
            + (-12.0 * b - 48.0 * c) * x
            + (8.0 * b + 24.0 * c)
    } else {
        0.0
    };
    v / 6.0
}

/// The Lanczos window `sinc(x)·sinc(x/lobes)` inside `|x| < lobes`.
fn lanczos(lobes: f64, x: f64) -> f64 {
    let sinc = |x: f64| {
        if x.abs() < 1e-5 {
            1.0
        } else {
            let px = std::f64::consts::PI * x;
            px.sin() / px
        }
    };
    if x.abs() >= lobes {
        0.0
    } else {
        sinc(x) * sinc(x / lobes)
    }
}

/// A tabulated profile for the filters with negative lobes and the stepped filters
/// (those not sampled in closed form): over `[-radius, radius]` in
/// bins of [`Profile::BINS_PER_PIXEL`] per pixel (or, for a filter of constant steps,
/// four bins a step, so that no bin straddles a step), the mass of `|f|` in each bin (so a
/// sample is drawn piecewise uniformly, with a bin's mass over its width as density),
/// and the running integral of `f` itself (for the normalisation `∫f`).
#[derive(PartialEq)]
pub struct Profile {
    radius: f64,
    step: f64,
    /// Each bin's mass of `|f|`, never zero: a floor keeps every offset in the support
    /// reachable, so the weights stay unbiased (no floor where `f` is positive
    /// throughout, see `never_negative`).
    mass: Vec<f64>,
    /// The running sum of `mass` at each bin's left edge, and the total at the end.
    cdf: Vec<f64>,
    /// `∫ f` from `-radius` to each bin's left edge, and to `radius` at the end.
    integral: Vec<f64>,
    /// A stepped filter that is positive throughout its support (a stepped Gaussian or
    /// tent): its bins' masses are exactly its steps' (no floor, and none is zero), so a
    /// sample's density is ∝ f and its weight 1.
    never_negative: bool,
}

impl std::fmt::Debug for Profile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Profile")
            .field("radius", &self.radius)
            .field("bins", &self.mass.len())
            .finish_non_exhaustive()
    }
}

impl Profile {
    const BINS_PER_PIXEL: usize = 64;

    fn new(radius: f64, steps: u32, f: impl Fn(f64) -> f64) -> Profile {
        let bins = if steps > 0 {
            8 * steps as usize
        } else {
            (2.0 * radius * Self::BINS_PER_PIXEL as f64).ceil() as usize
        };
        let step = 2.0 * radius / bins as f64;
        let never_negative =
            steps > 0 && (0..bins * 16).all(|k| f(-radius + (k as f64 + 0.5) * step / 16.0) > 0.0);
        let floor = if never_negative {
            0.0
        } else {
            1e-6 * f(0.0).abs() * step
        };
        let (mut mass, mut cdf, mut integral) = (Vec::new(), vec![0.0], vec![0.0]);
        for j in 0..bins {
            let a = -radius + j as f64 * step;
            let m = midpoint(|x| f(x).abs(), a, a + step, 16) + floor;
            mass.push(m);
            cdf.push(cdf[j] + m);
            integral.push(integral[j] + midpoint(&f, a, a + step, 16));
        }
        Profile {
            radius,
            step,
            mass,
            cdf,
            integral,
            never_negative,
        }
    }

    /// The bin holding offset `x` (clamped to the table).
    fn bin(&self, x: f64) -> usize {
        (((x + self.radius) / self.step).floor().max(0.0) as usize).min(self.mass.len() - 1)
    }

    /// The table's CDF (not normalised) at `x`.
    fn cdf_at(&self, x: f64) -> f64 {
        let j = self.bin(x);
        let left = -self.radius + j as f64 * self.step;
        self.cdf[j] + self.mass[j] * ((x - left) / self.step).clamp(0.0, 1.0)
    }

    /// An offset in `[lo, hi]` drawn from the table restricted there, and its density.
    fn sample(&self, u: f64, lo: f64, hi: f64) -> (f64, f64) {
        let (a, b) = (self.cdf_at(lo), self.cdf_at(hi));
        let p = a + u * (b - a);
        // The last bin whose left edge's CDF is at most p.
        let j = (self.cdf.partition_point(|&c| c <= p).max(1) - 1).min(self.mass.len() - 1);
        let left = -self.radius + j as f64 * self.step;
        let x = (left + (p - self.cdf[j]) / self.mass[j] * self.step).clamp(lo, hi);
        let j = self.bin(x);
        (x, self.mass[j] / self.step / (b - a))
    }

    /// `∫ f` over `[lo, hi]`: from the table where the interval is the whole support,
    /// else the table's running integral plus the partial bins by the midpoint rule.
    fn integral(&self, lo: f64, hi: f64, f: impl Fn(f64) -> f64) -> f64 {
        if lo <= -self.radius && hi >= self.radius {
            return self.integral[self.mass.len()];
        }
        let upto = |x: f64| {
            let j = self.bin(x);
            let left = -self.radius + j as f64 * self.step;
            self.integral[j] + midpoint(&f, left, x.min(left + self.step), 8)
        };
        upto(hi) - upto(lo)
    }
}

/// The midpoint rule for `f` over `[a, b]` in `n` intervals (exact for the constant
/// steps of a stepped filter, whose edges the bins share, as it never evaluates an edge).
fn midpoint(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let h = (b - a) / n as f64;
    (0..n).map(|k| f(a + (k as f64 + 0.5) * h)).sum::<f64>() * h
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
                let (x, _) = filter.sample_1d(u, -r, r);
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
                let (p, _) = filter.film_sample(Vec2::new(3.0, 0.0), u, res);
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

    /// The profiles of the filters with negative lobes, against values that Mitsuba
    /// 3.9.1's `eval` gives (to its six printed digits).
    #[test]
    fn negative_lobed_profiles_match_mitsuba() {
        let cases: [(Filter, [(f64, f64); 5]); 4] = [
            (
                Filter::mitchell(1.0 / 3.0, 1.0 / 3.0),
                [
                    (0.0, 0.888889),
                    (0.25, 0.782118),
                    (1.0, 0.055556),
                    (1.3, -0.029944),
                    (1.7, -0.0195),
                ],
            ),
            (
                Filter::catmull_rom(),
                [
                    (0.0, 1.0),
                    (0.25, 0.867188),
                    (0.5, 0.5625),
                    (1.3, -0.0735),
                    (1.7, -0.0315),
                ],
            ),
            (
                Filter::lanczos(3),
                [
                    (0.0, 1.0),
                    (0.25, 0.890067),
                    (1.3, -0.14233),
                    (1.7, -0.083231),
                    (2.5, 0.024317),
                ],
            ),
            (
                Filter::lanczos(2),
                [
                    (0.25, 0.877354),
                    (0.5, 0.573159),
                    (1.3, -0.086433),
                    (1.7, -0.025754),
                    (2.5, 0.0),
                ],
            ),
        ];
        for (filter, values) in cases {
            for (x, want) in values {
                let got = filter.profile(x);
                assert!(
                    (got - want).abs() < 2e-6,
                    "{filter:?} at {x}: {got}, Mitsuba {want}"
                );
                assert_eq!(filter.profile(-x), got);
            }
        }
        // As Mitsuba's film applies them (`eval_discretized`).
        let stepped: [(Filter, [(f64, f64); 3]); 2] = [
            (
                Filter::mitchell(1.0 / 3.0, 1.0 / 3.0),
                [(0.1, 0.880878), (0.25, 0.822426), (1.3, -0.028883)],
            ),
            (
                Filter::lanczos(3),
                [(0.1, 0.982981), (0.25, 0.933089), (1.3, -0.134753)],
            ),
        ];
        for (filter, values) in stepped {
            let filter = filter.with_steps(MITSUBA_FILTER_STEPS);
            for (x, want) in values {
                let got = filter.profile(x);
                assert!(
                    (got - want).abs() < 2e-5,
                    "{filter:?} at {x}: {got}, Mitsuba {want}"
                );
            }
        }
    }

    /// The weighted samples of every filter estimate the filter-weighted average
    /// `∫ f g / ∫ f` of a test function, over the whole support and cut at a film's edge:
    /// with the negative lobes' signs (dropping them, i.e. sampling |f| with weight 1,
    /// gives a different average, which the test would catch).
    #[test]
    fn weighted_samples_estimate_the_filtered_average() {
        let g = |x: f64| 1.0 + x + 2.0 * x * x;
        for filter in [
            Filter::Tent { radius: 1.5 },
            Filter::gaussian(0.5),
            Filter::mitchell(1.0 / 3.0, 1.0 / 3.0),
            Filter::catmull_rom(),
            Filter::lanczos(3),
            Filter::lanczos(3).with_steps(MITSUBA_FILTER_STEPS),
            Filter::gaussian(0.5).with_steps(MITSUBA_FILTER_STEPS),
            Filter::Tent { radius: 1.0 }.with_steps(MITSUBA_FILTER_STEPS),
        ] {
            let r = filter.radius() as f64;
            for (lo, hi) in [(-r, r), (-0.5, r), (-r, 1.2)] {
                // The exact average by quadrature.
                let steps = 20_000;
                let (mut fg, mut f) = (0.0, 0.0);
                for k in 0..steps {
                    let x = lo + (hi - lo) * (k as f64 + 0.5) / steps as f64;
                    fg += filter.profile(x) * g(x);
                    f += filter.profile(x);
                }
                let want = fg / f;
                // The estimate from stratified samples (equal weights per sample).
                let n = 100_000;
                let (mut sum, mut abs_weighted) = (0.0, 0.0);
                for i in 0..n {
                    let u = (i as f32 + 0.5) / n as f32;
                    let (x, w) = filter.sample_1d(u, lo as f32, hi as f32);
                    assert!((lo as f32..=hi as f32).contains(&x), "{filter:?}: {x}");
                    sum += w as f64 * g(x as f64);
                    abs_weighted += g(x as f64);
                }
                let got = sum / n as f64;
                assert!(
                    (got - want).abs() < 2e-3 * want.abs(),
                    "{filter:?} on [{lo}, {hi}]: {got}, expected {want}"
                );
                if matches!(filter, Filter::Mitchell { .. } | Filter::Lanczos { .. }) {
                    let unsigned = abs_weighted / n as f64;
                    assert!((unsigned - want).abs() > 1e-2 * want.abs(), "{filter:?}");
                }
            }
        }
    }

    #[test]
    fn box_keeps_samples_inside_the_pixel() {
        let res = Vec2::new(8.0, 8.0);
        let p = Filter::Box.film_sample(Vec2::new(3.0, 4.0), Vec2::new(0.25, 0.75), res);
        assert_eq!(p, (Vec2::new(3.25, 4.75), 1.0));
    }
}
