//! PCG32 (O'Neill 2014): a small, fast, statistically strong generator with
//! 2^63 selectable streams.

/// The PCG-XSH-RR 64/32 generator.
#[derive(Debug, Clone, Copy)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

const MULTIPLIER: u64 = 0x5851_f42d_4c95_7f2d;

impl Pcg32 {
    /// A generator on stream `stream` started from `seed`.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Pcg32 {
            state: 0,
            inc: (stream << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULTIPLIER).wrapping_add(self.inc);
        output(old)
    }

    /// A float uniformly in [0, 1): 24 random mantissa bits, never 1.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        unit_f32(self.next_u32())
    }

    /// Skips `delta` steps ahead in O(log delta) (Brown 1994).
    /// The next `N` numbers of [`Pcg32::next_f32`], in order, with the state moved on
    /// by `N`: each output's state is one jump from the current state, so the `N`
    /// products run side by side instead of one after another (the same numbers).
    #[inline(always)]
    pub fn next_f32s<const N: usize>(&mut self) -> [f32; N] {
        const { assert!(N < JUMPS.len(), "at most 8 numbers at once") };
        let (old, inc) = (self.state, self.inc);
        let out = std::array::from_fn(|k| unit_f32(output(JUMPS[k].apply(old, inc))));
        self.state = JUMPS[N].apply(old, inc);
        out
    }

    /// The state and the stream's increment, for code that draws the numbers of many
    /// streams at once ([`Pcg32::draw`]).
    #[inline(always)]
    pub(crate) fn parts(&self) -> (u64, u64) {
        (self.state, self.inc)
    }

    /// Moves the generator to `state` (of its own stream), as [`Pcg32::parts`] left
    /// code that drew its numbers.
    #[inline(always)]
    pub(crate) fn set_state(&mut self, state: u64) {
        self.state = state;
    }

    /// The float that [`Pcg32::next_f32`] gives after `k` numbers (`k` at most 8) of a
    /// generator of `state` and increment `inc`: one jump and the output, for code that
    /// draws the numbers of many streams at once.
    #[inline(always)]
    pub(crate) fn draw(k: usize, state: u64, inc: u64) -> f32 {
        unit_f32(output(JUMPS[k].apply(state, inc)))
    }

    /// The state `k` numbers (at most 8) on from `state` in the stream of `inc`.
    #[inline(always)]
    pub(crate) fn state_after(k: usize, state: u64, inc: u64) -> u64 {
        JUMPS[k].apply(state, inc)
    }

    pub fn advance(&mut self, delta: u64) {
        let (acc_mult, acc_plus) = advance_map(delta, self.inc);
        self.state = acc_mult.wrapping_mul(self.state).wrapping_add(acc_plus);
    }

    /// Skips ahead by the `delta` of `Pcg32::jump_map(delta)`, in O(1): the same state as
    /// `advance(delta)`.
    #[inline]
    pub fn jump(&mut self, map: JumpMap) {
        self.state = map.apply(self.state, self.inc);
    }

    /// What `advance(delta)` does to the state of any stream, for [`Pcg32::jump`].
    pub const fn jump_map(delta: u64) -> JumpMap {
        // The added constant is linear in the stream's increment: compute it for 1.
        let (mult, plus_per_inc) = advance_map(delta, 1);
        JumpMap { mult, plus_per_inc }
    }
}

/// The PCG output permutation (XSH RR) of a state.
#[inline(always)]
fn output(state: u64) -> u32 {
    let xorshifted = (((state >> 18) ^ state) >> 27) as u32;
    xorshifted.rotate_right((state >> 59) as u32)
}

/// The float in [0, 1) of an output: its top 24 bits.
#[inline(always)]
fn unit_f32(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// `JUMPS[k]` moves a state on by `k` steps (for [`Pcg32::next_f32s`]).
const JUMPS: [JumpMap; 9] = {
    let mut jumps = [JumpMap {
        mult: 1,
        plus_per_inc: 0,
    }; 9];
    let mut k = 1;
    while k < 9 {
        jumps[k] = Pcg32::jump_map(k as u64);
        k += 1;
    }
    jumps
};

/// A precomputed skip ahead: `advance(delta)` as state ↦ mult·state + plus_per_inc·inc.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct JumpMap {
    mult: u64,
    plus_per_inc: u64,
}

impl JumpMap {
    /// The state it moves `state` to in the stream of increment `inc`.
    #[inline(always)]
    fn apply(&self, state: u64, inc: u64) -> u64 {
        self.mult
            .wrapping_mul(state)
            .wrapping_add(self.plus_per_inc.wrapping_mul(inc))
    }
}

/// The affine map state ↦ mult·state + plus of `delta` steps of the stream with
/// increment `inc`.
const fn advance_map(mut delta: u64, inc: u64) -> (u64, u64) {
    let (mut cur_mult, mut cur_plus) = (MULTIPLIER, inc);
    let (mut acc_mult, mut acc_plus) = (1u64, 0u64);
    while delta > 0 {
        if delta & 1 == 1 {
            acc_mult = acc_mult.wrapping_mul(cur_mult);
            acc_plus = acc_plus.wrapping_mul(cur_mult).wrapping_add(cur_plus);
        }
        cur_plus = cur_mult.wrapping_add(1).wrapping_mul(cur_plus);
        cur_mult = cur_mult.wrapping_mul(cur_mult);
        delta >>= 1;
    }
    (acc_mult, acc_plus)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `next_f32s` gives the numbers of `N` calls of `next_f32`, and leaves the state
    /// where they leave it.
    #[test]
    fn batched_numbers_equal_one_by_one() {
        fn check<const N: usize>(seed: u64, stream: u64) {
            let mut one = Pcg32::new(seed, stream);
            let mut batch = one;
            let want: [f32; N] = std::array::from_fn(|_| one.next_f32());
            assert_eq!(batch.next_f32s::<N>(), want, "N = {N}");
            assert_eq!(batch.next_u32(), one.next_u32(), "N = {N}");
        }
        for (seed, stream) in [(0, 0), (42, 54), (u64::MAX, 7), (0x9e37_79b9, 1 << 62)] {
            check::<1>(seed, stream);
            check::<2>(seed, stream);
            check::<3>(seed, stream);
            check::<7>(seed, stream);
            check::<8>(seed, stream);
        }
    }

    #[test]
    fn matches_reference_sequence() {
        // The reference output of pcg32-demo (seed 42, stream 54).
        let mut rng = Pcg32::new(42, 54);
        let expected = [
            0xa15c02b7u32,
            0x7b47f409,
            0xba1d3330,
            0x83d2f293,
            0xbfa4784b,
            0xcbed606e,
        ];
        for e in expected {
            assert_eq!(rng.next_u32(), e);
        }
    }

    #[test]
    fn advance_skips_ahead() {
        let mut a = Pcg32::new(7, 3);
        let mut b = a;
        for _ in 0..1000 {
            a.next_u32();
        }
        b.advance(1000);
        assert_eq!(a.next_u32(), b.next_u32());
    }

    #[test]
    fn jump_equals_advance() {
        for (seed, stream, delta) in [(7u64, 3u64, 1u64 << 16), (1, 99, 12345), (5, 1 << 40, 1)] {
            let map = Pcg32::jump_map(delta);
            let mut a = Pcg32::new(seed, stream);
            let mut b = a;
            for _ in 0..3 {
                a.advance(delta);
                b.jump(map);
                assert_eq!(a.next_u32(), b.next_u32());
            }
        }
    }

    #[test]
    fn floats_are_in_unit_interval_and_uniform() {
        let mut rng = Pcg32::new(1, 1);
        let n = 100_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let x = rng.next_f32();
            assert!((0.0..1.0).contains(&x));
            sum += x as f64;
        }
        let mean = sum / n as f64;
        // Standard error of the mean is 1/sqrt(12 n) ≈ 0.0009; allow 5 sigma.
        assert!((mean - 0.5).abs() < 0.0046, "mean {mean}");
    }
}
