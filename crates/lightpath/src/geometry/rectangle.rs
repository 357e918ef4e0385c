//! The rectangle [-1, 1]² in the z = 0 plane with normal +z; uv run from 0 to 1.
//!
//! ```xml
//! <instance>
//!     <shape type="rectangle"/>
//!     <transform><scale value="10"/><rotate axis="1,0,0" angle="90"/></transform>
//! </instance>
//! ```

use super::plane::{intersect_z0, z0_interaction};
use super::{ShapeHit, SurfaceInteraction};
use crate::math::{Bounds3, Ray};
use glam::{Vec2, Vec3};

#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Rectangle;

impl Rectangle {
    pub fn bounds(&self) -> Bounds3 {
        Bounds3::new(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0))
    }

    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<ShapeHit> {
        let (t, p) = intersect_z0(ray)?;
        if p.x.abs() > 1.0 || p.y.abs() > 1.0 {
            return None;
        }
        Some(ShapeHit {
            t,
            prim: 0,
            uv: Vec2::new(p.x, p.y),
        })
    }

    pub fn interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        let p = Vec3::new(hit.uv.x, hit.uv.y, 0.0);
        let uv = (hit.uv + Vec2::ONE) * 0.5;
        z0_interaction(
            ray,
            hit,
            p,
            uv,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        )
    }

    pub fn area(&self) -> f32 {
        4.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn matches_analytic(ox in -3.0f32..3.0, oy in -3.0f32..3.0, oz in -3.0f32..3.0,
                            dx in -1.0f32..1.0, dy in -1.0f32..1.0, dz in -1.0f32..1.0) {
            let ray = Ray::new(Vec3::new(ox, oy, oz), Vec3::new(dx, dy, dz));
            prop_assume!(dz.abs() > 1e-3);
            let t = -oz / dz;
            let p = ray.at(t);
            let expected = t > 0.0 && p.x.abs() < 0.999 && p.y.abs() < 0.999;
            let clearly_out = t <= 0.0 || p.x.abs() > 1.001 || p.y.abs() > 1.001;
            let got = Rectangle.intersect(&ray);
            if expected {
                let h = got.unwrap();
                prop_assert!((h.t - t).abs() <= 1e-5 * (1.0 + t.abs()));
                let si = Rectangle.interaction(&ray, &h);
                prop_assert_eq!(si.n, Vec3::Z);
                prop_assert!(si.uv.cmpge(Vec2::ZERO).all() && si.uv.cmple(Vec2::ONE).all());
            } else if clearly_out {
                prop_assert!(got.is_none());
            }
        }
    }
}
