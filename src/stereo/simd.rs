//! Runs a hot loop compiled for AVX2 when the CPU has it (runtime detection), else for the
//! baseline target. The loops are written so that LLVM vectorises them (u8/u16 lanes, saturating
//! arithmetic, no branches inside); compiling the same body with AVX2 enabled doubles the lane
//! count and gives unsigned 16-bit min/max instructions that SSE2 lacks.

/// Calls `f`, compiled with AVX2 enabled when the CPU supports it.
#[inline(always)]
pub fn dispatch<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
    {
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { with_avx2(f) };
        }
    }
    f()
}

#[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
#[target_feature(enable = "avx2")]
unsafe fn with_avx2<R>(f: impl FnOnce() -> R) -> R {
    f()
}
