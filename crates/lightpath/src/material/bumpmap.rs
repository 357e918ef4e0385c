//! Bump mapping (Mitsuba's `bumpmap`): a height field `h(u, v)` (a texture's luminance
//! times `scale`) tilts the shading normal as if the surface were displaced by it along
//! its normal, without moving the geometry. With ∇h = (∂h/∂u, ∂h/∂v) from
//! [`Texture::luminance_gradient`] and the shading normal n, the displaced surface's
//! tangents are dp/du + n·(∂h/∂u − n·dp/du) and dp/dv + n·(∂h/∂v − n·dp/dv) (the
//! derivative of the normal itself neglected, as usual and as Mitsuba does), the new
//! normal is their cross product turned to the geometric normal's side, and the nested
//! BSDF is evaluated in the frame it defines (tangent: dp/du made orthogonal to it). As
//! with normal maps, a direction on different sides of the unperturbed and the perturbed
//! surface carries nothing.
//!
//! Two refinements, on by default in Mitsuba 3 (since 3.7) and so in its dialect here:
//! where the viewer is below the perturbed surface, the perturbed normal is mirrored
//! about the unperturbed one (`flip_invalid_normals`, Schüssler et al. 2017), and light
//! at grazing angles is attenuated by a Smith shadowing term of a roughness that grows
//! with the tilt (`use_shadowing_function`, Conty Estevez et al. 2019: see
//! [`super::terminator_shadowing`]), which softens the terminator; both are matched to
//! Mitsuba value for value in the material tests.
//!
//! The height is in the units of the scene per unit of texture coordinate: a texture
//! whose values span 0-1 over a texel bends the normal more on a finely tiled or small
//! surface. Only variations of the height matter, not its level.
//!
//! The perturbed frame needs the surface's dp/du and dp/dv, so it is built where a
//! material meets its [`SurfaceInteraction`] ([`super::Bsdf::new`]): a bump map may be
//! a shape's outermost BSDF, sit inside a `twosided` (either side), and wrap any BSDF
//! (also a normal map or another two-sided one). The Mitsuba reader rejects it elsewhere
//! (inside a `blendbsdf`, for one).
//!
//! ```xml
//! <bsdf type="bumpmap">
//!     <texture name="arbitrary" type="bitmap">
//!         <string name="filename" value="bumps.png"/>
//!         <boolean name="raw" value="true"/>
//!     </texture>
//!     <float name="scale" value="0.5"/>
//!     <bsdf type="roughplastic"/>
//! </bsdf>
//! ```

use super::{frame_from_normal_and_tangent, shading_frame, Material};
use crate::geometry::SurfaceInteraction;
use crate::math::Frame;
use crate::texture::Texture;
use glam::Vec3;
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct BumpMap {
    /// The height field: the texture's luminance.
    pub height: Arc<Texture>,
    /// Multiplies the height.
    pub scale: f32,
    pub inner: Arc<Material>,
    /// Where the viewer is below the perturbed surface, mirror the perturbed normal
    /// about the unperturbed one (Schüssler et al. 2017's flip; Mitsuba's
    /// `flip_invalid_normals`, on by default there).
    pub flip_invalid: bool,
    /// Attenuate light at grazing angles by the terminator shadowing of Conty Estevez
    /// et al. 2019 (Mitsuba's `use_shadowing_function`, on by default there).
    pub shadowing: bool,
}

impl BumpMap {
    /// The perturbed shading frame at `si` seen from the render-space direction `wo`, in
    /// render space; the unperturbed shading frame where the perturbed normal is
    /// undefined (tangents parallel, not finite).
    pub fn frame(&self, si: &SurfaceInteraction, wo: Vec3) -> Frame {
        let g = self.scale * self.height.luminance_gradient(si.uv);
        let n = si.shading_n;
        let dpdu = si.dpdu + n * (g.x - n.dot(si.dpdu));
        let dpdv = si.dpdv + n * (g.y - n.dot(si.dpdv));
        let mut bumped = dpdu.cross(dpdv).normalize_or_zero();
        if bumped == Vec3::ZERO || !bumped.is_finite() {
            return shading_frame(si);
        }
        if bumped.dot(si.n) < 0.0 {
            bumped = -bumped;
        }
        if self.flip_invalid && wo.dot(n) * wo.dot(bumped) <= 0.0 {
            bumped = n * (2.0 * bumped.dot(n)) - bumped;
        }
        frame_from_normal_and_tangent(bumped, si.dpdu)
    }
}
