//! Temporal-frequency demultiplexing of two heads projecting at once.
//!
//! In `simultaneous-multiplexed` capture both projectors run an N-step
//! sequence together; head A's phase shift advances at temporal frequency
//! `k_a`, head B's at `k_b` ([`phase_shift_rad`]). A camera pixel that sees
//! both then records
//!
//! ```text
//! I_n = A + B_a cos(phi_a + 2 pi k_a n / N) + B_b cos(phi_b + 2 pi k_b n / N)
//! ```
//!
//! and the N-point DFT separates them exactly: bin `k_a` holds head A,
//! bin `k_b` head B, bin 0 the background. With the project's convention
//! (DESIGN.md) each head's phase is `atan2(-sum I_n sin d_n, sum I_n cos d_n)`
//! and its modulation `(2/N) |sum I_n e^{-i d_n}|`, `d_n = 2 pi k n / N`.
//!
//! What can break the separation is a projector that is not linear: its
//! pattern then carries harmonics h * k of its own bin, which fold to bin
//! `±h k mod N`. [`TemporalBins::new`] refuses a choice where a listed
//! harmonic of one head folds onto the other head's bin, and
//! [`harmonic_aliases`] prints the whole folding table. Note that the
//! 2nd harmonic of bin 1 *is* bin 2 for every N: the DESIGN.md choice
//! (N = 8, bins 1 and 2) is safe against odd harmonics (defocused binary
//! fringes) but not against an uncorrected projector gamma, which makes
//! even harmonics; linearise the projector or pick bins with
//! [`smallest_safe_bins`].
//!
//! For K heads (issue 21) [`HeadBins`] holds one bin per head, refused with
//! the colliding heads and bins named ([`HeadBinsError::HarmonicCollision`]),
//! [`smallest_safe_head_bins`] picks them, and [`demultiplex_heads`]
//! separates them (the scan's path for every head count); the
//! [`Demultiplexer`] below is the two-head case written out.

mod bins;
mod head_bins;
mod heads;

pub use bins::{
    folded_bin, harmonic_aliases, phase_shift_rad, smallest_safe_bins, Alias, TemporalBins,
    MIN_STEPS, ODD_HARMONICS,
};
pub use head_bins::{smallest_safe_head_bins, HeadBins, HeadBinsError, GAMMA_HARMONICS};
pub use heads::{demultiplex_head, demultiplex_heads, HeadsImages};

use rayon::prelude::*;

/// What can be wrong with a multiplexed sequence or its frames.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DemuxError {
    /// Fewer steps than [`MIN_STEPS`].
    #[error("{steps} steps; temporal multiplexing needs at least {min}")]
    TooFewSteps {
        /// Steps asked for.
        steps: usize,
        /// Minimum.
        min: usize,
    },
    /// A bin is 0 (the background) or not below the Nyquist bin N/2.
    #[error("temporal bin {bin} is not in 1..{steps}/2 (need N > 2k)")]
    BinOutOfRange {
        /// The bin.
        bin: usize,
        /// Steps N.
        steps: usize,
    },
    /// Both heads on the same bin.
    #[error("both heads use temporal bin {bin}")]
    SameBin {
        /// The bin.
        bin: usize,
    },
    /// A projector harmonic of one head folds onto the other head's bin.
    #[error("with N = {steps}, harmonic {harmonic} of bin {source_bin} folds onto bin {lands_on_bin}, the other head's")]
    HarmonicAlias {
        /// Steps N.
        steps: usize,
        /// Bin whose harmonic it is.
        source_bin: usize,
        /// Harmonic order.
        harmonic: usize,
        /// Bin it lands on.
        lands_on_bin: usize,
    },
    /// A head the bins do not have.
    #[error("head {head} asked of a multiplex of {heads} heads")]
    NoSuchHead {
        /// Head asked for.
        head: usize,
        /// Heads the bins hold.
        heads: usize,
    },
    /// Wrong number of frames for the sequence.
    #[error("{got} frames for a {expected}-step sequence")]
    FrameCount {
        /// Steps N.
        expected: usize,
        /// Frames given.
        got: usize,
    },
    /// A frame's pixel count differs from the first frame's.
    #[error("frame {frame} has {got} pixels, frame 0 has {expected}")]
    FrameSize {
        /// Frame index.
        frame: usize,
        /// Pixels of frame 0.
        expected: usize,
        /// Pixels of this frame.
        got: usize,
    },
    /// A pixel is NaN or infinite.
    #[error("frame {frame} has a non-finite value at pixel {index}")]
    NonFinite {
        /// Frame index.
        frame: usize,
        /// Pixel index (row-major).
        index: usize,
    },
}

/// One pixel, demultiplexed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelDemux {
    /// Mean intensity (bin 0).
    pub background: f64,
    /// Head A's wrapped phase in (-pi, pi].
    pub phase_a_rad: f64,
    /// Head A's modulation.
    pub modulation_a: f64,
    /// Head B's wrapped phase in (-pi, pi].
    pub phase_b_rad: f64,
    /// Head B's modulation.
    pub modulation_b: f64,
}

/// Phase and modulation images of one head.
#[derive(Debug, Clone, PartialEq)]
pub struct HeadPhase {
    /// Wrapped phase per pixel, radians.
    pub phase_rad: Vec<f32>,
    /// Modulation per pixel (same units as the frames).
    pub modulation: Vec<f32>,
}

/// Both heads' phases and the background, per pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct DemuxImages {
    /// Mean intensity per pixel.
    pub background: Vec<f32>,
    /// Head A (bin `k_a`).
    pub head_a: HeadPhase,
    /// Head B (bin `k_b`).
    pub head_b: HeadPhase,
}

/// Demultiplexer for one [`TemporalBins`]: the cosine and sine tables are
/// computed once, each pixel is then two dot products per head.
///
/// ```
/// use slscan::demultiplex::{phase_shift_rad, Demultiplexer, TemporalBins};
///
/// // Head A at phase 1.0 on bin 1, head B at phase -2.0 on bin 2, N = 8.
/// let samples: Vec<f64> = (0..8)
///     .map(|n| {
///         0.5 + 0.2 * (1.0 + phase_shift_rad(1, n, 8)).cos()
///             + 0.1 * (-2.0 + phase_shift_rad(2, n, 8)).cos()
///     })
///     .collect();
/// let p = Demultiplexer::new(TemporalBins::design_default()).pixel(&samples);
/// assert!((p.phase_a_rad - 1.0).abs() < 1e-12 && (p.phase_b_rad + 2.0).abs() < 1e-12);
/// assert!((p.modulation_a - 0.2).abs() < 1e-12 && (p.background - 0.5).abs() < 1e-12);
/// ```
#[derive(Debug, Clone)]
pub struct Demultiplexer {
    bins: TemporalBins,
    cos_a: Vec<f64>,
    sin_a: Vec<f64>,
    cos_b: Vec<f64>,
    sin_b: Vec<f64>,
}

impl Demultiplexer {
    /// Tables for `bins`.
    pub fn new(bins: TemporalBins) -> Self {
        let table = |k: usize, f: fn(f64) -> f64| {
            (0..bins.steps())
                .map(|n| f(phase_shift_rad(k, n, bins.steps())))
                .collect()
        };
        Self {
            bins,
            cos_a: table(bins.bin_a(), f64::cos),
            sin_a: table(bins.bin_a(), f64::sin),
            cos_b: table(bins.bin_b(), f64::cos),
            sin_b: table(bins.bin_b(), f64::sin),
        }
    }

    /// The bins this demultiplexer separates.
    pub fn bins(&self) -> TemporalBins {
        self.bins
    }

    /// Demultiplexes one pixel's N samples (`samples.len()` must be N).
    pub fn pixel(&self, samples: &[f64]) -> PixelDemux {
        debug_assert_eq!(samples.len(), self.bins.steps());
        let n = self.bins.steps() as f64;
        let dot = |t: &[f64]| samples.iter().zip(t).map(|(i, c)| i * c).sum::<f64>();
        let (ca, sa) = (dot(&self.cos_a), dot(&self.sin_a));
        let (cb, sb) = (dot(&self.cos_b), dot(&self.sin_b));
        PixelDemux {
            background: samples.iter().sum::<f64>() / n,
            phase_a_rad: (-sa).atan2(ca),
            modulation_a: 2.0 / n * ca.hypot(sa),
            phase_b_rad: (-sb).atan2(cb),
            modulation_b: 2.0 / n * cb.hypot(sb),
        }
    }

    /// Demultiplexes N row-major frames of equal size, pixel by pixel.
    pub fn frames(&self, frames: &[&[f32]]) -> Result<DemuxImages, DemuxError> {
        let steps = self.bins.steps();
        let pixels = check_frames(frames, steps)?;
        let per_pixel: Vec<PixelDemux> = (0..pixels)
            .into_par_iter()
            .map_init(
                || vec![0.0; steps],
                |samples, i| {
                    for (s, f) in samples.iter_mut().zip(frames) {
                        *s = f64::from(f[i]);
                    }
                    self.pixel(samples)
                },
            )
            .collect();
        let column =
            |get: fn(&PixelDemux) -> f64| per_pixel.iter().map(|p| get(p) as f32).collect();
        Ok(DemuxImages {
            background: column(|p| p.background),
            head_a: HeadPhase {
                phase_rad: column(|p| p.phase_a_rad),
                modulation: column(|p| p.modulation_a),
            },
            head_b: HeadPhase {
                phase_rad: column(|p| p.phase_b_rad),
                modulation: column(|p| p.modulation_b),
            },
        })
    }
}

/// Checks `frames` are `steps` frames of one size with finite values;
/// returns their pixel count.
fn check_frames(frames: &[&[f32]], steps: usize) -> Result<usize, DemuxError> {
    if frames.len() != steps {
        return Err(DemuxError::FrameCount {
            expected: steps,
            got: frames.len(),
        });
    }
    let pixels = frames.first().map_or(0, |f| f.len());
    for (frame, f) in frames.iter().enumerate() {
        if f.len() != pixels {
            return Err(DemuxError::FrameSize {
                frame,
                expected: pixels,
                got: f.len(),
            });
        }
        if let Some(index) = f.iter().position(|v| !v.is_finite()) {
            return Err(DemuxError::NonFinite { frame, index });
        }
    }
    Ok(pixels)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};
    use std::f64::consts::{PI, TAU};

    fn wrap(d: f64) -> f64 {
        (d + PI).rem_euclid(TAU) - PI
    }

    /// One pixel's samples: background plus each head's displayed pattern
    /// `profile(phase + shift)`.
    fn samples(
        bins: TemporalBins,
        phases: (f64, f64),
        head_a: impl Fn(f64) -> f64,
        head_b: impl Fn(f64) -> f64,
    ) -> Vec<f64> {
        (0..bins.steps())
            .map(|n| {
                let da = phase_shift_rad(bins.bin_a(), n, bins.steps());
                let db = phase_shift_rad(bins.bin_b(), n, bins.steps());
                0.1 + head_a(phases.0 + da) + head_b(phases.1 + db)
            })
            .collect()
    }

    /// RMS phase error of (head A, head B) over random pixels.
    fn rms_errors(
        bins: TemporalBins,
        head_a: impl Fn(f64) -> f64 + Copy,
        head_b: impl Fn(f64) -> f64 + Copy,
    ) -> (f64, f64) {
        let demux = Demultiplexer::new(bins);
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let (mut ea, mut eb) = (0.0, 0.0);
        let count = 2000;
        for _ in 0..count {
            let phases = (rng.random_range(-PI..PI), rng.random_range(-PI..PI));
            let p = demux.pixel(&samples(bins, phases, head_a, head_b));
            ea += wrap(p.phase_a_rad - phases.0).powi(2);
            eb += wrap(p.phase_b_rad - phases.1).powi(2);
        }
        ((ea / count as f64).sqrt(), (eb / count as f64).sqrt())
    }

    fn sine(amplitude: f64) -> impl Fn(f64) -> f64 + Copy {
        move |t: f64| amplitude * (1.0 + t.cos())
    }

    /// Defocused binary fringe: odd harmonics only.
    fn defocused_binary(t: f64) -> f64 {
        0.3 * (1.0 + (1.5 * t.cos()).tanh() / 1.5f64.tanh())
    }

    /// An uncorrected projector gamma of 2.2: every harmonic.
    fn gamma_2_2(t: f64) -> f64 {
        0.6 * (0.5 + 0.5 * t.cos()).powf(2.2)
    }

    #[test]
    fn separates_two_heads_exactly() {
        for bins in [
            TemporalBins::design_default(),
            TemporalBins::new(7, 1, 3, &[]).unwrap(),
            TemporalBins::new(10, 2, 3, &[2, 3]).unwrap(),
        ] {
            let demux = Demultiplexer::new(bins);
            let mut rng = ChaCha8Rng::seed_from_u64(1);
            for _ in 0..500 {
                let phases = (rng.random_range(-PI..PI), rng.random_range(-PI..PI));
                let (ba, bb) = (rng.random_range(0.05..0.3), rng.random_range(0.05..0.3));
                let s = samples(bins, phases, sine(ba), sine(bb));
                let p = demux.pixel(&s);
                assert!(wrap(p.phase_a_rad - phases.0).abs() < 1e-12, "{bins:?}");
                assert!(wrap(p.phase_b_rad - phases.1).abs() < 1e-12, "{bins:?}");
                assert!((p.modulation_a - ba).abs() < 1e-12);
                assert!((p.modulation_b - bb).abs() < 1e-12);
                assert!((p.background - (0.1 + ba + bb)).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn frames_match_the_pixel_kernel() {
        let bins = TemporalBins::design_default();
        let (w, h) = (64, 48);
        let phase = |x: usize, y: usize| (x as f64 * 0.2 - PI, y as f64 * 0.1 - 2.0);
        let frames: Vec<Vec<f32>> = (0..8)
            .map(|n| {
                (0..w * h)
                    .map(|i| {
                        let (pa, pb) = phase(i % w, i / w);
                        let da = phase_shift_rad(1, n, 8);
                        let db = phase_shift_rad(2, n, 8);
                        (0.1 + sine(0.2)(pa + da) + sine(0.15)(pb + db)) as f32
                    })
                    .collect()
            })
            .collect();
        let refs: Vec<&[f32]> = frames.iter().map(Vec::as_slice).collect();
        let out = Demultiplexer::new(bins).frames(&refs).unwrap();
        for i in 0..w * h {
            let (pa, pb) = phase(i % w, i / w);
            // f32 frames: about 1e-7 relative per sample.
            assert!(wrap(f64::from(out.head_a.phase_rad[i]) - pa).abs() < 2e-6);
            assert!(wrap(f64::from(out.head_b.phase_rad[i]) - pb).abs() < 2e-6);
            assert!((out.head_a.modulation[i] - 0.2).abs() < 1e-6);
        }
    }

    #[test]
    fn noise_matches_the_cramer_rao_bound() {
        // sigma_phi = sigma_I sqrt(2/N) / B for each head.
        let bins = TemporalBins::new(10, 2, 3, &[2, 3]).unwrap();
        let demux = Demultiplexer::new(bins);
        let (ba, bb, sigma_i) = (0.3, 0.15, 0.01);
        let noise = Normal::new(0.0, sigma_i).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let count = 20_000;
        let (mut ea, mut eb) = (0.0, 0.0);
        for _ in 0..count {
            let phases = (rng.random_range(-PI..PI), rng.random_range(-PI..PI));
            let mut s = samples(bins, phases, sine(ba), sine(bb));
            s.iter_mut().for_each(|v| *v += noise.sample(&mut rng));
            let p = demux.pixel(&s);
            ea += wrap(p.phase_a_rad - phases.0).powi(2);
            eb += wrap(p.phase_b_rad - phases.1).powi(2);
        }
        let bound = |b: f64| sigma_i * (2.0 / 10.0f64).sqrt() / b;
        let ratio_a = (ea / count as f64).sqrt() / bound(ba);
        let ratio_b = (eb / count as f64).sqrt() / bound(bb);
        println!("measured / Cramer-Rao: head A {ratio_a:.4}, head B {ratio_b:.4}");
        // 20k samples estimate a std to about 0.5 %.
        assert!((ratio_a - 1.0).abs() < 0.03, "{ratio_a}");
        assert!((ratio_b - 1.0).abs() < 0.03, "{ratio_b}");
    }

    #[test]
    fn odd_harmonics_do_not_cross_with_n8_but_do_with_n5() {
        let good = TemporalBins::design_default();
        let bad = TemporalBins::new(5, 1, 2, &[]).unwrap();
        // Head A distorted, head B clean: B's error is pure cross-talk.
        let (_, b_good) = rms_errors(good, defocused_binary, sine(0.2));
        let (_, b_bad) = rms_errors(bad, defocused_binary, sine(0.2));
        // Head B distorted, head A clean.
        let (a_good, _) = rms_errors(good, sine(0.2), defocused_binary);
        let (a_bad, _) = rms_errors(bad, sine(0.2), defocused_binary);
        println!(
            "cross-talk rad: N=8 B {b_good:.2e} A {a_good:.2e}; N=5 B {b_bad:.2e} A {a_bad:.2e}"
        );
        assert!(b_good < 1e-9 && a_good < 1e-9);
        assert!(b_bad > 1e-2 && a_bad > 1e-2);
    }

    #[test]
    fn gamma_leaks_the_2nd_harmonic_of_bin_1_into_bin_2() {
        let design = TemporalBins::design_default();
        let safe = smallest_safe_bins(&[2, 3], 32).unwrap();
        let (_, b_design) = rms_errors(design, gamma_2_2, sine(0.2));
        let (_, b_safe) = rms_errors(safe, gamma_2_2, sine(0.2));
        println!("gamma 2.2 on head A, head B cross-talk rad: N=8 (1,2) {b_design:.2e}, {safe:?} {b_safe:.2e}");
        assert!(b_design > 1e-2, "{b_design}");
        // Only the 4th and higher harmonics leak now: much smaller.
        assert!(b_safe < b_design / 5.0, "{b_safe} vs {b_design}");
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(200))]
        /// Any valid (N, k_a, k_b) separates ideal sinusoids exactly, and
        /// the table-driven kernel equals a direct DFT of the two bins.
        #[test]
        fn any_valid_bins_separate(
            steps in 5usize..17,
            ka in 1usize..8,
            kb in 1usize..8,
            pa in -3.1f64..3.1,
            pb in -3.1f64..3.1,
            ba in 0.01f64..1.0,
            bb in 0.01f64..1.0,
        ) {
            let Ok(bins) = TemporalBins::new(steps, ka, kb, &[]) else {
                return Ok(());
            };
            let s = samples(bins, (pa, pb), sine(ba), sine(bb));
            let p = Demultiplexer::new(bins).pixel(&s);
            proptest::prop_assert!(wrap(p.phase_a_rad - pa).abs() < 1e-9);
            proptest::prop_assert!(wrap(p.phase_b_rad - pb).abs() < 1e-9);
            proptest::prop_assert!((p.modulation_a - ba).abs() < 1e-9);
            proptest::prop_assert!((p.modulation_b - bb).abs() < 1e-9);
            for (k, phase, modulation) in [(ka, p.phase_a_rad, p.modulation_a), (kb, p.phase_b_rad, p.modulation_b)] {
                let (re, im) = s.iter().enumerate().fold((0.0, 0.0), |(re, im), (n, v)| {
                    let d = TAU * (k * n) as f64 / steps as f64;
                    (re + v * d.cos(), im - v * d.sin())
                });
                // sum I e^{-i d} = re + i im, and phi = atan2(-sum I sin d, sum I cos d) = atan2(im, re).
                proptest::prop_assert!(wrap(phase - im.atan2(re)).abs() < 1e-12);
                proptest::prop_assert!((modulation - 2.0 / steps as f64 * re.hypot(im)).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn bad_frames_are_errors() {
        let demux = Demultiplexer::new(TemporalBins::design_default());
        let frame = vec![0.5f32; 16];
        let short = vec![0.5f32; 15];
        let mut nan = frame.clone();
        nan[3] = f32::NAN;
        let mut refs: Vec<&[f32]> = vec![&frame; 7];
        assert_eq!(
            demux.frames(&refs),
            Err(DemuxError::FrameCount {
                expected: 8,
                got: 7
            })
        );
        refs.push(&short);
        assert_eq!(
            demux.frames(&refs),
            Err(DemuxError::FrameSize {
                frame: 7,
                expected: 16,
                got: 15
            })
        );
        refs[7] = &nan;
        assert_eq!(
            demux.frames(&refs),
            Err(DemuxError::NonFinite { frame: 7, index: 3 })
        );
    }
}
