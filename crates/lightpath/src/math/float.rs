//! Floating-point error analysis helpers (pbrt's conventions): `gamma(n)` bounds the
//! relative error of `n` roundings, and `offset_ray_origin` moves a point off a surface by
//! its error bound along the normal, so spawned rays never re-hit the surface they leave.

use glam::Vec3;

/// Machine epsilon for `f32` rounding (half an ulp of 1).
pub const MACHINE_EPSILON: f32 = f32::EPSILON * 0.5;

/// Bound on the relative error after `n` floating-point roundings.
#[inline]
pub fn gamma(n: i32) -> f32 {
    let n = n as f32;
    (n * MACHINE_EPSILON) / (1.0 - n * MACHINE_EPSILON)
}

/// The next representable `f32` above `v`.
#[inline]
pub fn next_float_up(v: f32) -> f32 {
    if v.is_infinite() && v > 0.0 {
        return v;
    }
    let v = if v == -0.0 { 0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v >= 0.0 { bits + 1 } else { bits - 1 };
    f32::from_bits(bits)
}

/// The next representable `f32` below `v`.
#[inline]
pub fn next_float_down(v: f32) -> f32 {
    if v.is_infinite() && v < 0.0 {
        return v;
    }
    let v = if v == 0.0 { -0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v > 0.0 { bits - 1 } else { bits + 1 };
    f32::from_bits(bits)
}

/// Offsets `p` (with absolute error bound `p_error` per axis) along the geometric normal
/// `n` to the side that `w` points to, far enough that the rounding error of `p` can no
/// longer put the new origin on the other side of the surface.
#[inline]
pub fn offset_ray_origin(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error);
    let mut offset = n * d;
    if w.dot(n) < 0.0 {
        offset = -offset;
    }
    let po = p + offset;
    // Round away from p so the offset is not lost to rounding.
    Vec3::new(
        round_away(po.x, offset.x),
        round_away(po.y, offset.y),
        round_away(po.z, offset.z),
    )
}

/// `next_float_up(po)` where `off > 0`, `next_float_down(po)` where `off < 0`, else
/// `po`: the same values, computed with selects instead of branches (the offset's signs
/// follow the normal and are unpredictable, and this runs for every spawned ray).
#[inline(always)]
fn round_away(po: f32, off: f32) -> f32 {
    let bits = po.to_bits();
    let up = off > 0.0;
    // Moving away from zero adds one to the bit pattern, towards zero subtracts one; an
    // infinity moving away from zero stays (as in `next_float_up`/`next_float_down`).
    let away = up == (bits >> 31 == 0);
    let stepped = if away {
        if po.is_infinite() {
            bits
        } else {
            bits.wrapping_add(1)
        }
    } else {
        bits.wrapping_sub(1)
    };
    // ±0 steps to the smallest subnormal of the offset's sign.
    let from_zero = if up { 1 } else { 0x8000_0001 };
    let r = if po == 0.0 { from_zero } else { stepped };
    if up || off < 0.0 {
        f32::from_bits(r)
    } else {
        po
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn next_float_steps_one_ulp() {
        assert!(next_float_up(1.0) > 1.0);
        assert_eq!(next_float_down(next_float_up(1.0)), 1.0);
        assert!(next_float_up(0.0) > 0.0);
        assert!(next_float_down(0.0) < 0.0);
        assert!(next_float_up(-1.0) > -1.0);
    }

    /// The branch-free rounding gives `next_float_up`/`next_float_down` bit for bit,
    /// zeros, subnormals and infinities included.
    #[test]
    fn round_away_matches_next_float() {
        let mut values = vec![
            0.0f32,
            -0.0,
            1.0,
            -1.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::from_bits(1),
            f32::from_bits(0x8000_0001),
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        let mut rng = crate::sampling::Pcg32::new(5, 9);
        for _ in 0..10_000 {
            let v = f32::from_bits(rng.next_u32());
            if !v.is_nan() {
                values.push(v);
            }
        }
        for &v in &values {
            for off in [1e-3f32, -1e-3, 0.0, -0.0, f32::MIN_POSITIVE, -f32::INFINITY] {
                let expected = if off > 0.0 {
                    next_float_up(v)
                } else if off < 0.0 {
                    next_float_down(v)
                } else {
                    v
                };
                assert_eq!(
                    round_away(v, off).to_bits(),
                    expected.to_bits(),
                    "{v} {off}"
                );
            }
        }
    }

    #[test]
    fn offset_goes_to_the_side_of_w() {
        let p = Vec3::new(1.0, 2.0, 3.0);
        let n = Vec3::Z;
        let err = Vec3::splat(1e-5);
        assert!(offset_ray_origin(p, err, n, Vec3::Z).z > 3.0);
        assert!(offset_ray_origin(p, err, n, -Vec3::Z).z < 3.0);
    }
}
