//! Textures: colours that vary over a surface's uv coordinates.
//!
//! ```xml
//! <texture name="albedo" type="constant" value="0.1,0.3,0.7"/>
//! <texture name="albedo" type="image" filename="wood.png" border="repeat" filter="bilinear" exposure="1"/>
//! <texture name="albedo" type="checkerboard" scale="16,8" color0="0.1" color1="0.9"/>
//! ```

mod checkerboard;
mod image;

pub use checkerboard::Checkerboard;
pub use image::{BorderMode, FilterMode, ImageTexture};

use glam::{Affine2, Vec2, Vec3};
use std::sync::Arc;

/// A texture of any kind.
#[derive(Debug, Clone)]
pub enum Texture {
    Constant(Vec3),
    Image(ImageTexture),
    Checkerboard(Checkerboard),
    /// Another texture looked up at `to_uv · uv` (Mitsuba's `to_uv` transform).
    Transformed(TransformedTexture),
    /// The square root of another texture's value, channel by channel (negative values
    /// give 0): a Mitsuba microfacet `alpha` texture read as our roughness √α.
    Sqrt(Arc<Texture>),
}

/// A texture whose lookups go through an affine map of the texture coordinates.
#[derive(Debug, Clone)]
pub struct TransformedTexture {
    pub to_uv: Affine2,
    pub texture: Arc<Texture>,
}

impl Texture {
    /// The colour at texture coordinates `uv`.
    #[inline(always)]
    pub fn eval(&self, uv: Vec2) -> Vec3 {
        // Constants inline at the caller; the other kinds (and the recursion of
        // transformed textures) stay behind a call.
        match self {
            Texture::Constant(c) => *c,
            _ => self.eval_varying(uv),
        }
    }

    #[inline(never)]
    fn eval_varying(&self, uv: Vec2) -> Vec3 {
        match self {
            Texture::Constant(c) => *c,
            Texture::Image(t) => t.eval(uv),
            Texture::Checkerboard(t) => t.eval(uv),
            Texture::Transformed(t) => t.texture.eval(t.to_uv.transform_point2(uv)),
            Texture::Sqrt(t) => sqrt_or_zero(t.eval(uv)),
        }
    }

    /// The gradient over (u, v) of the texture's luminance (for bump mapping): exact for
    /// bilinearly filtered images (the derivative of the interpolation inside the texel
    /// cell), zero for constants, nearest-filtered images and checkerboards (flat almost
    /// everywhere), through the affine map of a transformed texture.
    pub fn luminance_gradient(&self, uv: Vec2) -> Vec2 {
        match self {
            Texture::Constant(_) | Texture::Checkerboard(_) => Vec2::ZERO,
            Texture::Image(t) => t.luminance_gradient(uv),
            Texture::Transformed(t) => {
                // d/duv f(A·uv + b) = Aᵀ ∇f.
                let g = t.texture.luminance_gradient(t.to_uv.transform_point2(uv));
                t.to_uv.matrix2.transpose() * g
            }
            // Of the luminance of √f, approximated as √ of the luminance (exact for
            // grey textures): ∇√L = ∇L / (2√L).
            Texture::Sqrt(t) => {
                let l = crate::light::luminance(t.eval(uv)).max(0.0).sqrt();
                if l > 0.0 {
                    t.luminance_gradient(uv) / (2.0 * l)
                } else {
                    Vec2::ZERO
                }
            }
        }
    }

    /// The mean colour over [0, 1]² (for light power estimates).
    pub fn average(&self) -> Vec3 {
        match self {
            Texture::Constant(c) => *c,
            Texture::Image(t) => t.average(),
            Texture::Checkerboard(t) => (t.color0 + t.color1) * 0.5,
            // Exact for maps that tile the unit square (scales by integers, shifts).
            Texture::Transformed(t) => t.texture.average(),
            // An upper bound (Jensen's inequality), equal for constants.
            Texture::Sqrt(t) => sqrt_or_zero(t.average()),
        }
    }
}

/// The square root of each channel, 0 for negative ones.
fn sqrt_or_zero(v: Vec3) -> Vec3 {
    let v = v.max(Vec3::ZERO);
    Vec3::new(v.x.sqrt(), v.y.sqrt(), v.z.sqrt())
}
