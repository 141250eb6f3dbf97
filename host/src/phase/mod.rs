//! Decoding fringes: wrapped phase, background and modulation.
//!
//! N-step phase shifting (DESIGN.md convention): the n-th frame is
//! `I_n = A + B cos(phi + delta_n)` with `delta_n = 2 pi k n / N` (`k = 1` normally; other
//! temporal bins separate heads multiplexed in time), and
//!
//! ```text
//! phi = atan2(-sum I_n sin delta_n, sum I_n cos delta_n)   in (-pi, pi]
//! B   = (2/N) |sum I_n e^{-i delta_n}|,   A = (1/N) sum I_n
//! ```
//!
//! With Gaussian intensity noise `sigma_I` this estimator reaches the Cramér-Rao bound
//! `sigma_phi = sigma_I sqrt(2/N) / B` ([`phase_noise_crb`]). Single-shot images go through
//! Fourier transform profilometry in [`ftp`].

pub mod ftp;
mod sample;

pub use sample::Sample;

use crate::raster::Raster;
use crate::simd::{simd_run, Simd};

/// What can be wrong with a set of phase-shifted frames.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PhaseError {
    /// Fewer frames than the method needs.
    #[error("{got} phase-shifted frames given, at least {need} needed")]
    NotEnoughFrames {
        /// Frames given.
        got: usize,
        /// Frames needed.
        need: usize,
    },
    /// The frame count does not match the shift set.
    #[error("{got} frames given for a {steps}-step shift set")]
    WrongFrameCount {
        /// Frames given.
        got: usize,
        /// Steps of the shift set.
        steps: usize,
    },
    /// A frame's size differs from the first frame's.
    #[error("frame {index} is {got:?} but frame 0 is {expected:?} (width, height)")]
    SizeMismatch {
        /// Index of the offending frame.
        index: usize,
        /// Size of frame 0.
        expected: (usize, usize),
        /// Size of the offending frame.
        got: (usize, usize),
    },
    /// The temporal bin cannot be separated with this many steps.
    #[error("temporal bin {bin} is not in 1..{steps}/2 (needs 2*bin < steps)")]
    BadBin {
        /// Bin asked for.
        bin: usize,
        /// Steps.
        steps: usize,
    },
    /// FTP needs at least two periods per line and more than two pixels per period.
    #[error("FTP carrier of period {period_px} px does not fit lines of {length_px} px (need 2..length/2 periods)")]
    CarrierOutOfBand {
        /// Fringe period asked for, pixels.
        period_px: f64,
        /// Line length, pixels.
        length_px: usize,
    },
    /// The frames have no pixels.
    #[error("frames are empty (0 pixels)")]
    Empty,
}

/// An N-step shift set with its precomputed sines and cosines (set up once, used per pixel).
#[derive(Clone, Debug, PartialEq)]
pub struct PhaseShift {
    steps: usize,
    bin: usize,
    cos: Vec<f32>,
    sin: Vec<f32>,
}

/// Wrapped phase, modulation and background of one shift set.
#[derive(Clone, Debug, PartialEq)]
pub struct WrappedPhase {
    /// Wrapped phase, radians, in (-pi, pi].
    pub phase: Raster<f32>,
    /// Modulation B (same units as the frames).
    pub modulation: Raster<f32>,
    /// Background A (same units as the frames).
    pub background: Raster<f32>,
}

impl PhaseShift {
    /// The standard N-step set, `delta_n = 2 pi n / N`, `N >= 3`.
    pub fn new(steps: usize) -> Result<Self, PhaseError> {
        Self::with_bin(steps, 1)
    }

    /// Shifts advancing at temporal frequency `bin`: `delta_n = 2 pi bin n / N`.
    ///
    /// Needs `2 * bin < N` so that the bin is neither DC nor its own mirror.
    pub fn with_bin(steps: usize, bin: usize) -> Result<Self, PhaseError> {
        if steps < 3 {
            return Err(PhaseError::NotEnoughFrames {
                got: steps,
                need: 3,
            });
        }
        if bin == 0 || 2 * bin >= steps {
            return Err(PhaseError::BadBin { bin, steps });
        }
        let delta = |n: usize| 2.0 * std::f64::consts::PI * (bin * n) as f64 / steps as f64;
        // Exact 0 and +-1 where the shift is a multiple of a quarter turn (cos(pi / 2) is
        // 6e-17 in floating point), so the 4-step fast path agrees bit for bit.
        let exact = |v: f64| -> f32 {
            let r = v.round();
            if (v - r).abs() < 1e-12 {
                r as f32
            } else {
                v as f32
            }
        };
        Ok(Self {
            steps,
            bin,
            cos: (0..steps).map(|n| exact(delta(n).cos())).collect(),
            sin: (0..steps).map(|n| exact(delta(n).sin())).collect(),
        })
    }

    /// Number of steps N.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// The shifts `delta_n`, radians.
    pub fn shifts_rad(&self) -> Vec<f64> {
        (0..self.steps)
            .map(|n| 2.0 * std::f64::consts::PI * (self.bin * n) as f64 / self.steps as f64)
            .collect()
    }

    /// Sums `(sum I_n cos delta_n, -sum I_n sin delta_n, sum I_n)` over one pixel's samples.
    #[inline]
    pub fn sums(&self, samples: impl IntoIterator<Item = f32>) -> (f32, f32, f32) {
        let (mut re, mut im, mut total) = (0.0f32, 0.0f32, 0.0f32);
        for ((i, c), s) in samples.into_iter().zip(&self.cos).zip(&self.sin) {
            re += i * c;
            im -= i * s;
            total += i;
        }
        (re, im, total)
    }

    /// `(phase, modulation, background)` of one pixel from its N samples.
    #[inline]
    pub fn decode(&self, samples: impl IntoIterator<Item = f32>) -> (f32, f32, f32) {
        let (re, im, total) = self.sums(samples);
        let n = self.steps as f32;
        (
            fast_atan2(im, re),
            (2.0 / n) * (re * re + im * im).sqrt(),
            total / n,
        )
    }

    /// Decodes one image row: `rows[n]` is the row of frame n; outputs are per column.
    ///
    /// The per-pixel results are bit-identical to [`PhaseShift::decode`] (same operation
    /// order); see [`PhaseShift::decode_row_scaled`] for integer frames.
    pub fn decode_row(
        &self,
        rows: &[&[f32]],
        phase: &mut [f32],
        modulation: &mut [f32],
        background: &mut [f32],
    ) {
        self.decode_row_scaled(rows, 1.0, phase, modulation, background);
    }

    /// [`PhaseShift::decode_row`] for any [`Sample`] type: each sample is multiplied by
    /// `scale` (`1 / full scale` gives modulation and background in `[0, 1]` units; the
    /// phase does not depend on it). With `scale = 1` the result is bit-identical to
    /// [`PhaseShift::decode`].
    ///
    /// Works in tiles of columns so the sums stay in L1 cache, with the shift index
    /// outside the column loops so they vectorise.
    #[inline(always)]
    pub fn decode_row_scaled<T: Sample>(
        &self,
        rows: &[&[T]],
        scale: f32,
        phase: &mut [f32],
        modulation: &mut [f32],
        background: &mut [f32],
    ) {
        const TILE: usize = 256;
        let width = phase.len();
        if self.steps == 4 && self.bin == 1 {
            return decode_row_four_step(rows, scale, phase, modulation, background);
        }
        let n = self.steps as f32;
        let mut x0 = 0;
        while x0 < width {
            let len = TILE.min(width - x0);
            let (mut re, mut im, mut total) = ([0.0f32; TILE], [0.0f32; TILE], [0.0f32; TILE]);
            let (re, im, total) = (&mut re[..len], &mut im[..len], &mut total[..len]);
            for ((row, &c), &s) in rows.iter().zip(&self.cos).zip(&self.sin) {
                let row = &row[x0..x0 + len];
                for x in 0..len {
                    let i = row[x].to_f32() * scale;
                    re[x] += i * c;
                    im[x] -= i * s;
                    total[x] += i;
                }
            }
            let phase = &mut phase[x0..x0 + len];
            let modulation = &mut modulation[x0..x0 + len];
            let background = &mut background[x0..x0 + len];
            for x in 0..len {
                phase[x] = fast_atan2(im[x], re[x]);
                modulation[x] = (2.0 / n) * (re[x] * re[x] + im[x] * im[x]).sqrt();
                background[x] = total[x] / n;
            }
            x0 += len;
        }
    }

    /// Decodes whole frames (in shift order) into wrapped phase, modulation and background.
    ///
    /// Rayon over rows, each through [`PhaseShift::decode_row_scaled`] (the pipeline's
    /// kernel) built for the widest SIMD the CPU has, so a pixel gets the same bits as
    /// from [`PhaseShift::decode`].
    pub fn wrapped_phase(&self, frames: &[&Raster<f32>]) -> Result<WrappedPhase, PhaseError> {
        let empty = || Raster {
            width: 0,
            height: 0,
            data: Vec::new(),
        };
        let mut out = WrappedPhase {
            phase: empty(),
            modulation: empty(),
            background: empty(),
        };
        self.wrapped_phase_into(frames, &mut out)?;
        Ok(out)
    }

    /// [`PhaseShift::wrapped_phase`] into an existing result, reusing its buffers: a
    /// scanner decoding capture after capture saves the fresh memory's page faults (the
    /// kernel clearing three maps per call). `out` is overwritten; on error it is left
    /// as it was.
    pub fn wrapped_phase_into(
        &self,
        frames: &[&Raster<f32>],
        out: &mut WrappedPhase,
    ) -> Result<(), PhaseError> {
        if frames.len() != self.steps {
            return Err(PhaseError::WrongFrameCount {
                got: frames.len(),
                steps: self.steps,
            });
        }
        let (width, height) = check_sizes(frames)?;
        // Every element is written by the row pass; fresh memory is filled in parallel on
        // huge pages so its page faults are not one thread's serial cost.
        for map in [&mut out.phase, &mut out.modulation, &mut out.background] {
            crate::huge_pages::sized(&mut map.data, width * height, 0.0);
            (map.width, map.height) = (width, height);
        }
        let simd = Simd::best();
        use rayon::prelude::*;
        out.phase
            .data
            .par_chunks_mut(width)
            .zip(out.modulation.data.par_chunks_mut(width))
            .zip(out.background.data.par_chunks_mut(width))
            .enumerate()
            .for_each(|(y, ((p, m), b))| {
                let span = y * width..(y + 1) * width;
                let rows: Vec<&[f32]> = frames.iter().map(|f| &f.data[span.clone()]).collect();
                // The pipeline's row kernel, built for the widest SIMD the CPU has.
                simd_run!(simd, self.decode_row_scaled(&rows, 1.0, p, m, b));
            });
        Ok(())
    }
}

/// [`PhaseShift::decode_row_scaled`] for the standard 4-step set (`cos delta_n` = 1, 0, -1,
/// 0 and `sin delta_n` = 0, 1, 0, -1): one pass over the four rows with no accumulators,
/// giving the same bits as the general loop (its products by 0 and 1 are exact).
#[inline(always)]
fn decode_row_four_step<T: Sample>(
    rows: &[&[T]],
    scale: f32,
    phase: &mut [f32],
    modulation: &mut [f32],
    background: &mut [f32],
) {
    let width = phase.len();
    // Cut to one length so that the loop has no bounds checks and vectorises.
    let [r0, r1, r2, r3] = [0, 1, 2, 3].map(|n| &rows[n][..width]);
    let (modulation, background) = (&mut modulation[..width], &mut background[..width]);
    for_each_four_step(
        r0,
        r1,
        r2,
        r3,
        scale,
        #[inline(always)]
        |x, [i0, i1, i2, i3]| {
            let (re, im) = (i0 - i2, i3 - i1);
            phase[x] = fast_atan2(im, re);
            modulation[x] = 0.5 * (re * re + im * im).sqrt();
            // Multiplying by 1/4 is exact, the same as the general loop's division by 4.
            background[x] = (i0 + i1 + i2 + i3) * 0.25;
        },
    );
}

/// `body(x, [i0, i1, i2, i3])` for every column of four rows of one width, the samples
/// times `scale`. At `scale = 1` (float frames) the multiply is left out: it is exact
/// there, and one of the few operations per sample.
#[inline(always)]
fn for_each_four_step<T: Sample>(
    r0: &[T],
    r1: &[T],
    r2: &[T],
    r3: &[T],
    scale: f32,
    mut body: impl FnMut(usize, [f32; 4]),
) {
    let width = r0.len();
    let (r1, r2, r3) = (&r1[..width], &r2[..width], &r3[..width]);
    if scale == 1.0 {
        for x in 0..width {
            body(x, [r0[x], r1[x], r2[x], r3[x]].map(|v| v.to_f32()));
        }
    } else {
        for x in 0..width {
            body(x, [r0[x], r1[x], r2[x], r3[x]].map(|v| v.to_f32() * scale));
        }
    }
}

impl PhaseShift {
    /// The wrapped phase of one row and its power `P = re^2 + im^2` (modulation is
    /// `(2 / N) sqrt(P)`), nothing else: for periods whose phase only feeds the
    /// unwrapping, whose smallest modulation is then one square root of the smallest
    /// power (the same bits: square root and scaling never reorder two values). Same
    /// phase bits as [`PhaseShift::decode_row_scaled`].
    #[inline(always)]
    pub(crate) fn phase_power_row_scaled<T: Sample>(
        &self,
        rows: &[&[T]],
        scale: f32,
        phase: &mut [f32],
        power: &mut [f32],
    ) {
        const TILE: usize = 256;
        let width = phase.len();
        let power = &mut power[..width];
        if self.steps == 4 && self.bin == 1 {
            let [r0, r1, r2, r3] = [0, 1, 2, 3].map(|n| &rows[n][..width]);
            let phase = &mut phase[..width];
            for_each_four_step(
                r0,
                r1,
                r2,
                r3,
                scale,
                #[inline(always)]
                |x, [i0, i1, i2, i3]| {
                    let (re, im) = (i0 - i2, i3 - i1);
                    phase[x] = fast_atan2(im, re);
                    power[x] = re * re + im * im;
                },
            );
            return;
        }
        let mut x0 = 0;
        while x0 < width {
            let len = TILE.min(width - x0);
            let (mut re, mut im) = ([0.0f32; TILE], [0.0f32; TILE]);
            let (re, im) = (&mut re[..len], &mut im[..len]);
            for ((row, &c), &s) in rows.iter().zip(&self.cos).zip(&self.sin) {
                let row = &row[x0..x0 + len];
                for x in 0..len {
                    let i = row[x].to_f32() * scale;
                    re[x] += i * c;
                    im[x] -= i * s;
                }
            }
            for x in 0..len {
                phase[x0 + x] = fast_atan2(im[x], re[x]);
                power[x0 + x] = re[x] * re[x] + im[x] * im[x];
            }
            x0 += len;
        }
    }
}

/// Checks that frames are non-empty and all the same size; returns `(width, height)`.
pub fn check_sizes<T>(frames: &[&Raster<T>]) -> Result<(usize, usize), PhaseError> {
    let first = frames
        .first()
        .ok_or(PhaseError::NotEnoughFrames { got: 0, need: 1 })?;
    let expected = first.size();
    if first.is_empty() {
        return Err(PhaseError::Empty);
    }
    for (index, f) in frames.iter().enumerate() {
        if f.size() != expected || f.data.len() != expected.0 * expected.1 {
            return Err(PhaseError::SizeMismatch {
                index,
                expected,
                got: f.size(),
            });
        }
    }
    Ok(expected)
}

/// Pixels whose modulation is at least `min_modulation` (true = usable).
pub fn modulation_mask(modulation: &Raster<f32>, min_modulation: f32) -> Raster<bool> {
    Raster {
        width: modulation.width,
        height: modulation.height,
        data: modulation
            .data
            .iter()
            .map(|&b| b >= min_modulation)
            .collect(),
    }
}

/// Cramér-Rao bound on the wrapped-phase standard deviation, radians:
/// `sigma_I sqrt(2/N) / B` for Gaussian intensity noise `sigma_I`.
pub fn phase_noise_crb(sigma_intensity: f64, steps: usize, modulation: f64) -> f64 {
    sigma_intensity * (2.0 / steps as f64).sqrt() / modulation
}

/// Wraps an angle into (-pi, pi].
#[inline]
pub fn wrap_pi(a: f32) -> f32 {
    use std::f32::consts::PI;
    let w = a - (2.0 * PI) * ((a + PI) / (2.0 * PI)).floor();
    // floor puts exactly +pi at -pi; the convention keeps +pi.
    if w <= -PI {
        w + 2.0 * PI
    } else {
        w
    }
}

/// `atan2(y, x)` to within 1.2e-6 rad (checked in the tests), several times faster than
/// `f32::atan2`: the phase of every pixel of every frequency goes through here.
#[inline(always)]
pub fn fast_atan2(y: f32, x: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, PI};
    // Branch-free (selects only) so that row loops vectorise.
    let ax = x.abs();
    let ay = y.abs();
    // Selects rather than `f32::min`/`max`, which skip a NaN: a NaN input (a corrupt
    // sample) must give a NaN phase, not a plausible one.
    let (num, den) = if ax < ay { (ax, ay) } else { (ay, ax) };
    // 0/0 -> 0: the smallest positive normal keeps the quotient finite.
    let t = num
        / if den < f32::MIN_POSITIVE {
            f32::MIN_POSITIVE
        } else {
            den
        };
    let t2 = t * t;
    // Abramowitz & Stegun 4.4.49: atan(t)/t on [0, 1] to 2e-8, then f32 rounding.
    // Plain multiply-adds: `mul_add` would call libm's fmaf without the `fma` target feature.
    let p = 0.002_866_225_7f32 * t2 - 0.016_165_737;
    let p = p * t2 + 0.042_909_614;
    let p = p * t2 - 0.075_289_64;
    let p = p * t2 + 0.106_562_64;
    let p = p * t2 - 0.142_089;
    let p = p * t2 + 0.199_935_51;
    let p = p * t2 - 0.333_331_45;
    let r = t * (p * t2 + 1.0);
    let r = if ay > ax { FRAC_PI_2 - r } else { r };
    let r = if x < 0.0 { PI - r } else { r };
    if y < 0.0 {
        -r
    } else {
        r
    }
}

/// `(sin a, cos a)` to within 3e-7 on [0, 2 pi) and 1.5e-6 for `|a| < 1e4` (checked
/// in the tests), branch-free so that loops over carriers vectorise: libm's `sincosf`
/// is a call per value, and the high-speed demultiplexer needs one per pixel of each
/// of its 24 patterns.
#[inline(always)]
pub fn fast_sin_cos(a: f32) -> (f32, f32) {
    // Quadrant by adding and removing 1.5 x 2^23 (nearest, ties even; exact for
    // |q| < 2^22): no float-to-int cast, which Rust saturates and LLVM then
    // leaves scalar. The same sum's low mantissa bits are q mod 4.
    const MAGIC: f32 = 12_582_912.0;
    let shifted = a * std::f32::consts::FRAC_2_PI + MAGIC;
    let quadrant = shifted.to_bits() & 3;
    let q = shifted - MAGIC;
    // Cody-Waite: pi/2 in three parts, so r keeps its bits for large q.
    let r = a - q * 1.570_312_5 - q * 4.837_513e-4 - q * 7.549_79e-8;
    let r2 = r * r;
    // Cephes' minimax polynomials on [-pi/4, pi/4].
    let s = ((-1.951_529_6e-4 * r2 + 8.332_161e-3) * r2 - 1.666_665_5e-1) * r2 * r + r;
    let c =
        ((2.443_315_7e-5 * r2 - 1.388_731_6e-3) * r2 + 4.166_664_6e-2) * r2 * r2 - 0.5 * r2 + 1.0;
    let (sin, cos) = if quadrant & 1 == 0 { (s, c) } else { (c, s) };
    let sin = if quadrant & 2 == 0 { sin } else { -sin };
    let cos = if (quadrant + 1) & 2 == 0 { cos } else { -cos };
    (sin, cos)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn fast_atan2_matches_std() {
        let mut worst = 0.0f64;
        for i in 0..20_000 {
            let a = -PI + 2.0 * PI * (i as f64 + 0.37) / 20_000.0;
            for r in [1e-3f64, 0.5, 7.0] {
                let (y, x) = ((r * a.sin()) as f32, (r * a.cos()) as f32);
                let got = fast_atan2(y, x) as f64;
                let want = (y as f64).atan2(x as f64);
                let mut d = (got - want).abs();
                d = d.min((d - 2.0 * PI).abs());
                worst = worst.max(d);
            }
        }
        assert!(worst < 1.2e-6, "worst error {worst}");
        assert_eq!(fast_atan2(0.0, 0.0), 0.0);
        // A corrupt sample's NaN reaches the phase.
        for (y, x) in [(f32::NAN, 1.0), (1.0, f32::NAN), (f32::NAN, f32::NAN)] {
            assert!(fast_atan2(y, x).is_nan(), "atan2({y}, {x})");
        }
    }

    #[test]
    fn fast_sin_cos_matches_std() {
        // (range, worst error allowed): the carriers' [0, 2 pi), then wider
        // angles of both signs, where the reduction's rounding adds a little.
        for (scale, offset, limit) in [(2.0 * PI, 0.0, 3e-7), (2e4, -1e4, 1.5e-6)] {
            let mut worst = 0.0f64;
            for i in 0..200_000 {
                let a = (offset + scale * i as f64 / 200_000.0) as f32;
                let (s, c) = fast_sin_cos(a);
                let (ws, wc) = f64::from(a).sin_cos();
                worst = worst.max((f64::from(s) - ws).abs().max((f64::from(c) - wc).abs()));
            }
            assert!(worst < limit, "worst error {worst} over {scale} rad");
        }
        let (s, c) = fast_sin_cos(f32::NAN);
        assert!(s.is_nan() && c.is_nan());
    }

    #[test]
    fn decodes_exact_samples_for_many_n() {
        for steps in 3..=12 {
            let shift = PhaseShift::new(steps).unwrap();
            for &phi in &[-3.0f64, -1.0, 0.0, 0.5, 2.9] {
                let samples: Vec<f32> = shift
                    .shifts_rad()
                    .iter()
                    .map(|d| (0.4 + 0.3 * (phi + d).cos()) as f32)
                    .collect();
                let (p, b, a) = shift.decode(samples.iter().copied());
                assert!((p as f64 - phi).abs() < 1e-5, "N={steps} phi={phi} got {p}");
                assert!((b - 0.3).abs() < 1e-5 && (a - 0.4).abs() < 1e-5);
            }
        }
    }

    #[test]
    fn temporal_bins_separate_two_heads() {
        let steps = 8;
        let a = PhaseShift::with_bin(steps, 1).unwrap();
        let b = PhaseShift::with_bin(steps, 2).unwrap();
        let (pa, pb) = (0.7f64, -2.1f64);
        let samples: Vec<f32> = (0..steps)
            .map(|n| {
                let d = 2.0 * PI * n as f64 / steps as f64;
                (0.5 + 0.2 * (pa + d).cos() + 0.15 * (pb + 2.0 * d).cos()) as f32
            })
            .collect();
        let (ga, ma, _) = a.decode(samples.iter().copied());
        let (gb, mb, _) = b.decode(samples.iter().copied());
        assert!((ga as f64 - pa).abs() < 1e-5 && (ma - 0.2).abs() < 1e-5);
        assert!((gb as f64 - pb).abs() < 1e-5 && (mb - 0.15).abs() < 1e-5);
        assert!(matches!(
            PhaseShift::with_bin(4, 2),
            Err(PhaseError::BadBin { .. })
        ));
    }

    #[test]
    fn frame_errors_are_typed() {
        assert!(matches!(
            PhaseShift::new(2),
            Err(PhaseError::NotEnoughFrames { got: 2, .. })
        ));
        let s = PhaseShift::new(3).unwrap();
        let a = Raster::filled(4, 3, 0.5f32);
        let b = Raster::filled(3, 4, 0.5f32);
        assert_eq!(
            s.wrapped_phase(&[&a, &a]),
            Err(PhaseError::WrongFrameCount { got: 2, steps: 3 })
        );
        assert_eq!(
            s.wrapped_phase(&[&a, &a, &b]),
            Err(PhaseError::SizeMismatch {
                index: 2,
                expected: (4, 3),
                got: (3, 4)
            })
        );
        let e = Raster::filled(0, 0, 0.0f32);
        assert_eq!(s.wrapped_phase(&[&e, &e, &e]), Err(PhaseError::Empty));
    }

    #[test]
    fn wrap_pi_keeps_the_convention() {
        use std::f32::consts::PI;
        assert_eq!(wrap_pi(PI), PI);
        assert!((wrap_pi(-PI) - PI).abs() < 1e-6);
        assert!((wrap_pi(3.0 * PI + 0.1) - (-PI + 0.1)).abs() < 1e-5);
        assert!((wrap_pi(0.2) - 0.2).abs() < 1e-7);
    }

    mod proptests {
        use super::super::*;
        use proptest::prelude::*;

        proptest! {
            #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]
            #[test]
            fn row_kernel_gives_the_per_pixel_bits(
                steps in 3usize..9,
                samples in proptest::collection::vec(0u16..4096, 8 * 37),
            ) {
                // Steps 4 take the one-pass path; 37 columns leave vector tails.
                let shift = PhaseShift::new(steps).unwrap();
                let width = 37;
                let rows: Vec<&[u16]> = samples.chunks(width).take(steps).collect();
                let (mut p, mut m, mut b) = (vec![0.0; width], vec![0.0; width], vec![0.0; width]);
                let scale = 1.0 / 4095.0;
                shift.decode_row_scaled(&rows, scale, &mut p, &mut m, &mut b);
                for x in 0..width {
                    let (wp, wm, wb) = shift.decode(rows.iter().map(|r| f32::from(r[x]) * scale));
                    prop_assert_eq!(
                        [p[x], m[x], b[x]].map(f32::to_bits),
                        [wp, wm, wb].map(f32::to_bits),
                        "column {}", x
                    );
                }
            }

            #[test]
            fn map_api_gives_the_per_pixel_bits(
                steps in 3usize..7,
                (width, height) in (1usize..41, 1usize..5),
                samples in proptest::collection::vec(-0.5f32..1.5, 6 * 40 * 4),
            ) {
                // The whole-map API through the pipeline's row kernel (in its AVX2 build
                // where the CPU has one) against the per-pixel decode.
                let shift = PhaseShift::new(steps).unwrap();
                let len = width * height;
                let frames: Vec<Raster<f32>> = samples
                    .chunks(len)
                    .take(steps)
                    .map(|c| Raster { width, height, data: c.to_vec() })
                    .collect();
                let refs: Vec<&Raster<f32>> = frames.iter().collect();
                let out = shift.wrapped_phase(&refs).unwrap();
                // Into a result of another size: the same maps.
                let stale = Raster::filled(3, 7, 0.25f32);
                let mut reused = shift.wrapped_phase(&vec![&stale; steps]).unwrap();
                shift.wrapped_phase_into(&refs, &mut reused).unwrap();
                prop_assert_eq!(&reused, &out);
                for i in 0..len {
                    let (wp, wm, wb) = shift.decode(frames.iter().map(|f| f.data[i]));
                    prop_assert_eq!(
                        [out.phase.data[i], out.modulation.data[i], out.background.data[i]]
                            .map(f32::to_bits),
                        [wp, wm, wb].map(f32::to_bits),
                        "pixel {}", i
                    );
                }
            }

            #[test]
            fn kernel_matches_slow_reference(
                steps in 3usize..10,
                samples in proptest::collection::vec(0.0f32..1.0, 10),
            ) {
                let shift = PhaseShift::new(steps).unwrap();
                let s = &samples[..steps];
                let (p, b, a) = shift.decode(s.iter().copied());
                // Slow reference straight from the DESIGN.md formula, in f64.
                let (mut re, mut im) = (0.0f64, 0.0f64);
                for (n, &i) in s.iter().enumerate() {
                    let d = 2.0 * std::f64::consts::PI * n as f64 / steps as f64;
                    re += i as f64 * d.cos();
                    im -= i as f64 * d.sin();
                }
                let mag = (2.0 / steps as f64) * (re * re + im * im).sqrt();
                prop_assert!((b as f64 - mag).abs() < 1e-5);
                let mean = s.iter().map(|&v| v as f64).sum::<f64>() / steps as f64;
                prop_assert!((a as f64 - mean).abs() < 1e-5);
                if mag > 1e-3 {
                    let want = im.atan2(re);
                    let mut d = (p as f64 - want).abs();
                    d = d.min((d - 2.0 * std::f64::consts::PI).abs());
                    prop_assert!(d < 1e-3, "phase {} vs {}", p, want);
                }
            }
        }
    }
}
