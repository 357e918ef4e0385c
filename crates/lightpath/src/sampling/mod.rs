//! Random numbers and warps: PCG32, the per-pixel seeded samplers, and the maps from the
//! unit square to disks, polygons, spheres and hemispheres with their densities.

mod distribution;
mod halton;
mod independent;
mod pcg32;
mod sobol;
pub mod warp;

pub use distribution::{Distribution1D, Distribution2D};
pub use halton::HaltonSampler;
pub use independent::IndependentSampler;
pub use pcg32::{JumpMap, Pcg32};
pub use sobol::SobolSampler;

use glam::{UVec2, Vec2};

/// A sampler: a stream of numbers in [0, 1) that is a pure function of
/// (pixel, sample index, seed), so images are bit-identical for any thread count.
///
/// ```xml
/// <sampler type="independent" count="64"/>
/// <sampler type="sobol" count="64"/>
/// <sampler type="halton" count="36"/>
/// ```
///
/// The low-discrepancy samplers' state (a batch of points, Halton's digit table) is
/// boxed: the path tracer keeps a sampler per path in flight (a tile's 256), and the
/// enum at the independent sampler's size keeps those close together in the cache.
#[derive(Debug, Clone)]
pub enum Sampler {
    Independent(IndependentSampler),
    Sobol(Box<SobolSampler>),
    Halton(Box<HaltonSampler>),
}

impl Sampler {
    /// The independent sampler's stream (`None` for other samplers), for code that
    /// draws its numbers itself.
    #[inline(always)]
    pub(crate) fn independent_rng(&mut self) -> Option<&mut Pcg32> {
        match self {
            Sampler::Independent(s) => Some(s.rng_mut()),
            _ => None,
        }
    }

    /// Samples per pixel.
    pub fn samples_per_pixel(&self) -> u32 {
        match self {
            Sampler::Independent(s) => s.samples_per_pixel,
            Sampler::Sobol(s) => s.samples_per_pixel,
            Sampler::Halton(s) => s.samples_per_pixel,
        }
    }

    /// The seed.
    pub fn seed(&self) -> u64 {
        match self {
            Sampler::Independent(s) => s.seed,
            Sampler::Sobol(s) => s.seed,
            Sampler::Halton(s) => s.seed,
        }
    }

    /// Positions the sampler at sample `index` of `pixel`.
    #[inline]
    pub fn start_pixel_sample(&mut self, pixel: UVec2, index: u32) {
        match self {
            Sampler::Independent(s) => s.start_pixel_sample(pixel, index),
            Sampler::Sobol(s) => s.start_pixel_sample(pixel, index),
            Sampler::Halton(s) => s.start_pixel_sample(pixel, index),
        }
    }

    #[inline(always)]
    pub fn next_1d(&mut self) -> f32 {
        match self {
            Sampler::Independent(s) => s.next_1d(),
            Sampler::Sobol(s) => s.next_1d(),
            Sampler::Halton(s) => s.next_1d(),
        }
    }

    #[inline(always)]
    pub fn next_2d(&mut self) -> Vec2 {
        match self {
            Sampler::Independent(s) => s.next_2d(),
            Sampler::Sobol(s) => s.next_2d(),
            Sampler::Halton(s) => s.next_2d(),
        }
    }

    /// A copy with another sample count (e.g. `--spp` overriding the scene).
    pub fn with_samples_per_pixel(&self, spp: u32) -> Sampler {
        match self {
            Sampler::Independent(s) => Sampler::Independent(IndependentSampler::new(spp, s.seed)),
            Sampler::Sobol(s) => Sampler::Sobol(Box::new(SobolSampler::new(spp, s.seed))),
            Sampler::Halton(s) => Sampler::Halton(Box::new(HaltonSampler::new(spp, s.seed))),
        }
    }

    /// A copy with another seed.
    pub fn with_seed(&self, seed: u64) -> Sampler {
        match self {
            Sampler::Independent(s) => {
                Sampler::Independent(IndependentSampler::new(s.samples_per_pixel, seed))
            }
            Sampler::Sobol(s) => {
                Sampler::Sobol(Box::new(SobolSampler::new(s.samples_per_pixel, seed)))
            }
            Sampler::Halton(s) => {
                Sampler::Halton(Box::new(HaltonSampler::new(s.samples_per_pixel, seed)))
            }
        }
    }

    /// The sampler kinds [`Sampler::with_kind`] knows.
    pub const KINDS: &'static [&'static str] = &["independent", "sobol", "halton"];

    /// The same count and seed with another kind: `independent`, `sobol` or `halton`.
    pub fn with_kind(&self, kind: &str) -> Option<Sampler> {
        let (spp, seed) = match self {
            Sampler::Independent(s) => (s.samples_per_pixel, s.seed),
            Sampler::Sobol(s) => (s.samples_per_pixel, s.seed),
            Sampler::Halton(s) => (s.samples_per_pixel, s.seed),
        };
        match kind {
            "independent" => Some(Sampler::Independent(IndependentSampler::new(spp, seed))),
            "sobol" => Some(Sampler::Sobol(Box::new(SobolSampler::new(spp, seed)))),
            "halton" => Some(Sampler::Halton(Box::new(HaltonSampler::new(spp, seed)))),
            _ => None,
        }
    }
}

/// Mixes 64-bit values into a well-distributed hash (MurmurHash3's finaliser over a
/// running combination), used to seed per-pixel streams.
#[inline]
pub fn mix_bits(mut v: u64) -> u64 {
    v ^= v >> 31;
    v = v.wrapping_mul(0x7fb5_d329_728e_a185);
    v ^= v >> 27;
    v = v.wrapping_mul(0x81da_def4_bc2d_d44d);
    v ^= v >> 33;
    v
}
