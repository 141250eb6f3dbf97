//! Two-dimensional FFT of a row-major complex image on `rustfft`, with the
//! spectrum left transposed (column-major) so one filter pass costs two
//! transposes instead of four. Lines and transposes run on all cores, so one
//! large image (the underwater restorer) or many small ones at once (the
//! high-speed demultiplexer, one per pattern) both keep the cores busy.

use std::sync::Arc;

use rayon::prelude::*;
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
    /// element `kx * height + ky`. `image` is used as scratch.
    pub fn forward(&self, image: &mut [Complex32], spectrum: &mut [Complex32]) {
        fft_lines(&self.rows_forward, image, self.width);
        transpose(image, spectrum, self.width, self.height);
        fft_lines(&self.cols_forward, spectrum, self.height);
    }

    /// [`Self::forward`] of a spectrum needed only in the columns of the band
    /// `|kx| <= max_kx` (low horizontal frequencies, as after a window at
    /// DC): the rows are transformed whole, the columns only in the band, and
    /// the other columns are left zero. Where the window is zero outside the
    /// band, the same bits as `forward` then the window, for a fraction of
    /// the column transforms.
    pub fn forward_band(&self, image: &mut [Complex32], spectrum: &mut [Complex32], max_kx: usize) {
        let (w, h) = (self.width, self.height);
        fft_lines(&self.rows_forward, image, w);
        let [left, right] = band_columns(w, max_kx);
        for columns in [left.clone(), right.clone()] {
            transpose_lines(image, spectrum, w, h, columns.clone());
            fft_lines(
                &self.cols_forward,
                &mut spectrum[columns.start * h..columns.end * h],
                h,
            );
        }
        spectrum[left.end * h..right.start * h]
            .par_chunks_mut(h)
            .for_each(|c| c.fill(Complex32::default()));
    }

    /// [`Self::inverse`] of a spectrum that is zero outside the columns
    /// `|kx| <= max_kx` ([`Self::forward_band`]'s band): only the band's
    /// columns are transformed (a zero column's transform is zero), the
    /// rows whole. The same bits as `inverse`.
    pub fn inverse_band(&self, spectrum: &mut [Complex32], image: &mut [Complex32], max_kx: usize) {
        let (w, h) = (self.width, self.height);
        for columns in band_columns(w, max_kx) {
            fft_lines(
                &self.cols_inverse,
                &mut spectrum[columns.start * h..columns.end * h],
                h,
            );
        }
        transpose(spectrum, image, h, w);
        fft_lines(&self.rows_inverse, image, w);
        let scale = 1.0 / (w * h) as f32;
        image.par_iter_mut().for_each(|z| *z *= scale);
    }

    /// Transposed spectrum -> image (row-major), scaled so `inverse(forward(x)) = x`.
    /// `spectrum` is used as scratch.
    pub fn inverse(&self, spectrum: &mut [Complex32], image: &mut [Complex32]) {
        self.inverse_rows(spectrum, image, self.height);
    }

    /// [`Self::inverse`] of the first `rows` image rows only (the rest of
    /// `image` is left part-way, not an image): what a padded filter keeps.
    pub fn inverse_rows(&self, spectrum: &mut [Complex32], image: &mut [Complex32], rows: usize) {
        fft_lines(&self.cols_inverse, spectrum, self.height);
        transpose(spectrum, image, self.height, self.width);
        let kept = &mut image[..rows.min(self.height) * self.width];
        fft_lines(&self.rows_inverse, kept, self.width);
        let scale = 1.0 / (self.width * self.height) as f32;
        kept.par_iter_mut().for_each(|z| *z *= scale);
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

/// In-place transforms of every `len`-long line of `data`, lines in parallel.
fn fft_lines(fft: &Arc<dyn Fft<f32>>, data: &mut [Complex32], len: usize) {
    let scratch = fft.get_inplace_scratch_len();
    // A few lines per task: rustfft runs a multiple of `len` in one call.
    data.par_chunks_mut(len * 8).for_each_init(
        || vec![Complex32::default(); scratch],
        |s, lines| fft.process_with_scratch(lines, s),
    );
}

/// The columns `0..=max_kx` and `w - max_kx..w` (all of them where those
/// meet), as two ranges, the second possibly empty.
fn band_columns(w: usize, max_kx: usize) -> [std::ops::Range<usize>; 2] {
    if 2 * max_kx + 1 >= w {
        return [0..w, w..w];
    }
    [0..max_kx + 1, w - max_kx..w]
}

/// `src` is `h` lines of `w`; `dst` becomes `w` lines of `h`.
fn transpose(src: &[Complex32], dst: &mut [Complex32], w: usize, h: usize) {
    transpose_lines(src, dst, w, h, 0..w);
}

/// [`transpose`] of the columns `lines` of `src` only: `dst`'s lines
/// `lines` are written, the others left as they are.
fn transpose_lines(
    src: &[Complex32],
    dst: &mut [Complex32],
    w: usize,
    h: usize,
    lines: std::ops::Range<usize>,
) {
    // Tiles of lines keep the strided reads in cache.
    const TILE: usize = 32;
    dst[lines.start * h..lines.end * h]
        .par_chunks_mut(h * TILE)
        .enumerate()
        .for_each(|(t, out)| {
            let x0 = lines.start + t * TILE;
            let lines = out.len() / h;
            for y in 0..h {
                let row = &src[y * w + x0..y * w + x0 + lines];
                for (i, c) in row.iter().enumerate() {
                    out[i * h + y] = *c;
                }
            }
        });
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
        // The first rows alone come back the same.
        fft.forward(&mut image.clone(), &mut spec);
        let mut part = vec![Complex32::default(); w * h];
        fft.inverse_rows(&mut spec, &mut part, 7);
        for (a, b) in part[..7 * w].iter().zip(&back[..7 * w]) {
            assert!((a - b).norm() < 1e-5);
        }
    }

    #[test]
    fn a_band_of_columns_gives_the_same_bits_as_the_whole_spectrum_cut_to_it() {
        let (w, h) = (40, 18);
        // A deterministic rough image: every frequency is present.
        let image: Vec<Complex32> = (0..w * h)
            .map(|i| {
                let v = ((i * 7919) % 101) as f32 / 101.0;
                Complex32::new(v, 0.5 - v * v)
            })
            .collect();
        let fft = Fft2::new(w, h);
        for max_kx in [0, 3, 19, 20, 40] {
            let mut whole = vec![Complex32::default(); w * h];
            fft.forward(&mut image.clone(), &mut whole);
            for (kx, column) in whole.chunks_mut(h).enumerate() {
                if kx.min(w - kx) > max_kx {
                    column.fill(Complex32::default());
                }
            }
            let mut band = vec![Complex32::new(9.0, 9.0); w * h];
            fft.forward_band(&mut image.clone(), &mut band, max_kx);
            assert_eq!(band, whole, "spectrum, band {max_kx}");
            let (mut a, mut b) = (
                vec![Complex32::default(); w * h],
                vec![Complex32::default(); w * h],
            );
            fft.inverse(&mut whole, &mut a);
            fft.inverse_band(&mut band, &mut b, max_kx);
            assert_eq!(a, b, "image, band {max_kx}");
        }
    }
}
