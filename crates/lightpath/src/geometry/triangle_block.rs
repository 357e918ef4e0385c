//! Triangles packed four to a block in the order of the mesh's BVH leaves, so that a leaf
//! is tested against a ray with one 4-lane SIMD watertight test per block instead of
//! four scalar tests behind three indirections each (BVH slot -> triangle -> vertices).
//!
//! The wide BVHs lay out their leaves at positions that are multiples of four and pad
//! each leaf to a whole number of blocks by repeating its last triangle, so a leaf at
//! `(first, count)` is exactly the blocks `first / 4 .. (first + count).div_ceil(4)`;
//! a repeated triangle can only find the same hit again.
//!
//! The lanes compute exactly what [`intersect_triangle_watertight`] computes, operation
//! for operation in the same order (no fused multiply-adds), so the packed path and the
//! scalar path agree bit for bit.
//!
//! A lane is *inside* when its three edge functions are all `>= 0` or all `<= 0` (their
//! minimum `>= 0` or maximum `<= 0`), and *strictly inside* with `>` and `<`. A lane that
//! is not inside is a miss for the scalar test too: that test redoes the edge functions
//! in double precision when one is exactly zero, but an edge function rounded to single
//! precision has the sign of the exact one or is zero (rounding the two products is
//! monotonic), so two nonzero ones of opposite signs stay opposite (for products in the
//! normal range, as for any coordinates above about 1e-19). Most blocks end there, with
//! no lane inside; a block with a lane inside but not strictly (on an edge, or
//! degenerate) falls back to the scalar test. Every lane left is strictly inside, and its
//! determinant (the sum) is not zero.

use super::mesh::{intersect_triangle_watertight, WatertightRay};
use crate::math::gamma;
use glam::{Vec3, Vec4};
#[cfg(target_arch = "x86_64")]
use std::mem::MaybeUninit;

/// Four triangles' vertices as structure of arrays: `p[vertex][axis]` holds that
/// coordinate of the four triangles, then the triangles' indices in the mesh (160
/// bytes). A hit's index is read from the block its test has just loaded: looked up in
/// a separate array it cost incoherent rays on a mesh larger than the caches one more
/// trip to main memory per hit (13-18% of the 1.1M-triangle bunny's random rays).
///
/// Aligned to 32 bytes, so that every block lies in three cache lines (at offset 0 or 32
/// of a line), the three that [`TriangleMesh`](super::TriangleMesh) prefetches for a
/// leaf. At 16 bytes a large array starts 16 bytes into a line (the allocator's
/// header), and every other block then spans four lines, its indices alone in the
/// fourth: a miss that the prefetch did not start.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(32))]
pub struct TriangleBlock {
    pub p: [[Vec4; 3]; 3],
    pub prim: [u32; BLOCK],
}

const _: () = assert!(std::mem::size_of::<TriangleBlock>() == 160);

/// Triangles a block holds.
pub const BLOCK: usize = 4;

impl TriangleBlock {
    /// Packs four triangles given as vertex triples, with their indices in the mesh.
    pub fn new(tris: [[Vec3; 3]; 4], prim: [u32; BLOCK]) -> TriangleBlock {
        let mut p = [[Vec4::ZERO; 3]; 3];
        for (lane, tri) in tris.iter().enumerate() {
            for (v, vertex) in tri.iter().enumerate() {
                for axis in 0..3 {
                    p[v][axis][lane] = vertex[axis];
                }
            }
        }
        TriangleBlock { p, prim }
    }

    /// The vertices of triangle `lane`.
    #[inline]
    pub fn triangle(&self, lane: usize) -> (Vec3, Vec3, Vec3) {
        let v = |i: usize| Vec3::new(self.p[i][0][lane], self.p[i][1][lane], self.p[i][2][lane]);
        (v(0), v(1), v(2))
    }

    /// The watertight test for the four triangles at once. Returns the mask of lanes hit
    /// with `t_min < t <= t_max` (provably in front of the origin), their distances and
    /// their barycentrics `b1`, `b2`.
    #[inline(always)]
    pub fn intersect(&self, wr: &WatertightRay, t_min: f32, t_max: f32) -> (u32, Vec4, Vec4, Vec4) {
        let (kx, ky, kz) = wr.axes();
        let [ox, oy, oz] = wr.origin_permuted().map(Vec4::splat);
        let s = wr.shear();
        let (sx, sy, sz) = (Vec4::splat(s.x), Vec4::splat(s.y), Vec4::splat(s.z));
        let p = &self.p;
        // Translate to the ray origin, permute and shear.
        let (az, bz, cz) = (p[0][kz] - oz, p[1][kz] - oz, p[2][kz] - oz);
        let ax = (p[0][kx] - ox) + sx * az;
        let ay = (p[0][ky] - oy) + sy * az;
        let bx = (p[1][kx] - ox) + sx * bz;
        let by = (p[1][ky] - oy) + sy * bz;
        let cx = (p[2][kx] - ox) + sx * cz;
        let cy = (p[2][ky] - oy) + sy * cz;
        let e0 = bx * cy - by * cx;
        let e1 = cx * ay - cy * ax;
        let e2 = ax * by - ay * bx;
        let zero = Vec4::ZERO;
        // The lanes inside all three edges, and those strictly inside (see the module
        // docs). Most blocks end here, with no lane inside.
        let (e_min, e_max) = (e0.min(e1).min(e2), e0.max(e1).max(e2));
        let inside = e_min.cmpge(zero) | e_max.cmple(zero);
        if !inside.any() {
            return (0, zero, zero, zero);
        }
        let mut valid = e_min.cmpgt(zero) | e_max.cmplt(zero);
        if valid.bitmask() != inside.bitmask() {
            return self.intersect_scalar(wr, t_min, t_max);
        }
        // Every lane still in is strictly inside, so its sum `det` is not zero.
        let det = e0 + e1 + e2;
        let (az, bz, cz) = (az * sz, bz * sz, cz * sz);
        let t_scaled = e0 * az + e1 * bz + e2 * cz;
        // `t_min < t_scaled / det <= t_max` as `t_min·|det| < ±t_scaled <= t_max·|det|`,
        // the sign flipped where `det` is negative: negation is exact, and so is
        // `t_min·|det| = |t_min·det|`, so this is the signed comparison bit for bit.
        let abs_det = det.abs();
        let (lo, hi) = (Vec4::splat(t_min) * abs_det, Vec4::splat(t_max) * abs_det);
        let t_signed = flip_sign(t_scaled, det);
        valid &= t_signed.cmpgt(lo) & t_signed.cmple(hi);
        if !valid.any() {
            return (0, zero, zero, zero);
        }
        let inv_det = Vec4::ONE / det;
        let t = t_scaled * inv_det;
        // Reject t that is not provably positive (pbrt-v4, section 6.8.4).
        let max_zt = az.abs().max(bz.abs()).max(cz.abs());
        let delta_z = Vec4::splat(gamma(3)) * max_zt;
        let max_xt = ax.abs().max(bx.abs()).max(cx.abs());
        let max_yt = ay.abs().max(by.abs()).max(cy.abs());
        // The unscaled `z` bound and `γ7` as in `mesh::delta_t`.
        let max_zu = max_zt * Vec4::splat(wr.dz_abs());
        let g7 = Vec4::splat(gamma(7));
        let delta_x = g7 * (max_xt + max_zu);
        let delta_y = g7 * (max_yt + max_zu);
        let delta_e = Vec4::splat(2.0)
            * (Vec4::splat(gamma(2)) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
        let max_e = e0.abs().max(e1.abs()).max(e2.abs());
        let delta_t = Vec4::splat(3.0)
            * (Vec4::splat(gamma(3)) * max_e * max_zt + delta_e * max_zt + delta_z * max_e)
            * inv_det.abs();
        valid &= t.cmpgt(delta_t);
        (valid.bitmask(), t, e1 * inv_det, e2 * inv_det)
    }

    /// The same test one lane at a time (for lanes with an edge function of exactly 0).
    #[cold]
    fn intersect_scalar(
        &self,
        wr: &WatertightRay,
        t_min: f32,
        t_max: f32,
    ) -> (u32, Vec4, Vec4, Vec4) {
        let (mut bits, mut t, mut b1, mut b2) = (0, Vec4::ZERO, Vec4::ZERO, Vec4::ZERO);
        for lane in 0..BLOCK {
            let (p0, p1, p2) = self.triangle(lane);
            if let Some((tl, _, u, v)) = intersect_triangle_watertight(wr, t_min, t_max, p0, p1, p2)
            {
                bits |= 1 << lane;
                t[lane] = tl;
                b1[lane] = u;
                b2[lane] = v;
            }
        }
        (bits, t, b1, b2)
    }
}

/// `x` negated where `by` is negative (has its sign bit set): exact.
#[inline(always)]
fn flip_sign(x: Vec4, by: Vec4) -> Vec4 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        // SAFETY: SSE2 is part of x86-64.
        unsafe {
            let sign = _mm_and_ps(by.into(), _mm_set1_ps(-0.0));
            Vec4::from(_mm_xor_ps(x.into(), sign))
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        // Multiplying by ±1 is exact (a NaN `by` gives NaN, which every comparison fails).
        x * by.signum()
    }
}

/// The hits of two consecutive blocks as eight lanes: a bit mask (block `a` in bits
/// 0-3, `b` in 4-7) and, where a lane hits, the distances and barycentrics `b1`, `b2`.
///
/// A leaf that no lane hits (most of them) returns no lanes at all, and the lanes of a
/// hit are read where they are, by reference. With arrays of floats, the compiler
/// stored zeros to the stack at every miss (where the lanes of a hit go to be
/// indexed), and where the caller is compiled for AVX-512 it did so, and copied the
/// lanes of a hit, with 512-bit moves: on Intel processors a 512-bit instruction takes
/// a vector port out of use for a while, and the single-ray closest-hit query of the
/// Stanford bunny ran 8% slower for those two moves.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub struct PairHits {
    bits: u32,
    /// Initialised whenever `bits` is not zero.
    lanes: MaybeUninit<[Lanes8; 3]>,
}

#[cfg(target_arch = "x86_64")]
impl PairHits {
    #[inline(always)]
    fn miss() -> PairHits {
        PairHits {
            bits: 0,
            lanes: MaybeUninit::uninit(),
        }
    }

    #[inline(always)]
    fn new(bits: u32, t: Lanes8, b1: Lanes8, b2: Lanes8) -> PairHits {
        PairHits {
            bits,
            lanes: MaybeUninit::new([t, b1, b2]),
        }
    }

    /// The lanes that hit.
    #[inline(always)]
    pub fn bits(&self) -> u32 {
        self.bits
    }

    /// Drops the lanes outside `mask`.
    #[inline(always)]
    pub fn keep(&mut self, mask: u32) {
        self.bits &= mask;
    }

    /// The distances and barycentrics `b1`, `b2` of the lanes, where any lane hits.
    #[inline(always)]
    pub fn lanes(&self) -> Option<&[Lanes8; 3]> {
        // SAFETY: the lanes are initialised whenever `bits` is not zero, and `keep` only
        // clears bits.
        (self.bits != 0).then(|| unsafe { self.lanes.assume_init_ref() })
    }
}

/// Eight floats in a vector register, read lane by lane through `Index`.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub struct Lanes8(std::arch::x86_64::__m256);

#[cfg(target_arch = "x86_64")]
impl std::ops::Index<usize> for Lanes8 {
    type Output = f32;

    #[inline(always)]
    fn index(&self, lane: usize) -> &f32 {
        // SAFETY: `__m256` is eight `f32`s, with at least their alignment.
        let lanes = unsafe { &*(&self.0 as *const std::arch::x86_64::__m256 as *const [f32; 8]) };
        &lanes[lane]
    }
}

#[cfg(target_arch = "x86_64")]
impl Lanes8 {
    /// The lanes from an array (no AVX needed: an unaligned copy).
    #[inline(always)]
    fn from_array(lanes: [f32; 8]) -> Lanes8 {
        // SAFETY: `__m256` has the size of eight `f32`s, and any bits are valid.
        Lanes8(unsafe { std::mem::transmute::<[f32; 8], std::arch::x86_64::__m256>(lanes) })
    }
}

/// Two blocks tested at once with 8-lane AVX2: the same operations as
/// [`TriangleBlock::intersect`] in the same order, so every lane equals the 4-lane (and
/// the scalar) result bit for bit.
///
/// # Safety
/// The processor must have the AVX2 tier (`crate::cpu`).
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
pub unsafe fn intersect_pair_avx2(
    a: &TriangleBlock,
    b: &TriangleBlock,
    wr: &WatertightRay,
    t_min: f32,
    t_max: f32,
) -> PairHits {
    // SAFETY: this function's caller guarantees AVX2.
    unsafe { intersect_pair_inline(a, b, wr, t_min, t_max) }
}

/// The pair test from a caller that is compiled for AVX2 (`AVX2_CALLER`: inlined, see
/// [`intersect_pair_inline`]) or not (a call to [`intersect_pair_avx2`]).
///
/// # Safety
/// The processor must have the AVX2 tier (`crate::cpu`).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub unsafe fn intersect_pair<const AVX2_CALLER: bool>(
    a: &TriangleBlock,
    b: &TriangleBlock,
    wr: &WatertightRay,
    t_min: f32,
    t_max: f32,
) -> PairHits {
    // SAFETY: the caller guarantees AVX2.
    unsafe {
        if AVX2_CALLER {
            intersect_pair_inline(a, b, wr, t_min, t_max)
        } else {
            intersect_pair_avx2(a, b, wr, t_min, t_max)
        }
    }
}

/// [`intersect_pair_avx2`]'s body, to be inlined into callers that are themselves
/// compiled for AVX2 (`#[target_feature]` functions cannot be forced inline): its
/// intrinsics inline there, and its lanes stay in registers.
///
/// # Safety
/// The processor must have the AVX2 tier (`crate::cpu`), and the caller should be
/// compiled for it (elsewhere each intrinsic becomes a call).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub unsafe fn intersect_pair_inline(
    a: &TriangleBlock,
    b: &TriangleBlock,
    wr: &WatertightRay,
    t_min: f32,
    t_max: f32,
) -> PairHits {
    use std::arch::x86_64::*;
    let (kx, ky, kz) = wr.axes();
    let [ox, oy, oz] = wr.origin_permuted().map(|c| _mm256_set1_ps(c));
    let s = wr.shear();
    let (sx, sy, sz) = (
        _mm256_set1_ps(s.x),
        _mm256_set1_ps(s.y),
        _mm256_set1_ps(s.z),
    );
    let lanes = |v: usize, axis: usize| -> __m256 {
        _mm256_set_m128(b.p[v][axis].into(), a.p[v][axis].into())
    };
    let (sub, mul, add) = (_mm256_sub_ps, _mm256_mul_ps, _mm256_add_ps);
    let az = sub(lanes(0, kz), oz);
    let bz = sub(lanes(1, kz), oz);
    let cz = sub(lanes(2, kz), oz);
    let ax = add(sub(lanes(0, kx), ox), mul(sx, az));
    let ay = add(sub(lanes(0, ky), oy), mul(sy, az));
    let bx = add(sub(lanes(1, kx), ox), mul(sx, bz));
    let by = add(sub(lanes(1, ky), oy), mul(sy, bz));
    let cx = add(sub(lanes(2, kx), ox), mul(sx, cz));
    let cy = add(sub(lanes(2, ky), oy), mul(sy, cz));
    let e0 = sub(mul(bx, cy), mul(by, cx));
    let e1 = sub(mul(cx, ay), mul(cy, ax));
    let e2 = sub(mul(ax, by), mul(ay, bx));
    let zero = _mm256_setzero_ps();
    let (or, and) = (_mm256_or_ps, _mm256_and_ps);
    // As in `TriangleBlock::intersect`: the lanes strictly inside, and the scalar test
    // where a lane is inside but on an edge (see the module docs).
    let (min, max) = (_mm256_min_ps, _mm256_max_ps);
    let (e_min, e_max) = (min(min(e0, e1), e2), max(max(e0, e1), e2));
    let mut valid = or(
        _mm256_cmp_ps::<_CMP_GT_OQ>(e_min, zero),
        _mm256_cmp_ps::<_CMP_LT_OQ>(e_max, zero),
    );
    let inside = or(
        _mm256_cmp_ps::<_CMP_GE_OQ>(e_min, zero),
        _mm256_cmp_ps::<_CMP_LE_OQ>(e_max, zero),
    );
    if _mm256_movemask_ps(inside) != _mm256_movemask_ps(valid) {
        return pair_by_blocks(a, b, wr, t_min, t_max);
    }
    let det = add(add(e0, e1), e2);
    let none = PairHits::miss();
    // No early return where every lane failed the edge test: for incoherent rays that is
    // a coin toss the branch predictor loses, and the distance test below costs less
    // than its misses. The return after the distance test stays: it skips a division
    // and the error bounds, and mostly goes one way (measured 7% faster with it).
    let (az, bz, cz) = (mul(az, sz), mul(bz, sz), mul(cz, sz));
    let t_scaled = add(add(mul(e0, az), mul(e1, bz)), mul(e2, cz));
    // As in `TriangleBlock::intersect`: `t_min·|det| < ±t_scaled <= t_max·|det|`.
    let sign = _mm256_set1_ps(-0.0);
    let abs = |x| _mm256_andnot_ps(sign, x);
    let abs_det = abs(det);
    let lo = mul(_mm256_set1_ps(t_min), abs_det);
    let hi = mul(_mm256_set1_ps(t_max), abs_det);
    let t_signed = _mm256_xor_ps(t_scaled, and(det, sign));
    valid = and(
        valid,
        and(
            _mm256_cmp_ps::<_CMP_GT_OQ>(t_signed, lo),
            _mm256_cmp_ps::<_CMP_LE_OQ>(t_signed, hi),
        ),
    );
    if _mm256_movemask_ps(valid) == 0 {
        return none;
    }
    let inv_det = _mm256_div_ps(_mm256_set1_ps(1.0), det);
    let t = mul(t_scaled, inv_det);
    let max_zt = max(max(abs(az), abs(bz)), abs(cz));
    let delta_z = mul(_mm256_set1_ps(gamma(3)), max_zt);
    let max_xt = max(max(abs(ax), abs(bx)), abs(cx));
    let max_yt = max(max(abs(ay), abs(by)), abs(cy));
    // The unscaled `z` bound and `γ7` as in `mesh::delta_t`.
    let max_zu = mul(max_zt, _mm256_set1_ps(wr.dz_abs()));
    let g7 = _mm256_set1_ps(gamma(7));
    let delta_x = mul(g7, add(max_xt, max_zu));
    let delta_y = mul(g7, add(max_yt, max_zu));
    let delta_e = mul(
        _mm256_set1_ps(2.0),
        add(
            add(
                mul(mul(_mm256_set1_ps(gamma(2)), max_xt), max_yt),
                mul(delta_y, max_xt),
            ),
            mul(delta_x, max_yt),
        ),
    );
    let max_e = max(max(abs(e0), abs(e1)), abs(e2));
    let delta_t = mul(
        mul(
            _mm256_set1_ps(3.0),
            add(
                add(
                    mul(mul(_mm256_set1_ps(gamma(3)), max_e), max_zt),
                    mul(delta_e, max_zt),
                ),
                mul(delta_z, max_e),
            ),
        ),
        abs(inv_det),
    );
    valid = and(valid, _mm256_cmp_ps::<_CMP_GT_OQ>(t, delta_t));
    PairHits::new(
        _mm256_movemask_ps(valid) as u32,
        Lanes8(t),
        Lanes8(mul(e1, inv_det)),
        Lanes8(mul(e2, inv_det)),
    )
}

/// [`intersect_pair_avx2`]'s rare case, one block at a time: out of line, so that the
/// common path need not keep its loaded vertices for it.
#[cold]
#[inline(never)]
fn pair_by_blocks(
    a: &TriangleBlock,
    b: &TriangleBlock,
    wr: &WatertightRay,
    t_min: f32,
    t_max: f32,
) -> PairHits {
    let (ba, ta, ua, va) = a.intersect(wr, t_min, t_max);
    let (bb, tb, ub, vb) = b.intersect(wr, t_min, t_max);
    let join = |x: Vec4, y: Vec4| {
        let mut out = [0.0; 8];
        out[..4].copy_from_slice(&x.to_array());
        out[4..].copy_from_slice(&y.to_array());
        Lanes8::from_array(out)
    };
    PairHits::new(ba | bb << 4, join(ta, tb), join(ua, ub), join(va, vb))
}

/// The nearest of the lanes in `bits` (the lowest lane among equal distances).
#[inline(always)]
pub fn nearest_lane<T: std::ops::Index<usize, Output = f32> + ?Sized>(bits: u32, t: &T) -> usize {
    let mut best = bits.trailing_zeros() as usize;
    let mut rest = bits & (bits - 1);
    while rest != 0 {
        let lane = rest.trailing_zeros() as usize;
        if t[lane] < t[best] {
            best = lane;
        }
        rest &= rest - 1;
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Ray;
    use crate::sampling::Pcg32;

    /// Every lane equals the scalar watertight test bit for bit, on random triangles,
    /// triangles sharing edges with the ray's axis, degenerate triangles and random rays
    /// with limited ranges.
    #[test]
    fn lanes_equal_the_scalar_test() {
        let mut rng = Pcg32::new(5, 11);
        let v = |rng: &mut Pcg32| {
            Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE
        };
        let mut hits = 0;
        for i in 0..20000 {
            let mut tris = [[Vec3::ZERO; 3]; 4];
            for tri in tris.iter_mut() {
                *tri = [v(&mut rng), v(&mut rng), v(&mut rng)];
            }
            if i % 7 == 0 {
                tris[1][2] = tris[1][1]; // degenerate: a segment
            }
            if i % 11 == 0 {
                tris[2] = [Vec3::ZERO, Vec3::X, Vec3::Y]; // edges on the axes
            }
            let block = TriangleBlock::new(tris, [0, 1, 2, 3]);
            let o = v(&mut rng) * 2.0;
            // Mostly aimed at one of the triangles, so that many lanes hit.
            let aim = tris[i % 4];
            let mut d = (aim[0] + aim[1] + aim[2]) / 3.0 + v(&mut rng) * 0.2 - o;
            if i % 5 == 0 {
                d = [Vec3::Z, Vec3::NEG_X, Vec3::Y][i % 3];
            }
            let ray = Ray::with_range(o, d, rng.next_f32() * 0.2, 0.5 + rng.next_f32() * 3.0);
            let wr = WatertightRay::new(&ray);
            let (bits, t, b1, b2) = block.intersect(&wr, ray.t_min, ray.t_max);
            for (lane, tri) in tris.iter().enumerate() {
                let scalar = intersect_triangle_watertight(
                    &wr, ray.t_min, ray.t_max, tri[0], tri[1], tri[2],
                );
                match scalar {
                    Some((ts, _, u, w)) => {
                        hits += 1;
                        assert!(bits & (1 << lane) != 0, "ray {i} lane {lane}: missed");
                        assert_eq!(
                            (t[lane].to_bits(), b1[lane].to_bits(), b2[lane].to_bits()),
                            (ts.to_bits(), u.to_bits(), w.to_bits()),
                            "ray {i} lane {lane}"
                        );
                    }
                    None => assert!(bits & (1 << lane) == 0, "ray {i} lane {lane}: false hit"),
                }
            }
        }
        assert!(hits > 10000, "only {hits} hits: the test is too weak");
    }

    /// Two blocks tested as eight AVX2 lanes equal the two 4-lane tests bit for bit,
    /// including blocks that take the scalar fallback.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_pairs_equal_two_blocks() {
        if !crate::cpu::has_avx2() {
            return;
        }
        let mut rng = Pcg32::new(8, 2);
        let v = |rng: &mut Pcg32| {
            Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE
        };
        let mut hits = 0;
        for i in 0..20000 {
            let mut tris = [[Vec3::ZERO; 3]; 8];
            for tri in tris.iter_mut() {
                *tri = [v(&mut rng), v(&mut rng), v(&mut rng)];
            }
            if i % 13 == 0 {
                tris[5] = [Vec3::ZERO, Vec3::X, Vec3::Y]; // edges on the axes
            }
            let a = TriangleBlock::new([tris[0], tris[1], tris[2], tris[3]], [0, 1, 2, 3]);
            let b = TriangleBlock::new([tris[4], tris[5], tris[6], tris[7]], [4, 5, 6, 7]);
            let o = v(&mut rng) * 2.0;
            let aim = tris[i % 8];
            let mut d = (aim[0] + aim[1] + aim[2]) / 3.0 + v(&mut rng) * 0.2 - o;
            if i % 5 == 0 {
                d = [Vec3::Z, Vec3::NEG_X, Vec3::Y][i % 3];
            }
            let ray = Ray::with_range(o, d, rng.next_f32() * 0.2, 0.5 + rng.next_f32() * 3.0);
            let wr = WatertightRay::new(&ray);
            // SAFETY: the AVX2 tier was detected above.
            let pair = unsafe { intersect_pair_avx2(&a, &b, &wr, ray.t_min, ray.t_max) };
            let bits = pair.bits();
            for (half, block) in [a, b].iter().enumerate() {
                let (bb, tb, ub, vb) = block.intersect(&wr, ray.t_min, ray.t_max);
                assert_eq!((bits >> (4 * half)) & 0xf, bb, "ray {i} half {half}");
                for lane in 0..4 {
                    if bb & (1 << lane) != 0 {
                        hits += 1;
                        let k = 4 * half + lane;
                        let [t, b1, b2] = pair.lanes().expect("a lane hits");
                        assert_eq!(
                            (t[k].to_bits(), b1[k].to_bits(), b2[k].to_bits()),
                            (tb[lane].to_bits(), ub[lane].to_bits(), vb[lane].to_bits()),
                            "ray {i} lane {k}"
                        );
                    }
                }
            }
        }
        assert!(hits > 10000, "only {hits} hits: the test is too weak");
    }

    #[test]
    fn nearest_lane_takes_the_smallest_distance() {
        let t = Vec4::new(3.0, 1.0, 2.0, 1.0);
        assert_eq!(nearest_lane(0b1111, &t), 1);
        assert_eq!(nearest_lane(0b0101, &t), 2);
        assert_eq!(nearest_lane(0b1000, &t), 3);
    }
}
