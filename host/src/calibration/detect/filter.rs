//! Small image kernels the detector needs: Gaussian blur, bilinear sampling.
//!
//! Plain f32 planes (row-major, `width * height`) so that they compose
//! without conversions; borders are clamped.

/// A grey plane, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Plane {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// `width * height` samples.
    pub data: Vec<f32>,
}

impl Plane {
    /// Sample at integer `(x, y)`, clamped to the border.
    pub fn at(&self, x: isize, y: isize) -> f32 {
        let x = x.clamp(0, self.width as isize - 1) as usize;
        let y = y.clamp(0, self.height as isize - 1) as usize;
        self.data[y * self.width + x]
    }

    /// Bilinear sample at `(x, y)`, pixel centres at integers.
    pub fn bilinear(&self, x: f64, y: f64) -> f64 {
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as isize, y0 as isize);
        let a = f64::from(self.at(x0, y0));
        let b = f64::from(self.at(x0 + 1, y0));
        let c = f64::from(self.at(x0, y0 + 1));
        let d = f64::from(self.at(x0 + 1, y0 + 1));
        (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy
    }
}

fn kernel(sigma: f64) -> Vec<f32> {
    let radius = (3.0 * sigma).ceil().max(1.0) as isize;
    let mut k: Vec<f32> = (-radius..=radius)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let sum: f32 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= sum);
    k
}

/// Separable Gaussian blur with standard deviation `sigma_px` (none if <= 0).
pub fn gaussian_blur(plane: &Plane, sigma_px: f64) -> Plane {
    if sigma_px <= 0.0 {
        return plane.clone();
    }
    let k = kernel(sigma_px);
    let r = (k.len() / 2) as isize;
    let (w, h) = (plane.width, plane.height);
    let mut tmp = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            tmp[y * w + x] = k
                .iter()
                .enumerate()
                .map(|(i, kv)| kv * plane.at(x as isize + i as isize - r, y as isize))
                .sum();
        }
    }
    let tmp = Plane {
        width: w,
        height: h,
        data: tmp,
    };
    let mut out = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            out[y * w + x] = k
                .iter()
                .enumerate()
                .map(|(i, kv)| kv * tmp.at(x as isize, y as isize + i as isize - r))
                .sum();
        }
    }
    Plane {
        width: w,
        height: h,
        data: out,
    }
}

/// A wide Gaussian blur, computed on a block-averaged copy and sampled back
/// bilinearly: for the slowly varying background levels it serves, the
/// difference from [`gaussian_blur`] is negligible and it costs `1/f^2`.
pub fn wide_blur(plane: &Plane, sigma_px: f64) -> Plane {
    let f = (sigma_px / 3.0).floor() as usize;
    if f < 2 {
        return gaussian_blur(plane, sigma_px);
    }
    let (sw, sh) = (plane.width.div_ceil(f), plane.height.div_ceil(f));
    let mut small = vec![0.0f32; sw * sh];
    let mut counts = vec![0u32; sw * sh];
    for y in 0..plane.height {
        for x in 0..plane.width {
            let k = (y / f) * sw + x / f;
            small[k] += plane.data[y * plane.width + x];
            counts[k] += 1;
        }
    }
    for (v, c) in small.iter_mut().zip(&counts) {
        *v /= (*c).max(1) as f32;
    }
    // Block-averaging is itself a blur of variance (f^2 - 1) / 12 pixels^2.
    let residual = (sigma_px * sigma_px - (f * f - 1) as f64 / 12.0)
        .max(0.0)
        .sqrt();
    let blurred = gaussian_blur(
        &Plane {
            width: sw,
            height: sh,
            data: small,
        },
        residual / f as f64,
    );
    let data = (0..plane.width * plane.height)
        .map(|k| {
            let (x, y) = ((k % plane.width) as f64, (k / plane.width) as f64);
            // Block b covers pixels [b f, b f + f): its centre is at b f + (f - 1) / 2.
            let bx = (x - 0.5 * (f as f64 - 1.0)) / f as f64;
            let by = (y - 0.5 * (f as f64 - 1.0)) / f as f64;
            blurred.bilinear(bx, by) as f32
        })
        .collect();
    Plane {
        width: plane.width,
        height: plane.height,
        data,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blur_keeps_constant_and_mass() {
        let p = Plane {
            width: 9,
            height: 7,
            data: vec![0.5; 63],
        };
        let b = gaussian_blur(&p, 1.3);
        assert!(b.data.iter().all(|v| (v - 0.5).abs() < 1e-6));
        let mut spike = vec![0.0; 21 * 21];
        spike[10 * 21 + 10] = 1.0;
        let p = Plane {
            width: 21,
            height: 21,
            data: spike,
        };
        let b = gaussian_blur(&p, 1.0);
        assert!((b.data.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        assert!((b.bilinear(10.0, 10.0) - f64::from(b.at(10, 10))).abs() < 1e-9);
    }

    #[test]
    fn wide_blur_approximates_gaussian_blur() {
        let (w, h) = (120, 90);
        let data = (0..w * h)
            .map(|k| {
                let (x, y) = ((k % w) as f32, (k / w) as f32);
                0.5 + 0.3 * (x / 17.0).sin() * (y / 23.0).cos()
                    + if (x - 60.0).abs() < 6.0 { 0.2 } else { 0.0 }
            })
            .collect();
        let p = Plane {
            width: w,
            height: h,
            data,
        };
        let (a, b) = (gaussian_blur(&p, 12.0), wide_blur(&p, 12.0));
        // Away from the border (where the two clamp differently).
        let mut worst = 0.0f32;
        for y in 30..60 {
            for x in 30..90 {
                worst = worst.max((a.data[y * w + x] - b.data[y * w + x]).abs());
            }
        }
        assert!(worst < 0.01, "{worst}");
    }

    #[test]
    fn bilinear_interpolates_a_ramp_exactly() {
        let p = Plane {
            width: 4,
            height: 3,
            data: (0..12)
                .map(|i| (i % 4) as f32 + 10.0 * (i / 4) as f32)
                .collect(),
        };
        assert!((p.bilinear(1.25, 0.5) - (1.25 + 5.0)).abs() < 1e-6);
    }

    /// Slow reference: direct 2-D convolution with the same clamped border.
    fn blur_ref(p: &Plane, sigma: f64) -> Vec<f32> {
        let k = kernel(sigma);
        let r = (k.len() / 2) as isize;
        let mut out = vec![0.0f32; p.width * p.height];
        for y in 0..p.height as isize {
            for x in 0..p.width as isize {
                let mut acc = 0.0f64;
                for (j, kj) in k.iter().enumerate() {
                    for (i, ki) in k.iter().enumerate() {
                        let v = p.at(x + i as isize - r, y + j as isize - r);
                        acc += f64::from(*ki) * f64::from(*kj) * f64::from(v);
                    }
                }
                out[y as usize * p.width + x as usize] = acc as f32;
            }
        }
        out
    }

    mod proptests {
        use super::*;
        use proptest::prelude::*;

        proptest! {
            #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]
            #[test]
            fn separable_blur_matches_direct_convolution(
                w in 1usize..12,
                h in 1usize..12,
                sigma in 0.3f64..2.5,
                seed in any::<u64>(),
            ) {
                let data: Vec<f32> = (0..w * h)
                    .map(|i| ((i as u64).wrapping_mul(seed | 1).wrapping_add(seed >> 7) % 1000) as f32 / 1000.0)
                    .collect();
                let p = Plane { width: w, height: h, data };
                let fast = gaussian_blur(&p, sigma);
                for (a, b) in fast.data.iter().zip(blur_ref(&p, sigma)) {
                    prop_assert!((a - b).abs() < 1e-5, "{a} vs {b}");
                }
            }
        }
    }
}
