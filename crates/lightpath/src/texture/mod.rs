//! Textures: colours that vary over a surface's uv coordinates.
//!
//! ```xml
//! <texture name="albedo" type="constant" value="0.1,0.3,0.7"/>
//! <texture name="albedo" type="image" filename="wood.png" border="repeat" filter="bilinear" exposure="1"/>
//! <texture name="albedo" type="checkerboard" scale="16,8" color0="0.1" color1="0.9"/>
//! <texture name="albedo" type="vertexcolor"/>
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
    /// Another texture's value times the surface's vertex colour ([`TexCoord::color`]:
    /// the colours a mesh file gives its vertices, interpolated over each triangle;
    /// white on shapes and meshes without them).
    VertexColor(Arc<Texture>),
    /// Another texture's luminance in every channel (a colour texture read as one value,
    /// as Mitsuba's `eval_1` reads one).
    Luminance(Arc<Texture>),
}

/// Where a texture is looked up: the surface's texture coordinates and its vertex colour
/// (a mesh's per-vertex colours interpolated at the hit; white where there are none).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TexCoord {
    pub uv: Vec2,
    pub color: Vec3,
}

impl TexCoord {
    /// A lookup at `uv` on a surface of vertex colour `color`.
    #[inline(always)]
    pub fn new(uv: Vec2, color: Vec3) -> Self {
        TexCoord { uv, color }
    }
}

impl From<Vec2> for TexCoord {
    /// A lookup at `uv` on a surface without vertex colours (white).
    #[inline(always)]
    fn from(uv: Vec2) -> Self {
        TexCoord {
            uv,
            color: Vec3::ONE,
        }
    }
}

/// A texture whose lookups go through an affine map of the texture coordinates.
#[derive(Debug, Clone)]
pub struct TransformedTexture {
    pub to_uv: Affine2,
    pub texture: Arc<Texture>,
}

impl Texture {
    /// The colour at `at`: texture coordinates (a `Vec2`, on a surface without vertex
    /// colours) or a [`TexCoord`].
    #[inline(always)]
    pub fn eval(&self, at: impl Into<TexCoord>) -> Vec3 {
        // Constants inline at the caller; the other kinds (and the recursion of
        // transformed textures) stay behind a call.
        match self {
            Texture::Constant(c) => *c,
            _ => self.eval_varying(at.into()),
        }
    }

    #[inline(never)]
    fn eval_varying(&self, at: TexCoord) -> Vec3 {
        match self {
            Texture::Constant(c) => *c,
            Texture::Image(t) => t.eval(at.uv),
            Texture::Checkerboard(t) => t.eval(at.uv),
            Texture::Transformed(t) => t.texture.eval(TexCoord {
                uv: t.to_uv.transform_point2(at.uv),
                ..at
            }),
            Texture::Sqrt(t) => sqrt_or_zero(t.eval(at)),
            Texture::VertexColor(t) => t.eval(at) * at.color,
            Texture::Luminance(t) => Vec3::splat(crate::light::luminance(t.eval(at))),
        }
    }

    /// Whether the texture reads the surface's vertex colours.
    pub fn uses_vertex_colors(&self) -> bool {
        match self {
            Texture::VertexColor(_) => true,
            Texture::Transformed(t) => t.texture.uses_vertex_colors(),
            Texture::Sqrt(t) | Texture::Luminance(t) => t.uses_vertex_colors(),
            Texture::Constant(_) | Texture::Image(_) | Texture::Checkerboard(_) => false,
        }
    }

    /// The gradient over (u, v) of the texture's luminance (for bump mapping): exact for
    /// bilinearly filtered images (the derivative of the interpolation inside the texel
    /// cell), zero for constants, nearest-filtered images and checkerboards (flat almost
    /// everywhere), through the affine map of a transformed texture.
    pub fn luminance_gradient(&self, uv: Vec2) -> Vec2 {
        match self {
            Texture::Constant(_) | Texture::Checkerboard(_) => Vec2::ZERO,
            // Vertex colours vary over a triangle but not with its texture coordinates:
            // the other texture's gradient (on white).
            Texture::VertexColor(t) | Texture::Luminance(t) => t.luminance_gradient(uv),
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
            // Vertex colours are unknown here: white, an upper bound for colours in [0, 1].
            Texture::VertexColor(t) => t.average(),
            // Luminance is linear: the mean's luminance.
            Texture::Luminance(t) => Vec3::splat(crate::light::luminance(t.average())),
        }
    }
}

/// The square root of each channel, 0 for negative ones.
fn sqrt_or_zero(v: Vec3) -> Vec3 {
    let v = v.max(Vec3::ZERO);
    Vec3::new(v.x.sqrt(), v.y.sqrt(), v.z.sqrt())
}
