//! A low-discrepancy sampler: the padded (0,2)-sequence. Every pair of dimensions takes
//! the first two dimensions of the Sobol sequence (van der Corput and its (0,2) partner),
//! with the pixel's sample indices shuffled by a hashed permutation per dimension pair
//! (Kensler 2013) and the points Owen-scrambled by the hash-based nested uniform scramble
//! of Burley (2020). The result is stratified in every 2D projection a path tracer uses,
//! decorrelated between pixels and dimensions, and still a pure function of
//! (pixel, sample index, seed). Sample counts that are powers of two stratify best.
//!
//! The sampler computes sixteen dimensions at a time, each lane of a vector register one
//! dimension (one AVX-512 register, or two AVX2 ones, where the processor has them);
//! the values are those of the one-dimension-at-a-time definition, bit for bit. The
//! per-dimension seeds depend only on the pixel, so they are hashed at a pixel's first
//! sample and kept for its others.
//!
//! ```xml
//! <sampler type="sobol" count="64"/>
//! ```

use super::mix_bits;
use glam::{UVec2, Vec2};

#[derive(Debug, Clone)]
pub struct SobolSampler {
    pub samples_per_pixel: u32,
    pub seed: u64,
    pixel_hash: u64,
    index: u32,
    /// The first dimension of the next batch.
    dimension: u32,
    /// Position in the current batch of the next draw (`BATCH`: none left).
    next: usize,
    xs: [f32; BATCH],
    ys: [f32; BATCH],
    /// The seeds of the current pixel's first batches, in order (see [`BatchSeeds`]).
    kept: Vec<BatchSeeds>,
    /// The pixel hash and sample count `kept` belong to.
    kept_pixel_hash: u64,
    kept_count: u32,
    lanes: Lanes,
}

/// 1 - ε in f32: the largest value below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// The second Sobol dimension (primitive polynomial x + 1): direction numbers
/// v_k = v_{k-1} ⊕ (v_{k-1} >> 1), v_0 = 2^31. The value is linear over GF(2) in the bits
/// of `i`, so it is the XOR of one table entry per byte of `i`.
#[cfg(test)]
fn sobol_dim1(i: u32) -> u32 {
    let t = &SOBOL_DIM1_BYTES;
    if i < 256 {
        return t[0][i as usize];
    }
    t[0][(i & 0xff) as usize]
        ^ t[1][((i >> 8) & 0xff) as usize]
        ^ t[2][((i >> 16) & 0xff) as usize]
        ^ t[3][(i >> 24) as usize]
}

/// `SOBOL_DIM1_BYTES[b][x]`: the second dimension's value of `x << (8 b)`.
#[cfg(test)]
static SOBOL_DIM1_BYTES: [[u32; 256]; 4] = sobol_dim1_tables();

/// [`sobol_dim1`] with its bits reversed, the form the scramble takes: reversal is linear
/// over GF(2) too, so this is the XOR of reversed table entries.
#[cfg(test)]
fn sobol_dim1_reversed(i: u32) -> u32 {
    let t = &SOBOL_DIM1_REVERSED_BYTES;
    t[0][(i & 0xff) as usize]
        ^ t[1][((i >> 8) & 0xff) as usize]
        ^ t[2][((i >> 16) & 0xff) as usize]
        ^ t[3][(i >> 24) as usize]
}

#[cfg(test)]
static SOBOL_DIM1_REVERSED_BYTES: [[u32; 256]; 4] = {
    let mut t = sobol_dim1_tables();
    let mut b = 0;
    while b < 4 {
        let mut x = 0;
        while x < 256 {
            t[b][x] = t[b][x].reverse_bits();
            x += 1;
        }
        b += 1;
    }
    t
};

/// The second Sobol dimension by its definition, one bit of `i` at a time.
#[cfg(test)]
const fn sobol_dim1_bitwise(mut i: u32) -> u32 {
    let mut v = 1u32 << 31;
    let mut x = 0u32;
    while i != 0 {
        if i & 1 != 0 {
            x ^= v;
        }
        i >>= 1;
        v ^= v >> 1;
    }
    x
}

#[cfg(test)]
const fn sobol_dim1_tables() -> [[u32; 256]; 4] {
    let mut t = [[0u32; 256]; 4];
    let mut b = 0;
    while b < 4 {
        let mut x = 0;
        while x < 256 {
            t[b][x] = sobol_dim1_bitwise((x as u32) << (8 * b));
            x += 1;
        }
        b += 1;
    }
    t
}

/// Burley's hash-based Owen scramble of a 32-bit fixed-point value.
#[cfg(test)]
fn owen_scramble(v: u32, seed: u32) -> u32 {
    owen_scramble_reversed(v.reverse_bits(), seed)
}

/// [`owen_scramble`] of the value whose bits, reversed, are `x` (the van der Corput
/// value of `i` is `i` reversed, so its scramble starts from `i` itself).
#[inline]
pub(super) fn owen_scramble_reversed(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x.reverse_bits()
}

/// Element `i` of a pseudo-random permutation of 0..n chosen by `p` (Kensler,
/// "Correlated Multi-Jittered Sampling", 2013): cycle-walking a hashed bijection.
pub(super) fn permutation_element(mut i: u32, n: u32, p: u32) -> u32 {
    let w = bit_mask(n);
    loop {
        i = permutation_round(i, w, p);
        if i < n {
            break;
        }
    }
    finish_permutation(i, n, p)
}

#[inline]
fn to_unit(x: u32) -> f32 {
    (x as f32 * (1.0 / 4_294_967_296.0)).min(ONE_MINUS_EPSILON)
}

/// Bit `j` of the second dimension's value, reversed, is the parity of the bits of `i` at
/// the positions `k ⊇ j` (its generator matrix is Pascal's triangle mod 2, and by Lucas's
/// theorem `C(k, j)` is odd exactly when `j ⊆ k`): a superset-sum transform in five
/// shift-and-XOR steps, which vectorises where [`sobol_dim1_reversed`]'s tables do not.
#[inline(always)]
fn sobol_dim1_reversed_alu(i: u32) -> u32 {
    let mut y = i;
    y ^= (y >> 1) & 0x5555_5555;
    y ^= (y >> 2) & 0x3333_3333;
    y ^= (y >> 4) & 0x0f0f_0f0f;
    y ^= (y >> 8) & 0x00ff_00ff;
    y ^= (y >> 16) & 0x0000_ffff;
    y
}

/// One round of [`permutation_element`]'s cycle walk, for the mask `w` of `n`'s bits.
#[inline(always)]
fn permutation_round(mut i: u32, w: u32, p: u32) -> u32 {
    i ^= p;
    i = i.wrapping_mul(0xe170_893d);
    i ^= p >> 16;
    i ^= (i & w) >> 4;
    i ^= p >> 8;
    i = i.wrapping_mul(0x0929_eb3f);
    i ^= p >> 23;
    i ^= (i & w) >> 1;
    i = i.wrapping_mul(1 | p >> 27);
    i = i.wrapping_mul(0x6935_fa69);
    i ^= (i & w) >> 11;
    i = i.wrapping_mul(0x74dc_b303);
    i ^= (i & w) >> 2;
    i = i.wrapping_mul(0x9e50_1cc3);
    i ^= (i & w) >> 2;
    i = i.wrapping_mul(0xc860_a3df);
    i &= w;
    i ^= i >> 5;
    i
}

/// Draws computed together: the sampler fills this many dimensions at once.
const BATCH: usize = 16;

/// Where a batch starts: the pixel's hash, the batch's first dimension, the sample index
/// and the sample count.
#[derive(Debug, Clone, Copy)]
struct BatchStart {
    pixel_hash: u64,
    dim0: u32,
    index: u32,
    n: u32,
}

/// The seeds of a batch's dimensions, lane by lane: of the index permutation and of the x
/// and y scrambles. They depend on the pixel and the dimension but not on the sample
/// index, so the sampler keeps them for the samples of a pixel after the first.
#[derive(Debug, Clone, Copy, Default)]
struct BatchSeeds {
    permutation: [u32; BATCH],
    /// `permutation` modulo the sample count.
    permutation_mod: [u32; BATCH],
    x: [u32; BATCH],
    y: [u32; BATCH],
}

/// Batches of seeds a sampler keeps per pixel (at most this many dimensions are drawn
/// from kept seeds; deeper ones are hashed again at every sample).
const KEPT_BATCHES: usize = 32;

/// The points of dimensions `dim0 .. dim0 + BATCH` of sample `index` (out of `n`) for the
/// pixel hashed to `pixel_hash`, as x and y coordinates: the same values as the scalar
/// definition ([`SobolSampler::point`]), written as straight-line loops over the lanes so
/// that the compiler computes the lanes together in vector registers. `seeds` are the
/// batch's ([`batch_seeds`]).
#[inline(always)]
fn fill_lanes(at: BatchStart, seeds: &BatchSeeds, xs: &mut [f32; BATCH], ys: &mut [f32; BATCH]) {
    let BatchStart { index, n, .. } = at;
    let p = &seeds.permutation;
    let mut idx = [index; BATCH];
    if index < n {
        let w = bit_mask(n);
        for k in 0..BATCH {
            idx[k] = permutation_round(index, w, p[k]);
        }
        // The lanes stay in vector registers on the usual path (a count that is a power of
        // two); the per-lane loops of the other counts are out of line, so that they do
        // not make the compiler keep `idx` in memory.
        if n.is_power_of_two() {
            for k in 0..BATCH {
                idx[k] = idx[k].wrapping_add(p[k]) & (n - 1);
            }
        } else {
            finish_lanes_not_power_of_two(&mut idx, n, w, p);
        }
    }
    for k in 0..BATCH {
        let i = idx[k];
        xs[k] = to_unit(owen_scramble_reversed(i, seeds.x[k]));
        ys[k] = to_unit(owen_scramble_reversed(
            sobol_dim1_reversed_alu(i),
            seeds.y[k],
        ));
    }
}

/// The end of [`fill_lanes`]'s permutation for counts that are not powers of two: cycle
/// walking (rounds until the index is below `n`), then [`finish_permutation`].
#[inline(never)]
fn finish_lanes_not_power_of_two(idx: &mut [u32; BATCH], n: u32, w: u32, p: &[u32; BATCH]) {
    for k in 0..BATCH {
        while idx[k] >= n {
            idx[k] = permutation_round(idx[k], w, p[k]);
        }
        idx[k] = finish_permutation(idx[k], n, p[k]);
    }
}

/// The seeds of the batch of dimensions `dim0 .. dim0 + BATCH` of the pixel hashed to
/// `pixel_hash`, for `n` samples, written as a straight-line loop over the lanes for the
/// vector units.
#[inline(always)]
fn batch_seeds(pixel_hash: u64, dim0: u32, n: u32, seeds: &mut BatchSeeds) {
    for k in 0..BATCH {
        let h = dimension_hash(pixel_hash, dim0 + k as u32);
        seeds.permutation[k] = h as u32;
        seeds.x[k] = (h >> 32) as u32;
        seeds.y[k] = mix_bits(h) as u32;
    }
    for k in 0..BATCH {
        let p = seeds.permutation[k];
        // (A count of 0, only possible by setting the public field, draws no shuffled
        // index, so its residue is never used.)
        seeds.permutation_mod[k] = if n.is_power_of_two() {
            p & (n - 1)
        } else {
            p.checked_rem(n).unwrap_or(p)
        };
    }
}

/// [`batch_seeds`] and [`fill_lanes`] compiled for a set of processor features (used only
/// where the processor has them).
macro_rules! lanes_for {
    ($(#[$doc:meta])* $seeds:ident, $fill:ident, $features:literal) => {
        $(#[$doc])*
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        unsafe fn $seeds(pixel_hash: u64, dim0: u32, n: u32, seeds: &mut BatchSeeds) {
            batch_seeds(pixel_hash, dim0, n, seeds)
        }
        $(#[$doc])*
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        unsafe fn $fill(
            at: BatchStart,
            seeds: &BatchSeeds,
            xs: &mut [f32; BATCH],
            ys: &mut [f32; BATCH],
        ) {
            fill_lanes(at, seeds, xs, ys)
        }
    };
}

lanes_for!(
    /// Eight 32-bit lanes per instruction.
    batch_seeds_avx2,
    fill_lanes_avx2,
    "avx2"
);
lanes_for!(
    /// With native 64-bit lane multiplies (AVX-512DQ), as the two 64-bit hashes per lane
    /// want.
    batch_seeds_avx512,
    fill_lanes_avx512,
    "avx2,avx512f,avx512dq,avx512vl"
);

/// The vector units [`SobolSampler::refill`] may use, found once per sampler.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
enum Lanes {
    Avx512,
    Avx2,
    Portable,
}

impl Lanes {
    fn detect() -> Lanes {
        #[cfg(target_arch = "x86_64")]
        {
            use crate::cpu::{allowed, SimdTier};
            if allowed(SimdTier::Avx512)
                && std::arch::is_x86_feature_detected!("avx512dq")
                && std::arch::is_x86_feature_detected!("avx512vl")
                && std::arch::is_x86_feature_detected!("avx512bw")
            {
                return Lanes::Avx512;
            }
            if allowed(SimdTier::Avx2) && std::arch::is_x86_feature_detected!("avx2") {
                return Lanes::Avx2;
            }
        }
        Lanes::Portable
    }
}

/// Byte indices that reverse the bytes of each 32-bit lane (per 128-bit half, as
/// `_mm256_shuffle_epi8` indexes).
#[cfg(target_arch = "x86_64")]
const BYTES_REVERSED: [u8; 32] = {
    let mut t = [0u8; 32];
    let mut i = 0;
    while i < 32 {
        t[i] = (i as u8 & !3) % 16 + 3 - (i as u8 & 3);
        i += 1;
    }
    t
};

/// Each nibble value with its 4 bits reversed, shifted left by `shift` (twice, one per
/// 128-bit half, as `_mm256_shuffle_epi8` indexes).
#[cfg(target_arch = "x86_64")]
const fn nibbles_reversed(shift: u32) -> [u8; 32] {
    let mut t = [0u8; 32];
    let mut i = 0;
    while i < 32 {
        t[i] = ((i as u8 & 15) << 4).reverse_bits() << shift;
        i += 1;
    }
    t
}

/// Reversed nibbles in the low half of a byte.
#[cfg(target_arch = "x86_64")]
const NIBBLES_REVERSED: [u8; 32] = nibbles_reversed(0);

/// Reversed nibbles in the high half of a byte.
#[cfg(target_arch = "x86_64")]
const NIBBLES_REVERSED_HIGH: [u8; 32] = nibbles_reversed(4);

/// Counts up to this take [`fill_lanes_explicit_avx2`] (twice the count fits a signed
/// 32-bit lane).
#[cfg(target_arch = "x86_64")]
const EXPLICIT_MAX_COUNT: u32 = 1 << 30;

/// [`fill_lanes`] for a sample index below the count (up to [`EXPLICIT_MAX_COUNT`]) in
/// explicit AVX2 intrinsics: the lanes stay in vector registers throughout (the
/// compiler's vectorisation of the loops spills them between steps, and cannot vectorise
/// the cycle walk or the remainder). Same values, bit for bit: every step is the same
/// 32-bit integer operation per lane, the remainder is exact integer arithmetic, and the
/// final conversion to `f32` rounds once, as `as f32` does.
///
/// # Safety
/// The processor must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn fill_lanes_explicit_avx2(
    index: u32,
    n: u32,
    seeds: &BatchSeeds,
    xs: &mut [f32; BATCH],
    ys: &mut [f32; BATCH],
) {
    for first in (0..BATCH).step_by(8) {
        // SAFETY: the caller guarantees AVX2.
        unsafe { fill_eight_explicit_avx2(index, n, seeds, first, xs, ys) };
    }
}

/// Lanes `first .. first + 8` of [`fill_lanes_explicit_avx2`].
///
/// # Safety
/// The processor must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn fill_eight_explicit_avx2(
    index: u32,
    n: u32,
    seeds: &BatchSeeds,
    first: usize,
    xs: &mut [f32; BATCH],
    ys: &mut [f32; BATCH],
) {
    use std::arch::x86_64::*;
    debug_assert!(index < n && n <= EXPLICIT_MAX_COUNT);
    debug_assert!(first + 8 <= BATCH);
    let splat = |x: u32| _mm256_set1_epi32(x as i32);
    let load = |a: &[u32; BATCH]| {
        // SAFETY: `a` holds eight u32 from `first` (unaligned load).
        unsafe { _mm256_loadu_si256(a[first..].as_ptr() as *const __m256i) }
    };
    let (xor, and, or) = (_mm256_xor_si256, _mm256_and_si256, _mm256_or_si256);
    let mul = _mm256_mullo_epi32;
    let p = load(&seeds.permutation);
    let w = splat(bit_mask(n));
    // permutation_round(i, w, p), lane by lane.
    let round = |mut i: __m256i| -> __m256i {
        i = xor(i, p);
        i = mul(i, splat(0xe170_893d));
        i = xor(i, _mm256_srli_epi32::<16>(p));
        i = xor(i, _mm256_srli_epi32::<4>(and(i, w)));
        i = xor(i, _mm256_srli_epi32::<8>(p));
        i = mul(i, splat(0x0929_eb3f));
        i = xor(i, _mm256_srli_epi32::<23>(p));
        i = xor(i, _mm256_srli_epi32::<1>(and(i, w)));
        i = mul(i, or(splat(1), _mm256_srli_epi32::<27>(p)));
        i = mul(i, splat(0x6935_fa69));
        i = xor(i, _mm256_srli_epi32::<11>(and(i, w)));
        i = mul(i, splat(0x74dc_b303));
        i = xor(i, _mm256_srli_epi32::<2>(and(i, w)));
        i = mul(i, splat(0x9e50_1cc3));
        i = xor(i, _mm256_srli_epi32::<2>(and(i, w)));
        i = mul(i, splat(0xc860_a3df));
        i = and(i, w);
        xor(i, _mm256_srli_epi32::<5>(i))
    };
    let mut i = round(splat(index));
    let i = if n.is_power_of_two() {
        // finish_permutation: (i + p) mod n. With n a power of two, `w` is n - 1 and
        // every round's result is below n, so there is no cycle walking.
        and(_mm256_add_epi32(i, p), splat(n - 1))
    } else {
        // Cycle walking: another round for the lanes at or above n (all values are at
        // most `w` < 2n <= 2^31, so signed comparisons order them).
        let last = splat(n - 1);
        loop {
            let above = _mm256_cmpgt_epi32(i, last);
            if _mm256_testz_si256(above, above) != 0 {
                break;
            }
            i = _mm256_blendv_epi8(i, round(i), above);
        }
        // finish_permutation: ((i + p) mod 2^32) mod n, which is congruent to
        // i + (p mod n) - (2^32 mod n if i + p wrapped) and lies in (-n, 2n).
        let j = _mm256_add_epi32(i, p);
        let wrapped = xor(
            _mm256_cmpeq_epi32(_mm256_max_epu32(j, p), j),
            _mm256_set1_epi32(-1),
        );
        let wrap = ((1u64 << 32) % n as u64) as u32;
        let mut v = _mm256_add_epi32(i, load(&seeds.permutation_mod));
        v = _mm256_sub_epi32(v, and(wrapped, splat(wrap)));
        let zero = _mm256_setzero_si256();
        v = _mm256_add_epi32(v, and(_mm256_cmpgt_epi32(zero, v), splat(n)));
        _mm256_sub_epi32(v, and(_mm256_cmpgt_epi32(v, last), splat(n)))
    };
    // sobol_dim1_reversed_alu(i).
    let mut d = i;
    d = xor(d, and(_mm256_srli_epi32::<1>(d), splat(0x5555_5555)));
    d = xor(d, and(_mm256_srli_epi32::<2>(d), splat(0x3333_3333)));
    d = xor(d, and(_mm256_srli_epi32::<4>(d), splat(0x0f0f_0f0f)));
    d = xor(d, and(_mm256_srli_epi32::<8>(d), splat(0x00ff_00ff)));
    d = xor(d, and(_mm256_srli_epi32::<16>(d), splat(0x0000_ffff)));
    // owen_scramble_reversed(x, seed): the hash, then the bits reversed.
    let owen = |x: __m256i, seed: __m256i| -> __m256i {
        let mut x = _mm256_add_epi32(x, seed);
        x = xor(x, mul(x, splat(0x6c50_b47c)));
        x = xor(x, mul(x, splat(0xb82f_1e52)));
        x = xor(x, mul(x, splat(0xc7af_e638)));
        x = xor(x, mul(x, splat(0x8d22_f6e6)));
        // Reverse the bytes of each lane, then the bits of each byte (a nibble table).
        let table = |t: &[u8; 32]| {
            // SAFETY: `t` holds 32 bytes (unaligned load).
            unsafe { _mm256_loadu_si256(t.as_ptr() as *const __m256i) }
        };
        x = _mm256_shuffle_epi8(x, table(&BYTES_REVERSED));
        let low_nibbles = _mm256_set1_epi8(0x0f);
        let (hi, lo) = (table(&NIBBLES_REVERSED_HIGH), table(&NIBBLES_REVERSED));
        let low = _mm256_shuffle_epi8(hi, and(x, low_nibbles));
        let high = _mm256_shuffle_epi8(lo, and(_mm256_srli_epi16::<4>(x), low_nibbles));
        or(low, high)
    };
    // to_unit: u32 to f32 rounded once (high and low 16 bits as exact floats, then one
    // rounding add), scaled by 2^-32 (exact) and kept below 1.
    let to_unit = |x: __m256i| -> __m256 {
        let low = _mm256_blend_epi16::<0xaa>(x, splat(0x4b00_0000));
        let high = _mm256_blend_epi16::<0xaa>(_mm256_srli_epi32::<16>(x), splat(0x5300_0000));
        let high = _mm256_sub_ps(
            _mm256_castsi256_ps(high),
            _mm256_set1_ps(f32::from_bits(0x5300_0080)),
        );
        let f = _mm256_add_ps(high, _mm256_castsi256_ps(low));
        _mm256_min_ps(
            _mm256_mul_ps(f, _mm256_set1_ps(1.0 / 4_294_967_296.0)),
            _mm256_set1_ps(ONE_MINUS_EPSILON),
        )
    };
    let x = to_unit(owen(i, load(&seeds.x)));
    let y = to_unit(owen(d, load(&seeds.y)));
    // SAFETY: `xs` and `ys` hold eight f32 each from `first` (unaligned stores).
    unsafe {
        _mm256_storeu_ps(xs[first..].as_mut_ptr(), x);
        _mm256_storeu_ps(ys[first..].as_mut_ptr(), y);
    }
}

/// [`fill_lanes_explicit_avx2`] with sixteen lanes in AVX-512 registers (F, BW, DQ): a
/// whole batch per instruction, comparisons into mask registers. The same operations per
/// lane, so the same values bit for bit.
///
/// # Safety
/// The processor must support AVX-512 F, BW, DQ and VL.
#[cfg(all(target_arch = "x86_64", lightpath_avx512))]
#[allow(clippy::incompatible_msrv)]
#[target_feature(enable = "avx2,avx512f,avx512bw,avx512dq,avx512vl")]
unsafe fn fill_lanes_explicit_avx512(
    index: u32,
    n: u32,
    seeds: &BatchSeeds,
    xs: &mut [f32; BATCH],
    ys: &mut [f32; BATCH],
) {
    use std::arch::x86_64::*;
    debug_assert!(index < n && n <= EXPLICIT_MAX_COUNT);
    const { assert!(BATCH == 16) };
    let splat = |x: u32| _mm512_set1_epi32(x as i32);
    let load = |a: &[u32; BATCH]| {
        // SAFETY: `a` holds sixteen u32 (unaligned load).
        unsafe { _mm512_loadu_si512(a.as_ptr() as *const _) }
    };
    let (xor, and, or) = (_mm512_xor_si512, _mm512_and_si512, _mm512_or_si512);
    let mul = _mm512_mullo_epi32;
    let p = load(&seeds.permutation);
    let w = splat(bit_mask(n));
    // permutation_round(i, w, p), lane by lane.
    let round = |mut i: __m512i| -> __m512i {
        i = xor(i, p);
        i = mul(i, splat(0xe170_893d));
        i = xor(i, _mm512_srli_epi32::<16>(p));
        i = xor(i, _mm512_srli_epi32::<4>(and(i, w)));
        i = xor(i, _mm512_srli_epi32::<8>(p));
        i = mul(i, splat(0x0929_eb3f));
        i = xor(i, _mm512_srli_epi32::<23>(p));
        i = xor(i, _mm512_srli_epi32::<1>(and(i, w)));
        i = mul(i, or(splat(1), _mm512_srli_epi32::<27>(p)));
        i = mul(i, splat(0x6935_fa69));
        i = xor(i, _mm512_srli_epi32::<11>(and(i, w)));
        i = mul(i, splat(0x74dc_b303));
        i = xor(i, _mm512_srli_epi32::<2>(and(i, w)));
        i = mul(i, splat(0x9e50_1cc3));
        i = xor(i, _mm512_srli_epi32::<2>(and(i, w)));
        i = mul(i, splat(0xc860_a3df));
        i = and(i, w);
        xor(i, _mm512_srli_epi32::<5>(i))
    };
    let mut i = round(splat(index));
    let i = if n.is_power_of_two() {
        // finish_permutation: (i + p) mod n, a mask (see the AVX2 version).
        and(_mm512_add_epi32(i, p), splat(n - 1))
    } else {
        // Cycle walking, then finish_permutation, as in the AVX2 version.
        let last = splat(n - 1);
        loop {
            let above = _mm512_cmpgt_epi32_mask(i, last);
            if above == 0 {
                break;
            }
            i = _mm512_mask_blend_epi32(above, i, round(i));
        }
        let j = _mm512_add_epi32(i, p);
        // i + p wrapped around 2^32 where the sum is below p (unsigned).
        let wrapped = _mm512_cmplt_epu32_mask(j, p);
        let wrap = ((1u64 << 32) % n as u64) as u32;
        let mut v = _mm512_add_epi32(i, load(&seeds.permutation_mod));
        v = _mm512_sub_epi32(v, _mm512_maskz_mov_epi32(wrapped, splat(wrap)));
        let zero = _mm512_setzero_si512();
        let negative = _mm512_cmpgt_epi32_mask(zero, v);
        v = _mm512_add_epi32(v, _mm512_maskz_mov_epi32(negative, splat(n)));
        let past = _mm512_cmpgt_epi32_mask(v, last);
        _mm512_sub_epi32(v, _mm512_maskz_mov_epi32(past, splat(n)))
    };
    // sobol_dim1_reversed_alu(i).
    let mut d = i;
    d = xor(d, and(_mm512_srli_epi32::<1>(d), splat(0x5555_5555)));
    d = xor(d, and(_mm512_srli_epi32::<2>(d), splat(0x3333_3333)));
    d = xor(d, and(_mm512_srli_epi32::<4>(d), splat(0x0f0f_0f0f)));
    d = xor(d, and(_mm512_srli_epi32::<8>(d), splat(0x00ff_00ff)));
    d = xor(d, and(_mm512_srli_epi32::<16>(d), splat(0x0000_ffff)));
    // The byte tables index within each 128-bit quarter: the 32-byte AVX2 tables, twice.
    let table = |t: &[u8; 32]| {
        // SAFETY: `t` holds 32 bytes (unaligned load).
        _mm512_broadcast_i64x4(unsafe { _mm256_loadu_si256(t.as_ptr() as *const __m256i) })
    };
    let (bytes_reversed, nibbles_high, nibbles) = (
        table(&BYTES_REVERSED),
        table(&NIBBLES_REVERSED_HIGH),
        table(&NIBBLES_REVERSED),
    );
    // owen_scramble_reversed(x, seed): the hash, then the bits reversed.
    let owen = |x: __m512i, seed: __m512i| -> __m512i {
        let mut x = _mm512_add_epi32(x, seed);
        x = xor(x, mul(x, splat(0x6c50_b47c)));
        x = xor(x, mul(x, splat(0xb82f_1e52)));
        x = xor(x, mul(x, splat(0xc7af_e638)));
        x = xor(x, mul(x, splat(0x8d22_f6e6)));
        x = _mm512_shuffle_epi8(x, bytes_reversed);
        let low_nibbles = _mm512_set1_epi8(0x0f);
        let low = _mm512_shuffle_epi8(nibbles_high, and(x, low_nibbles));
        let high = _mm512_shuffle_epi8(nibbles, and(_mm512_srli_epi16::<4>(x), low_nibbles));
        or(low, high)
    };
    // to_unit, as in the AVX2 version: the odd 16-bit halves replaced by exponents.
    let odd = 0xaaaa_aaaa;
    let to_unit = |x: __m512i| -> __m512 {
        let low = _mm512_mask_blend_epi16(odd, x, splat(0x4b00_0000));
        let high = _mm512_mask_blend_epi16(odd, _mm512_srli_epi32::<16>(x), splat(0x5300_0000));
        let high = _mm512_sub_ps(
            _mm512_castsi512_ps(high),
            _mm512_set1_ps(f32::from_bits(0x5300_0080)),
        );
        let f = _mm512_add_ps(high, _mm512_castsi512_ps(low));
        _mm512_min_ps(
            _mm512_mul_ps(f, _mm512_set1_ps(1.0 / 4_294_967_296.0)),
            _mm512_set1_ps(ONE_MINUS_EPSILON),
        )
    };
    let x = to_unit(owen(i, load(&seeds.x)));
    let y = to_unit(owen(d, load(&seeds.y)));
    // SAFETY: `xs` and `ys` hold sixteen f32 each (unaligned stores).
    unsafe {
        _mm512_storeu_ps(xs.as_mut_ptr(), x);
        _mm512_storeu_ps(ys.as_mut_ptr(), y);
    }
}

/// The hash of one dimension of a pixel: seeds of its permutation (low 32 bits) and of the
/// x scramble (high 32 bits); `mix_bits` of it seeds the y scramble.
#[inline(always)]
fn dimension_hash(pixel_hash: u64, dimension: u32) -> u64 {
    mix_bits(pixel_hash ^ (dimension as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// All ones up to `n - 1`'s highest bit.
#[inline(always)]
fn bit_mask(n: u32) -> u32 {
    let mut w = n - 1;
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    w
}

/// The end of [`permutation_element`] after its cycle walk.
#[inline(always)]
fn finish_permutation(i: u32, n: u32, p: u32) -> u32 {
    let j = i.wrapping_add(p);
    // The usual sample counts are powers of two: a mask instead of a division.
    if n.is_power_of_two() {
        j & (n - 1)
    } else {
        j % n
    }
}

impl SobolSampler {
    pub fn new(samples_per_pixel: u32, seed: u64) -> Self {
        SobolSampler {
            samples_per_pixel: samples_per_pixel.max(1),
            seed,
            pixel_hash: 0,
            index: 0,
            dimension: 0,
            next: BATCH,
            xs: [0.0; BATCH],
            ys: [0.0; BATCH],
            kept: Vec::new(),
            kept_pixel_hash: 0,
            kept_count: 0,
            lanes: Lanes::detect(),
        }
    }

    #[inline]
    pub fn start_pixel_sample(&mut self, pixel: UVec2, index: u32) {
        self.pixel_hash =
            mix_bits(((pixel.x as u64) << 32) ^ pixel.y as u64 ^ mix_bits(self.seed ^ 0x5EED));
        self.index = index;
        self.dimension = 0;
        self.next = BATCH;
        if self.pixel_hash != self.kept_pixel_hash || self.samples_per_pixel != self.kept_count {
            // Pixel hashes are distinct for distinct pixels (an injective map of (x, y)
            // through the bijection `mix_bits`), so kept seeds are never a wrong pixel's.
            self.kept.clear();
            self.kept_pixel_hash = self.pixel_hash;
            self.kept_count = self.samples_per_pixel;
        }
    }

    /// The 2D point of `dimension` for the current pixel and sample index, by definition
    /// (one dimension at a time); the sampler draws the same values in batches.
    #[cfg(test)]
    fn point(&self, dimension: u32) -> Vec2 {
        let h = dimension_hash(self.pixel_hash, dimension);
        let i = if self.index < self.samples_per_pixel {
            permutation_element(self.index, self.samples_per_pixel, h as u32)
        } else {
            // Past the declared count (progressive rendering): no shuffle.
            self.index
        };
        Vec2::new(
            to_unit(owen_scramble_reversed(i, (h >> 32) as u32)),
            to_unit(owen_scramble_reversed(
                sobol_dim1_reversed(i),
                mix_bits(h) as u32,
            )),
        )
    }

    /// The batch position of the next dimension, computing a new batch when the last one
    /// is used up.
    #[inline]
    fn advance(&mut self) -> usize {
        if self.next == BATCH {
            self.refill();
        }
        let k = self.next;
        self.next += 1;
        k
    }

    #[inline(never)]
    fn refill(&mut self) {
        let at = BatchStart {
            pixel_hash: self.pixel_hash,
            dim0: self.dimension,
            index: self.index,
            n: self.samples_per_pixel,
        };
        self.dimension += BATCH as u32;
        self.next = 0;
        // Dimensions are drawn in order from 0 at every sample, so batch `b` is either
        // kept already or the next one to keep.
        let batch = (at.dim0 / BATCH as u32) as usize;
        let mut scratch = BatchSeeds::default();
        let (seeds, known) = if batch < self.kept.len() {
            (&mut self.kept[batch], true)
        } else if batch == self.kept.len() && batch < KEPT_BATCHES {
            self.kept.push(BatchSeeds::default());
            (&mut self.kept[batch], false)
        } else {
            (&mut scratch, false)
        };
        let (xs, ys) = (&mut self.xs, &mut self.ys);
        match self.lanes {
            #[cfg(target_arch = "x86_64")]
            Lanes::Avx512 | Lanes::Avx2 => {
                if !known {
                    if self.lanes == Lanes::Avx512 {
                        // SAFETY: the processor supports AVX-512 F, DQ and VL (detected in
                        // `Lanes::detect`; DQ and VL imply F).
                        unsafe { batch_seeds_avx512(at.pixel_hash, at.dim0, at.n, seeds) };
                    } else {
                        // SAFETY: the processor supports AVX2 (detected in `Lanes::detect`).
                        unsafe { batch_seeds_avx2(at.pixel_hash, at.dim0, at.n, seeds) };
                    }
                }
                let explicit = at.index < at.n && at.n <= EXPLICIT_MAX_COUNT;
                #[cfg(lightpath_avx512)]
                if explicit && self.lanes == Lanes::Avx512 {
                    // SAFETY: the processor supports AVX-512 F, BW, DQ and VL (detected
                    // in `Lanes::detect`).
                    unsafe { fill_lanes_explicit_avx512(at.index, at.n, seeds, xs, ys) };
                    return;
                }
                if explicit {
                    // SAFETY: every AVX-512 processor has AVX2 (and so does `Lanes::Avx2`).
                    unsafe { fill_lanes_explicit_avx2(at.index, at.n, seeds, xs, ys) };
                } else if self.lanes == Lanes::Avx512 {
                    // SAFETY: as for `batch_seeds_avx512` above.
                    unsafe { fill_lanes_avx512(at, seeds, xs, ys) };
                } else {
                    // SAFETY: as for `batch_seeds_avx2` above.
                    unsafe { fill_lanes_avx2(at, seeds, xs, ys) };
                }
            }
            _ => {
                if !known {
                    batch_seeds(at.pixel_hash, at.dim0, at.n, seeds);
                }
                fill_lanes(at, seeds, xs, ys);
            }
        }
    }

    /// One dimension: the x coordinate of that dimension's 2D point.
    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        let k = self.advance();
        self.xs[k]
    }

    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        let k = self.advance();
        Vec2::new(self.xs[k], self.ys[k])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reversed_forms_equal_the_definitions() {
        let mut rng = crate::sampling::Pcg32::new(5, 7);
        for k in 0..10_000u32 {
            let i = if k < 4096 { k } else { rng.next_u32() };
            let seed = rng.next_u32();
            assert_eq!(sobol_dim1_reversed(i), sobol_dim1(i).reverse_bits(), "{i}");
            assert_eq!(
                owen_scramble_reversed(sobol_dim1_reversed(i), seed),
                owen_scramble(sobol_dim1(i), seed)
            );
            assert_eq!(
                owen_scramble_reversed(i, seed),
                owen_scramble(i.reverse_bits(), seed)
            );
        }
    }

    #[test]
    fn dim1_tables_equal_the_definition() {
        let mut rng = crate::sampling::Pcg32::new(2, 3);
        let special = [0u32, 1, 255, 256, 65535, 65536, u32::MAX];
        for i in special
            .into_iter()
            .chain((0..100_000).map(|_| rng.next_u32()))
        {
            assert_eq!(sobol_dim1(i), sobol_dim1_bitwise(i), "{i}");
        }
        for i in 0..4096 {
            assert_eq!(sobol_dim1(i), sobol_dim1_bitwise(i), "{i}");
        }
    }

    #[test]
    fn superset_parity_equals_the_tables() {
        let mut rng = crate::sampling::Pcg32::new(9, 4);
        for k in 0..100_000u32 {
            let i = if k < 65_536 { k } else { rng.next_u32() };
            assert_eq!(sobol_dim1_reversed_alu(i), sobol_dim1_reversed(i), "{i}");
        }
        assert_eq!(
            sobol_dim1_reversed_alu(u32::MAX),
            sobol_dim1_reversed(u32::MAX)
        );
    }

    /// The batched draws (vector code where the processor has AVX2, the portable loops
    /// elsewhere) are the definition's values, bit for bit, for 1D and 2D draws in any
    /// order, counts that are and are not powers of two, and indices past the count.
    #[test]
    fn batched_draws_equal_the_definition() {
        let mut rng = crate::sampling::Pcg32::new(3, 8);
        for spp in [1u32, 3, 16, 64, 100, 1024] {
            let mut s = SobolSampler::new(spp, 17);
            for _ in 0..200 {
                let pixel = UVec2::new(rng.next_u32() % 512, rng.next_u32() % 512);
                let index = rng.next_u32() % (spp * 2);
                s.start_pixel_sample(pixel, index);
                let mut reference = s.clone();
                reference.start_pixel_sample(pixel, index);
                for dim in 0..40 {
                    let want = reference.point(dim);
                    if rng.next_u32() % 3 == 0 {
                        assert_eq!(s.next_1d().to_bits(), want.x.to_bits(), "{spp} {dim}");
                    } else {
                        let got = s.next_2d();
                        assert_eq!(got.x.to_bits(), want.x.to_bits(), "{spp} {dim}");
                        assert_eq!(got.y.to_bits(), want.y.to_bits(), "{spp} {dim}");
                    }
                }
            }
        }
        // Every variant the processor can run, whichever the sampler picks.
        let mut variants = vec![Lanes::Portable];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                variants.push(Lanes::Avx2);
            }
            if std::arch::is_x86_feature_detected!("avx512dq")
                && std::arch::is_x86_feature_detected!("avx512vl")
                && std::arch::is_x86_feature_detected!("avx512bw")
            {
                variants.push(Lanes::Avx512);
            }
        }
        for lanes in variants {
            for spp in [1u32, 2, 3, 31, 64, 100, 1 << 20] {
                let mut s = SobolSampler::new(spp, 5);
                s.lanes = lanes;
                for _ in 0..50 {
                    let pixel = UVec2::new(rng.next_u32() % 64, rng.next_u32() % 64);
                    let index = match rng.next_u32() % 4 {
                        0 => spp - 1,
                        1 => spp + rng.next_u32() % 8,
                        _ => rng.next_u32() % spp,
                    };
                    for _ in 0..2 {
                        // The second time from kept seeds.
                        s.start_pixel_sample(pixel, index);
                        let reference = s.clone();
                        for dim in 0..24 {
                            let want = reference.point(dim);
                            let got = s.next_2d();
                            assert_eq!(
                                (got.x.to_bits(), got.y.to_bits()),
                                (want.x.to_bits(), want.y.to_bits()),
                                "{lanes:?} {spp} {index} {dim}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// The explicit-intrinsics path equals the portable lanes on arbitrary seeds, for
    /// counts that are and are not powers of two (up to its limit), indices spread over
    /// them, and permutation seeds that make `index + seed` wrap around 2^32.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn explicit_lanes_equal_the_portable_ones() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut rng = crate::sampling::Pcg32::new(21, 6);
        let mut counts: Vec<u32> = (0..=30).map(|k| 1u32 << k).collect();
        counts.extend([
            3,
            5,
            7,
            31,
            33,
            63,
            100,
            1000,
            65_537,
            (1 << 30) - 1,
            (1 << 29) + 3,
        ]);
        counts.extend((0..40).map(|_| 2 + rng.next_u32() % (1 << 30)));
        for n in counts {
            for _ in 0..200 {
                let mut seeds = BatchSeeds::default();
                for k in 0..BATCH {
                    let p = if rng.next_u32() % 4 == 0 {
                        u32::MAX - rng.next_u32() % n.min(64)
                    } else {
                        rng.next_u32()
                    };
                    seeds.permutation[k] = p;
                    seeds.permutation_mod[k] = p % n;
                    seeds.x[k] = rng.next_u32();
                    seeds.y[k] = rng.next_u32();
                }
                let index = match rng.next_u32() % 4 {
                    0 => n - 1,
                    1 => 0,
                    _ => rng.next_u32() % n,
                };
                let at = BatchStart {
                    pixel_hash: 0,
                    dim0: 0,
                    index,
                    n,
                };
                let (mut xs, mut ys) = ([0.0; BATCH], [0.0; BATCH]);
                fill_lanes(at, &seeds, &mut xs, &mut ys);
                let (mut vx, mut vy) = ([0.0; BATCH], [0.0; BATCH]);
                // SAFETY: AVX2 is available (checked above).
                unsafe { fill_lanes_explicit_avx2(index, n, &seeds, &mut vx, &mut vy) };
                assert_eq!(
                    (xs.map(f32::to_bits), ys.map(f32::to_bits)),
                    (vx.map(f32::to_bits), vy.map(f32::to_bits)),
                    "n {n} index {index}"
                );
                #[cfg(lightpath_avx512)]
                if Lanes::detect() == Lanes::Avx512 {
                    let (mut wx, mut wy) = ([0.0; BATCH], [0.0; BATCH]);
                    // SAFETY: AVX-512 F, BW, DQ and VL are available (detected).
                    unsafe { fill_lanes_explicit_avx512(index, n, &seeds, &mut wx, &mut wy) };
                    assert_eq!(
                        (xs.map(f32::to_bits), ys.map(f32::to_bits)),
                        (wx.map(f32::to_bits), wy.map(f32::to_bits)),
                        "AVX-512: n {n} index {index}"
                    );
                }
            }
        }
    }

    /// Seeds kept across the samples of a pixel give the definition's values: samples
    /// drawing different numbers of dimensions (so the kept batches grow between samples),
    /// past the kept limit, and pixels revisited after others.
    #[test]
    fn kept_seeds_equal_the_definition() {
        let mut rng = crate::sampling::Pcg32::new(11, 2);
        let mut s = SobolSampler::new(16, 9);
        let limit = (KEPT_BATCHES * BATCH) as u32 + 20;
        for pixel in [(1, 2), (5, 0), (1, 2), (1, 3)] {
            let pixel = UVec2::new(pixel.0, pixel.1);
            for index in 0..20 {
                s.start_pixel_sample(pixel, index);
                let reference = s.clone();
                let dims = match index {
                    0 => 3,
                    1 => limit,
                    _ => rng.next_u32() % limit,
                };
                for dim in 0..dims {
                    let want = reference.point(dim);
                    let got = s.next_2d();
                    assert_eq!(got.x.to_bits(), want.x.to_bits(), "{pixel} {index} {dim}");
                    assert_eq!(got.y.to_bits(), want.y.to_bits(), "{pixel} {index} {dim}");
                }
            }
            assert_eq!(s.kept.len(), KEPT_BATCHES);
            // Seeds for another count are not reused.
            s.samples_per_pixel = if s.samples_per_pixel == 16 { 15 } else { 16 };
        }
        // A count of 0 (the field is public) draws unshuffled indices, without panicking.
        s.samples_per_pixel = 0;
        s.start_pixel_sample(UVec2::new(2, 2), 3);
        let reference = s.clone();
        for dim in 0..20 {
            let (got, want) = (s.next_2d(), reference.point(dim));
            assert_eq!(
                (got.x.to_bits(), got.y.to_bits()),
                (want.x.to_bits(), want.y.to_bits())
            );
        }
    }

    #[test]
    fn permutation_is_a_bijection() {
        for n in [1u32, 2, 3, 7, 16, 100, 1000] {
            for p in [0u32, 1, 0xdead_beef, 12345] {
                let mut seen = vec![false; n as usize];
                for i in 0..n {
                    let j = permutation_element(i, n, p);
                    assert!(j < n);
                    assert!(!seen[j as usize], "n={n} p={p}: {j} twice");
                    seen[j as usize] = true;
                }
            }
        }
    }

    /// The first 2^k points of every 2D dimension pair are a (0,2)-net: each of the 2^k
    /// elementary intervals of every shape (2^a × 2^(k-a)) holds exactly one point.
    #[test]
    fn each_dimension_pair_is_a_0_2_net() {
        let k = 6u32;
        let n = 1u32 << k;
        let mut s = SobolSampler::new(n, 3);
        for dim in 0..5 {
            let points: Vec<Vec2> = (0..n)
                .map(|i| {
                    s.start_pixel_sample(UVec2::new(7, 11), i);
                    for _ in 0..dim {
                        s.next_2d();
                    }
                    s.next_2d()
                })
                .collect();
            for a in 0..=k {
                let (nx, ny) = (1u32 << a, 1u32 << (k - a));
                let mut count = vec![0u32; n as usize];
                for p in &points {
                    let cx = ((p.x * nx as f32) as u32).min(nx - 1);
                    let cy = ((p.y * ny as f32) as u32).min(ny - 1);
                    count[(cy * nx + cx) as usize] += 1;
                }
                assert!(
                    count.iter().all(|&c| c == 1),
                    "dimension pair {dim}, intervals {nx}x{ny}"
                );
            }
        }
    }

    /// Low discrepancy pays: the error of integrating a smooth function is far below the
    /// independent sampler's at the same count, and the mean over many pixels is unbiased.
    #[test]
    fn integrates_better_than_random_and_unbiased() {
        let f = |p: Vec2| (p.x * 3.0).sin() * (p.y * 2.0).cos() + p.x * p.y;
        // ∫∫ sin(3x) cos(2y) + xy over [0,1]² in closed form.
        let exact = ((1.0 - 3.0f64.cos()) / 3.0) * (2.0f64.sin() / 2.0) + 0.25;
        let n = 256u32;
        let mut sobol = SobolSampler::new(n, 1);
        let mut indep = super::super::IndependentSampler::new(n, 1);
        let (mut es, mut ei, mut mean) = (0.0f64, 0.0f64, 0.0f64);
        let pixels = 64;
        for px in 0..pixels {
            let (mut a, mut b) = (0.0f64, 0.0f64);
            for i in 0..n {
                sobol.start_pixel_sample(UVec2::new(px, 0), i);
                sobol.next_1d();
                a += f(sobol.next_2d()) as f64;
                indep.start_pixel_sample(UVec2::new(px, 0), i);
                indep.next_1d();
                b += f(indep.next_2d()) as f64;
            }
            let (a, b) = (a / n as f64, b / n as f64);
            es += (a - exact).powi(2);
            ei += (b - exact).powi(2);
            mean += a;
        }
        let (rmse_s, rmse_i) = ((es / pixels as f64).sqrt(), (ei / pixels as f64).sqrt());
        assert!(
            rmse_s < rmse_i * 0.2,
            "sobol {rmse_s} vs independent {rmse_i}"
        );
        assert!((mean / pixels as f64 - exact).abs() < 1e-3);
    }
}
