//! Normal mapping: a tangent-space normal n = 2·rgb − 1 from a (linear) image, expressed
//! in the shading frame (dp/du, n × dp/du, shading normal), replaces the shading normal;
//! the nested BSDF is evaluated in the perturbed frame (its tangent is dp/du made
//! orthogonal to the new normal). The value returned is the nested BSDF's f·|cos θi|
//! with the perturbed cosine. The bitangent is n × dp/du: for meshes whose uv mapping is
//! mirrored (dp/dv pointing the other way) the map's green channel is flipped.
//!
//! In Mitsuba scenes, Mitsuba's flip of invalid normals and terminator shadowing apply
//! (on by default there, as for [`super::BumpMap`]); in lightwave, glTF and OBJ scenes
//! they are off.
//!
//! ```xml
//! <bsdf type="normalmap">
//!     <texture name="normal" type="image" filename="bricks_normal.png" linear="true"/>
//!     <bsdf type="diffuse"/>
//! </bsdf>
//! ```

use super::{BsdfSample, Material};
use crate::math::Frame;
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct NormalMap {
    pub normal: Arc<Texture>,
    pub inner: Arc<Material>,
    /// Where the viewer is below the perturbed surface, mirror the perturbed normal
    /// about the unperturbed one (Mitsuba's `flip_invalid_normals`, on by default there;
    /// see [`super::BumpMap`]).
    pub flip_invalid: bool,
    /// Attenuate light at grazing angles by the terminator shadowing of Conty Estevez
    /// et al. 2019 (Mitsuba's `use_shadowing_function`, on by default there).
    pub shadowing: bool,
}

impl NormalMap {
    /// A normal map without Mitsuba's flip and shadowing (the course's and glTF's).
    pub fn new(normal: Arc<Texture>, inner: Arc<Material>) -> NormalMap {
        NormalMap {
            normal,
            inner,
            flip_invalid: false,
            shadowing: false,
        }
    }

    /// The perturbed frame in local shading coordinates, seen from the local `wo`.
    pub fn frame(&self, uv: TexCoord, wo: Vec3) -> Frame {
        let mut n = (2.0 * self.normal.eval(uv) - Vec3::ONE).normalize_or_zero();
        if n == Vec3::ZERO || !n.is_finite() {
            return Frame {
                s: Vec3::X,
                t: Vec3::Y,
                n: Vec3::Z,
            };
        }
        if self.flip_invalid && wo.z * wo.dot(n) <= 0.0 {
            n = Vec3::new(-n.x, -n.y, n.z);
        }
        super::frame_from_normal_and_tangent(n, Vec3::X)
    }

    /// The terminator shadowing of a local direction `w` under the perturbed frame `f`.
    #[inline]
    fn shadowing(&self, f: &Frame, w: Vec3) -> f32 {
        if self.shadowing {
            super::terminator_shadowing(f.n.z, w.z)
        } else {
            1.0
        }
    }

    pub fn eval(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> Vec3 {
        let f = self.frame(uv, wo);
        let wi_local = f.to_local(wi);
        if !same_side(wi, wi_local) {
            return Vec3::ZERO;
        }
        self.inner.eval_local(uv, f.to_local(wo), wi_local) * self.shadowing(&f, wi)
    }

    pub fn pdf(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> f32 {
        let f = self.frame(uv, wo);
        let wi_local = f.to_local(wi);
        if !same_side(wi, wi_local) {
            return 0.0;
        }
        self.inner.pdf_local(uv, f.to_local(wo), wi_local)
    }

    pub fn sample(&self, uv: TexCoord, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let f = self.frame(uv, wo);
        let mut bs = self.inner.sample_local(uv, f.to_local(wo), u_lobe, u)?;
        let wi_local = bs.wi;
        bs.wi = f.to_world(wi_local);
        bs.weight *= self.shadowing(&f, bs.wi);
        same_side(bs.wi, wi_local).then_some(bs)
    }
}

/// Whether a direction is on the same side of the unperturbed and the perturbed
/// surface. Light arriving from behind the surface must not reach the front through a
/// tilted normal (nor leave through it): as Mitsuba's `normalmap`, such directions
/// carry nothing.
#[inline]
fn same_side(w: Vec3, w_perturbed: Vec3) -> bool {
    w.z * w_perturbed.z > 0.0
}
