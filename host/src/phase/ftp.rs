//! Fourier transform profilometry (Takeda): wrapped phase from ONE fringe image.
//!
//! Each line across the fringes is transformed, the band around the carrier
//! (`length / period_px` cycles) is kept with a Hann window, and the inverse transform is
//! the analytic signal `(B/2) e^{i Phi}`; its angle is the wrapped phase in the same
//! convention as the N-step decoder (`Phi = 2 pi u / P`, carrier included). FTP trades
//! resolution for speed: the phase is smoothed over about one period and is biased near
//! image edges and steep slopes, which the tests measure rather than hide.

use rustfft::num_complex::Complex32;
use rustfft::FftPlanner;

use super::{PhaseError, WrappedPhase};
use crate::raster::Raster;

/// Which way the fringes vary.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FringeAxis {
    /// Phase grows along x (vertical fringes): transform rows.
    X,
    /// Phase grows along y (horizontal fringes): transform columns.
    Y,
}

/// Wrapped phase and modulation of a single fringe image by FTP.
///
/// `period_px` is the fringe period along `axis` in the camera image; the pass band is
/// `[f0 / 2, 3 f0 / 2]` around the carrier `f0`. The background is the low-pass band.
pub fn ftp_phase(
    image: &Raster<f32>,
    period_px: f64,
    axis: FringeAxis,
) -> Result<WrappedPhase, PhaseError> {
    let (width, height) = super::check_sizes(&[image])?;
    let (len, lines) = match axis {
        FringeAxis::X => (width, height),
        FringeAxis::Y => (height, width),
    };
    // Band limits in FFT bins; at least two bins wide so short lines still work.
    let f0 = len as f64 / period_px;
    if !(f0 >= 2.0 && 2.0 * f0 < len as f64) {
        return Err(PhaseError::CarrierOutOfBand {
            period_px,
            length_px: len,
        });
    }
    let lo = (f0 * 0.5).floor().max(1.0) as usize;
    let hi = ((f0 * 1.5).ceil() as usize).min(len / 2);
    let fft = FftPlanner::<f32>::new().plan_fft_forward(len);
    let ifft = FftPlanner::<f32>::new().plan_fft_inverse(len);
    let mut phase = Raster::filled(width, height, 0.0f32);
    let mut modulation = Raster::filled(width, height, 0.0f32);
    let mut background = Raster::filled(width, height, 0.0f32);
    let mut buf = vec![Complex32::default(); len];
    let mut band = vec![Complex32::default(); len];
    let mut low = vec![Complex32::default(); len];
    let scale = 1.0 / len as f32;
    for line in 0..lines {
        let index = |i: usize| match axis {
            FringeAxis::X => line * width + i,
            FringeAxis::Y => i * width + line,
        };
        for (i, b) in buf.iter_mut().enumerate() {
            *b = Complex32::new(image.data[index(i)], 0.0);
        }
        fft.process(&mut buf);
        band.iter_mut().for_each(|b| *b = Complex32::default());
        low.iter_mut().for_each(|b| *b = Complex32::default());
        for k in lo..=hi {
            // Hann window across the pass band.
            let t = (k - lo) as f32 / (hi - lo).max(1) as f32;
            let w = 0.5 - 0.5 * (2.0 * std::f32::consts::PI * t).cos();
            band[k] = buf[k] * w;
        }
        low[0] = buf[0];
        for k in 1..lo {
            low[k] = buf[k];
            low[len - k] = buf[len - k];
        }
        ifft.process(&mut band);
        ifft.process(&mut low);
        for i in 0..len {
            let c = band[i] * scale;
            phase.data[index(i)] = super::fast_atan2(c.im, c.re);
            modulation.data[index(i)] = 2.0 * c.norm();
            background.data[index(i)] = low[i].re * scale;
        }
    }
    Ok(WrappedPhase {
        phase,
        modulation,
        background,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::wrap_pi;

    #[test]
    fn recovers_a_smooth_phase_away_from_the_edges() {
        let (w, h, period) = (256usize, 8usize, 16.0f64);
        let truth = |x: usize, y: usize| {
            let u = x as f64 + 3.0 * (2.0 * std::f64::consts::PI * x as f64 / 256.0).sin();
            2.0 * std::f64::consts::PI * u / period + 0.1 * y as f64
        };
        let img = Raster::from_fn(w, h, |x, y| (0.5 + 0.3 * truth(x, y).cos()) as f32);
        let out = ftp_phase(&img, period, FringeAxis::X).unwrap();
        let mut worst = 0.0f32;
        for y in 0..h {
            for x in 32..w - 32 {
                let e = wrap_pi(*out.phase.at(x, y) - truth(x, y) as f32).abs();
                worst = worst.max(e);
            }
        }
        assert!(worst < 0.05, "worst interior phase error {worst} rad");
        let b = *out.modulation.at(128, 4);
        assert!((b - 0.3).abs() < 0.03, "modulation {b}");
    }

    #[test]
    fn y_axis_matches_transposed_x_axis() {
        let period = 10.0;
        let img = Raster::from_fn(8, 128, |_, y| {
            (0.5 + 0.3 * (2.0 * std::f64::consts::PI * y as f64 / period).cos()) as f32
        });
        let out = ftp_phase(&img, period, FringeAxis::Y).unwrap();
        let e = wrap_pi(*out.phase.at(3, 64) - (2.0 * std::f32::consts::PI * 64.0 / 10.0));
        assert!(e.abs() < 0.02, "{e}");
    }

    #[test]
    fn too_few_periods_is_an_error() {
        let img = Raster::filled(16, 4, 0.5f32);
        assert!(ftp_phase(&img, 12.0, FringeAxis::X).is_err());
    }
}
