//! The independent sampler: uniform random numbers from PCG32, one stream per
//! (pixel, sample index, seed).
//!
//! ```xml
//! <sampler type="independent" count="64"/>
//! ```

use super::{mix_bits, JumpMap, Pcg32};
use glam::{UVec2, Vec2};

#[derive(Debug, Clone)]
pub struct IndependentSampler {
    pub samples_per_pixel: u32,
    pub seed: u64,
    rng: Pcg32,
    /// The stream's state at the start of the current sample, and that sample's pixel
    /// and index: the next index of the same pixel is one jump away.
    sample_start: Option<(Pcg32, UVec2, u32)>,
}

/// How far apart the streams of consecutive sample indices start.
const SAMPLE_STRIDE: u64 = 1 << 16;
const NEXT_SAMPLE: JumpMap = Pcg32::jump_map(SAMPLE_STRIDE);
/// `SAMPLE_JUMPS[k]` skips `2^k` samples: the start of sample `index` is one jump per
/// set bit of `index` away from the stream's start.
const SAMPLE_JUMPS: [JumpMap; 32] = {
    let mut jumps = [NEXT_SAMPLE; 32];
    let mut k = 1;
    while k < 32 {
        jumps[k] = Pcg32::jump_map(SAMPLE_STRIDE << k);
        k += 1;
    }
    jumps
};

impl IndependentSampler {
    pub fn new(samples_per_pixel: u32, seed: u64) -> Self {
        IndependentSampler {
            samples_per_pixel,
            seed,
            rng: Pcg32::new(seed, 0),
            sample_start: None,
        }
    }

    /// Restarts the stream for sample `index` of `pixel`: the stream is chosen by the
    /// pixel and seed, and the sample index skips far ahead in it, so no two
    /// (pixel, sample) pairs share numbers. The sample after the previous one of the same
    /// pixel (the renderer's order) is reached by one precomputed jump.
    #[inline]
    pub fn start_pixel_sample(&mut self, pixel: UVec2, index: u32) {
        match self.sample_start {
            Some((mut rng, p, i)) if p == pixel && index.checked_sub(1) == Some(i) => {
                rng.jump(NEXT_SAMPLE);
                self.rng = rng;
            }
            _ => {
                let pixel_hash =
                    mix_bits(((pixel.x as u64) << 32) ^ pixel.y as u64 ^ mix_bits(self.seed));
                self.rng = Pcg32::new(pixel_hash, mix_bits(pixel_hash ^ self.seed.rotate_left(17)));
                // `advance(index * SAMPLE_STRIDE)`, in one jump per set bit of `index`.
                let mut bits = index;
                while bits != 0 {
                    self.rng.jump(SAMPLE_JUMPS[bits.trailing_zeros() as usize]);
                    bits &= bits - 1;
                }
            }
        }
        self.sample_start = Some((self.rng, pixel, index));
    }

    /// The stream the sampler draws from (for code that draws its numbers itself).
    #[inline(always)]
    pub(crate) fn rng_mut(&mut self) -> &mut Pcg32 {
        &mut self.rng
    }

    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        self.rng.next_f32()
    }

    /// The next `N` (at most 8) numbers of [`IndependentSampler::next_1d`] at once.
    #[inline(always)]
    pub fn next_1ds<const N: usize>(&mut self) -> [f32; N] {
        self.rng.next_f32s()
    }

    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        let x = self.rng.next_f32();
        let y = self.rng.next_f32();
        Vec2::new(x, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pure_function_of_pixel_index_seed() {
        let mut a = IndependentSampler::new(4, 9);
        let mut b = IndependentSampler::new(4, 9);
        b.start_pixel_sample(UVec2::new(1, 1), 0);
        b.next_2d();
        a.start_pixel_sample(UVec2::new(3, 5), 2);
        b.start_pixel_sample(UVec2::new(3, 5), 2);
        assert_eq!(a.next_2d(), b.next_2d());
        a.start_pixel_sample(UVec2::new(3, 5), 3);
        b.start_pixel_sample(UVec2::new(5, 3), 3);
        assert_ne!(a.next_1d(), b.next_1d());
        let mut c = IndependentSampler::new(4, 10);
        c.start_pixel_sample(UVec2::new(3, 5), 3);
        a.start_pixel_sample(UVec2::new(3, 5), 3);
        assert_ne!(a.next_1d(), c.next_1d());
    }

    /// The jump table starts every sample where the plain skip ahead does.
    #[test]
    fn jumps_equal_advance() {
        let mut a = IndependentSampler::new(8, 3);
        for index in [0, 1, 2, 3, 63, 64, 1000, 65535, 1 << 20, u32::MAX] {
            let pixel = UVec2::new(index % 7, 2);
            a.start_pixel_sample(UVec2::new(99, 99), 0); // not the previous sample
            a.start_pixel_sample(pixel, index);
            let pixel_hash = mix_bits(((pixel.x as u64) << 32) ^ pixel.y as u64 ^ mix_bits(3));
            let mut b = Pcg32::new(pixel_hash, mix_bits(pixel_hash ^ 3u64.rotate_left(17)));
            b.advance(index as u64 * SAMPLE_STRIDE);
            for _ in 0..3 {
                assert_eq!(
                    a.next_1d().to_bits(),
                    b.next_f32().to_bits(),
                    "index {index}"
                );
            }
        }
    }

    /// Sample indices taken in order (jumping from the previous sample) give the same
    /// numbers as each index started on its own.
    #[test]
    fn consecutive_samples_equal_fresh_starts() {
        let mut a = IndependentSampler::new(8, 3);
        for pixel in [UVec2::new(1, 2), UVec2::new(7, 0)] {
            for index in 0..8 {
                a.start_pixel_sample(pixel, index);
                let mut fresh = IndependentSampler::new(8, 3);
                fresh.start_pixel_sample(pixel, index);
                for _ in 0..5 {
                    assert_eq!(a.next_1d().to_bits(), fresh.next_1d().to_bits());
                }
            }
        }
    }
}
