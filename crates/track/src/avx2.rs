//! Hot loops compiled for AVX2 where the CPU has it.
//!
//! The crate is built for the x86_64 baseline (SSE2, four `f32` lanes), so that one binary
//! runs everywhere. The loops that touch every pixel of every frame are also compiled for
//! AVX2 (eight lanes) and chosen at run time: the same operations in the same order, so
//! the same values to the bit.

/// Runs `f` compiled for AVX2 when the CPU has it (the check is a cached flag), for the
/// baseline otherwise. `f` should be a small closure around a loop: it is inlined into the
/// AVX2 version, whose vectoriser then uses the wider lanes.
#[inline(always)]
pub(crate) fn with_avx2<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        /// `f` compiled for AVX2.
        ///
        /// # Safety
        /// The CPU must have AVX2.
        #[target_feature(enable = "avx2")]
        unsafe fn run<R>(f: impl FnOnce() -> R) -> R {
            f()
        }
        // SAFETY: the CPU has AVX2, just checked.
        return unsafe { run(f) };
    }
    f()
}
