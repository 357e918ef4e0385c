//! Orthonormal frames, built with the branchless basis of Duff et al. 2017.

use glam::{Vec3, Vec3A};

/// An orthonormal basis `(s, t, n)`; `to_local`/`to_world` change coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    pub s: Vec3,
    pub t: Vec3,
    pub n: Vec3,
}

impl Frame {
    /// A frame whose `n` is the given unit vector (Duff et al., "Building an Orthonormal
    /// Basis, Revisited", 2017).
    #[inline]
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        // In 4-lane arithmetic: the same operations as with `Vec3`, bit for bit.
        let (s, t, n) = (
            Vec3A::from(self.s),
            Vec3A::from(self.t),
            Vec3A::from(self.n),
        );
        (s * v.x + t * v.y + n * v.z).into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn frame_is_orthonormal(x in -1.0f32..1.0, y in -1.0f32..1.0, z in -1.0f32..1.0) {
            let v = Vec3::new(x, y, z);
            prop_assume!(v.length() > 1e-3);
            let f = Frame::from_normal(v.normalize());
            prop_assert!((f.s.length() - 1.0).abs() < 1e-5);
            prop_assert!((f.t.length() - 1.0).abs() < 1e-5);
            prop_assert!(f.s.dot(f.t).abs() < 1e-5);
            prop_assert!(f.s.dot(f.n).abs() < 1e-5);
            prop_assert!(f.t.dot(f.n).abs() < 1e-5);
            // Right-handed: s x t = n.
            prop_assert!((f.s.cross(f.t) - f.n).length() < 1e-4);
            let w = Vec3::new(0.3, -0.2, 0.9);
            prop_assert!((f.to_world(f.to_local(w)) - w).length() < 1e-5);
        }
    }
}
