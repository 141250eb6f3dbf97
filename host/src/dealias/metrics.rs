//! Figures of a de-aliased fringe against the twin's clean image: MSE and
//! PSNR on the 8-bit scale and SSIM (as seed 000 reports them), over a
//! mask; and statistics of the wrapped-phase error (the phase itself by
//! `crate::phase::PhaseShift`).

use crate::raster::Raster;

/// Frame values (full scale 1) to the 8-bit scale seed 000 reports on.
const EIGHT_BIT: f64 = 255.0;

/// Squared error sum and count over `mask`, 8-bit scale.
fn squared_error(est: &[f32], truth: &[f32], mask: &[bool]) -> (f64, usize) {
    est.iter()
        .zip(truth)
        .zip(mask)
        .filter(|(_, &m)| m)
        .fold((0.0, 0), |(s, n), ((&e, &t), _)| {
            let d = EIGHT_BIT * f64::from(e - t);
            (s + d * d, n + 1)
        })
}

/// Mean squared error over `mask` of all `frames`, 8-bit scale; NaN when
/// the mask is empty.
pub fn mse_8bit(est: &[Raster<f32>], truth: &[Raster<f32>], mask: &[bool]) -> f64 {
    let (s, n) = est
        .iter()
        .zip(truth)
        .map(|(e, t)| squared_error(&e.data, &t.data, mask))
        .fold((0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

/// PSNR in dB of an 8-bit-scale MSE.
pub fn psnr_db(mse: f64) -> f64 {
    10.0 * (EIGHT_BIT * EIGHT_BIT / mse).log10()
}

/// SSIM's constants for an 8-bit range (K1 = 0.01, K2 = 0.03).
const C1: f64 = (0.01 * EIGHT_BIT) * (0.01 * EIGHT_BIT);
const C2: f64 = (0.03 * EIGHT_BIT) * (0.03 * EIGHT_BIT);
/// Half side of SSIM's window (7 x 7, uniform).
const SSIM_HALF: usize = 3;

/// Mean SSIM of one frame over the pixels of `mask` whose whole 7 x 7
/// window lies in `mask` (statistics from masked pixels only); `None` when
/// no such pixel exists.
pub fn ssim_masked(est: &Raster<f32>, truth: &Raster<f32>, mask: &[bool]) -> Option<(f64, usize)> {
    let (w, h) = (est.width, est.height);
    let mut sum = 0.0;
    let mut count = 0;
    for y in SSIM_HALF..h.saturating_sub(SSIM_HALF) {
        for x in SSIM_HALF..w.saturating_sub(SSIM_HALF) {
            let window = || {
                (y - SSIM_HALF..=y + SSIM_HALF)
                    .flat_map(move |v| (x - SSIM_HALF..=x + SSIM_HALF).map(move |u| v * w + u))
            };
            if !window().all(|i| mask[i]) {
                continue;
            }
            let n = ((2 * SSIM_HALF + 1) * (2 * SSIM_HALF + 1)) as f64;
            let (mut ma, mut mb) = (0.0, 0.0);
            for i in window() {
                ma += EIGHT_BIT * f64::from(est.data[i]);
                mb += EIGHT_BIT * f64::from(truth.data[i]);
            }
            ma /= n;
            mb /= n;
            let (mut va, mut vb, mut cov) = (0.0, 0.0, 0.0);
            for i in window() {
                let a = EIGHT_BIT * f64::from(est.data[i]) - ma;
                let b = EIGHT_BIT * f64::from(truth.data[i]) - mb;
                va += a * a;
                vb += b * b;
                cov += a * b;
            }
            let (va, vb, cov) = (va / (n - 1.0), vb / (n - 1.0), cov / (n - 1.0));
            sum += ((2.0 * ma * mb + C1) * (2.0 * cov + C2))
                / ((ma * ma + mb * mb + C1) * (va + vb + C2));
            count += 1;
        }
    }
    (count > 0).then(|| (sum / count as f64, count))
}

/// Mean SSIM over frames (each frame's windows weighted alike).
pub fn ssim_frames(est: &[Raster<f32>], truth: &[Raster<f32>], mask: &[bool]) -> f64 {
    let (s, n) = est
        .iter()
        .zip(truth)
        .filter_map(|(e, t)| ssim_masked(e, t, mask))
        .fold((0.0, 0), |(s, n), (v, c)| (s + v * c as f64, n + c));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

/// Max, 99th percentile and mean of absolute errors (NaN when empty).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorStats {
    /// Largest.
    pub max: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Mean.
    pub mae: f64,
    /// How many.
    pub count: usize,
}

/// The statistics of `errors` (absolute values taken).
pub fn error_stats(errors: &[f64]) -> ErrorStats {
    let mut a: Vec<f64> = errors.iter().map(|e| e.abs()).collect();
    if a.is_empty() {
        return ErrorStats {
            max: f64::NAN,
            p99: f64::NAN,
            mae: f64::NAN,
            count: 0,
        };
    }
    a.sort_by(f64::total_cmp);
    let p99 = a[((a.len() - 1) as f64 * 0.99).round() as usize];
    ErrorStats {
        max: a[a.len() - 1],
        p99,
        mae: a.iter().sum::<f64>() / a.len() as f64,
        count: a.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize, k: f32) -> Raster<f32> {
        Raster::from_fn(w, h, |x, y| {
            0.3 + 0.2 * ((x as f32 * 0.3 + y as f32 * 0.1) + k).sin()
        })
    }

    #[test]
    fn identical_images_score_perfectly_and_noise_lowers_the_score() {
        let (w, h) = (20, 16);
        let t = vec![ramp(w, h, 0.0), ramp(w, h, 1.0)];
        let mask = vec![true; w * h];
        assert_eq!(mse_8bit(&t, &t, &mask), 0.0);
        assert!((ssim_frames(&t, &t, &mask) - 1.0).abs() < 1e-12);
        // One 8-bit level everywhere: MSE 1, PSNR 48.13 dB.
        let off: Vec<Raster<f32>> = t
            .iter()
            .map(|r| Raster::from_fn(w, h, |x, y| r.data[y * w + x] + 1.0 / 255.0))
            .collect();
        assert!((mse_8bit(&off, &t, &mask) - 1.0).abs() < 1e-6);
        assert!((psnr_db(1.0) - 48.1308).abs() < 1e-3);
        let noisy: Vec<Raster<f32>> = t
            .iter()
            .map(|r| {
                Raster::from_fn(w, h, |x, y| {
                    r.data[y * w + x] + 0.05 * ((x * 7 + y * 13) % 5) as f32 - 0.1
                })
            })
            .collect();
        assert!(ssim_frames(&noisy, &t, &mask) < 0.9);
    }

    #[test]
    fn masked_pixels_do_not_count() {
        let (w, h) = (20, 16);
        let t = vec![ramp(w, h, 0.0)];
        let mut bad = t.clone();
        bad[0].data[0] = 5.0;
        let mut mask = vec![true; w * h];
        mask[0] = false;
        assert_eq!(mse_8bit(&bad, &t, &mask), 0.0);
        assert!(mse_8bit(&bad, &t, &[false; 320]).is_nan());
        assert!(ssim_masked(&bad[0], &t[0], &[false; 320]).is_none());
    }

    #[test]
    fn error_statistics_take_absolute_values() {
        let s = error_stats(&[0.1, -0.3, 0.2]);
        assert_eq!((s.max, s.count), (0.3, 3));
        assert!((s.mae - 0.2).abs() < 1e-12);
    }
}
