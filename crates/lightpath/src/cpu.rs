//! The processor's vector instruction tiers, detected at run time. The hot loops
//! (triangle tests, traversals, the BVH build, the path tracer's tile) are compiled a
//! second time for a tier with `#[target_feature]` and entered only where the
//! processor has it; elsewhere they run as baseline x86-64 (SSE2) code.
//!
//! - **AVX2**: `avx2,fma,bmi1,bmi2,lzcnt,popcnt`. Every processor with AVX2 has the
//!   other five (Intel since Haswell, AMD since Excavator), and naming them lets the
//!   compiler use `popcnt`, `tzcnt`/`lzcnt` and BMI2's shifts: a traversal that counts
//!   a node's hit children with `count_ones` otherwise computes it with two
//!   multiplications (measured: shadow rays of the Stanford bunny 1-2% faster).
//! - **AVX-512**: the AVX2 tier and `avx512f,avx512vl,avx512dq,avx512bw` (only where
//!   the compiler has the AVX-512 intrinsics, `lightpath_avx512`). The same AVX2
//!   intrinsics then compile to EVEX code with 32 vector registers and mask-register
//!   compares, which traverses a few per cent faster; the packet traversals and the
//!   path tracer's lanes use 16-lane intrinsics.
//!
//! A function compiled for a tier inlines only into functions compiled for the same
//! tier or a higher one, so every `#[target_feature]` of the crate spells out one of
//! these two lists in full. FMA being enabled changes no result: Rust never fuses a
//! multiplication and an addition on its own, only where the code asks for it.

use std::sync::atomic::{AtomicU8, Ordering};

/// A vector instruction tier, lowest first (see the module notes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SimdTier {
    /// Baseline x86-64 (SSE2), or the target's own baseline elsewhere.
    Baseline,
    /// AVX2 with FMA, BMI1, BMI2, LZCNT and POPCNT.
    Avx2,
    /// The AVX2 tier and AVX-512 F, VL, DQ and BW.
    Avx512,
}

impl SimdTier {
    /// Every tier, lowest first.
    pub const ALL: [SimdTier; 3] = [SimdTier::Baseline, SimdTier::Avx2, SimdTier::Avx512];

    /// The tiers' names on the command line, lowest first.
    pub const NAMES: &'static [&'static str] = &["baseline", "avx2", "avx512"];

    /// The tier's name on the command line: `baseline`, `avx2` or `avx512`.
    pub fn name(self) -> &'static str {
        SimdTier::NAMES[self as usize]
    }

    /// The tier called `name` ([`SimdTier::name`]).
    pub fn from_name(name: &str) -> Option<SimdTier> {
        SimdTier::ALL.into_iter().find(|t| t.name() == name)
    }
}

/// The highest tier the crate may use, as a [`SimdTier`] discriminant.
static LIMIT: AtomicU8 = AtomicU8::new(SimdTier::Avx512 as u8);

/// Caps the tiers the crate uses at `tier`, for the whole process: from then on the
/// crate runs no code of a higher tier, even where the processor has it. Every tier
/// gives the same results, bit for bit (but see below); a cap is for comparing tiers'
/// speeds, and for tools that do not decode the higher tiers' instructions (valgrind
/// 3.19 stops at some AVX2 ones). Set it before building scenes: a mesh or tree built
/// before keeps the tier it was built for.
///
/// Where a ray hits two triangles at exactly the same distance (a shared edge), either
/// may be reported, and the tiers' trees and traversals may pick differently: on
/// Mitsuba's Cornell box (128², 16 spp) one pixel in 16,384 differs between tiers.
pub fn limit_simd_tier(tier: SimdTier) {
    LIMIT.store(tier as u8, Ordering::Relaxed);
}

/// The highest tier the crate uses here: the processor's (and this build's) highest,
/// or the cap of [`limit_simd_tier`] if lower.
pub fn simd_tier() -> SimdTier {
    #[cfg(all(target_arch = "x86_64", lightpath_avx512))]
    if has_avx512() {
        return SimdTier::Avx512;
    }
    if has_avx2() {
        SimdTier::Avx2
    } else {
        SimdTier::Baseline
    }
}

/// Whether [`limit_simd_tier`] allows `tier`.
#[inline]
pub(crate) fn allowed(tier: SimdTier) -> bool {
    LIMIT.load(Ordering::Relaxed) >= tier as u8
}

/// The processor's highest tier, ignoring the cap, detected once. (The standard
/// library caches each feature, but the ten checks of a tier, made once per tile and
/// per packet, cost about 0.5% of a path-traced render.)
fn detected() -> SimdTier {
    static DETECTED: std::sync::OnceLock<SimdTier> = std::sync::OnceLock::new();
    *DETECTED.get_or_init(detect)
}

/// The processor's highest tier that this build can use (see the module notes).
fn detect() -> SimdTier {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        let avx2 = has!("avx2")
            && has!("fma")
            && has!("bmi1")
            && has!("bmi2")
            && has!("lzcnt")
            && has!("popcnt");
        #[cfg(lightpath_avx512)]
        if avx2 && has!("avx512f") && has!("avx512vl") && has!("avx512dq") && has!("avx512bw") {
            return SimdTier::Avx512;
        }
        if avx2 {
            return SimdTier::Avx2;
        }
    }
    SimdTier::Baseline
}

/// Whether the processor has the AVX2 tier (and the cap allows it).
#[inline]
pub(crate) fn has_avx2() -> bool {
    allowed(SimdTier::Avx2) && detected() >= SimdTier::Avx2
}

/// Whether the processor executes each 256-bit vector instruction as two 128-bit
/// halves: AMD's cores before Zen 2 that have AVX2 (Excavator, Zen, Zen+; family 15h,
/// and 17h below model 30h) and Hygon's Zen-based Dhyana (family 18h). An 8-lane test
/// there costs two 4-lane tests, so pairing a leaf's 4-triangle blocks into 8 lanes
/// gains nothing, and pairing a lone block with itself doubles its cost.
pub(crate) fn splits_256_bit() -> bool {
    vendor_and_signature().is_some_and(|(vendor, eax)| splits_256_bit_on(&vendor, eax))
}

/// The processor's vendor string and signature (`cpuid` leaf 1's `eax`), where it has
/// them.
fn vendor_and_signature() -> Option<([u8; 12], u32)> {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::__cpuid;
        #[allow(unused_unsafe)]
        // SAFETY: `cpuid` exists on every x86-64 processor; leaf 0 reports the highest
        // standard leaf, and leaf 1 is read only where it exists.
        let (vendor, signature) = unsafe {
            let id = __cpuid(0);
            let mut vendor = [0u8; 12];
            for (k, word) in [id.ebx, id.edx, id.ecx].into_iter().enumerate() {
                vendor[4 * k..4 * k + 4].copy_from_slice(&word.to_le_bytes());
            }
            (vendor, (id.eax >= 1).then(|| __cpuid(1).eax))
        };
        signature.map(|eax| (vendor, eax))
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        None
    }
}

/// A processor signature's family and model, with their extensions.
fn family_and_model(signature: u32) -> (u32, u32) {
    let base_family = (signature >> 8) & 0xf;
    if base_family == 0xf {
        (
            base_family + ((signature >> 20) & 0xff),
            ((signature >> 4) & 0xf) | ((signature >> 16) & 0xf) << 4,
        )
    } else {
        (base_family, (signature >> 4) & 0xf)
    }
}

/// [`splits_256_bit`] for a processor's vendor string and signature (`cpuid` leaf 1's
/// `eax`: stepping, model, family and their extensions).
fn splits_256_bit_on(vendor: &[u8; 12], signature: u32) -> bool {
    let (family, model) = family_and_model(signature);
    match vendor {
        b"AuthenticAMD" => family == 0x15 || family == 0x16 || (family == 0x17 && model < 0x30),
        b"HygonGenuine" => family == 0x18,
        _ => false,
    }
}

/// How many 4-triangle blocks of a BVH leaf one SIMD test takes: two (8 lanes) where
/// the processor has the AVX2 tier and full-width 256-bit units, else one (4 lanes,
/// see [`splits_256_bit`]). The 8-wide BVH's collapse prices leaves by these tests, and
/// the mesh's leaf test pairs blocks only where this is two.
/// (The cap of [`limit_simd_tier`] is read at every call; the processor's family once.)
pub(crate) fn leaf_blocks_per_test() -> u32 {
    static SPLITS: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    if has_avx2() && !*SPLITS.get_or_init(splits_256_bit) {
        2
    } else {
        1
    }
}

/// Whether the processor executes each 512-bit vector instruction as two 256-bit
/// halves: AMD's Zen 4 (family 19h; Zen 3, the same family, has no AVX-512). Intel's
/// AVX-512 cores, and Zen 5's full-width ones, execute them whole.
#[cfg_attr(not(all(target_arch = "x86_64", lightpath_avx512)), allow(dead_code))]
fn splits_512_bit_on(vendor: &[u8; 12], signature: u32) -> bool {
    vendor == b"AuthenticAMD" && family_and_model(signature).0 == 0x19
}

/// The packets' leaf test takes the rays that enter a leaf one by one (each against
/// 8-lane pairs of its 4-triangle blocks) rather than all sixteen lanes against each
/// triangle where `rays · ⌈blocks / 2⌉ ≤ this · blocks`. A sixteen-lane test costs two
/// 8-lane ones where 512-bit instructions run as two halves (Zen 4), and about one and
/// a half elsewhere (Intel's cores issue two 512-bit or three 256-bit operations per
/// cycle). Measured on Mitsuba's Cornell box with the path tracer
/// (`benches/normalized-ab.sh`): on Zen 4, 2 traced faster than 1 and 3; on an Intel
/// Xeon with AMX, 1 took 4-6% less tracing time than 2, 0 3%, and 3 5% more.
#[cfg_attr(not(all(target_arch = "x86_64", lightpath_avx512)), allow(dead_code))]
pub(crate) fn packet_leaf_rays_per_block() -> u32 {
    static SPLITS: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let splits = *SPLITS.get_or_init(|| {
        vendor_and_signature().is_some_and(|(vendor, eax)| splits_512_bit_on(&vendor, eax))
    });
    if splits {
        2
    } else {
        1
    }
}

/// Whether the processor has the AVX-512 tier (which includes the AVX2 tier), and the
/// cap allows it.
#[cfg(all(target_arch = "x86_64", lightpath_avx512))]
#[inline]
pub(crate) fn has_avx512() -> bool {
    allowed(SimdTier::Avx512) && detected() >= SimdTier::Avx512
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_256_bit_units_are_told_by_family_and_model() {
        let amd = b"AuthenticAMD";
        // Zen (EPYC 7601, family 17h model 01h) and Zen+ (Ryzen 2700X, model 08h) split
        // 256-bit operations; Zen 2 (EPYC 7742, model 31h), Zen 4 (EPYC 9654, family
        // 19h) and Intel (Skylake-SP) do not; Excavator (family 15h) and Hygon's
        // Dhyana (family 18h) do.
        assert!(splits_256_bit_on(amd, 0x0080_0f12));
        assert!(splits_256_bit_on(amd, 0x0080_0f82));
        assert!(!splits_256_bit_on(amd, 0x0083_0f10));
        assert!(!splits_256_bit_on(amd, 0x00a1_0f11));
        assert!(!splits_256_bit_on(b"GenuineIntel", 0x0005_0654));
        assert!(splits_256_bit_on(amd, 0x0066_0f51));
        assert!(splits_256_bit_on(b"HygonGenuine", 0x0090_0f01));
    }

    #[test]
    fn split_512_bit_units_are_told_by_family() {
        let amd = b"AuthenticAMD";
        // Zen 4 (EPYC 9654, family 19h model 11h) splits 512-bit operations; Zen 5
        // (EPYC 9005, family 1Ah), Zen 2 and Intel (Sapphire Rapids, family 6 model
        // 8Fh; Skylake-SP) do not.
        assert!(splits_512_bit_on(amd, 0x00a1_0f11));
        assert!(!splits_512_bit_on(amd, 0x00b0_0f00));
        assert!(!splits_512_bit_on(amd, 0x0083_0f10));
        assert!(!splits_512_bit_on(b"GenuineIntel", 0x0008_06f8));
        assert!(!splits_512_bit_on(b"GenuineIntel", 0x0005_0654));
        assert!((1..=2).contains(&packet_leaf_rays_per_block()));
    }
}
