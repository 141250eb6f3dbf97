//! Two-dimensional FFT of a row-major complex image on `rustfft`, with the
//! spectrum left transposed (column-major) so one filter pass costs two
//! transposes instead of four.

use std::sync::Arc;

use rustfft::num_complex::Complex32;
use rustfft::{Fft, FftPlanner};

/// Plans for one image size.
pub struct Fft2 {
    width: usize,
    height: usize,
    rows_forward: Arc<dyn Fft<f32>>,
    rows_inverse: Arc<dyn Fft<f32>>,
    cols_forward: Arc<dyn Fft<f32>>,
    cols_inverse: Arc<dyn Fft<f32>>,
}

impl Fft2 {
    /// Plans for `width` x `height` images.
    pub fn new(width: usize, height: usize) -> Self {
        let mut planner = FftPlanner::<f32>::new();
        Self {
            width,
            height,
            rows_forward: planner.plan_fft_forward(width),
            rows_inverse: planner.plan_fft_inverse(width),
            cols_forward: planner.plan_fft_forward(height),
            cols_inverse: planner.plan_fft_inverse(height),
        }
    }

    /// Image (row-major, `width * height`) -> spectrum in `spectrum`, transposed:
    /// element `kx * height + ky`.
    pub fn forward(&self, image: &mut [Complex32], spectrum: &mut [Complex32]) {
        self.rows_forward.process(image);
        transpose(image, spectrum, self.width, self.height);
        self.cols_forward.process(spectrum);
    }

    /// Transposed spectrum -> image (row-major), scaled so `inverse(forward(x)) = x`.
    /// `spectrum` is used as scratch.
    pub fn inverse(&self, spectrum: &mut [Complex32], image: &mut [Complex32]) {
        self.cols_inverse.process(spectrum);
        transpose(spectrum, image, self.height, self.width);
        self.rows_inverse.process(image);
        let scale = 1.0 / (self.width * self.height) as f32;
        image.iter_mut().for_each(|z| *z *= scale);
    }

    /// The signed frequency of bin `k` of `n`, cycles per pixel.
    pub fn frequency(k: usize, n: usize) -> f32 {
        let k = if k <= n / 2 {
            k as f32
        } else {
            k as f32 - n as f32
        };
        k / n as f32
    }

    /// Image size (width, height).
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }
}

/// `src` is `rows` x `cols` row-major; `dst` becomes `cols` x `rows`. Blocked so
/// both sides stay in cache.
fn transpose(src: &[Complex32], dst: &mut [Complex32], cols: usize, rows: usize) {
    const B: usize = 32;
    for r0 in (0..rows).step_by(B) {
        for c0 in (0..cols).step_by(B) {
            for r in r0..(r0 + B).min(rows) {
                for c in c0..(c0 + B).min(cols) {
                    dst[c * rows + r] = src[r * cols + c];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plane_wave_lands_in_its_bin_and_comes_back() {
        let (w, h) = (24, 18);
        let (kx, ky) = (5usize, 16usize); // ky = 16 is the frequency -2/18
        let image: Vec<Complex32> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let phase = std::f32::consts::TAU
                    * (x * Fft2::frequency(kx, w) + y * Fft2::frequency(ky, h));
                Complex32::from_polar(1.0, phase)
            })
            .collect();
        let fft = Fft2::new(w, h);
        let mut buf = image.clone();
        let mut spec = vec![Complex32::default(); w * h];
        fft.forward(&mut buf, &mut spec);
        let peak = spec
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.norm().total_cmp(&b.1.norm()))
            .unwrap()
            .0;
        assert_eq!(peak, kx * h + ky);
        assert!((spec[peak].norm() - (w * h) as f32).abs() < 1e-2);
        let mut back = vec![Complex32::default(); w * h];
        fft.inverse(&mut spec, &mut back);
        let err = back
            .iter()
            .zip(&image)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0f32, f32::max);
        assert!(err < 1e-4, "{err}");
    }
}
