//! Affine and projective transforms with a cached inverse.
//!
//! Transforms are named `a_from_b`: `render_from_object.point(p)` takes an object-space
//! point to render space. Points, vectors and normals transform differently; normals use
//! the inverse transpose, so they stay perpendicular to surfaces under non-uniform scale
//! and shear.

use super::{gamma, Bounds3};
use glam::{Mat3, Mat4, Vec3, Vec4};

/// A 4x4 transform and its inverse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transform {
    m: Mat4,
    m_inv: Mat4,
}

impl Default for Transform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

/// Order of Euler rotations. `Xyz` rotates about the fixed (extrinsic) world X axis
/// first, then world Y, then world Z: the matrix is `Rz * Ry * Rx`. This equals
/// intrinsic rotations about the body's Z, then Y', then X''. Every other order reads the
/// same way: the first letter is the first rotation about a world axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EulerOrder {
    Xyz,
    Xzy,
    Yxz,
    Yzx,
    Zxy,
    Zyx,
}

/// Which way a coordinate system's axes turn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Handedness {
    Right,
    Left,
}

/// The up axis and handedness of a tool's world space. lightpath's render space is
/// right-handed; importers convert with [`Transform::convert_axes`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AxisConvention {
    /// Y up, right-handed (Mitsuba, glTF, Maya, OpenGL).
    YUpRightHanded,
    /// Y up, left-handed (Unity, DirectX, pbrt's camera space).
    YUpLeftHanded,
    /// Z up, right-handed (Blender, 3ds Max).
    ZUpRightHanded,
    /// Z up, left-handed (Unreal Engine).
    ZUpLeftHanded,
}

impl AxisConvention {
    /// The matrix taking this convention's coordinates to Y-up right-handed ones. The
    /// horizontal axis X is kept; "up" maps to +Y; the remaining axis goes to ±Z with
    /// the sign that makes the handedness right.
    fn to_y_up_right(self) -> Mat3 {
        match self {
            AxisConvention::YUpRightHanded => Mat3::IDENTITY,
            AxisConvention::YUpLeftHanded => Mat3::from_diagonal(Vec3::new(1.0, 1.0, -1.0)),
            // (x, y, z) -> (x, z, -y)
            AxisConvention::ZUpRightHanded => {
                Mat3::from_cols(Vec3::X, Vec3::new(0.0, 0.0, -1.0), Vec3::Y)
            }
            // (x, y, z) -> (x, z, y)
            AxisConvention::ZUpLeftHanded => Mat3::from_cols(Vec3::X, Vec3::Z, Vec3::Y),
        }
    }
}

impl Transform {
    pub const IDENTITY: Transform = Transform {
        m: Mat4::IDENTITY,
        m_inv: Mat4::IDENTITY,
    };

    /// A transform from a matrix; `None` if the matrix is singular or not finite.
    pub fn from_matrix(m: Mat4) -> Option<Transform> {
        if !m.is_finite() {
            return None;
        }
        let det = m.determinant();
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let m_inv = m.inverse();
        if !m_inv.is_finite() {
            return None;
        }
        Some(Transform { m, m_inv })
    }

    /// A transform from 16 numbers in row-major order (how scene files write matrices).
    pub fn from_row_major(v: &[f32; 16]) -> Option<Transform> {
        Self::from_matrix(Mat4::from_cols_array(v).transpose())
    }

    /// A transform from a matrix and its known inverse.
    pub fn from_matrix_and_inverse(m: Mat4, m_inv: Mat4) -> Transform {
        Transform { m, m_inv }
    }

    pub fn translate(t: Vec3) -> Transform {
        Transform {
            m: Mat4::from_translation(t),
            m_inv: Mat4::from_translation(-t),
        }
    }

    /// Scale by `s`; `None` if a factor is zero.
    pub fn scale(s: Vec3) -> Option<Transform> {
        if s.cmpeq(Vec3::ZERO).any() || !s.is_finite() {
            return None;
        }
        Some(Transform {
            m: Mat4::from_scale(s),
            m_inv: Mat4::from_scale(s.recip()),
        })
    }

    /// Rotation by `degrees` about `axis` (right-hand rule). `None` for a zero axis.
    pub fn rotate(axis: Vec3, degrees: f32) -> Option<Transform> {
        let len = axis.length();
        if len == 0.0 || !len.is_finite() || !degrees.is_finite() {
            return None;
        }
        let m = Mat4::from_axis_angle(axis / len, degrees.to_radians());
        Some(Transform {
            m,
            m_inv: m.transpose(),
        })
    }

    /// Rotation by Euler angles in degrees; see [`EulerOrder`] for the convention.
    /// `angles` holds the X, Y and Z angles whatever the order.
    pub fn euler(order: EulerOrder, angles_degrees: Vec3) -> Transform {
        let r = angles_degrees * (std::f32::consts::PI / 180.0);
        let (rx, ry, rz) = (
            Mat4::from_rotation_x(r.x),
            Mat4::from_rotation_y(r.y),
            Mat4::from_rotation_z(r.z),
        );
        // The first rotation applied is the right-most factor.
        let m = match order {
            EulerOrder::Xyz => rz * ry * rx,
            EulerOrder::Xzy => ry * rz * rx,
            EulerOrder::Yxz => rz * rx * ry,
            EulerOrder::Yzx => rx * rz * ry,
            EulerOrder::Zxy => ry * rx * rz,
            EulerOrder::Zyx => rx * ry * rz,
        };
        Transform {
            m,
            m_inv: m.transpose(),
        }
    }

    /// The camera-to-world transform of a camera at `origin` looking at `target`: camera
    /// +z maps to the viewing direction, camera +y to `up` (made perpendicular), and
    /// camera +x to `up × direction`. `None` if the directions are degenerate.
    pub fn look_at(origin: Vec3, target: Vec3, up: Vec3) -> Option<Transform> {
        let dir = (target - origin).normalize_or_zero();
        let x = up.cross(dir).normalize_or_zero();
        if dir == Vec3::ZERO || x == Vec3::ZERO {
            return None;
        }
        let y = dir.cross(x);
        let m = Mat4::from_cols(
            x.extend(0.0),
            y.extend(0.0),
            dir.extend(0.0),
            origin.extend(1.0),
        );
        Self::from_matrix(m)
    }

    /// The change of basis from one tool's axis convention to another's.
    pub fn convert_axes(from: AxisConvention, to: AxisConvention) -> Transform {
        let m = to.to_y_up_right().transpose() * from.to_y_up_right();
        let m4 = Mat4::from_mat3(m);
        Transform {
            m: m4,
            m_inv: m4.transpose(),
        }
    }

    #[inline]
    pub fn matrix(&self) -> &Mat4 {
        &self.m
    }

    #[inline]
    pub fn inverse_matrix(&self) -> &Mat4 {
        &self.m_inv
    }

    #[inline]
    pub fn inverse(&self) -> Transform {
        Transform {
            m: self.m_inv,
            m_inv: self.m,
        }
    }

    /// `self ∘ other`: applies `other` first, then `self`.
    #[inline]
    pub fn compose(&self, other: &Transform) -> Transform {
        Transform {
            m: self.m * other.m,
            m_inv: other.m_inv * self.m_inv,
        }
    }

    /// `other ∘ self`: applies `self` first, then `other` (document order in scene files).
    #[inline]
    pub fn then(&self, other: &Transform) -> Transform {
        other.compose(self)
    }

    pub fn is_identity(&self) -> bool {
        self.m == Mat4::IDENTITY
    }

    /// True if the transform flips handedness (negative determinant of the linear part).
    pub fn swaps_handedness(&self) -> bool {
        Mat3::from_mat4(self.m).determinant() < 0.0
    }

    /// Whether the last row is (0, 0, 0, 1).
    pub fn is_affine(&self) -> bool {
        self.m.row(3) == Vec4::W
    }

    #[inline]
    pub fn point(&self, p: Vec3) -> Vec3 {
        if self.is_affine() {
            self.m.transform_point3(p)
        } else {
            self.m.project_point3(p)
        }
    }

    #[inline]
    pub fn vector(&self, v: Vec3) -> Vec3 {
        self.m.transform_vector3(v)
    }

    /// Transforms a normal by the inverse transpose; the result is not normalised.
    #[inline]
    pub fn normal(&self, n: Vec3) -> Vec3 {
        // (M^-1)^T n, written without forming the transpose.
        let mi = &self.m_inv;
        Vec3::new(
            mi.x_axis.x * n.x + mi.x_axis.y * n.y + mi.x_axis.z * n.z,
            mi.y_axis.x * n.x + mi.y_axis.y * n.y + mi.y_axis.z * n.z,
            mi.z_axis.x * n.x + mi.z_axis.y * n.y + mi.z_axis.z * n.z,
        )
    }

    /// Transforms an (affine) point with absolute error `p_error`, returning the point and
    /// a conservative bound on its new absolute error (pbrt-v4, section 6.8.5).
    pub fn point_with_error(&self, p: Vec3, p_error: Vec3) -> (Vec3, Vec3) {
        let m = &self.m;
        let r = [m.row(0), m.row(1), m.row(2)];
        let mut err = [0.0f32; 3];
        for (i, row) in r.iter().enumerate() {
            let a = row.truncate().abs();
            err[i] = (gamma(3) + 1.0) * a.dot(p_error) + gamma(3) * (a.dot(p.abs()) + row.w.abs());
        }
        (self.point(p), Vec3::from_array(err))
    }

    /// A tight bound of a box under an affine transform (Arvo 1990): each output extent
    /// is the sum over input axes of the min/max of the scaled slab.
    pub fn bounds(&self, b: &Bounds3) -> Bounds3 {
        if b.is_empty() {
            return *b;
        }
        if !self.is_affine() || !b.min.is_finite() || !b.max.is_finite() {
            let mut out = Bounds3::EMPTY;
            for c in b.corners() {
                out.expand(self.point(c));
            }
            return out;
        }
        let t = self.m.w_axis.truncate();
        let mut min = t;
        let mut max = t;
        let cols = [
            self.m.x_axis.truncate(),
            self.m.y_axis.truncate(),
            self.m.z_axis.truncate(),
        ];
        for (axis, col) in cols.iter().enumerate() {
            let a = *col * b.min[axis];
            let c = *col * b.max[axis];
            min += a.min(c);
            max += a.max(c);
        }
        Bounds3 { min, max }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn close(a: Vec3, b: Vec3, eps: f32) -> bool {
        (a - b).abs().max_element()
            <= eps * (1.0 + a.abs().max_element().max(b.abs().max_element()))
    }

    fn arb_affine() -> impl Strategy<Value = Transform> {
        (
            prop::array::uniform3(-3.0f32..3.0),
            prop::array::uniform3(0.2f32..3.0),
            prop::array::uniform3(-1.0f32..1.0),
            -180.0f32..180.0,
            prop::array::uniform3(-0.8f32..0.8),
            any::<[bool; 3]>(),
        )
            .prop_filter_map("degenerate", |(t, s, axis, angle, shear, flip)| {
                let s = Vec3::new(
                    if flip[0] { -s[0] } else { s[0] },
                    if flip[1] { -s[1] } else { s[1] },
                    if flip[2] { -s[2] } else { s[2] },
                );
                let sh = Transform::from_matrix(Mat4::from_cols(
                    Vec4::new(1.0, shear[0], shear[1], 0.0),
                    Vec4::new(0.0, 1.0, shear[2], 0.0),
                    Vec4::Z,
                    Vec4::W,
                ))?;
                let r = Transform::rotate(Vec3::from_array(axis), angle)?;
                Some(
                    Transform::scale(s)?
                        .then(&sh)
                        .then(&r)
                        .then(&Transform::translate(Vec3::from_array(t))),
                )
            })
    }

    proptest! {
        #[test]
        fn round_trip(t in arb_affine(), p in prop::array::uniform3(-10.0f32..10.0)) {
            let p = Vec3::from_array(p);
            let q = t.inverse().point(t.point(p));
            prop_assert!(close(p, q, 1e-4), "{p} vs {q}");
            let v = t.inverse().vector(t.vector(p));
            prop_assert!(close(p, v, 1e-4));
        }

        #[test]
        fn normals_stay_perpendicular(t in arb_affine(),
                                      n in prop::array::uniform3(-1.0f32..1.0),
                                      a in prop::array::uniform3(-1.0f32..1.0)) {
            let n = Vec3::from_array(n);
            prop_assume!(n.length() > 0.1);
            // A tangent perpendicular to n.
            let tangent = n.cross(Vec3::from_array(a));
            prop_assume!(tangent.length() > 0.1);
            let n2 = t.normal(n).normalize();
            let t2 = t.vector(tangent).normalize();
            prop_assert!(n2.dot(t2).abs() < 1e-4, "dot {}", n2.dot(t2));
        }

        #[test]
        fn bounds_contain_transformed_corners(t in arb_affine()) {
            let b = Bounds3::new(Vec3::new(-1.0, -2.0, 0.5), Vec3::new(2.0, 1.0, 3.0));
            let tb = t.bounds(&b);
            for c in b.corners() {
                let q = t.point(c);
                prop_assert!(q.cmpge(tb.min - 1e-4).all() && q.cmple(tb.max + 1e-4).all());
            }
        }

        #[test]
        fn euler_is_a_rotation(ax in -180.0f32..180.0, ay in -180.0f32..180.0, az in -180.0f32..180.0) {
            let e = Transform::euler(EulerOrder::Xyz, Vec3::new(ax, ay, az));
            let composed = Transform::rotate(Vec3::X, ax).unwrap()
                .then(&Transform::rotate(Vec3::Y, ay).unwrap())
                .then(&Transform::rotate(Vec3::Z, az).unwrap());
            let p = Vec3::new(0.3, -1.2, 0.7);
            prop_assert!(close(e.point(p), composed.point(p), 1e-5));
            prop_assert!((Mat3::from_mat4(*e.matrix()).determinant() - 1.0).abs() < 1e-4);
        }
    }

    #[test]
    fn composition_applies_in_document_order() {
        let s = Transform::scale(Vec3::splat(2.0)).unwrap();
        let t = Transform::translate(Vec3::X);
        // scale, then translate.
        assert_eq!(s.then(&t).point(Vec3::X), Vec3::new(3.0, 0.0, 0.0));
        // translate, then scale.
        assert_eq!(t.then(&s).point(Vec3::X), Vec3::new(4.0, 0.0, 0.0));
    }

    #[test]
    fn look_at_maps_axes() {
        let t = Transform::look_at(Vec3::ZERO, Vec3::Z, Vec3::Y).unwrap();
        assert!(t.is_identity());
        let t = Transform::look_at(Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, 2.0, 10.0), Vec3::Y)
            .unwrap();
        assert!(close(t.vector(Vec3::Z), Vec3::Z, 1e-6));
        assert!(close(t.point(Vec3::ZERO), Vec3::new(1.0, 2.0, 3.0), 1e-6));
        assert!(Transform::look_at(Vec3::ZERO, Vec3::Y, Vec3::Y).is_none());
    }

    #[test]
    fn rotation_is_right_handed() {
        let r = Transform::rotate(Vec3::Z, 90.0).unwrap();
        assert!(close(r.vector(Vec3::X), Vec3::Y, 1e-6));
    }

    #[test]
    fn mirror_swaps_handedness() {
        assert!(Transform::scale(Vec3::new(-1.0, 1.0, 1.0))
            .unwrap()
            .swaps_handedness());
        assert!(!Transform::rotate(Vec3::Y, 30.0).unwrap().swaps_handedness());
    }

    #[test]
    fn axis_conversion() {
        let t = Transform::convert_axes(
            AxisConvention::ZUpRightHanded,
            AxisConvention::YUpRightHanded,
        );
        // Blender's up (+Z) becomes +Y, its forward (+Y) becomes -Z.
        assert!(close(t.vector(Vec3::Z), Vec3::Y, 1e-6));
        assert!(close(t.vector(Vec3::Y), -Vec3::Z, 1e-6));
        assert!(!t.swaps_handedness());
        let l = Transform::convert_axes(
            AxisConvention::YUpLeftHanded,
            AxisConvention::YUpRightHanded,
        );
        assert!(l.swaps_handedness());
        let back = Transform::convert_axes(
            AxisConvention::YUpRightHanded,
            AxisConvention::ZUpLeftHanded,
        );
        let there = Transform::convert_axes(
            AxisConvention::ZUpLeftHanded,
            AxisConvention::YUpRightHanded,
        );
        assert!(there.then(&back).is_identity());
    }

    #[test]
    fn singular_matrices_are_rejected() {
        assert!(Transform::from_matrix(Mat4::ZERO).is_none());
        assert!(Transform::scale(Vec3::new(1.0, 0.0, 1.0)).is_none());
        assert!(Transform::rotate(Vec3::ZERO, 10.0).is_none());
    }

    #[test]
    fn row_major_matrix() {
        let t = Transform::from_row_major(&[
            1.0, -0.5, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
        ])
        .unwrap();
        assert_eq!(t.point(Vec3::Y), Vec3::new(-0.5, 1.0, 0.0));
    }
}
