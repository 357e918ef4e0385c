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

/// Whether the processor has the AVX2 tier.
pub(crate) fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("bmi1")
            && std::arch::is_x86_feature_detected!("bmi2")
            && std::arch::is_x86_feature_detected!("lzcnt")
            && std::arch::is_x86_feature_detected!("popcnt")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether the processor has the AVX-512 tier (which includes the AVX2 tier).
#[cfg(all(target_arch = "x86_64", lightpath_avx512))]
pub(crate) fn has_avx512() -> bool {
    has_avx2()
        && std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512vl")
        && std::arch::is_x86_feature_detected!("avx512dq")
        && std::arch::is_x86_feature_detected!("avx512bw")
}
