//! Help from the CPU for the loops over every pixel: AVX2 where it has it, and cache
//! prefetches.
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
    if std::arch::is_x86_feature_detected!("avx2") && !baseline_forced() {
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

#[cfg(test)]
thread_local! {
    /// Set by [`baseline_only`]: this thread runs the baseline versions.
    static BASELINE_ONLY: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Whether this thread must run the baseline versions (only ever in tests).
#[inline(always)]
fn baseline_forced() -> bool {
    #[cfg(test)]
    return BASELINE_ONLY.with(std::cell::Cell::get);
    #[cfg(not(test))]
    false
}

/// Runs `f` with every [`with_avx2`] on this thread in its baseline version, so that tests
/// can compare the two on a CPU that has AVX2.
#[cfg(test)]
pub(crate) fn baseline_only<R>(f: impl FnOnce() -> R) -> R {
    BASELINE_ONLY.with(|b| b.set(true));
    let out = f();
    BASELINE_ONLY.with(|b| b.set(false));
    out
}

/// Asks the CPU to start loading `values[at]` into the cache, so that a later read does not
/// wait for memory (nothing out of bounds or off x86_64).
#[inline(always)]
pub(crate) fn prefetch<T>(values: &[T], at: usize) {
    #[cfg(target_arch = "x86_64")]
    if let Some(v) = values.get(at) {
        // SAFETY: SSE is part of the x86_64 baseline, and a prefetch of an address inside a
        // live slice reads nothing the program sees.
        unsafe {
            std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
                (v as *const T).cast::<i8>(),
            );
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (values, at);
}
