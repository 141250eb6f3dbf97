//! Demultiplexing of K heads (issue 21): each head's phase and modulation
//! from the N-point DFT at its own temporal bin ([`HeadBins`]), the
//! background from bin 0. The scan's multiplexed capture uses this for
//! every head count (two heads on [`HeadBins::design_default`], the
//! DESIGN.md choice); [`super::Demultiplexer`] is the same arithmetic
//! written out for exactly two.

use rayon::prelude::*;

use super::{check_frames, DemuxError, HeadBins, HeadPhase, ODD_HARMONICS};

/// Every head's phase and modulation and the background, per pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct HeadsImages {
    /// Mean intensity per pixel.
    pub background: Vec<f32>,
    /// Per head, in the order of the bins.
    pub heads: Vec<HeadPhase>,
}

impl HeadBins {
    /// DESIGN.md's two-head choice, N = 8 with heads on bins 1 and 2: safe
    /// against odd harmonics (defocused binary fringes), not against an
    /// uncorrected gamma's 2nd (pre-compensate the patterns).
    pub fn design_default() -> Self {
        Self::new(8, &[1, 2], &ODD_HARMONICS).expect("N = 8, bins 1 and 2 keep odd harmonics apart")
    }
}

/// Separates the heads of `bins` in N row-major frames of equal size
/// (N = `bins.steps()`): per pixel and head, the phase
/// `atan2(-sum I_n sin d_n, sum I_n cos d_n)` and modulation
/// `(2/N) |sum I_n e^{-i d_n}|` with `d_n = 2 pi k n / N` at the head's bin k.
///
/// ```
/// use slscan::demultiplex::{demultiplex_heads, phase_shift_rad, HeadBins, GAMMA_HARMONICS};
///
/// let bins = HeadBins::new(12, &[1, 4, 5], &GAMMA_HARMONICS).unwrap();
/// let phases = [0.5, -1.0, 2.5];
/// let frames: Vec<Vec<f32>> = (0..12)
///     .map(|n| {
///         let v: f64 = 0.3 + (0..3)
///             .map(|h| 0.1 * (phases[h] + phase_shift_rad(bins.bins()[h], n, 12)).cos())
///             .sum::<f64>();
///         vec![v as f32]
///     })
///     .collect();
/// let refs: Vec<&[f32]> = frames.iter().map(|f| f.as_slice()).collect();
/// let out = demultiplex_heads(&bins, &refs).unwrap();
/// for h in 0..3 {
///     assert!((f64::from(out.heads[h].phase_rad[0]) - phases[h]).abs() < 1e-5);
/// }
/// ```
pub fn demultiplex_heads(bins: &HeadBins, frames: &[&[f32]]) -> Result<HeadsImages, DemuxError> {
    let all: Vec<usize> = (0..bins.bins().len()).collect();
    demultiplex_selected(bins, frames, &all)
}

/// Head `head`'s phase and modulation and the background: what one camera
/// of a multiplexed scan needs (its own head's bin and bin 0, not every
/// head's DFT). `heads` of the result holds that one head.
pub fn demultiplex_head(
    bins: &HeadBins,
    frames: &[&[f32]],
    head: usize,
) -> Result<HeadsImages, DemuxError> {
    let heads = bins.bins().len();
    if head >= heads {
        return Err(DemuxError::NoSuchHead { head, heads });
    }
    demultiplex_selected(bins, frames, &[head])
}

/// [`demultiplex_heads`] for the heads `selected` (indices into the bins,
/// in range), in that order.
fn demultiplex_selected(
    bins: &HeadBins,
    frames: &[&[f32]],
    selected: &[usize],
) -> Result<HeadsImages, DemuxError> {
    let steps = bins.steps();
    let pixels = check_frames(frames, steps)?;
    let tables: Vec<(Vec<f64>, Vec<f64>)> = selected
        .iter()
        .map(|&h| {
            let shifts = bins.shifts_rad(h).expect("head within the bins");
            (
                shifts.iter().map(|d| d.cos()).collect(),
                shifts.iter().map(|d| d.sin()).collect(),
            )
        })
        .collect();
    let heads = tables.len();
    // Per pixel: background, then (phase, modulation) per head.
    let per_pixel: Vec<(f32, Vec<(f32, f32)>)> = (0..pixels)
        .into_par_iter()
        .map(|i| {
            let sample = |n: usize| f64::from(frames[n][i]);
            let background = (0..steps).map(sample).sum::<f64>() / steps as f64;
            let own = tables
                .iter()
                .map(|(cos, sin)| {
                    let (mut c, mut s) = (0.0, 0.0);
                    for n in 0..steps {
                        c += sample(n) * cos[n];
                        s += sample(n) * sin[n];
                    }
                    (
                        (-s).atan2(c) as f32,
                        (2.0 / steps as f64 * c.hypot(s)) as f32,
                    )
                })
                .collect();
            (background as f32, own)
        })
        .collect();
    Ok(HeadsImages {
        background: per_pixel.iter().map(|p| p.0).collect(),
        heads: (0..heads)
            .map(|h| HeadPhase {
                phase_rad: per_pixel.iter().map(|p| p.1[h].0).collect(),
                modulation: per_pixel.iter().map(|p| p.1[h].1).collect(),
            })
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::demultiplex::{
        phase_shift_rad, smallest_safe_head_bins, Demultiplexer, TemporalBins, GAMMA_HARMONICS,
    };
    use std::f64::consts::PI;

    fn wrap(d: f64) -> f64 {
        (d + PI).rem_euclid(2.0 * PI) - PI
    }

    /// Frames of `pixels` pixels: head h at phase `phase(h, i)` with
    /// modulation 0.1 + 0.02 h, plus a background of 0.3.
    fn frames(
        bins: &HeadBins,
        pixels: usize,
        phase: impl Fn(usize, usize) -> f64,
    ) -> Vec<Vec<f32>> {
        let n = bins.steps();
        (0..n)
            .map(|step| {
                (0..pixels)
                    .map(|i| {
                        let v: f64 = 0.3
                            + bins
                                .bins()
                                .iter()
                                .enumerate()
                                .map(|(h, &k)| {
                                    (0.1 + 0.02 * h as f64)
                                        * (phase(h, i) + phase_shift_rad(k, step, n)).cos()
                                })
                                .sum::<f64>();
                        v as f32
                    })
                    .collect()
            })
            .collect()
    }

    #[test]
    fn three_and_four_heads_separate_exactly_on_gamma_safe_bins() {
        for heads in 3..=4 {
            let bins = smallest_safe_head_bins(heads, &GAMMA_HARMONICS, 32).unwrap();
            let phase = |h: usize, i: usize| -3.0 + 0.37 * i as f64 + 1.3 * h as f64;
            let f = frames(&bins, 17, phase);
            let refs: Vec<&[f32]> = f.iter().map(|v| v.as_slice()).collect();
            let out = demultiplex_heads(&bins, &refs).unwrap();
            assert_eq!(out.heads.len(), heads);
            for (h, head) in out.heads.iter().enumerate() {
                for i in 0..17 {
                    let e = wrap(f64::from(head.phase_rad[i]) - phase(h, i));
                    assert!(e.abs() < 1e-5, "{heads} heads, head {h} pixel {i}: {e}");
                    let m = f64::from(head.modulation[i]) - (0.1 + 0.02 * h as f64);
                    assert!(m.abs() < 1e-6, "modulation off by {m}");
                }
            }
            assert!(out.background.iter().all(|b| (b - 0.3).abs() < 1e-6));
        }
    }

    #[test]
    fn one_head_alone_is_the_same_bits_as_all_heads() {
        let bins = smallest_safe_head_bins(4, &GAMMA_HARMONICS, 32).unwrap();
        let phase = |h: usize, i: usize| 0.4 * i as f64 - 0.9 * h as f64;
        let f = frames(&bins, 23, phase);
        let refs: Vec<&[f32]> = f.iter().map(|v| v.as_slice()).collect();
        let all = demultiplex_heads(&bins, &refs).unwrap();
        for h in 0..4 {
            let one = demultiplex_head(&bins, &refs, h).unwrap();
            assert_eq!(one.background, all.background);
            assert_eq!(one.heads, vec![all.heads[h].clone()], "head {h}");
        }
        assert!(matches!(
            demultiplex_head(&bins, &refs, 4),
            Err(DemuxError::NoSuchHead { head: 4, heads: 4 })
        ));
    }

    #[test]
    fn two_heads_agree_with_the_two_head_demultiplexer() {
        let bins = HeadBins::design_default();
        let phase = |h: usize, i: usize| 0.21 * i as f64 - 1.7 * h as f64;
        let f = frames(&bins, 40, phase);
        let refs: Vec<&[f32]> = f.iter().map(|v| v.as_slice()).collect();
        let k = demultiplex_heads(&bins, &refs).unwrap();
        let two = Demultiplexer::new(TemporalBins::design_default())
            .frames(&refs)
            .unwrap();
        assert_eq!(k.background, two.background);
        assert_eq!(k.heads[0], two.head_a);
        assert_eq!(k.heads[1], two.head_b);
    }

    #[test]
    fn wrong_frame_count_size_or_nan_is_refused() {
        let bins = smallest_safe_head_bins(3, &GAMMA_HARMONICS, 32).unwrap();
        let f = frames(&bins, 4, |_, _| 0.0);
        let refs: Vec<&[f32]> = f.iter().map(|v| v.as_slice()).collect();
        assert!(matches!(
            demultiplex_heads(&bins, &refs[1..]),
            Err(DemuxError::FrameCount { .. })
        ));
        let mut short = refs.clone();
        short[3] = &refs[3][..2];
        assert!(matches!(
            demultiplex_heads(&bins, &short),
            Err(DemuxError::FrameSize { frame: 3, .. })
        ));
        let nan = vec![f32::NAN; 4];
        let mut bad = refs.clone();
        bad[5] = &nan;
        assert!(matches!(
            demultiplex_heads(&bins, &bad),
            Err(DemuxError::NonFinite { frame: 5, index: 0 })
        ));
    }
}
