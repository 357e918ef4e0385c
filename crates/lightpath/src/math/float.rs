//! Floating-point error analysis helpers (pbrt's conventions): `gamma(n)` bounds the
//! relative error of `n` roundings, and `offset_ray_origin` moves a point off a surface by
//! its error bound along the normal, so spawned rays never re-hit the surface they leave.

use glam::{Vec3, Vec3A};

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
    // In 4-lane arithmetic: the same operations as with `Vec3`, bit for bit.
    let n = Vec3A::from(n);
    let d = n.abs().dot(p_error.into());
    let mut offset = n * d;
    if Vec3A::from(w).dot(n) < 0.0 {
        offset = -offset;
    }
    let po = Vec3A::from(p) + offset;
    // Round away from p so the offset is not lost to rounding.
    round_away3(po, offset).into()
}

/// [`round_away`] of the three lanes at once.
#[inline(always)]
fn round_away3(po: Vec3A, off: Vec3A) -> Vec3A {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 is part of the x86_64 baseline.
    unsafe {
        use std::arch::x86_64::*;
        let (po, off): (__m128, __m128) = (po.into(), off.into());
        let zero = _mm_setzero_ps();
        let select = |m: __m128i, a: __m128i, b: __m128i| {
            _mm_or_si128(_mm_and_si128(m, a), _mm_andnot_si128(m, b))
        };
        let bits = _mm_castps_si128(po);
        let up = _mm_castps_si128(_mm_cmpgt_ps(off, zero));
        let down = _mm_castps_si128(_mm_cmplt_ps(off, zero));
        let ones = _mm_set1_epi32(-1);
        // Moving away from zero adds one to the bit pattern, towards zero subtracts one.
        let positive = _mm_cmpgt_epi32(bits, ones);
        let away = _mm_xor_si128(_mm_xor_si128(up, positive), ones);
        let infinite = _mm_castps_si128(_mm_cmpeq_ps(
            _mm_andnot_ps(_mm_set1_ps(-0.0), po),
            _mm_set1_ps(f32::INFINITY),
        ));
        let plus = select(infinite, bits, _mm_sub_epi32(bits, ones));
        let stepped = select(away, plus, _mm_add_epi32(bits, ones));
        // ±0 steps to the smallest subnormal of the offset's sign.
        let from_zero = select(up, _mm_set1_epi32(1), _mm_set1_epi32(0x8000_0001u32 as i32));
        let is_zero = _mm_castps_si128(_mm_cmpeq_ps(po, zero));
        let r = select(is_zero, from_zero, stepped);
        Vec3A::from(_mm_castsi128_ps(select(_mm_or_si128(up, down), r, bits)))
    }
    #[cfg(not(target_arch = "x86_64"))]
    Vec3A::new(
        round_away(po.x, off.x),
        round_away(po.y, off.y),
        round_away(po.z, off.z),
    )
}

/// `next_float_up(po)` where `off > 0`, `next_float_down(po)` where `off < 0`, else
/// `po`: the same values, computed with selects instead of branches (the offset's signs
/// follow the normal and are unpredictable, and this runs for every spawned ray). On
/// x86_64 `round_away3` does three at once; this is the portable path and its oracle,
/// and the path tracer's lanes run it on sixteen values at once.
#[inline(always)]
pub fn round_away(po: f32, off: f32) -> f32 {
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
                let lanes = round_away3(Vec3A::new(v, 1.0, v), Vec3A::new(off, off, -off));
                assert_eq!(lanes.x.to_bits(), expected.to_bits(), "{v} {off}");
                assert_eq!(
                    lanes.z.to_bits(),
                    round_away(v, -off).to_bits(),
                    "{v} {off}"
                );
                assert_eq!(lanes.y.to_bits(), round_away(1.0, off).to_bits(), "{off}");
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
