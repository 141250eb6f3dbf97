//! The classical restorer: Wiener deconvolution with the forward-scatter
//! Gaussian, then backscatter-veil subtraction, from the known degradation
//! model (seed 002 eq. 2 and 10; the twin's `medium.rs`).
//!
//! Choices, and why:
//!
//! - **PSF sigma is given**, not estimated per frame. The Gaussian's sigma
//!   is the medium's forward-scatter rate times the camera-side water path
//!   (`sigma_s ~ b_f z`); a scanner knows its working distance and the
//!   water it is set for, while a blind estimate from a fringe frame cannot
//!   tell a blurred fringe from a low-contrast surface (the modulation
//!   depends on the albedo as much as on the blur).
//! - **The signal spectrum is estimated from the frame**: the Wiener gain
//!   `H / (H^2 + N sigma_n^2 / P_x)` needs the clean signal's power `P_x`;
//!   it is taken from the frame's own periodogram smoothed over 3 x 3 bins,
//!   less the noise power (`P_x = (P_y - N sigma_n^2) / H^2`). A fringe's
//!   spectrum is a few peaks (background, carrier, object edges), so this
//!   keeps and sharpens the carrier and drops the bins that hold only
//!   noise: one frame, no tuning per turbidity. The gain is capped at
//!   `max_gain` where the PSF has all but erased a band.
//! - **Noise sigma from the frame**: the median absolute response to a
//!   3 x 3 second-difference mask (Immerkaer 1996; median instead of mean,
//!   so edges do not count). A blurred fringe has almost no energy there.
//! - **Mirror padding** to twice the size in each axis: the padded frame is
//!   periodic and continuous, so the FFT's wrap-around adds no ringing at
//!   the borders (the symmetric PSF makes this the reflective-boundary
//!   deconvolution).
//! - **The veil is estimated from the frame itself, after deconvolution**:
//!   the projected fringe reaches its minimum once per period, so the low
//!   percentile of a block at least one period wide is the additive floor
//!   (backscatter veil plus ambient light), and the veil varies only with
//!   the water path, slowly. Flat or dark frames do not isolate it: a dark
//!   frame has no veil (the projector makes it), a full-on flat has twice a
//!   fringe frame's. Deconvolution and subtraction are both linear and the
//!   veil is smooth, so their order does not change the veil removed; but
//!   after deconvolution the floor is the fringe's true minimum, while
//!   before it the troughs still hold light the blur moved into them.
//! - **Flagged pixels are never invented**: NaN, infinite and saturated
//!   pixels are filled from their block's median only so the transform can
//!   run, and come out NaN.

use std::sync::Arc;

use rayon::prelude::*;
use rustfft::num_complex::Complex32;
use rustfft::{Fft, FftPlanner};

use crate::raster::Raster;

/// Smallest image side the restorer takes, pixels (the noise estimate's
/// 3 x 3 windows need an interior).
pub const MIN_SIDE_PX: usize = 8;

/// Largest forward-scatter sigma accepted, pixels: a fringe of period `P`
/// keeps `exp(-2 pi^2 sigma^2 / P^2)` of its modulation, under 1e-8 for
/// sigma = P at any period the scanner projects; beyond this nothing is left
/// to restore.
pub const MAX_PSF_SIGMA_PX: f64 = 32.0;

/// What is wrong with a frame or the restorer's parameters.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RestoreError {
    /// A side is shorter than [`MIN_SIDE_PX`].
    #[error("image is {width}x{height}: each side must be at least {min_px} pixels")]
    TooSmall {
        /// Columns.
        width: usize,
        /// Rows.
        height: usize,
        /// Smallest side accepted.
        min_px: usize,
    },
    /// The buffer does not hold `width * height` values.
    #[error("image buffer holds {len} values, {width}x{height} needs {}", width * height)]
    BufferSize {
        /// Values in the buffer.
        len: usize,
        /// Columns claimed.
        width: usize,
        /// Rows claimed.
        height: usize,
    },
    /// The frame's size is not the one the restorer was built for.
    #[error("frame is {got:?} but the restorer was built for {expected:?} (width, height)")]
    SizeMismatch {
        /// Size the restorer was built for.
        expected: (usize, usize),
        /// Size of the frame given.
        got: (usize, usize),
    },
    /// The PSF sigma is NaN, infinite, negative or beyond [`MAX_PSF_SIGMA_PX`].
    #[error("forward-scatter PSF sigma {sigma_px} px: must be finite, >= 0 and <= {max_px}")]
    BadPsfSigma {
        /// Sigma given, pixels.
        sigma_px: f64,
        /// Largest accepted, pixels.
        max_px: f64,
    },
    /// Another parameter is out of its range.
    #[error("{name} = {value}: {why}")]
    BadParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// Its range.
        why: &'static str,
    },
    /// Every pixel is NaN, infinite or saturated: there is nothing to restore.
    #[error("no valid pixel: all {pixels} are NaN, infinite or saturated")]
    NoValidPixels {
        /// Pixels in the frame.
        pixels: usize,
    },
}

/// How to restore: the PSF, the deconvolution's cap, the veil estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RestoreParams {
    /// Forward-scatter Gaussian sigma in camera pixels: the medium's sigma
    /// per metre of water times the camera-side water path.
    pub psf_sigma_px: f64,
    /// Largest gain the deconvolution applies at any spatial frequency (> 1).
    pub max_gain: f64,
    /// Side of the square blocks the veil floor is taken over, pixels; at
    /// least one fringe period, so every block holds a trough.
    pub veil_block_px: usize,
    /// Percentile of each block's restored values taken as its floor (0..50).
    pub veil_percentile: f64,
    /// Values at or above this level are saturated and masked (1 for frames
    /// in [0, 1] whose top code is full scale).
    pub saturation_level: f32,
}

impl RestoreParams {
    /// Defaults around a given PSF sigma: gain capped at 20, veil from the
    /// 2nd percentile of 64-pixel blocks, saturation at 1.0.
    pub fn new(psf_sigma_px: f64) -> Self {
        Self {
            psf_sigma_px,
            max_gain: 20.0,
            veil_block_px: 64,
            veil_percentile: 2.0,
            saturation_level: 1.0,
        }
    }

    /// Rejects parameters out of range.
    pub fn validate(&self) -> Result<(), RestoreError> {
        let s = self.psf_sigma_px;
        if !(s.is_finite() && (0.0..=MAX_PSF_SIGMA_PX).contains(&s)) {
            return Err(RestoreError::BadPsfSigma {
                sigma_px: s,
                max_px: MAX_PSF_SIGMA_PX,
            });
        }
        if !(self.max_gain.is_finite() && self.max_gain > 1.0) {
            return Err(RestoreError::BadParameter {
                name: "max_gain",
                value: self.max_gain,
                why: "must be finite and > 1",
            });
        }
        if self.veil_block_px < 4 {
            return Err(RestoreError::BadParameter {
                name: "veil_block_px",
                value: self.veil_block_px as f64,
                why: "must be >= 4",
            });
        }
        if !(self.veil_percentile.is_finite() && (0.0..=50.0).contains(&self.veil_percentile)) {
            return Err(RestoreError::BadParameter {
                name: "veil_percentile",
                value: self.veil_percentile,
                why: "must be in 0..=50",
            });
        }
        if !self.saturation_level.is_finite() {
            return Err(RestoreError::BadParameter {
                name: "saturation_level",
                value: f64::from(self.saturation_level),
                why: "must be finite",
            });
        }
        Ok(())
    }
}

/// A restored frame and what the restorer estimated on the way.
#[derive(Clone, Debug, PartialEq)]
pub struct Restored {
    /// The restored frame; NaN where the input was NaN, infinite or saturated.
    pub image: Raster<f32>,
    /// The additive floor subtracted (backscatter veil plus ambient light).
    pub veil: Raster<f32>,
    /// Noise sigma estimated from the frame, in the frame's units.
    pub noise_sigma: f32,
    /// Pixels masked (NaN in `image`).
    pub masked: usize,
}

/// A classical restorer for one frame size: FFT plans and the PSF's
/// transfer function made once, then [`ClassicalRestorer::restore`] per frame.
pub struct ClassicalRestorer {
    width: usize,
    height: usize,
    params: RestoreParams,
    row_forward: Arc<dyn Fft<f32>>,
    row_inverse: Arc<dyn Fft<f32>>,
    col_forward: Arc<dyn Fft<f32>>,
    col_inverse: Arc<dyn Fft<f32>>,
    /// The Gaussian's transfer function along the padded x and y axes.
    otf_x: Vec<f32>,
    otf_y: Vec<f32>,
}

impl std::fmt::Debug for ClassicalRestorer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ClassicalRestorer")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("params", &self.params)
            .finish_non_exhaustive()
    }
}

/// Transfer function of a unit-sum Gaussian of `sigma_px` on a periodic
/// axis of `len` samples: `exp(-2 pi^2 sigma^2 f^2)`, `f` in cycles per pixel.
fn gaussian_otf(len: usize, sigma_px: f64) -> Vec<f32> {
    (0..len)
        .map(|k| {
            let f = k.min(len - k) as f64 / len as f64;
            (-2.0 * std::f64::consts::PI.powi(2) * sigma_px * sigma_px * f * f).exp() as f32
        })
        .collect()
}

impl ClassicalRestorer {
    /// Validates `params` and plans the transforms for `width x height` frames.
    pub fn new(width: usize, height: usize, params: RestoreParams) -> Result<Self, RestoreError> {
        if width < MIN_SIDE_PX || height < MIN_SIDE_PX {
            return Err(RestoreError::TooSmall {
                width,
                height,
                min_px: MIN_SIDE_PX,
            });
        }
        params.validate()?;
        let (pw, ph) = (2 * width, 2 * height);
        let mut planner = FftPlanner::<f32>::new();
        Ok(Self {
            width,
            height,
            params,
            row_forward: planner.plan_fft_forward(pw),
            row_inverse: planner.plan_fft_inverse(pw),
            col_forward: planner.plan_fft_forward(ph),
            col_inverse: planner.plan_fft_inverse(ph),
            otf_x: gaussian_otf(pw, params.psf_sigma_px),
            otf_y: gaussian_otf(ph, params.psf_sigma_px),
        })
    }

    /// The parameters the restorer was built with.
    pub fn params(&self) -> &RestoreParams {
        &self.params
    }

    /// Restores one frame (see the module doc for the steps).
    pub fn restore(&self, image: &Raster<f32>) -> Result<Restored, RestoreError> {
        let (w, h) = (image.width, image.height);
        if image.data.len() != w * h {
            return Err(RestoreError::BufferSize {
                len: image.data.len(),
                width: w,
                height: h,
            });
        }
        if (w, h) != (self.width, self.height) {
            return Err(RestoreError::SizeMismatch {
                expected: (self.width, self.height),
                got: (w, h),
            });
        }
        let sat = self.params.saturation_level;
        let valid: Vec<bool> = image
            .data
            .iter()
            .map(|v| v.is_finite() && *v < sat)
            .collect();
        let masked = valid.iter().filter(|v| !**v).count();
        if masked == w * h {
            return Err(RestoreError::NoValidPixels { pixels: w * h });
        }
        let block = self.params.veil_block_px;
        // Flagged pixels get their block's median, only so the transform runs.
        let filled: Vec<f32> = if masked == 0 {
            image.data.clone()
        } else {
            let median = block_floor(&image.data, &valid, w, h, block, 50.0);
            image
                .data
                .iter()
                .zip(&valid)
                .zip(&median)
                .map(|((&v, &ok), &m)| if ok { v } else { m })
                .collect()
        };
        let noise_sigma = noise_sigma(&filled, &valid, w, h);
        let deconvolved = self.deconvolve(&filled, noise_sigma);
        let veil = block_floor(
            &deconvolved,
            &valid,
            w,
            h,
            block,
            self.params.veil_percentile,
        );
        let out = deconvolved
            .iter()
            .zip(&veil)
            .zip(&valid)
            .map(|((&d, &v), &ok)| if ok { d - v } else { f32::NAN })
            .collect();
        Ok(Restored {
            image: Raster {
                width: w,
                height: h,
                data: out,
            },
            veil: Raster {
                width: w,
                height: h,
                data: veil,
            },
            noise_sigma,
            masked,
        })
    }

    /// Wiener deconvolution of a frame with no flagged pixels left.
    fn deconvolve(&self, img: &[f32], noise_sigma: f32) -> Vec<f32> {
        let (w, h) = (self.width, self.height);
        let (pw, ph) = (2 * w, 2 * h);
        // Mirror padding: x in w..2w reads column 2w-1-x, likewise rows.
        let mut rows = vec![Complex32::default(); pw * ph];
        rows.par_chunks_mut(pw).enumerate().for_each(|(y, row)| {
            let sy = if y < h { y } else { 2 * h - 1 - y };
            let src = &img[sy * w..(sy + 1) * w];
            for (x, c) in row.iter_mut().enumerate() {
                let sx = if x < w { x } else { 2 * w - 1 - x };
                *c = Complex32::new(src[sx], 0.0);
            }
        });
        fft_lines(&self.row_forward, &mut rows, pw);
        // Transposed: line kx holds the ph column frequencies of row frequency kx.
        let mut cols = transpose(&rows, pw, ph);
        fft_lines(&self.col_forward, &mut cols, ph);
        let power = smoothed_power(&cols, pw, ph);
        let n = (pw * ph) as f32;
        let noise_power = n * noise_sigma * noise_sigma;
        // |H / (H^2 + K)| <= 1 / (2 sqrt K): the cap on K caps the gain.
        let k_min = 1.0 / (4.0 * (self.params.max_gain as f32).powi(2));
        cols.par_chunks_mut(ph)
            .zip(power.par_chunks(ph))
            .enumerate()
            .for_each(|(kx, (line, p))| {
                let hx = self.otf_x[kx];
                for ((c, &py), &hy) in line.iter_mut().zip(p).zip(&self.otf_y) {
                    let otf = hx * hy;
                    // K = N sigma_n^2 / P_x with P_x = (P_y - N sigma_n^2) / H^2.
                    let signal = py - noise_power;
                    let k = if signal > 0.0 {
                        (noise_power * otf * otf / signal).max(k_min)
                    } else {
                        f32::INFINITY
                    };
                    let gain = if k.is_finite() {
                        otf / (otf * otf + k)
                    } else {
                        0.0
                    };
                    *c *= gain / n;
                }
            });
        fft_lines(&self.col_inverse, &mut cols, ph);
        let mut rows = transpose(&cols, ph, pw);
        fft_lines(&self.row_inverse, &mut rows, pw);
        let mut out = vec![0.0f32; w * h];
        out.par_chunks_mut(w).enumerate().for_each(|(y, o)| {
            for (v, c) in o.iter_mut().zip(&rows[y * pw..y * pw + w]) {
                *v = c.re;
            }
        });
        out
    }
}

/// Validates, plans and restores one frame: [`ClassicalRestorer::new`] then
/// [`ClassicalRestorer::restore`]. Build the restorer once to restore many
/// frames of one size.
pub fn restore_classical(
    image: &Raster<f32>,
    params: &RestoreParams,
) -> Result<Restored, RestoreError> {
    ClassicalRestorer::new(image.width, image.height, *params)?.restore(image)
}

/// In-place transforms of every `len`-long line of `data`, lines in parallel.
fn fft_lines(fft: &Arc<dyn Fft<f32>>, data: &mut [Complex32], len: usize) {
    let scratch = fft.get_inplace_scratch_len();
    // A few lines per task: rustfft runs a multiple of `len` in one call.
    data.par_chunks_mut(len * 8).for_each_init(
        || vec![Complex32::default(); scratch],
        |s, lines| fft.process_with_scratch(lines, s),
    );
}

/// `src` is `h` lines of `w`; returns `w` lines of `h`.
fn transpose(src: &[Complex32], w: usize, h: usize) -> Vec<Complex32> {
    let mut dst = vec![Complex32::default(); w * h];
    // Tiles of lines keep the strided reads in cache.
    const TILE: usize = 32;
    dst.par_chunks_mut(h * TILE)
        .enumerate()
        .for_each(|(t, out)| {
            let x0 = t * TILE;
            let lines = out.len() / h;
            for y in 0..h {
                let row = &src[y * w + x0..y * w + x0 + lines];
                for (i, c) in row.iter().enumerate() {
                    out[i * h + y] = *c;
                }
            }
        });
    dst
}

/// Periodogram `|Y|^2` averaged over the 3 x 3 neighbouring bins (the
/// spectrum is periodic, so the neighbours wrap).
fn smoothed_power(spec: &[Complex32], lines: usize, len: usize) -> Vec<f32> {
    let power: Vec<f32> = spec.par_iter().map(|c| c.norm_sqr()).collect();
    let mut along = vec![0.0f32; lines * len];
    along
        .par_chunks_mut(len)
        .zip(power.par_chunks(len))
        .for_each(|(o, p)| {
            for (i, v) in o.iter_mut().enumerate() {
                *v = p[(i + len - 1) % len] + p[i] + p[(i + 1) % len];
            }
        });
    let mut out = vec![0.0f32; lines * len];
    out.par_chunks_mut(len).enumerate().for_each(|(l, o)| {
        let a = &along[((l + lines - 1) % lines) * len..][..len];
        let b = &along[l * len..][..len];
        let c = &along[((l + 1) % lines) * len..][..len];
        for (((o, a), b), c) in o.iter_mut().zip(a).zip(b).zip(c) {
            *o = (a + b + c) / 9.0;
        }
    });
    out
}

/// Noise sigma from the median absolute response to Immerkaer's mask
/// `[1 -2 1; -2 4 -2; 1 -2 1]` (its response to white noise has sigma
/// `6 sigma`) over the 3 x 3 windows of valid pixels; 0 when there is none.
fn noise_sigma(img: &[f32], valid: &[bool], w: usize, h: usize) -> f32 {
    const MASK: [[f32; 3]; 3] = [[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]];
    let mut responses: Vec<f32> = (1..h - 1)
        .into_par_iter()
        .flat_map_iter(|y| {
            (1..w - 1).filter_map(move |x| {
                let mut r = 0.0;
                for (dy, m) in MASK.iter().enumerate() {
                    for (dx, &k) in m.iter().enumerate() {
                        let i = (y + dy - 1) * w + x + dx - 1;
                        if !valid[i] {
                            return None;
                        }
                        r += k * img[i];
                    }
                }
                Some(r.abs())
            })
        })
        .collect();
    if responses.is_empty() {
        return 0.0;
    }
    let mid = responses.len() / 2;
    let (_, median, _) = responses.select_nth_unstable_by(mid, f32::total_cmp);
    // Median |N(0, s)| = 0.6745 s.
    *median / 0.674_49 / 6.0
}

/// The `percentile` of the valid pixels of each `block x block` tile,
/// interpolated bilinearly between tile centres to every pixel. Tiles with
/// fewer than an eighth of their pixels valid take their neighbours' level.
fn block_floor(
    img: &[f32],
    valid: &[bool],
    w: usize,
    h: usize,
    block: usize,
    percentile: f64,
) -> Vec<f32> {
    let (nbx, nby) = (w.div_ceil(block), h.div_ceil(block));
    let mut level: Vec<f32> = (0..nbx * nby)
        .into_par_iter()
        .map(|b| {
            let (bx, by) = (b % nbx, b / nbx);
            let (x0, y0) = (bx * block, by * block);
            let (x1, y1) = ((x0 + block).min(w), (y0 + block).min(h));
            let mut v: Vec<f32> = (y0..y1)
                .flat_map(|y| (x0..x1).map(move |x| y * w + x))
                .filter(|&i| valid[i])
                .map(|i| img[i])
                .collect();
            if v.is_empty() || v.len() * 8 < (x1 - x0) * (y1 - y0) {
                return f32::NAN;
            }
            let k = ((v.len() - 1) as f64 * percentile / 100.0).round() as usize;
            *v.select_nth_unstable_by(k, f32::total_cmp).1
        })
        .collect();
    // Empty tiles take the mean of their known neighbours, ring by ring; at
    // least one tile is known (the caller has a valid pixel, and a tile of
    // valid pixels only would pass the eighth), else all tiles keep the
    // mean of the valid pixels.
    if level.iter().all(|l| l.is_nan()) {
        let (s, n) = img
            .iter()
            .zip(valid)
            .filter(|(_, &ok)| ok)
            .fold((0.0f64, 0usize), |(s, n), (&v, _)| {
                (s + f64::from(v), n + 1)
            });
        level.fill((s / n.max(1) as f64) as f32);
    }
    while level.iter().any(|l| l.is_nan()) {
        let before = level.clone();
        for by in 0..nby {
            for bx in 0..nbx {
                if !before[by * nbx + bx].is_nan() {
                    continue;
                }
                let mut sum = 0.0;
                let mut n = 0;
                for (dx, dy) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                    let (x, y) = (bx as i64 + dx, by as i64 + dy);
                    if x >= 0 && y >= 0 && (x as usize) < nbx && (y as usize) < nby {
                        let l = before[y as usize * nbx + x as usize];
                        if !l.is_nan() {
                            sum += l;
                            n += 1;
                        }
                    }
                }
                if n > 0 {
                    level[by * nbx + bx] = sum / n as f32;
                }
            }
        }
    }
    let mut out = vec![0.0f32; w * h];
    let b = block as f32;
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let fy = ((y as f32 + 0.5) / b - 0.5).clamp(0.0, (nby - 1) as f32);
        let y0 = (fy.floor() as usize).min(nby.saturating_sub(2));
        let ty = fy - y0 as f32;
        let y1 = (y0 + 1).min(nby - 1);
        for (x, o) in row.iter_mut().enumerate() {
            let fx = ((x as f32 + 0.5) / b - 0.5).clamp(0.0, (nbx - 1) as f32);
            let x0 = (fx.floor() as usize).min(nbx.saturating_sub(2));
            let tx = fx - x0 as f32;
            let x1 = (x0 + 1).min(nbx - 1);
            let top = level[y0 * nbx + x0] * (1.0 - tx) + level[y0 * nbx + x1] * tx;
            let bottom = level[y1 * nbx + x0] * (1.0 - tx) + level[y1 * nbx + x1] * tx;
            *o = top * (1.0 - ty) + bottom * ty;
        }
    });
    out
}

#[cfg(test)]
#[path = "restore_tests.rs"]
mod tests;
