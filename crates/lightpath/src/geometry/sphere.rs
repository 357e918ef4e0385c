//! The unit sphere at the origin; place and size it with the instance transform.
//!
//! ```xml
//! <instance>
//!     <shape type="sphere"/>
//!     <transform><scale value="0.5"/><translate y="1"/></transform>
//! </instance>
//! ```
//!
//! Hits are rejected unless they are provably in front of the origin (`t` larger than its
//! rounding error bound), so rays that start on the surface do not hit it again.

use super::{ShapeHit, SurfaceInteraction};
use crate::math::{gamma, Bounds3, Ray, PI};
use glam::{Vec2, Vec3};

#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Sphere;

impl Sphere {
    pub fn bounds(&self) -> Bounds3 {
        Bounds3::new(Vec3::splat(-1.0), Vec3::splat(1.0))
    }

    /// Both roots of the ray–sphere quadratic and a bound on their absolute error.
    #[inline]
    pub(crate) fn roots(ray: &Ray) -> Option<(f32, f32, f32)> {
        let o = ray.origin;
        let d = ray.direction;
        let a = d.length_squared();
        if a == 0.0 {
            return None;
        }
        let b = 2.0 * d.dot(o);
        let c = o.length_squared() - 1.0;
        // Discriminant in the numerically stable form of pbrt-v4 (Haines et al. 2019).
        let v = o - (b / (2.0 * a)) * d;
        let len = v.length();
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
        let (mut t0, mut t1) = (q / a, c / q);
        if q == 0.0 {
            t1 = t0;
        }
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        // The roots are accurate to a few ulps of the origin's distance, measured in
        // units of the direction.
        let t_err = gamma(12) * (o.length() + 1.0) / a.sqrt();
        Some((t0, t1, t_err))
    }

    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<ShapeHit> {
        let (t0, t1, t_err) = Self::roots(ray)?;
        let valid = |t: f32| t > ray.t_min && t > t_err && t < ray.t_max;
        let t = if valid(t0) {
            t0
        } else if valid(t1) {
            t1
        } else {
            return None;
        };
        Some(ShapeHit {
            t,
            prim: 0,
            uv: Vec2::ZERO,
        })
    }

    pub fn interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        // Reproject onto the surface: the error is then a few ulps of |p|.
        let mut p = ray.at(hit.t);
        p /= p.length();
        let p_error = gamma(5) * p.abs();
        let mut phi = p.y.atan2(p.x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let theta = p.z.clamp(-1.0, 1.0).acos();
        let mut dpdu = Vec3::new(-2.0 * PI * p.y, 2.0 * PI * p.x, 0.0);
        if dpdu.length_squared() == 0.0 {
            dpdu = Vec3::X;
        }
        // v = θ/π: dp/dθ = (z cos φ, z sin φ, −sin θ).
        let rd = (p.x * p.x + p.y * p.y).sqrt();
        let (cos_phi, sin_phi) = if rd > 0.0 {
            (p.x / rd, p.y / rd)
        } else {
            (1.0, 0.0)
        };
        let dpdv = Vec3::new(p.z * cos_phi, p.z * sin_phi, -rd) * PI;
        SurfaceInteraction {
            p,
            p_error,
            t: hit.t,
            n: p,
            shading_n: p,
            dpdu,
            dpdv,
            uv: Vec2::new(phi / (2.0 * PI), theta / PI),
            color: Vec3::ONE,
            wo: -ray.direction.normalize(),
            instance: 0,
            prim: 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn hits_from_outside_and_inside() {
        let s = Sphere;
        let h = s
            .intersect(&Ray::new(Vec3::new(0.0, 0.0, -3.0), Vec3::Z))
            .unwrap();
        assert!((h.t - 2.0).abs() < 1e-6);
        let h = s.intersect(&Ray::new(Vec3::ZERO, Vec3::Z)).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
        assert!(s
            .intersect(&Ray::new(Vec3::new(0.0, 2.0, -3.0), Vec3::Z))
            .is_none());
        // Behind the origin.
        assert!(s
            .intersect(&Ray::new(Vec3::new(0.0, 0.0, 3.0), Vec3::Z))
            .is_none());
        // t_max honoured.
        assert!(s
            .intersect(&Ray::with_range(
                Vec3::new(0.0, 0.0, -3.0),
                Vec3::Z,
                0.0,
                1.5
            ))
            .is_none());
        // t_min honoured: skips the near hit.
        let h = s
            .intersect(&Ray::with_range(
                Vec3::new(0.0, 0.0, -3.0),
                Vec3::Z,
                2.5,
                10.0,
            ))
            .unwrap();
        assert!((h.t - 4.0).abs() < 1e-5);
    }

    #[test]
    fn unnormalised_direction_measures_t_in_its_units() {
        let h = Sphere
            .intersect(&Ray::new(Vec3::new(0.0, 0.0, -3.0), Vec3::Z * 2.0))
            .unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
    }

    #[test]
    fn ray_starting_on_surface_does_not_self_intersect() {
        // Origin one ulp outside the pole, looking inward: the near root is within the
        // rounding error and must be skipped for the far side.
        let o = Vec3::new(0.0, 0.0, -1.000_000_1);
        let h = Sphere.intersect(&Ray::new(o, Vec3::Z)).unwrap();
        assert!((h.t - 2.0).abs() < 1e-5, "{}", h.t);
    }

    proptest! {
        #[test]
        fn hit_points_lie_on_the_sphere(ox in -5.0f32..5.0, oy in -5.0f32..5.0, oz in -5.0f32..5.0,
                                        dx in -1.0f32..1.0, dy in -1.0f32..1.0, dz in -1.0f32..1.0) {
            let d = Vec3::new(dx, dy, dz);
            prop_assume!(d.length() > 0.05);
            let ray = Ray::new(Vec3::new(ox, oy, oz), d);
            // Analytic answer in f64.
            let (o, d64) = (ray.origin.as_dvec3(), d.as_dvec3());
            let a = d64.length_squared();
            let b = 2.0 * o.dot(d64);
            let c = o.length_squared() - 1.0;
            let disc = b * b - 4.0 * a * c;
            let expected = if disc < 0.0 { None } else {
                let r = disc.sqrt();
                let (t0, t1) = ((-b - r) / (2.0 * a), (-b + r) / (2.0 * a));
                if t0 > 1e-4 { Some(t0) } else if t1 > 1e-4 { Some(t1) } else { None }
            };
            let got = Sphere.intersect(&ray);
            match (expected, got) {
                (Some(t), Some(h)) => {
                    prop_assert!((h.t as f64 - t).abs() < 1e-3 * (1.0 + t));
                    let si = Sphere.interaction(&ray, &h);
                    prop_assert!((si.p.length() - 1.0).abs() < 1e-5);
                    prop_assert!((si.n - si.p).length() < 1e-6);
                    // The error bound covers the true point.
                    let truth = (o + d64 * t).as_vec3();
                    prop_assert!(((si.p - truth).abs() - si.p_error).max_element() < 1e-3);
                }
                (None, None) => {}
                // Grazing rays may go either way within rounding.
                (Some(_), None) | (None, Some(_)) => prop_assert!(disc.abs() < 1e-3 * (1.0 + b * b)),
            }
        }
    }
}
