//! Temporal bins for K multiplexed heads (issue 21): every head's projector
//! runs the same N-step sequence at its own temporal frequency, and the
//! choice is refused when a projector harmonic of one head folds onto
//! another head's bin (where the N-point DFT could not tell them apart).
//!
//! [`TemporalBins`](super::TemporalBins) is the two-head case the scan
//! pipeline demultiplexes today; this is the plan side for any K up to
//! `protocol::limits::MAX_HEADS`, checked the same way pair by pair.

use super::bins::{folded_bin, phase_shift_rad};

/// Harmonics a projector's gamma adds that matter at our modulation depth:
/// gamma 2.2 puts the 2nd at ~0.1 and the 3rd at ~0.03 of the fundamental
/// (DESIGN.md: N = 8 with bins 1, 2 breaks on the 2nd; N = 10 with bins 1,
/// 4 is safe against both).
pub const GAMMA_HARMONICS: [usize; 2] = [2, 3];

/// Why a set of temporal bins for K heads is refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HeadBinsError {
    /// No head, or more than the protocol's heads.
    #[error("{heads} heads; a multiplexed plan takes 1 to {max}")]
    HeadCount {
        /// Heads asked for.
        heads: usize,
        /// `protocol::limits::MAX_HEADS`.
        max: usize,
    },
    /// Too few steps to separate K bins and the background: the N real
    /// samples hold N/2 + 1 independent bins, so N >= 2K + 1.
    #[error("{steps} steps cannot separate {heads} heads; they need at least {min}")]
    TooFewSteps {
        /// Steps N.
        steps: usize,
        /// Heads.
        heads: usize,
        /// 2K + 1.
        min: usize,
    },
    /// A bin is 0 (the background) or not below the Nyquist bin N/2.
    #[error("head {head}'s temporal bin {bin} is not in 1..{steps}/2 (need N > 2k)")]
    BinOutOfRange {
        /// Head index (0 = A).
        head: usize,
        /// The bin.
        bin: usize,
        /// Steps N.
        steps: usize,
    },
    /// Two heads on one bin.
    #[error("heads {first} and {second} both use temporal bin {bin}")]
    SharedBin {
        /// The first head's index.
        first: usize,
        /// The second head's index.
        second: usize,
        /// The bin.
        bin: usize,
    },
    /// A projector harmonic of one head folds onto another head's bin.
    #[error("with N = {steps}, harmonic {harmonic} of head {source_head}'s bin {source_bin} folds onto bin {lands_on_bin}, head {target_head}'s: the bins collide under the projector's gamma")]
    HarmonicCollision {
        /// Steps N.
        steps: usize,
        /// Head whose projector makes the harmonic.
        source_head: usize,
        /// Its bin.
        source_bin: usize,
        /// Harmonic order.
        harmonic: usize,
        /// Head whose bin the harmonic lands on.
        target_head: usize,
        /// That bin.
        lands_on_bin: usize,
    },
}

/// A validated choice of steps and one temporal bin per head (index 0 =
/// head A).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HeadBins {
    steps: usize,
    bins: Vec<usize>,
}

impl HeadBins {
    /// Checks 1 to `MAX_HEADS` heads, `N >= 2K + 1`, `0 < k < N/2` for every
    /// bin, distinct bins, and that no listed harmonic of one head's bin
    /// folds onto another head's bin.
    ///
    /// ```
    /// use slscan::demultiplex::{HeadBins, HeadBinsError, GAMMA_HARMONICS};
    ///
    /// assert!(HeadBins::new(10, &[1, 4], &GAMMA_HARMONICS).is_ok());
    /// // The 2nd harmonic of bin 1 is bin 2.
    /// assert!(matches!(
    ///     HeadBins::new(8, &[1, 2], &GAMMA_HARMONICS),
    ///     Err(HeadBinsError::HarmonicCollision { source_bin: 1, harmonic: 2, lands_on_bin: 2, .. })
    /// ));
    /// ```
    pub fn new(steps: usize, bins: &[usize], harmonics: &[usize]) -> Result<Self, HeadBinsError> {
        let heads = bins.len();
        let max = protocol::limits::MAX_HEADS;
        if heads == 0 || heads > max {
            return Err(HeadBinsError::HeadCount { heads, max });
        }
        let min = 2 * heads + 1;
        if steps < min {
            return Err(HeadBinsError::TooFewSteps { steps, heads, min });
        }
        for (head, &bin) in bins.iter().enumerate() {
            if bin == 0 || 2 * bin >= steps {
                return Err(HeadBinsError::BinOutOfRange { head, bin, steps });
            }
            if let Some(first) = bins[..head].iter().position(|&b| b == bin) {
                return Err(HeadBinsError::SharedBin {
                    first,
                    second: head,
                    bin,
                });
            }
        }
        for (source_head, &source_bin) in bins.iter().enumerate() {
            for &harmonic in harmonics {
                let lands_on_bin = folded_bin(harmonic * source_bin, steps);
                let target = bins
                    .iter()
                    .enumerate()
                    .find(|&(h, &b)| h != source_head && b == lands_on_bin);
                if let Some((target_head, _)) = target {
                    return Err(HeadBinsError::HarmonicCollision {
                        steps,
                        source_head,
                        source_bin,
                        harmonic,
                        target_head,
                        lands_on_bin,
                    });
                }
            }
        }
        Ok(Self {
            steps,
            bins: bins.to_vec(),
        })
    }

    /// Steps N.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// The bins, head A first.
    pub fn bins(&self) -> &[usize] {
        &self.bins
    }

    /// Head `head`'s phase shift at each of the N steps, radians (what its
    /// projector's patterns add to the fringe phase); `None` past the heads.
    pub fn shifts_rad(&self, head: usize) -> Option<Vec<f64>> {
        let bin = *self.bins.get(head)?;
        Some(
            (0..self.steps)
                .map(|step| phase_shift_rad(bin, step, self.steps))
                .collect(),
        )
    }
}

/// The choice for `heads` heads with the fewest steps up to `max_steps`,
/// then the lowest bins (lexicographically), that keeps every listed
/// harmonic of each head off every other head's bin; `None` when no N up to
/// `max_steps` has one (or `heads` is 0 or above `MAX_HEADS`).
///
/// ```
/// use slscan::demultiplex::{smallest_safe_head_bins, GAMMA_HARMONICS};
///
/// let two = smallest_safe_head_bins(2, &GAMMA_HARMONICS, 32).unwrap();
/// assert_eq!((two.steps(), two.bins()), (10, &[1, 4][..]));
/// ```
pub fn smallest_safe_head_bins(
    heads: usize,
    harmonics: &[usize],
    max_steps: usize,
) -> Option<HeadBins> {
    if heads == 0 || heads > protocol::limits::MAX_HEADS {
        return None;
    }
    (2 * heads + 1..=max_steps).find_map(|steps| {
        let mut chosen = Vec::with_capacity(heads);
        extend_safe(steps, heads, harmonics, 1, &mut chosen)
    })
}

/// Depth-first over increasing bins from `from`: the first (lowest)
/// completion of `chosen` to `heads` bins that validates. Every prefix must
/// validate on its own (a collision between two chosen bins stays whatever
/// is added), which prunes the search to a few hundred checks at K = 4.
fn extend_safe(
    steps: usize,
    heads: usize,
    harmonics: &[usize],
    from: usize,
    chosen: &mut Vec<usize>,
) -> Option<HeadBins> {
    if chosen.len() == heads {
        return HeadBins::new(steps, chosen, harmonics).ok();
    }
    for bin in from..steps.div_ceil(2) {
        chosen.push(bin);
        let prefix_ok = chosen.len() == heads || prefix_safe(steps, chosen, harmonics);
        if prefix_ok {
            if let Some(found) = extend_safe(steps, heads, harmonics, bin + 1, chosen) {
                return Some(found);
            }
        }
        chosen.pop();
    }
    None
}

/// Whether the bins chosen so far collide with each other under
/// `harmonics` (the step-count check is left to the full set).
fn prefix_safe(steps: usize, bins: &[usize], harmonics: &[usize]) -> bool {
    bins.iter().enumerate().all(|(h, &bin)| {
        harmonics.iter().all(|&harmonic| {
            let lands = folded_bin(harmonic * bin, steps);
            bins.iter()
                .enumerate()
                .all(|(other, &b)| other == h || b != lands)
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::demultiplex::{smallest_safe_bins, ODD_HARMONICS};

    /// Slow reference: every K-subset of bins for every N, in the same
    /// order, checked by `HeadBins::new`.
    fn brute_force(heads: usize, harmonics: &[usize], max_steps: usize) -> Option<HeadBins> {
        fn subsets(from: usize, below: usize, k: usize) -> Vec<Vec<usize>> {
            if k == 0 {
                return vec![vec![]];
            }
            (from..below)
                .flat_map(|b| {
                    subsets(b + 1, below, k - 1).into_iter().map(move |mut s| {
                        s.insert(0, b);
                        s
                    })
                })
                .collect()
        }
        (2 * heads + 1..=max_steps).find_map(|steps| {
            subsets(1, steps.div_ceil(2), heads)
                .into_iter()
                .find_map(|bins| HeadBins::new(steps, &bins, harmonics).ok())
        })
    }

    #[test]
    fn search_matches_the_brute_force_reference_for_every_k() {
        for harmonics in [&GAMMA_HARMONICS[..], &ODD_HARMONICS[..], &[2, 3, 4][..]] {
            for heads in 1..=protocol::limits::MAX_HEADS {
                let fast = smallest_safe_head_bins(heads, harmonics, 40);
                assert_eq!(
                    fast,
                    brute_force(heads, harmonics, 40),
                    "{heads} {harmonics:?}"
                );
            }
        }
    }

    #[test]
    fn two_heads_agree_with_the_two_head_search() {
        for harmonics in [&GAMMA_HARMONICS[..], &ODD_HARMONICS[..], &[][..]] {
            let pair = smallest_safe_bins(harmonics, 32).unwrap();
            let k = smallest_safe_head_bins(2, harmonics, 32).unwrap();
            assert_eq!(
                (k.steps(), k.bins()),
                (pair.steps(), &[pair.bin_a(), pair.bin_b()][..])
            );
        }
    }

    #[test]
    fn four_heads_under_gamma_get_distinct_bins_no_harmonic_reaches() {
        let four = smallest_safe_head_bins(4, &GAMMA_HARMONICS, 64).unwrap();
        let (n, bins) = (four.steps(), four.bins());
        assert_eq!(bins.len(), 4);
        for (h, &bin) in bins.iter().enumerate() {
            for harmonic in GAMMA_HARMONICS {
                let lands = folded_bin(harmonic * bin, n);
                for (other, &b) in bins.iter().enumerate() {
                    assert!(other == h || b != lands, "N={n} {bins:?}");
                }
            }
        }
        // Fewest steps: no smaller N holds four such bins.
        assert_eq!(brute_force(4, &GAMMA_HARMONICS, n - 1), None);
        let shifts = four.shifts_rad(3).unwrap();
        assert_eq!(shifts.len(), n);
        assert!((shifts[1] - std::f64::consts::TAU * bins[3] as f64 / n as f64).abs() < 1e-12);
        assert_eq!(four.shifts_rad(4), None);
    }

    #[test]
    fn colliding_bins_are_refused_naming_them() {
        // Three heads on N = 10, bins 1, 2, 4: the 2nd harmonic of head A's
        // bin 1 is head B's bin 2.
        let err = HeadBins::new(10, &[1, 2, 4], &GAMMA_HARMONICS).unwrap_err();
        assert_eq!(
            err,
            HeadBinsError::HarmonicCollision {
                steps: 10,
                source_head: 0,
                source_bin: 1,
                harmonic: 2,
                target_head: 1,
                lands_on_bin: 2
            }
        );
        assert_eq!(
            err.to_string(),
            "with N = 10, harmonic 2 of head 0's bin 1 folds onto bin 2, head 1's: the bins \
             collide under the projector's gamma"
        );
        // The 3rd harmonic of bin 3 is 9, folded to 2 on N = 11.
        assert!(matches!(
            HeadBins::new(11, &[3, 2], &GAMMA_HARMONICS),
            Err(HeadBinsError::HarmonicCollision {
                source_head: 0,
                harmonic: 3,
                target_head: 1,
                ..
            })
        ));
        assert_eq!(
            HeadBins::new(12, &[1, 5, 1], &[]),
            Err(HeadBinsError::SharedBin {
                first: 0,
                second: 2,
                bin: 1
            })
        );
        assert_eq!(
            HeadBins::new(8, &[1, 2, 3, 5], &[]),
            Err(HeadBinsError::TooFewSteps {
                steps: 8,
                heads: 4,
                min: 9
            })
        );
        assert_eq!(
            HeadBins::new(12, &[1, 6], &[]),
            Err(HeadBinsError::BinOutOfRange {
                head: 1,
                bin: 6,
                steps: 12
            })
        );
        assert_eq!(
            HeadBins::new(40, &[1, 2, 3, 4, 5], &[]),
            Err(HeadBinsError::HeadCount { heads: 5, max: 4 })
        );
        assert_eq!(smallest_safe_head_bins(5, &[], 64), None);
        assert_eq!(smallest_safe_head_bins(0, &[], 64), None);
    }
}
