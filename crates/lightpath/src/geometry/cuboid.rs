//! The axis-aligned box [-1, 1]³ (Mitsuba's `cube`); each face has its own uv square.
//!
//! ```xml
//! <instance>
//!     <shape type="cube"/>
//!     <transform><scale x="2" y="0.1" z="2"/></transform>
//! </instance>
//! ```

use super::{ShapeHit, SurfaceInteraction};
use crate::math::{gamma, Bounds3, Ray};
use glam::{Vec2, Vec3};

#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Cuboid;

impl Cuboid {
    pub fn bounds(&self) -> Bounds3 {
        Bounds3::new(Vec3::splat(-1.0), Vec3::splat(1.0))
    }

    /// Slab test; the face is encoded in `prim` as `axis * 2 + (positive side)`.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<ShapeHit> {
        let inv = ray.direction.recip();
        let t0 = (Vec3::splat(-1.0) - ray.origin) * inv;
        let t1 = (Vec3::splat(1.0) - ray.origin) * inv;
        let tn = t0.min(t1);
        let tf = t0.max(t1);
        let (mut enter, mut enter_axis) = (f32::NEG_INFINITY, 0);
        let (mut exit, mut exit_axis) = (f32::INFINITY, 0);
        for axis in 0..3 {
            // Axis-parallel rays give NaN for 0 * inf: they constrain nothing if inside.
            if ray.direction[axis] == 0.0 {
                if ray.origin[axis].abs() > 1.0 {
                    return None;
                }
                continue;
            }
            if tn[axis] > enter {
                enter = tn[axis];
                enter_axis = axis;
            }
            if tf[axis] < exit {
                exit = tf[axis];
                exit_axis = axis;
            }
        }
        if enter > exit {
            return None;
        }
        let t_err = gamma(6) * (ray.origin.abs().max_element() + 1.0) / ray.direction.length();
        let valid = |t: f32| t > ray.t_min && t > t_err && t < ray.t_max;
        let (t, axis) = if valid(enter) {
            (enter, enter_axis)
        } else if valid(exit) {
            (exit, exit_axis)
        } else {
            return None;
        };
        let positive = ray.at(t)[axis] > 0.0;
        Some(ShapeHit {
            t,
            prim: (axis * 2 + positive as usize) as u32,
            uv: Vec2::ZERO,
        })
    }

    pub fn interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        let axis = (hit.prim / 2) as usize;
        let sign = if hit.prim % 2 == 1 { 1.0 } else { -1.0 };
        let mut p = ray.at(hit.t).clamp(Vec3::splat(-1.0), Vec3::splat(1.0));
        p[axis] = sign;
        let mut n = Vec3::ZERO;
        n[axis] = sign;
        let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut p_error = gamma(5) * p.abs();
        p_error[axis] = 0.0;
        let (mut dpdu, mut dpdv) = (Vec3::ZERO, Vec3::ZERO);
        dpdu[a1] = 2.0;
        dpdv[a2] = 2.0;
        SurfaceInteraction {
            p,
            p_error,
            t: hit.t,
            n,
            shading_n: n,
            dpdu,
            dpdv,
            uv: Vec2::new((p[a1] + 1.0) * 0.5, (p[a2] + 1.0) * 0.5),
            color: Vec3::ONE,
            wo: -ray.direction.normalize(),
            instance: 0,
            prim: hit.prim,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn faces_and_inside() {
        let ray = Ray::new(Vec3::new(0.2, 0.3, -5.0), Vec3::Z);
        let h = Cuboid.intersect(&ray).unwrap();
        assert!((h.t - 4.0).abs() < 1e-6);
        assert_eq!(Cuboid.interaction(&ray, &h).n, -Vec3::Z);
        let inside = Ray::new(Vec3::ZERO, Vec3::new(0.0, 1.0, 0.0));
        let h = Cuboid.intersect(&inside).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
        assert_eq!(Cuboid.interaction(&inside, &h).n, Vec3::Y);
        assert!(Cuboid
            .intersect(&Ray::new(Vec3::new(2.0, 0.0, -5.0), Vec3::Z))
            .is_none());
    }

    proptest! {
        #[test]
        fn matches_f64_slabs(o in prop::array::uniform3(-4.0f32..4.0), d in prop::array::uniform3(-1.0f32..1.0)) {
            let ray = Ray::new(Vec3::from_array(o), Vec3::from_array(d));
            prop_assume!(ray.direction.abs().min_element() > 1e-3);
            let (o64, d64) = (ray.origin.as_dvec3(), ray.direction.as_dvec3());
            let t0 = (glam::DVec3::splat(-1.0) - o64) / d64;
            let t1 = (glam::DVec3::splat(1.0) - o64) / d64;
            let enter = t0.min(t1).max_element();
            let exit = t0.max(t1).min_element();
            let expected = if enter > exit { None } else if enter > 1e-4 { Some(enter) } else if exit > 1e-4 { Some(exit) } else { None };
            let got = Cuboid.intersect(&ray);
            match (expected, got) {
                (Some(t), Some(h)) => {
                    // An entry this near the origin (which lies within 1e-3 of a face) is
                    // either taken or skipped as self-intersection: the reference skips
                    // it below 1e-4, the cuboid only below its rounding error.
                    let near_entry = enter.abs() < 1e-3 && (h.t as f64 - enter).abs() < 1e-5;
                    prop_assert!(near_entry || (h.t as f64 - t).abs() < 1e-4 * (1.0 + t));
                    let si = Cuboid.interaction(&ray, &h);
                    prop_assert!((si.p.abs().max_element() - 1.0).abs() < 1e-6);
                    prop_assert!((si.n.length() - 1.0).abs() < 1e-6);
                }
                (None, None) => {}
                _ => prop_assert!((enter - exit).abs() < 1e-3 || enter.abs() < 1e-3 || exit.abs() < 1e-3),
            }
        }
    }
}
