//! The film: where samples are averaged into pixels, and the images it develops.

mod filter;
mod image;
mod tonemap;

pub use filter::{Filter, MITSUBA_FILTER_STEPS};
pub use image::Image;
pub use tonemap::{exposure_scale, Tonemap};

use glam::Vec3;

/// Error metrics between two images of equal size, over all pixels and channels
/// (`test - reference`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageErrors {
    /// Mean absolute error.
    pub mae: f64,
    /// Mean signed error (bias).
    pub me: f64,
    /// Root mean squared error.
    pub rmse: f64,
    /// Mean relative squared error, `(t - r)² / (r² + 0.01)`.
    pub rel_mse: f64,
    /// Pixels of `test` holding NaN or infinity.
    pub non_finite: usize,
}

impl ImageErrors {
    /// Compares two images; `None` if their sizes differ.
    pub fn compute(test: &Image, reference: &Image) -> Option<ImageErrors> {
        if test.width != reference.width || test.height != reference.height {
            return None;
        }
        let (mut abs, mut signed, mut sq, mut rel) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let mut non_finite = 0;
        for (t, r) in test.pixels.iter().zip(&reference.pixels) {
            if !t.is_finite() {
                non_finite += 1;
                continue;
            }
            let d: Vec3 = *t - *r;
            for c in 0..3 {
                let (dc, rc) = (d[c] as f64, r[c] as f64);
                abs += dc.abs();
                signed += dc;
                sq += dc * dc;
                rel += dc * dc / (rc * rc + 0.01);
            }
        }
        let n = (test.pixels.len() * 3).max(1) as f64;
        Some(ImageErrors {
            mae: abs / n,
            me: (signed / n).abs(),
            rmse: (sq / n).sqrt(),
            rel_mse: rel / n,
            non_finite,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metrics() {
        let mut a = Image::new(2, 1);
        let b = Image::new(2, 1);
        a.set(0, 0, Vec3::splat(0.3));
        a.set(1, 0, Vec3::splat(-0.1));
        let e = ImageErrors::compute(&a, &b).unwrap();
        assert!((e.mae - 0.2).abs() < 1e-6);
        assert!((e.me - 0.1).abs() < 1e-6);
        assert!((e.rmse - (0.05f64).sqrt()).abs() < 1e-6);
        assert!(ImageErrors::compute(&a, &Image::new(1, 2)).is_none());
        a.set(0, 0, Vec3::NAN);
        assert_eq!(ImageErrors::compute(&a, &b).unwrap().non_finite, 1);
    }
}
