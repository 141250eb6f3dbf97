//! Choice of steps and temporal bins for two multiplexed heads, and the
//! shifts the pattern generator displays.

use std::f64::consts::TAU;

use super::DemuxError;

/// Fewest steps of a multiplexed sequence (two bins plus background need
/// 5 real samples).
pub const MIN_STEPS: usize = 5;

/// Harmonics of defocused binary fringes (odd), the DESIGN.md default.
pub const ODD_HARMONICS: [usize; 3] = [3, 5, 7];

/// Phase shift of a head running at temporal bin `temporal_bin` at step
/// `step` of a `steps`-step sequence, radians: `2 pi k n / N`. The pattern
/// generator displays `cos(phase + shift)`.
pub fn phase_shift_rad(temporal_bin: usize, step: usize, steps: usize) -> f64 {
    TAU * ((temporal_bin * step) % steps) as f64 / steps as f64
}

/// Bin 0..=N/2 that temporal frequency `frequency` shows up in for real
/// samples (bins j and N - j are conjugates).
pub fn folded_bin(frequency: usize, steps: usize) -> usize {
    let f = frequency % steps;
    f.min(steps - f)
}

/// One row of the folding table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Alias {
    /// Bin of the head whose projector makes the harmonic.
    pub source_bin: usize,
    /// Harmonic order.
    pub harmonic: usize,
    /// Bin the harmonic lands on after folding.
    pub lands_on_bin: usize,
}

/// Where each listed harmonic of each bin lands for `steps` samples.
///
/// ```
/// use slscan::demultiplex::{harmonic_aliases, Alias};
///
/// // N = 5: the 3rd harmonic of bin 2 (frequency 6) folds onto bin 1.
/// let table = harmonic_aliases(5, &[2], &[3]);
/// assert_eq!(table, vec![Alias { source_bin: 2, harmonic: 3, lands_on_bin: 1 }]);
/// ```
pub fn harmonic_aliases(steps: usize, bins: &[usize], harmonics: &[usize]) -> Vec<Alias> {
    bins.iter()
        .flat_map(|&source_bin| {
            harmonics.iter().map(move |&harmonic| Alias {
                source_bin,
                harmonic,
                lands_on_bin: folded_bin(harmonic * source_bin, steps),
            })
        })
        .collect()
}

/// A validated choice of steps and temporal bins for two heads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TemporalBins {
    steps: usize,
    bin_a: usize,
    bin_b: usize,
}

impl TemporalBins {
    /// Checks `steps >= 5`, `0 < k < N/2` for both bins, distinct bins, and
    /// that none of `harmonics` of one bin folds onto the other.
    pub fn new(
        steps: usize,
        bin_a: usize,
        bin_b: usize,
        harmonics: &[usize],
    ) -> Result<Self, DemuxError> {
        if steps < MIN_STEPS {
            return Err(DemuxError::TooFewSteps {
                steps,
                min: MIN_STEPS,
            });
        }
        for bin in [bin_a, bin_b] {
            if bin == 0 || 2 * bin >= steps {
                return Err(DemuxError::BinOutOfRange { bin, steps });
            }
        }
        if bin_a == bin_b {
            return Err(DemuxError::SameBin { bin: bin_a });
        }
        for alias in harmonic_aliases(steps, &[bin_a, bin_b], harmonics) {
            let other = if alias.source_bin == bin_a {
                bin_b
            } else {
                bin_a
            };
            if alias.lands_on_bin == other {
                return Err(DemuxError::HarmonicAlias {
                    steps,
                    source_bin: alias.source_bin,
                    harmonic: alias.harmonic,
                    lands_on_bin: other,
                });
            }
        }
        Ok(Self {
            steps,
            bin_a,
            bin_b,
        })
    }

    /// DESIGN.md's choice: N = 8, head A on bin 1, head B on bin 2, safe
    /// against the 3rd, 5th and 7th harmonics.
    pub fn design_default() -> Self {
        Self::new(8, 1, 2, &ODD_HARMONICS).expect("N = 8 with bins 1, 2 is valid")
    }

    /// Steps N.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Head A's temporal bin.
    pub fn bin_a(&self) -> usize {
        self.bin_a
    }

    /// Head B's temporal bin.
    pub fn bin_b(&self) -> usize {
        self.bin_b
    }
}

/// The valid choice with the fewest steps (then lowest bins) up to
/// `max_steps` that keeps every listed harmonic off the other head's bin.
pub fn smallest_safe_bins(harmonics: &[usize], max_steps: usize) -> Option<TemporalBins> {
    (MIN_STEPS..=max_steps).find_map(|steps| {
        (1..steps.div_ceil(2)).find_map(|a| {
            (a + 1..steps.div_ceil(2)).find_map(|b| TemporalBins::new(steps, a, b, harmonics).ok())
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shift_is_2_pi_k_n_over_n() {
        assert!((phase_shift_rad(2, 3, 8) - TAU * 6.0 / 8.0).abs() < 1e-15);
        assert_eq!(phase_shift_rad(2, 4, 8), 0.0);
    }

    #[test]
    fn folding_table_and_validation() {
        // N = 5: 3rd harmonic of bin 1 is 3 = -2, of bin 2 is 6 = 1.
        let table = harmonic_aliases(5, &[1, 2], &[3]);
        assert_eq!(table[0].lands_on_bin, 2);
        assert_eq!(table[1].lands_on_bin, 1);
        assert_eq!(
            TemporalBins::new(5, 1, 2, &ODD_HARMONICS),
            Err(DemuxError::HarmonicAlias {
                steps: 5,
                source_bin: 1,
                harmonic: 3,
                lands_on_bin: 2
            })
        );
        // N = 8: odd harmonics of 1 land on 3, 3, 1; of 2 on 2, 2, 2.
        let lands: Vec<usize> = harmonic_aliases(8, &[1, 2], &ODD_HARMONICS)
            .iter()
            .map(|a| a.lands_on_bin)
            .collect();
        assert_eq!(lands, vec![3, 3, 1, 2, 2, 2]);
        assert!(TemporalBins::new(8, 1, 2, &ODD_HARMONICS).is_ok());
        // ... but the 2nd harmonic of bin 1 is bin 2, whatever N.
        assert!(matches!(
            TemporalBins::new(8, 1, 2, &[2]),
            Err(DemuxError::HarmonicAlias { harmonic: 2, .. })
        ));
        assert_eq!(
            TemporalBins::new(4, 1, 2, &[]),
            Err(DemuxError::TooFewSteps { steps: 4, min: 5 })
        );
        assert_eq!(
            TemporalBins::new(8, 1, 4, &[]),
            Err(DemuxError::BinOutOfRange { bin: 4, steps: 8 })
        );
        assert_eq!(
            TemporalBins::new(8, 0, 2, &[]),
            Err(DemuxError::BinOutOfRange { bin: 0, steps: 8 })
        );
        assert_eq!(
            TemporalBins::new(8, 2, 2, &[]),
            Err(DemuxError::SameBin { bin: 2 })
        );
        let safe = smallest_safe_bins(&[2, 3], 32).unwrap();
        assert_eq!((safe.steps(), safe.bin_a(), safe.bin_b()), (10, 1, 4));
        // N = 6 already keeps odd harmonics apart: 3 x bin 1 lands on the
        // Nyquist bin 3, 5 x bin 1 on bin 1 itself.
        let odd = smallest_safe_bins(&ODD_HARMONICS, 32).unwrap();
        assert_eq!((odd.steps(), odd.bin_a(), odd.bin_b()), (6, 1, 2));
    }
}
