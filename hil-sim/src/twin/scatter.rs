//! Underwater forward scatter: a Gaussian blur whose sigma varies per pixel
//! with the water path (seed 002 eq. 2, sigma_s proportional to b_f z).
//! Computed as a few uniformly blurred layers, interpolated per pixel.

use super::pattern::{convolve_rows, gaussian_kernel, transpose};

/// Blurs a band image (w x h, 3 bands) with per-pixel sigma `sigma_px`.
pub fn blur_varying(img: &[[f32; 3]], w: usize, h: usize, sigma_px: &[f32]) -> Vec<[f32; 3]> {
    let max_sigma = sigma_px
        .iter()
        .cloned()
        .filter(|s| s.is_finite())
        .fold(0.0f32, f32::max);
    if max_sigma < 0.05 {
        return img.to_vec();
    }
    const LAYERS: usize = 5;
    let sigmas: Vec<f32> = (0..LAYERS)
        .map(|k| max_sigma * k as f32 / (LAYERS - 1) as f32)
        .collect();
    let layers: Vec<Vec<[f32; 3]>> = sigmas
        .iter()
        .map(|&s| blur_uniform(img, w, h, s as f64))
        .collect();
    let step = sigmas[1];
    img.iter()
        .enumerate()
        .map(|(i, _)| {
            let s = if sigma_px[i].is_finite() {
                sigma_px[i]
            } else {
                0.0
            };
            let pos = (s / step).clamp(0.0, (LAYERS - 1) as f32);
            let k = (pos.floor() as usize).min(LAYERS - 2);
            let f = pos - k as f32;
            let (a, b) = (layers[k][i], layers[k + 1][i]);
            [0, 1, 2].map(|c| a[c] + f * (b[c] - a[c]))
        })
        .collect()
}

/// Uniform Gaussian blur of a 3-band image (edges clamped).
pub fn blur_uniform(img: &[[f32; 3]], w: usize, h: usize, sigma_px: f64) -> Vec<[f32; 3]> {
    if sigma_px < 1e-3 {
        return img.to_vec();
    }
    let k = gaussian_kernel(sigma_px);
    let mut out = vec![[0.0f32; 3]; w * h];
    for c in 0..3 {
        let plane: Vec<f32> = img.iter().map(|p| p[c]).collect();
        let a = convolve_rows(&plane, w, h, &k);
        let t = transpose(&a, w, h);
        let b = convolve_rows(&t, h, w, &k);
        let r = transpose(&b, h, w);
        for (o, v) in out.iter_mut().zip(r) {
            o[c] = v;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blur_keeps_energy_and_zero_sigma_is_identity() {
        let (w, h) = (40, 30);
        let mut img = vec![[0.0f32; 3]; w * h];
        img[15 * w + 20] = [1.0, 2.0, 3.0];
        let b = blur_uniform(&img, w, h, 2.0);
        let sum: f32 = b.iter().map(|p| p[1]).sum();
        assert!((sum - 2.0).abs() < 1e-4);
        assert_eq!(blur_varying(&img, w, h, &vec![0.0; w * h]), img);
    }
}
