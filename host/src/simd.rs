//! Runs the pipeline's row loops compiled for the widest vector unit the CPU has.
//!
//! The build targets baseline x86-64 (SSE2: 4 f32 lanes) so that one binary runs on any
//! x86-64 machine. The row loops of the pipeline are written to vectorise; compiled a
//! second time inside an AVX2 function (everything they call inlined into it) they use 8
//! lanes, which on the bench's 6 MP capture is ~1.5x faster. Rust does not contract
//! `a * b + c` into FMA, and the loops do no reductions, so both builds give the same
//! bits (tested in `reconstruct`).

/// Which build of the pipeline's row loops runs (`simd_run!` in this crate).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Simd {
    /// Baseline x86-64 (or whatever the target is): SSE2 on x86-64.
    Baseline,
    /// AVX2 (8 f32 lanes), when the running CPU has it; baseline otherwise.
    Avx2,
}

impl Simd {
    /// The widest this CPU runs.
    pub fn best() -> Self {
        if avx2_detected() {
            Simd::Avx2
        } else {
            Simd::Baseline
        }
    }

    /// Whether `simd_run!` takes the AVX2 build: `Avx2` on a CPU without AVX2 falls
    /// back to the baseline, so no value of `self` is unsafe.
    #[inline]
    pub fn uses_avx2(self) -> bool {
        self == Simd::Avx2 && avx2_detected()
    }
}

/// Evaluates `$body` built for `$simd` (a [`Simd`]): once as written, once in an
/// `#[inline(always)]` closure handed to the AVX2 function, so that the closure, and the
/// `#[inline(always)]` functions the body calls, are compiled inside it. (Without the
/// attribute LLVM left large closures out of line, compiled for the baseline.)
macro_rules! simd_run {
    ($simd:expr, $body:expr) => {
        if $simd.uses_avx2() {
            // SAFETY: `uses_avx2` checked that the running CPU has AVX2.
            unsafe {
                $crate::simd::run_avx2(
                    #[inline(always)]
                    || $body,
                )
            }
        } else {
            $body
        }
    };
}
pub(crate) use simd_run;

/// Whether the running CPU has AVX2 (std caches the answer after the first call).
fn avx2_detected() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// `f()` with AVX2 enabled: `f` is a closure with this one call site, so LLVM inlines it
/// (and what it inlines) here and vectorises its loops with 8 lanes. Only for
/// [`simd_run!`], which checks the CPU first.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[doc(hidden)]
pub fn run_avx2<R>(f: impl FnOnce() -> R) -> R {
    f()
}

/// Never called: [`Simd::uses_avx2`] is false off x86-64.
#[cfg(not(target_arch = "x86_64"))]
#[doc(hidden)]
pub unsafe fn run_avx2<R>(f: impl FnOnce() -> R) -> R {
    f()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_levels_compute_the_same_bits() {
        let xs: Vec<f32> = (0..1000).map(|i| (i as f32 * 0.37).sin() * 3.0).collect();
        let roots = |simd: Simd| {
            simd_run!(
                simd,
                xs.iter()
                    .map(|&x| (x * x + 1.0).sqrt() / (x.abs() + 0.5))
                    .collect::<Vec<f32>>()
            )
        };
        assert_eq!(roots(Simd::Baseline), roots(Simd::best()));
        assert_eq!(roots(Simd::Avx2), roots(Simd::Baseline));
    }
}
