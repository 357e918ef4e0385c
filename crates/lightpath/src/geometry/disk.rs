//! The unit disk in the z = 0 plane with normal +z; u is the radius, v the angle / 2π.
//!
//! ```xml
//! <instance>
//!     <shape type="disk"/>
//! </instance>
//! ```

use super::plane::{intersect_z0, z0_interaction};
use super::{ShapeHit, SurfaceInteraction};
use crate::math::{Bounds3, Ray, PI};
use glam::{Vec2, Vec3};

#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Disk;

impl Disk {
    pub fn bounds(&self) -> Bounds3 {
        Bounds3::new(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0))
    }

    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<ShapeHit> {
        let (t, p) = intersect_z0(ray)?;
        if p.x * p.x + p.y * p.y > 1.0 {
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
        let r = hit.uv.length();
        let mut phi = p.y.atan2(p.x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let dpdu = if r > 0.0 {
            Vec3::new(p.x / r, p.y / r, 0.0)
        } else {
            Vec3::X
        };
        // v = φ/2π: the point turns by 2π·(−y, x) per unit of v.
        let dpdv = Vec3::new(-p.y, p.x, 0.0) * (2.0 * PI);
        z0_interaction(ray, hit, p, Vec2::new(r, phi / (2.0 * PI)), dpdu, dpdv)
    }

    pub fn area(&self) -> f32 {
        PI
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disk_hits_inside_only() {
        let down = -Vec3::Z;
        assert!(Disk
            .intersect(&Ray::new(Vec3::new(0.7, 0.7, 1.0), down))
            .is_some());
        assert!(Disk
            .intersect(&Ray::new(Vec3::new(0.72, 0.72, 1.0), down))
            .is_none());
        let ray = Ray::new(Vec3::new(0.0, 0.5, 1.0), down);
        let h = Disk.intersect(&ray).unwrap();
        let si = Disk.interaction(&ray, &h);
        assert!((si.uv.x - 0.5).abs() < 1e-6 && (si.uv.y - 0.25).abs() < 1e-6);
    }
}
