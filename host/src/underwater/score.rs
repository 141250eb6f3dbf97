//! Scores of a restored 4-step set against a reference set (the twin's
//! clean frames): PSNR (8-bit scale) and SSIM after one least-squares gain
//! and offset per frame, and the wrapped-phase MAE over the pixels the
//! reference modulates (the 4-step phase ignores gain and offset).

use crate::dealias::metrics::{mse_8bit, psnr_db, ssim_frames};
use crate::phase::{wrap_pi, PhaseError, PhaseShift};
use crate::raster::Raster;

/// Reference modulation below which a pixel's phase is not scored.
pub const MIN_MODULATION: f32 = 0.02;

/// `est` put on `truth` by the least-squares gain and offset over the
/// pixels finite in both; pixels not finite in `est` stay NaN.
pub fn fit_affine(est: &Raster<f32>, truth: &Raster<f32>) -> Raster<f32> {
    let (mut n, mut se, mut st, mut see, mut set) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
    for (&e, &t) in est.data.iter().zip(&truth.data) {
        if e.is_finite() && t.is_finite() {
            let (e, t) = (f64::from(e), f64::from(t));
            n += 1.0;
            se += e;
            st += t;
            see += e * e;
            set += e * t;
        }
    }
    let var = see - se * se / n;
    let gain = if var > 0.0 {
        (set - se * st / n) / var
    } else {
        0.0
    };
    let offset = (st - gain * se) / n;
    Raster {
        width: est.width,
        height: est.height,
        data: est
            .data
            .iter()
            .map(|&e| (gain * f64::from(e) + offset) as f32)
            .collect(),
    }
}

/// Sums of one method against one reference over samples.
#[derive(Default, Clone)]
pub struct Score {
    mse: Vec<f64>,
    ssim: Vec<f64>,
    phase_abs_sum: f64,
    phase_count: usize,
}

impl Score {
    /// Scores one set `est` against `reference` (4 frames each, one size).
    pub fn add(
        &mut self,
        est: &[Raster<f32>],
        reference: &[Raster<f32>],
    ) -> Result<(), PhaseError> {
        let fitted: Vec<Raster<f32>> = est
            .iter()
            .zip(reference)
            .map(|(e, r)| fit_affine(e, r))
            .collect();
        let mask: Vec<bool> = (0..reference[0].len())
            .map(|i| {
                fitted
                    .iter()
                    .zip(reference)
                    .all(|(e, r)| e.data[i].is_finite() && r.data[i].is_finite())
            })
            .collect();
        self.mse.push(mse_8bit(&fitted, reference, &mask));
        self.ssim.push(ssim_frames(&fitted, reference, &mask));
        let decoder = PhaseShift::new(4)?;
        let phase = |f: &[Raster<f32>]| {
            let refs: Vec<&Raster<f32>> = f.iter().collect();
            decoder.wrapped_phase(&refs)
        };
        let (pe, pr) = (phase(est)?, phase(reference)?);
        for (i, &m) in mask.iter().enumerate() {
            let e = pe.phase.data[i];
            if m && e.is_finite() && pr.modulation.data[i] >= MIN_MODULATION {
                self.phase_abs_sum += f64::from(wrap_pi(e - pr.phase.data[i]).abs());
                self.phase_count += 1;
            }
        }
        Ok(())
    }

    /// (PSNR of the mean MSE, mean SSIM, phase MAE).
    pub fn figures(&self) -> (f64, f64, f64) {
        let mse = self.mse.iter().sum::<f64>() / self.mse.len() as f64;
        let ssim = self.ssim.iter().sum::<f64>() / self.ssim.len() as f64;
        (
            psnr_db(mse),
            ssim,
            self.phase_abs_sum / self.phase_count as f64,
        )
    }
}
