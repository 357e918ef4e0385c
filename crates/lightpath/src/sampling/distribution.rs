//! Piecewise-constant distributions in 1D and 2D, for sampling proportional to a
//! tabulated function (aperture images, environment maps).

use glam::Vec2;

/// A piecewise-constant density on [0, 1) with `n` equal cells.
#[derive(Debug, Clone, PartialEq)]
pub struct Distribution1D {
    func: Vec<f32>,
    cdf: Vec<f32>,
    integral: f32,
}

/// Cdfs up to this long are counted rather than searched (see
/// [`Distribution1D::sample_discrete`]).
const SHORT_CDF: usize = 33;

impl Distribution1D {
    /// From non-negative cell values; an all-zero function samples uniformly.
    pub fn new(values: &[f32]) -> Self {
        let n = values.len().max(1);
        let func: Vec<f32> = if values.is_empty() {
            vec![0.0]
        } else {
            values.iter().map(|v| v.max(0.0)).collect()
        };
        let mut cdf = vec![0.0f32; n + 1];
        let mut acc = 0.0f64;
        for i in 0..n {
            acc += func[i] as f64 / n as f64;
            cdf[i + 1] = acc as f32;
        }
        let integral = acc as f32;
        if integral > 0.0 {
            for c in cdf.iter_mut() {
                *c /= integral;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / n as f32;
            }
        }
        cdf[n] = 1.0;
        Distribution1D {
            func,
            cdf,
            integral,
        }
    }

    pub fn len(&self) -> usize {
        self.func.len()
    }

    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// Integral of the function over [0, 1).
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// The cell a uniform `u` in [0, 1) falls in, in proportion to the cells' values: the
    /// cell of [`Distribution1D::sample_continuous`] without its position and density.
    #[inline]
    pub fn sample_discrete(&self, u: f32) -> usize {
        // The last cell whose cdf start is <= u: the number of cdf entries <= u (the cdf
        // does not decrease), less one. A short cdf is counted without branches, which a
        // binary search over random `u` mispredicts; a long one is searched.
        let at_or_below = if self.cdf.len() <= SHORT_CDF {
            self.cdf.iter().map(|&c| usize::from(c <= u)).sum()
        } else {
            self.cdf.partition_point(|&c| c <= u)
        };
        at_or_below.saturating_sub(1).min(self.func.len() - 1)
    }

    /// The cell of [`Distribution1D::sample_discrete`] and `u`'s position inside that
    /// cell's cdf interval, rescaled to [0, 1): a uniform number again, independent of the
    /// cell, so one coordinate of a stratified 2D sample can pick a cell and still serve
    /// as a coordinate within it (Mitsuba's `sample_reuse`).
    #[inline]
    pub fn sample_reuse(&self, u: f32) -> (usize, f32) {
        let (cell, du) = self.cell_and_offset(u);
        (cell, du.clamp(0.0, 1.0 - f32::EPSILON / 2.0))
    }

    /// The cell `u` falls in and `u`'s relative position in that cell's cdf interval.
    #[inline]
    fn cell_and_offset(&self, u: f32) -> (usize, f32) {
        let (cell, c0, c1) = self.cell_interval(u);
        (cell, if c1 > c0 { (u - c0) / (c1 - c0) } else { 0.0 })
    }

    /// The cell of [`Distribution1D::sample_discrete`] and its cdf interval `[c0, c1)`,
    /// for code that computes `u`'s offset in it elsewhere (many at once).
    #[inline(always)]
    pub(crate) fn cell_interval(&self, u: f32) -> (usize, f32, f32) {
        let cell = self.sample_discrete(u);
        (cell, self.cdf[cell], self.cdf[cell + 1])
    }

    /// Cell `cell`'s cdf interval, as [`Distribution1D::cell_interval`] gives it.
    #[inline]
    pub(crate) fn cell_bounds(&self, cell: usize) -> (f32, f32) {
        (self.cdf[cell], self.cdf[cell + 1])
    }

    /// Samples a continuous position in [0, 1); returns (x, density, cell).
    #[inline]
    pub fn sample_continuous(&self, u: f32) -> (f32, f32, usize) {
        let (cell, du) = self.cell_and_offset(u);
        let pdf = if self.integral > 0.0 {
            self.func[cell] / self.integral
        } else {
            1.0
        };
        let x = ((cell as f32 + du) / self.func.len() as f32).min(1.0 - f32::EPSILON);
        (x, pdf, cell)
    }

    /// Density at `x` in [0, 1).
    pub fn pdf(&self, x: f32) -> f32 {
        let cell = ((x * self.func.len() as f32) as usize).min(self.func.len() - 1);
        if self.integral > 0.0 {
            self.func[cell] / self.integral
        } else {
            1.0
        }
    }
}

/// A piecewise-constant density on [0, 1)², rows along v.
#[derive(Debug, Clone, PartialEq)]
pub struct Distribution2D {
    conditional: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// From `width * height` values, row-major, row 0 at v = 0.
    pub fn new(values: &[f32], width: usize, height: usize) -> Self {
        let conditional: Vec<Distribution1D> = (0..height)
            .map(|y| Distribution1D::new(&values[y * width..(y + 1) * width]))
            .collect();
        let marginal =
            Distribution1D::new(&conditional.iter().map(|c| c.integral()).collect::<Vec<_>>());
        Distribution2D {
            conditional,
            marginal,
        }
    }

    /// Samples (u, v) in [0, 1)² with its density.
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (v, pdf_v, row) = self.marginal.sample_continuous(u.y);
        let (x, pdf_u, _) = self.conditional[row].sample_continuous(u.x);
        (Vec2::new(x, v), pdf_u * pdf_v)
    }

    pub fn pdf(&self, p: Vec2) -> f32 {
        let row = ((p.y * self.conditional.len() as f32) as usize).min(self.conditional.len() - 1);
        self.marginal.pdf(p.y) * self.conditional[row].pdf(p.x)
    }

    pub fn integral(&self) -> f32 {
        self.marginal.integral()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    #[test]
    fn samples_follow_the_function() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0]);
        let mut rng = Pcg32::new(3, 3);
        let mut counts = [0usize; 3];
        for _ in 0..40_000 {
            let u = rng.next_f32();
            let (x, pdf, cell) = d.sample_continuous(u);
            assert_eq!(d.sample_discrete(u), cell);
            assert!((0.0..1.0).contains(&x));
            assert_eq!(cell, (x * 3.0) as usize);
            assert!((pdf - d.pdf(x)).abs() < 1e-6);
            counts[cell] += 1;
        }
        assert_eq!(counts[1], 0);
        assert!((counts[2] as f32 / counts[0] as f32 - 3.0).abs() < 0.15);
    }

    /// The counted cell (short cdfs) equals the binary search's, on cdfs with empty
    /// cells, at the cdf's own values, at their neighbours and for NaN; on both sides of
    /// the length where the search takes over.
    #[test]
    fn counting_equals_searching() {
        let mut rng = Pcg32::new(7, 1);
        for n in [1, 2, 3, SHORT_CDF - 2, SHORT_CDF - 1, SHORT_CDF, 100] {
            let values: Vec<f32> = (0..n)
                .map(|i| {
                    if i % 3 == 1 {
                        0.0
                    } else {
                        rng.next_f32() + 0.1
                    }
                })
                .collect();
            let d = Distribution1D::new(&values);
            let search = |u: f32| {
                d.cdf
                    .partition_point(|&c| c <= u)
                    .saturating_sub(1)
                    .min(d.func.len() - 1)
            };
            let mut us: Vec<f32> = (0..2000).map(|_| rng.next_f32()).collect();
            for &c in &d.cdf {
                us.extend([c, c.next_down(), c.next_up()]);
            }
            us.extend([0.0, -1.0, 1.0, f32::NAN]);
            for u in us {
                assert_eq!(d.sample_discrete(u), search(u), "{n} cells, u = {u}");
            }
        }
    }

    #[test]
    fn pdf_2d_integrates_to_one() {
        let values: Vec<f32> = (0..12).map(|i| (i % 5) as f32).collect();
        let d = Distribution2D::new(&values, 4, 3);
        let n = 200;
        let mut sum = 0.0;
        for y in 0..n {
            for x in 0..n {
                sum += d.pdf(Vec2::new(
                    (x as f32 + 0.5) / n as f32,
                    (y as f32 + 0.5) / n as f32,
                ));
            }
        }
        assert!((sum / (n * n) as f32 - 1.0).abs() < 1e-3);
    }
}
