//! Image textures. `v` runs up the image: uv (0, 0) is the bottom-left corner, so texel
//! row `⌊(1 - v)·height⌋`. 8-bit images are decoded from sRGB unless `linear="true"`;
//! HDR and EXR files are linear. `exposure` multiplies the values.
//!
//! ```xml
//! <texture name="albedo" type="image" filename="hamster.png" border="clamp" filter="nearest"/>
//! ```
//!
//! | property   | values                 | default    |
//! |------------|------------------------|------------|
//! | `border`   | `repeat`, `clamp`      | `repeat`   |
//! | `filter`   | `bilinear`, `nearest`  | `bilinear` |
//! | `exposure` | a factor               | 1          |
//! | `linear`   | true: no sRGB decoding | false      |

use crate::film::Image;
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BorderMode {
    Repeat,
    Clamp,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FilterMode {
    Nearest,
    Bilinear,
}

#[derive(Debug, Clone)]
pub struct ImageTexture {
    pub image: Arc<Image>,
    pub border: BorderMode,
    pub filter: FilterMode,
    pub exposure: f32,
}

impl ImageTexture {
    #[inline]
    fn texel(&self, x: i64, y: i64) -> Vec3 {
        let (w, h) = (self.image.width as i64, self.image.height as i64);
        let (x, y) = match self.border {
            BorderMode::Clamp => (x.clamp(0, w - 1), y.clamp(0, h - 1)),
            BorderMode::Repeat => (x.rem_euclid(w), y.rem_euclid(h)),
        };
        self.image.get(x as u32, y as u32)
    }

    #[inline]
    pub fn eval(&self, uv: Vec2) -> Vec3 {
        let (w, h) = (self.image.width as f32, self.image.height as f32);
        let p = Vec2::new(uv.x * w, (1.0 - uv.y) * h);
        let value = match self.filter {
            FilterMode::Nearest => self.texel(p.x.floor() as i64, p.y.floor() as i64),
            FilterMode::Bilinear => {
                // Texel centres sit at integer + 0.5.
                let q = p - Vec2::splat(0.5);
                let (x0, y0) = (q.x.floor(), q.y.floor());
                let (fx, fy) = (q.x - x0, q.y - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let top = self.texel(x0, y0) * (1.0 - fx) + self.texel(x0 + 1, y0) * fx;
                let bottom = self.texel(x0, y0 + 1) * (1.0 - fx) + self.texel(x0 + 1, y0 + 1) * fx;
                top * (1.0 - fy) + bottom * fy
            }
        };
        value * self.exposure
    }

    /// The gradient over (u, v) of the luminance that [`ImageTexture::eval`] returns;
    /// zero with nearest filtering.
    pub fn luminance_gradient(&self, uv: Vec2) -> Vec2 {
        if self.filter == FilterMode::Nearest {
            return Vec2::ZERO;
        }
        let (w, h) = (self.image.width as f32, self.image.height as f32);
        let q = Vec2::new(uv.x * w, (1.0 - uv.y) * h) - Vec2::splat(0.5);
        let (x0, y0) = (q.x.floor(), q.y.floor());
        let (fx, fy) = (q.x - x0, q.y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let f = |x, y| crate::light::luminance(self.texel(x, y));
        let (f00, f10, f01, f11) = (f(x0, y0), f(x0 + 1, y0), f(x0, y0 + 1), f(x0 + 1, y0 + 1));
        // Derivatives over the texel coordinates (x along u, y down the image, against v).
        let df_dx = (f10 - f00) * (1.0 - fy) + (f11 - f01) * fy;
        let df_dy = (f01 - f00) * (1.0 - fx) + (f11 - f10) * fx;
        Vec2::new(df_dx * w, -df_dy * h) * self.exposure
    }

    pub fn average(&self) -> Vec3 {
        let sum: Vec3 = self.image.pixels.iter().copied().sum();
        sum / self.image.pixels.len().max(1) as f32 * self.exposure
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tex(border: BorderMode, filter: FilterMode) -> ImageTexture {
        // 2x2: top row (0, 1), bottom row (2, 3).
        let mut img = Image::new(2, 2);
        for (i, v) in [0.0, 1.0, 2.0, 3.0].into_iter().enumerate() {
            img.set(i as u32 % 2, i as u32 / 2, Vec3::splat(v));
        }
        ImageTexture {
            image: Arc::new(img),
            border,
            filter,
            exposure: 1.0,
        }
    }

    #[test]
    fn v_runs_up_the_image() {
        let t = tex(BorderMode::Clamp, FilterMode::Nearest);
        assert_eq!(t.eval(Vec2::new(0.25, 0.25)).x, 2.0); // bottom-left
        assert_eq!(t.eval(Vec2::new(0.75, 0.75)).x, 1.0); // top-right
    }

    #[test]
    fn bilinear_interpolates_between_centres() {
        let t = tex(BorderMode::Clamp, FilterMode::Bilinear);
        assert!((t.eval(Vec2::new(0.5, 0.5)).x - 1.5).abs() < 1e-6);
        assert!((t.eval(Vec2::new(0.25, 0.75)).x - 0.0).abs() < 1e-6);
        // Repeat wraps: between the last and first column.
        let r = tex(BorderMode::Repeat, FilterMode::Bilinear);
        assert!((r.eval(Vec2::new(0.0, 0.75)).x - 0.5).abs() < 1e-6);
        assert!((t.eval(Vec2::new(0.0, 0.75)).x - 0.0).abs() < 1e-6);
    }
}
