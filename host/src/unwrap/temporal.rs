//! Phase-shifted frames of several periods -> absolute phase, in one pass over the rows.
//!
//! Each row is decoded ([`PhaseShift`], N steps per period) and unwrapped
//! ([`Heterodyne`]) while it is in cache, so every frame sample is read once and no
//! wrapped-phase map is written: at 6 MP that traffic (a write and a read of a map per
//! period) cost more than the arithmetic. The reconstruction pipeline runs these same
//! row functions, and a pixel of finite samples gets the same bits as from
//! [`PhaseShift::wrapped_phase`] then [`Heterodyne::unwrap`] (tested); a pixel with a
//! non-finite sample is refused here, where that path can give it a phase.

use rayon::prelude::*;

use super::heterodyne::{status_row, Heterodyne};
use super::{AbsolutePhase, PixelStatus, UnwrapError};
use crate::phase::{check_sizes, PhaseError, PhaseShift, Sample};
use crate::raster::Raster;
use crate::simd::{simd_run, Simd};

/// N-step phase shifting of every period, then heterodyne unwrapping: a capture's frames
/// straight to the absolute phase of the finest period.
#[derive(Clone, Debug, PartialEq)]
pub struct TemporalDecoder {
    shift: PhaseShift,
    heterodyne: Heterodyne,
    simd: Simd,
}

/// What [`TemporalDecoder::decode`] gives per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct TemporalPhase {
    /// Absolute phase of the finest period (NaN where not valid) and each pixel's status.
    pub phase: AbsolutePhase,
    /// Smallest modulation B over the periods, in units of the frames' full scale (NaN
    /// where a sample was not finite).
    pub modulation: Raster<f32>,
    /// Background A of the finest period, same units.
    pub background: Raster<f32>,
}

/// What can be wrong with a decoding request.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TemporalError {
    /// Not one frame per step of every period.
    #[error("{got} frames given; {periods} periods x {steps} steps need {expected}")]
    FrameCount {
        /// Frames given.
        got: usize,
        /// Frames needed.
        expected: usize,
        /// Periods set up.
        periods: usize,
        /// Steps per period.
        steps: usize,
    },
    /// The frames are empty or of different sizes.
    #[error(transparent)]
    Frames(#[from] PhaseError),
    /// The mask is not the frames' size.
    #[error(transparent)]
    Mask(#[from] UnwrapError),
}

/// One row decoded: `phase[p * width + x]` per period p (the pipeline's scratch).
#[derive(Clone, Debug, Default)]
pub(crate) struct DecodedRow {
    pub phase: Vec<f32>,
    pub modulation: Vec<f32>,
    /// Background A of the finest period.
    pub background: Vec<f32>,
    /// Smallest modulation over the periods.
    pub min_modulation: Vec<f32>,
    /// Absolute phase of the finest period (NaN where the heterodyne refused).
    pub absolute: Vec<f32>,
}

impl TemporalDecoder {
    /// A decoder for frames in period-major order (`frames[p * N + n]` is step n of
    /// `heterodyne`'s period p), built for the widest SIMD the CPU has.
    pub fn new(shift: PhaseShift, heterodyne: Heterodyne) -> Self {
        Self {
            shift,
            heterodyne,
            simd: Simd::best(),
        }
    }

    /// The same decoder with its row loops built for `simd` (results are identical).
    pub fn with_simd(mut self, simd: Simd) -> Self {
        self.simd = simd;
        self
    }

    /// The shift set of every period.
    pub fn shift(&self) -> &PhaseShift {
        &self.shift
    }

    /// The unwrapper (periods, field).
    pub fn heterodyne(&self) -> &Heterodyne {
        &self.heterodyne
    }

    /// Frames one capture needs: periods x steps.
    pub fn frames_needed(&self) -> usize {
        self.heterodyne.periods_px().len() * self.shift.steps()
    }

    /// Decodes a capture (period-major frames, `f32` in `[0, 1]` or camera `u8` /
    /// `u16`, scaled by the type's full scale). Pixels outside `mask` are
    /// [`PixelStatus::Masked`]; pixels whose orders the heterodyne refused are
    /// [`PixelStatus::Unreliable`].
    pub fn decode<T: Sample>(
        &self,
        frames: &[&Raster<T>],
        mask: Option<&Raster<bool>>,
    ) -> Result<TemporalPhase, TemporalError> {
        let empty = || Raster {
            width: 0,
            height: 0,
            data: Vec::new(),
        };
        let mut out = TemporalPhase {
            phase: AbsolutePhase {
                phase: empty(),
                status: Raster {
                    width: 0,
                    height: 0,
                    data: Vec::new(),
                },
                period_px: self.heterodyne.periods_px()[0],
            },
            modulation: empty(),
            background: empty(),
        };
        self.decode_into(frames, mask, &mut out)?;
        Ok(out)
    }

    /// [`TemporalDecoder::decode`] into an existing result, reusing its buffers (no
    /// fresh memory to fault in). `out` is overwritten; on error it is left as it was.
    pub fn decode_into<T: Sample>(
        &self,
        frames: &[&Raster<T>],
        mask: Option<&Raster<bool>>,
        out: &mut TemporalPhase,
    ) -> Result<(), TemporalError> {
        let (width, height) = self.check(frames, mask)?;
        let len = width * height;
        for map in [
            &mut out.phase.phase,
            &mut out.modulation,
            &mut out.background,
        ] {
            crate::huge_pages::sized(&mut map.data, len, 0.0);
            (map.width, map.height) = (width, height);
        }
        let status = &mut out.phase.status;
        crate::huge_pages::sized(&mut status.data, len, PixelStatus::Masked);
        (status.width, status.height) = (width, height);
        out.phase.period_px = self.heterodyne.periods_px()[0];

        let scale = 1.0 / T::FULL_SCALE;
        let simd = self.simd;
        out.phase
            .phase
            .data
            .par_chunks_mut(width)
            .zip(out.phase.status.data.par_chunks_mut(width))
            .zip(out.modulation.data.par_chunks_mut(width))
            .zip(out.background.data.par_chunks_mut(width))
            .enumerate()
            .for_each_init(
                DecodedRow::default,
                |row, (y, (((phase, status), modulation), background))| {
                    let span = y * width..(y + 1) * width;
                    let rows: Vec<&[T]> = frames.iter().map(|f| &f.data[span.clone()]).collect();
                    let mask = mask.map(|m| &m.data[span]);
                    // One dispatch per stage, as in the pipeline's fused pass.
                    simd_run!(simd, self.decode_row(&rows, scale, row));
                    simd_run!(simd, {
                        self.unwrap_row(row);
                        refuse_non_finite(&row.absolute, &row.min_modulation, phase);
                        modulation.copy_from_slice(&row.min_modulation);
                        background.copy_from_slice(&row.background);
                        status_row(phase, status, mask);
                    });
                },
            );
        Ok(())
    }

    /// Checks frame count and sizes and the mask's size; returns `(width, height)`.
    fn check<T>(
        &self,
        frames: &[&Raster<T>],
        mask: Option<&Raster<bool>>,
    ) -> Result<(usize, usize), TemporalError> {
        let expected = self.frames_needed();
        if frames.len() != expected {
            return Err(TemporalError::FrameCount {
                got: frames.len(),
                expected,
                periods: self.heterodyne.periods_px().len(),
                steps: self.shift.steps(),
            });
        }
        let size = check_sizes(frames)?;
        if let Some(m) = mask.filter(|m| m.size() != size) {
            return Err(UnwrapError::SizeMismatch {
                index: frames.len(),
                expected: size,
                got: m.size(),
            }
            .into());
        }
        Ok(size)
    }

    /// Decodes one row (`rows[p * N + n]` is step n of period p), samples scaled by
    /// `scale` into `[0, 1]` units: every period's wrapped phase, the finest period's
    /// modulation and background, and the smallest modulation over the periods.
    #[inline(always)]
    pub(crate) fn decode_row<T: Sample>(&self, rows: &[&[T]], scale: f32, out: &mut DecodedRow) {
        let n = self.shift.steps();
        let k = self.heterodyne.periods_px().len();
        let width = rows[0].len();
        out.phase.resize(k * width, 0.0);
        out.modulation.resize(width, 0.0);
        out.background.resize(width, 0.0);
        out.min_modulation.resize(width, 0.0);
        // The coarser periods' power, one at a time (overwritten by the unwrap stage).
        out.absolute.resize(width, 0.0);
        let (phase0, phase_rest) = out.phase.split_at_mut(width);
        self.shift.decode_row_scaled(
            &rows[..n],
            scale,
            phase0,
            &mut out.modulation,
            &mut out.background,
        );
        // Smallest power of the coarser periods; a non-finite one (NaN or infinite
        // samples) makes it NaN for good. (`f32::min` would skip a NaN.)
        let min_power = &mut out.min_modulation[..width];
        min_power.fill(f32::INFINITY);
        for (p, phase) in phase_rest.chunks_exact_mut(width).enumerate() {
            let power = &mut out.absolute[..width];
            let rows = &rows[(p + 1) * n..(p + 2) * n];
            self.shift.phase_power_row_scaled(rows, scale, phase, power);
            for (m, &q) in min_power.iter_mut().zip(power.iter()) {
                *m = if !q.is_finite() {
                    f32::NAN
                } else if q < *m {
                    q
                } else {
                    *m
                };
            }
        }
        // The smallest modulation: `(2 / N) sqrt` of the smallest power is the smallest
        // of the coarser periods' modulations, bit for bit. NaN (masked for good) where
        // any period's was not finite.
        let gain = 2.0 / n as f32;
        let first = &out.modulation[..width];
        for (m, &b0) in min_power.iter_mut().zip(first) {
            let coarser = gain * m.sqrt();
            *m = if !b0.is_finite() || m.is_nan() {
                f32::NAN
            } else if coarser < b0 {
                coarser
            } else {
                b0
            };
        }
    }

    /// Heterodyne over one decoded row: fills `row.absolute`.
    #[inline(always)]
    pub(crate) fn unwrap_row(&self, row: &mut DecodedRow) {
        self.heterodyne.unwrap_row(&row.phase, &mut row.absolute);
    }
}

/// `phase[x] = absolute[x]`, NaN where a sample was not finite (its modulation is NaN):
/// an infinite sample can leave a finite, plausible wrapped phase.
#[inline(always)]
fn refuse_non_finite(absolute: &[f32], modulation: &[f32], phase: &mut [f32]) {
    let (absolute, modulation) = (&absolute[..phase.len()], &modulation[..phase.len()]);
    for x in 0..phase.len() {
        phase[x] = if modulation[x].is_nan() {
            f32::NAN
        } else {
            absolute[x]
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const PERIODS: [f64; 3] = [16.0, 20.0, 25.0];

    fn decoder(steps: usize) -> TemporalDecoder {
        TemporalDecoder::new(
            PhaseShift::new(steps).unwrap(),
            Heterodyne::new(&PERIODS, 200.0, 1.2).unwrap(),
        )
    }

    /// Period-major frames of a slanted projector field with noise from `seed`.
    fn frames(steps: usize, width: usize, height: usize, seed: u64) -> Vec<Raster<f32>> {
        let tau = std::f64::consts::TAU;
        let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
        let mut noise = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 40) as f64 / (1u64 << 24) as f64 - 0.5) * 0.01
        };
        let mut out = Vec::new();
        for &period in &PERIODS {
            for n in 0..steps {
                let delta = tau * n as f64 / steps as f64;
                let mut f = Raster::from_fn(width, height, |x, y| {
                    let u = 3.0 + 190.0 * x as f64 / width as f64 + 2.0 * y as f64;
                    (0.5 + 0.3 * (tau * u / period + delta).cos()) as f32
                });
                for v in &mut f.data {
                    *v += noise() as f32;
                }
                out.push(f);
            }
        }
        out
    }

    /// `wrapped_phase` per period then `Heterodyne::unwrap`: the two-pass public path;
    /// also the smallest modulation over the periods and the finest's background.
    fn two_pass(
        d: &TemporalDecoder,
        frames: &[&Raster<f32>],
        mask: Option<&Raster<bool>>,
    ) -> (AbsolutePhase, Vec<f32>, Vec<f32>) {
        let wrapped: Vec<_> = frames
            .chunks(d.shift().steps())
            .map(|set| d.shift().wrapped_phase(set).unwrap())
            .collect();
        let maps: Vec<&Raster<f32>> = wrapped.iter().map(|w| &w.phase).collect();
        let smallest = (0..wrapped[0].modulation.data.len())
            .map(|i| {
                let all = wrapped.iter().map(|w| w.modulation.data[i]);
                all.fold(f32::INFINITY, |a, m| {
                    if !m.is_finite() || a.is_nan() {
                        f32::NAN
                    } else {
                        a.min(m)
                    }
                })
            })
            .collect();
        let background = wrapped[0].background.data.clone();
        (
            d.heterodyne().unwrap(&maps, mask).unwrap(),
            smallest,
            background,
        )
    }

    fn same_bits(a: &[f32], b: &[f32]) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
    }

    #[test]
    fn decodes_the_field_it_was_shown() {
        let d = decoder(4);
        let f = frames(4, 97, 5, 1);
        let refs: Vec<&Raster<f32>> = f.iter().collect();
        let out = d.decode(&refs, None).unwrap();
        assert_eq!(out.phase.count(PixelStatus::Valid), 97 * 5);
        let tau = std::f64::consts::TAU;
        for y in 0..5 {
            for x in 0..97 {
                let u = 3.0 + 190.0 * x as f64 / 97.0 + 2.0 * y as f64;
                let got = f64::from(*out.phase.phase.at(x, y));
                assert!(
                    (got - tau * u / PERIODS[0]).abs() < 0.2,
                    "({x}, {y}): {got}"
                );
                assert!((f64::from(*out.modulation.at(x, y)) - 0.3).abs() < 0.05);
                assert!((f64::from(*out.background.at(x, y)) - 0.5).abs() < 0.05);
            }
        }
    }

    #[test]
    fn camera_samples_are_scaled_by_their_full_scale() {
        let d = decoder(4);
        let f = frames(4, 40, 3, 2);
        let as_u16: Vec<Raster<u16>> = f
            .iter()
            .map(|r| Raster {
                width: r.width,
                height: r.height,
                data: r
                    .data
                    .iter()
                    .map(|&v| (v * 65535.0).round() as u16)
                    .collect(),
            })
            .collect();
        let refs: Vec<&Raster<u16>> = as_u16.iter().collect();
        let out = d.decode(&refs, None).unwrap();
        assert_eq!(out.phase.count(PixelStatus::Valid), 40 * 3);
        assert!(out.modulation.data.iter().all(|m| (m - 0.3).abs() < 0.05));
    }

    #[test]
    fn bad_requests_are_typed_errors_and_leave_the_output() {
        let d = decoder(4);
        let f = frames(4, 16, 4, 3);
        let refs: Vec<&Raster<f32>> = f.iter().collect();
        let mut out = d.decode(&refs, None).unwrap();
        let before = out.clone();
        assert_eq!(
            d.decode_into(&refs[..11], None, &mut out),
            Err(TemporalError::FrameCount {
                got: 11,
                expected: 12,
                periods: 3,
                steps: 4
            })
        );
        let small = Raster::from_fn(15, 4, |_, _| 0.5f32);
        let mut odd = refs.clone();
        odd[7] = &small;
        assert!(matches!(
            d.decode_into(&odd, None, &mut out),
            Err(TemporalError::Frames(PhaseError::SizeMismatch {
                index: 7,
                ..
            }))
        ));
        let mask = Raster::from_fn(16, 3, |_, _| true);
        assert!(matches!(
            d.decode_into(&refs, Some(&mask), &mut out),
            Err(TemporalError::Mask(UnwrapError::SizeMismatch { .. }))
        ));
        assert_eq!(out, before);
    }

    #[test]
    fn a_non_finite_sample_is_refused_not_guessed() {
        let d = decoder(4);
        let mut f = frames(4, 16, 2, 4);
        f[5].data[3] = f32::NAN;
        f[9].data[20] = f32::INFINITY;
        let refs: Vec<&Raster<f32>> = f.iter().collect();
        let out = d.decode(&refs, None).unwrap();
        for i in [3, 20] {
            assert_eq!(out.phase.status.data[i], PixelStatus::Unreliable, "{i}");
            assert!(out.phase.phase.data[i].is_nan());
            assert!(out.modulation.data[i].is_nan());
        }
        assert_eq!(out.phase.count(PixelStatus::Valid), 30);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn one_pass_gives_the_two_pass_bits(
            width in 1usize..300,
            height in 1usize..4,
            steps in prop::sample::select(vec![3usize, 4, 5, 8]),
            seed in any::<u64>(),
            masked in any::<bool>(),
            camera in any::<bool>(),
        ) {
            let d = decoder(steps);
            let mut f = frames(steps, width, height, seed);
            let mask = Raster::from_fn(width, height, |x, y| !(x * 7 + y * 3 + seed as usize).is_multiple_of(5));
            let mask = masked.then_some(&mask);
            // Camera frames: the two-pass path gets the same samples scaled to [0, 1].
            let words: Vec<Raster<u16>> = f
                .iter()
                .map(|r| Raster {
                    width,
                    height,
                    data: r.data.iter().map(|&v| (v * 65535.0).round() as u16).collect(),
                })
                .collect();
            if camera {
                for (r, w) in f.iter_mut().zip(&words) {
                    for (v, &q) in r.data.iter_mut().zip(&w.data) {
                        *v = f32::from(q) * (1.0 / 65535.0);
                    }
                }
            }
            let refs: Vec<&Raster<f32>> = f.iter().collect();
            let (want, smallest, background) = two_pass(&d, &refs, mask);
            for simd in [Simd::Baseline, Simd::best()] {
                let d = d.clone().with_simd(simd);
                let got = if camera {
                    d.decode(&words.iter().collect::<Vec<_>>(), mask).unwrap()
                } else {
                    d.decode(&refs, mask).unwrap()
                };
                prop_assert!(same_bits(&got.phase.phase.data, &want.phase.data));
                prop_assert_eq!(&got.phase.status, &want.status);
                prop_assert!(same_bits(&got.modulation.data, &smallest));
                prop_assert!(same_bits(&got.background.data, &background));
            }
        }
    }
}
