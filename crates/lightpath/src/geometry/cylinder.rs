//! The cylinder of radius 1 around the z axis from z = 0 to z = 1 (Mitsuba's
//! convention), open or closed by two caps.
//!
//! ```xml
//! <instance>
//!     <shape type="cylinder" caps="true"/>
//! </instance>
//! ```
//!
//! `prim` tells the part that was hit: 0 the side, 1 the bottom cap, 2 the top cap.

use super::{ShapeHit, SurfaceInteraction};
use crate::math::{gamma, Bounds3, Ray, PI};
use glam::{Vec2, Vec3};

#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Cylinder {
    pub caps: bool,
}

impl Cylinder {
    pub fn bounds(&self) -> Bounds3 {
        Bounds3::new(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 1.0))
    }

    /// Both roots (unordered) of the ray's crossings with the infinite side x² + y² = 1,
    /// solved in the numerically stable form; `None` if the ray misses it or runs parallel
    /// to the axis.
    #[inline]
    pub(crate) fn side_roots(ray: &Ray) -> Option<(f32, f32)> {
        let (o, d) = (ray.origin, ray.direction);
        let a = d.x * d.x + d.y * d.y;
        if a <= 0.0 {
            return None;
        }
        let b = 2.0 * (d.x * o.x + d.y * o.y);
        let c = o.x * o.x + o.y * o.y - 1.0;
        let f = b / (2.0 * a);
        let (vx, vy) = (o.x - f * d.x, o.y - f * d.y);
        let len = (vx * vx + vy * vy).sqrt();
        let discrim = 4.0 * a * (1.0 - len) * (1.0 + len);
        if discrim < 0.0 {
            return None;
        }
        let root = discrim.sqrt();
        let q = if b < 0.0 {
            -0.5 * (b - root)
        } else {
            -0.5 * (b + root)
        };
        let t0 = q / a;
        let t1 = if q != 0.0 { c / q } else { t0 };
        Some((t0, t1))
    }

    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<ShapeHit> {
        let o = ray.origin;
        let d = ray.direction;
        let t_err = gamma(12) * (o.length() + 1.0) / d.length();
        let valid = |t: f32| t > ray.t_min && t > t_err && t < ray.t_max;
        let mut best: Option<(f32, u32)> = None;
        let mut consider = |t: f32, prim: u32| {
            if valid(t) && best.is_none_or(|(bt, _)| t < bt) {
                best = Some((t, prim));
            }
        };
        // Side: x² + y² = 1.
        if let Some((t0, t1)) = Self::side_roots(ray) {
            for t in [t0, t1] {
                let z = o.z + t * d.z;
                if (0.0..=1.0).contains(&z) {
                    consider(t, 0);
                }
            }
        }
        // Caps.
        if self.caps && d.z != 0.0 {
            for (z, prim) in [(0.0f32, 1u32), (1.0, 2)] {
                let t = (z - o.z) / d.z;
                let p = ray.at(t);
                if p.x * p.x + p.y * p.y <= 1.0 {
                    consider(t, prim);
                }
            }
        }
        best.map(|(t, prim)| ShapeHit {
            t,
            prim,
            uv: Vec2::ZERO,
        })
    }

    pub fn interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        let mut p = ray.at(hit.t);
        let wo = -ray.direction.normalize();
        if hit.prim == 0 {
            // Reproject onto the side.
            let r = (p.x * p.x + p.y * p.y).sqrt();
            p.x /= r;
            p.y /= r;
            p.z = p.z.clamp(0.0, 1.0);
            let mut phi = p.y.atan2(p.x);
            if phi < 0.0 {
                phi += 2.0 * PI;
            }
            let n = Vec3::new(p.x, p.y, 0.0);
            SurfaceInteraction {
                p,
                p_error: gamma(3) * Vec3::new(p.x.abs(), p.y.abs(), 0.0)
                    + gamma(5) * Vec3::new(0.0, 0.0, p.z.abs()),
                t: hit.t,
                n,
                shading_n: n,
                dpdu: Vec3::new(-2.0 * PI * p.y, 2.0 * PI * p.x, 0.0),
                dpdv: Vec3::Z,
                uv: Vec2::new(phi / (2.0 * PI), p.z),
                color: Vec3::ONE,
                wo,
                instance: 0,
                prim: 0,
            }
        } else {
            let top = hit.prim == 2;
            p.z = if top { 1.0 } else { 0.0 };
            let n = if top { Vec3::Z } else { -Vec3::Z };
            let r = (p.x * p.x + p.y * p.y).sqrt();
            let mut phi = p.y.atan2(p.x);
            if phi < 0.0 {
                phi += 2.0 * PI;
            }
            SurfaceInteraction {
                p,
                p_error: Vec3::new(gamma(5) * p.x.abs(), gamma(5) * p.y.abs(), 0.0),
                t: hit.t,
                n,
                shading_n: n,
                dpdu: if r > 0.0 {
                    Vec3::new(p.x / r, p.y / r, 0.0)
                } else {
                    Vec3::X
                },
                // v = φ/2π, as on a disk.
                dpdv: Vec3::new(-p.y, p.x, 0.0) * (2.0 * PI),
                uv: Vec2::new(r, phi / (2.0 * PI)),
                color: Vec3::ONE,
                wo,
                instance: 0,
                prim: hit.prim,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn side_and_caps() {
        let open = Cylinder { caps: false };
        let closed = Cylinder { caps: true };
        let side = Ray::new(Vec3::new(-5.0, 0.0, 0.5), Vec3::X);
        let h = open.intersect(&side).unwrap();
        assert!((h.t - 4.0).abs() < 1e-5);
        assert!((open.interaction(&side, &h).n - (-Vec3::X)).length() < 1e-6);
        // Down the axis: the open tube is missed, the closed one hits the top cap.
        let axial = Ray::new(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z);
        assert!(open.intersect(&axial).is_none());
        let h = closed.intersect(&axial).unwrap();
        assert_eq!(h.prim, 2);
        assert!((h.t - 4.0).abs() < 1e-6);
        assert_eq!(closed.interaction(&axial, &h).n, Vec3::Z);
        // From inside the open tube, the ray leaves through the side.
        let inside = Ray::new(Vec3::new(0.0, 0.0, 0.5), Vec3::Y);
        let h = open.intersect(&inside).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
        // Above the tube.
        assert!(open
            .intersect(&Ray::new(Vec3::new(-5.0, 0.0, 1.5), Vec3::X))
            .is_none());
    }
}
