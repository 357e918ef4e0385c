//! Axis-aligned bounding boxes.

use super::Ray;
use glam::Vec3;

/// An axis-aligned box `[min, max]`. The empty box has `min = +∞`, `max = -∞`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds3 {
    pub min: Vec3,
    pub max: Vec3,
}

impl Default for Bounds3 {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Bounds3 {
    pub const EMPTY: Bounds3 = Bounds3 {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// The box spanned by two corners, in any order.
    #[inline]
    pub fn new(a: Vec3, b: Vec3) -> Self {
        Bounds3 {
            min: a.min(b),
            max: a.max(b),
        }
    }

    #[inline]
    pub fn from_point(p: Vec3) -> Self {
        Bounds3 { min: p, max: p }
    }

    #[inline]
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    #[inline]
    pub fn union(&self, other: &Bounds3) -> Bounds3 {
        Bounds3 {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    #[inline]
    pub fn expand(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    #[inline]
    pub fn intersection(&self, other: &Bounds3) -> Bounds3 {
        Bounds3 {
            min: self.min.max(other.min),
            max: self.max.min(other.max),
        }
    }

    #[inline]
    pub fn diagonal(&self) -> Vec3 {
        self.max - self.min
    }

    #[inline]
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Surface area; 0 for an empty box.
    #[inline]
    pub fn surface_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let d = self.diagonal();
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }

    /// Index of the longest axis.
    #[inline]
    pub fn max_extent(&self) -> usize {
        let d = self.diagonal();
        if d.x > d.y && d.x > d.z {
            0
        } else if d.y > d.z {
            1
        } else {
            2
        }
    }

    #[inline]
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// The eight corners.
    pub fn corners(&self) -> [Vec3; 8] {
        let (a, b) = (self.min, self.max);
        [
            Vec3::new(a.x, a.y, a.z),
            Vec3::new(b.x, a.y, a.z),
            Vec3::new(a.x, b.y, a.z),
            Vec3::new(b.x, b.y, a.z),
            Vec3::new(a.x, a.y, b.z),
            Vec3::new(b.x, a.y, b.z),
            Vec3::new(a.x, b.y, b.z),
            Vec3::new(b.x, b.y, b.z),
        ]
    }

    /// Slab test against a ray with precomputed reciprocal direction. Returns the entry
    /// and exit parameters clipped to `[t_min, t_max]`, or `None` on a miss. The exit is
    /// widened by `1 + 2γ(3)` so rounding never makes a grazing ray miss (pbrt's rule).
    #[inline]
    pub fn intersect_p(
        &self,
        origin: Vec3,
        inv_dir: Vec3,
        t_min: f32,
        t_max: f32,
    ) -> Option<(f32, f32)> {
        if self.is_empty() {
            return None;
        }
        let t0 = (self.min - origin) * inv_dir;
        let t1 = (self.max - origin) * inv_dir;
        // A ray in the plane of a face (0·∞ = NaN) is inside that slab.
        let on_face = t0.is_nan_mask() | t1.is_nan_mask();
        let tnear = Vec3::select(on_face, Vec3::NEG_INFINITY, t0.min(t1));
        let tfar = Vec3::select(
            on_face,
            Vec3::INFINITY,
            t0.max(t1) * (1.0 + 2.0 * super::gamma(3)),
        );
        let enter = tnear.max_element().max(t_min);
        let exit = tfar.min_element().min(t_max);
        if enter <= exit {
            Some((enter, exit))
        } else {
            None
        }
    }

    /// Slab test for a `Ray`.
    #[inline]
    pub fn intersect_ray(&self, ray: &Ray) -> Option<(f32, f32)> {
        self.intersect_p(ray.origin, ray.direction.recip(), ray.t_min, ray.t_max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slab_hits_and_misses() {
        let b = Bounds3::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let r = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
        let (t0, t1) = b.intersect_ray(&r).unwrap();
        assert!((t0 - 4.0).abs() < 1e-5 && (t1 - 6.0).abs() < 1e-4);
        let miss = Ray::new(Vec3::new(2.0, 0.0, -5.0), Vec3::Z);
        assert!(b.intersect_ray(&miss).is_none());
        // Axis-parallel ray exactly on a face still hits (inclusive slabs).
        let edge = Ray::new(Vec3::new(1.0, 0.0, -5.0), Vec3::Z);
        assert!(b.intersect_ray(&edge).is_some());
        // Ray starting inside.
        let inside = Ray::new(Vec3::ZERO, Vec3::X);
        assert_eq!(b.intersect_ray(&inside).unwrap().0, 0.0);
    }

    #[test]
    fn empty_box_behaves() {
        let e = Bounds3::EMPTY;
        assert!(e.is_empty());
        assert_eq!(e.surface_area(), 0.0);
        let b = e.union(&Bounds3::from_point(Vec3::ONE));
        assert_eq!(b.min, Vec3::ONE);
        assert!(e.intersect_ray(&Ray::new(Vec3::ZERO, Vec3::X)).is_none());
    }

    /// Rays running exactly in the plane of a face, with a zero direction component
    /// (0·∞ = NaN in the slab test), hit the box; rays beside it do not.
    #[test]
    fn rays_in_a_face_plane_hit() {
        let b = Bounds3::new(Vec3::ZERO, Vec3::ONE);
        for (o, d) in [
            (Vec3::new(-1.0, 0.0, 0.5), Vec3::X),
            (Vec3::new(-1.0, 1.0, 0.5), Vec3::X),
            (Vec3::new(2.0, 0.0, 0.5), -Vec3::X),
            (Vec3::new(2.0, 1.0, 1.0), -Vec3::X),
            (Vec3::new(0.0, 0.0, -3.0), Vec3::Z),
        ] {
            let hit = b.intersect_p(o, d.recip(), 0.0, f32::INFINITY);
            assert!(hit.is_some(), "{o} {d}");
        }
        let beside = b.intersect_p(Vec3::new(-1.0, 1.0001, 0.5), Vec3::X.recip(), 0.0, 10.0);
        assert!(beside.is_none());
    }
}
