//! What a DMD shows: 8-bit or 1-bit patterns, fringe generators, the
//! defocus blur of the projection lens, and the timeline of what each
//! projector displayed when.
//!
//! Phase convention (DESIGN.md): a fringe pattern with shift delta is
//! I = 0.5 + 0.5 cos(Phi + delta) with absolute phase
//! Phi(u, v) = 2 pi (u cos(theta) + v sin(theta)) / P at DMD pixel (u, v)
//! (pixel centres at integers, u right, v down); theta = 0 gives vertical
//! fringes, Phi = 2 pi u / P. Decoding with
//! phi = atan2(-sum I sin d, sum I cos d) returns Phi wrapped.

use std::sync::Arc;

use super::error::TwinError;

/// Bit depth of a DMD pattern.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum BitDepth {
    /// 8-bit grey (values k/255).
    Eight,
    /// Binary (values 0 or 1), e.g. dithered fringes for kHz projection.
    One,
}

/// A displayed image in DMD pixels, values in [0, 1], row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Pattern {
    /// Width, DMD pixels.
    pub width: u32,
    /// Height, DMD pixels.
    pub height: u32,
    /// Row-major values in [0, 1].
    pub values: Vec<f32>,
}

/// A sinusoidal fringe: period, direction and shift.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Fringe {
    /// Period along the fringe normal, DMD pixels.
    pub period_px: f64,
    /// Direction of the phase gradient from +u towards +v, radians (0 = vertical fringes).
    pub angle_rad: f64,
    /// Phase shift delta, radians.
    pub shift_rad: f64,
}

impl Fringe {
    /// Absolute phase Phi at DMD pixel (u, v), radians.
    pub fn phase_at(&self, u_px: f64, v_px: f64) -> f64 {
        std::f64::consts::TAU * (u_px * self.angle_rad.cos() + v_px * self.angle_rad.sin())
            / self.period_px
    }
}

impl Pattern {
    /// A pattern from 8-bit values.
    pub fn from_u8(width: u32, height: u32, data: &[u8]) -> Result<Pattern, TwinError> {
        check_len(data.len(), width, height)?;
        Ok(Pattern {
            width,
            height,
            values: data.iter().map(|&b| b as f32 / 255.0).collect(),
        })
    }

    /// A binary pattern (mirror on / off).
    pub fn from_bits(width: u32, height: u32, bits: &[bool]) -> Result<Pattern, TwinError> {
        check_len(bits.len(), width, height)?;
        Ok(Pattern {
            width,
            height,
            values: bits.iter().map(|&b| b as u8 as f32).collect(),
        })
    }

    /// All mirrors at `level` (quantised to 8 bits).
    pub fn flat(width: u32, height: u32, level: f32) -> Pattern {
        let v = (level.clamp(0.0, 1.0) * 255.0).round() / 255.0;
        Pattern {
            width,
            height,
            values: vec![v; width as usize * height as usize],
        }
    }

    /// A fringe pattern at the given bit depth: 8-bit rounds, 1-bit uses
    /// Floyd-Steinberg error diffusion so that defocus makes it quasi-sinusoidal.
    pub fn fringe(width: u32, height: u32, fringe: &Fringe, depth: BitDepth) -> Pattern {
        let mut values = Vec::with_capacity(width as usize * height as usize);
        for v in 0..height {
            for u in 0..width {
                let phi = fringe.phase_at(u as f64, v as f64) + fringe.shift_rad;
                values.push((0.5 + 0.5 * phi.cos()) as f32);
            }
        }
        let mut p = Pattern {
            width,
            height,
            values,
        };
        match depth {
            BitDepth::Eight => p
                .values
                .iter_mut()
                .for_each(|x| *x = (*x * 255.0).round() / 255.0),
            BitDepth::One => p.dither(),
        }
        p
    }

    fn dither(&mut self) {
        let (w, h) = (self.width as usize, self.height as usize);
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let old = self.values[i];
                let new = if old >= 0.5 { 1.0 } else { 0.0 };
                self.values[i] = new;
                let e = old - new;
                let mut spread = |dx: isize, dy: usize, k: f32| {
                    let xx = x as isize + dx;
                    if xx >= 0 && (xx as usize) < w && y + dy < h {
                        self.values[(y + dy) * w + xx as usize] += e * k;
                    }
                };
                spread(1, 0, 7.0 / 16.0);
                spread(-1, 1, 3.0 / 16.0);
                spread(0, 1, 5.0 / 16.0);
                spread(1, 1, 1.0 / 16.0);
            }
        }
    }

    /// The image the lens puts on the scene: this pattern blurred by a
    /// Gaussian of `sigma_px` DMD pixels (separable, edges clamped).
    pub fn defocused(&self, sigma_px: f64) -> Pattern {
        if sigma_px <= 1e-6 {
            return self.clone();
        }
        let k = gaussian_kernel(sigma_px);
        let (w, h) = (self.width as usize, self.height as usize);
        let tmp = convolve_rows(&self.values, w, h, &k);
        let t = transpose(&tmp, w, h);
        let out = convolve_rows(&t, h, w, &k);
        Pattern {
            width: self.width,
            height: self.height,
            values: transpose(&out, h, w),
        }
    }

    /// Bilinear sample at DMD coordinate (u, v) with pixel centres at
    /// integers; 0 (dark) outside the DMD.
    #[inline]
    pub fn sample(&self, u: f32, v: f32) -> f32 {
        match Tap::new(self.width, self.height, u, v) {
            Some(t) => self.sample_tap(&t),
            None => 0.0,
        }
    }

    /// Bilinear sample through a precomputed [`Tap`] (made for this size).
    #[inline]
    pub fn sample_tap(&self, t: &Tap) -> f32 {
        let i = t.i00 as usize;
        let (a, b) = (self.values[i], self.values[i + t.dx as usize]);
        let (c, d) = (
            self.values[i + t.dy as usize],
            self.values[i + (t.dx + t.dy) as usize],
        );
        let top = a + t.fx * (b - a);
        let bot = c + t.fx * (d - c);
        top + t.fy * (bot - top)
    }

    /// Mean value over the DMD (drives the backscatter veil).
    pub fn mean(&self) -> f32 {
        self.values.iter().sum::<f32>() / self.values.len().max(1) as f32
    }
}

/// Where and how to sample a DMD coordinate bilinearly: computed once per
/// camera pixel and reused for every pattern of a sequence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tap {
    /// Index of the top-left neighbour.
    i00: u32,
    /// Offset to the right neighbour (0 on the last column).
    dx: u32,
    /// Offset to the neighbour below (0 on the last row).
    dy: u32,
    /// Horizontal weight of the right neighbour.
    fx: f32,
    /// Vertical weight of the lower neighbours.
    fy: f32,
}

impl Tap {
    /// The tap of DMD coordinate (u, v) on a `width` x `height` DMD, or None outside it.
    #[inline]
    pub fn new(width: u32, height: u32, u: f32, v: f32) -> Option<Tap> {
        let (w, h) = (width as i32, height as i32);
        if !(u >= -0.5 && v >= -0.5 && u < w as f32 - 0.5 && v < h as f32 - 0.5) {
            return None;
        }
        let u = u.clamp(0.0, (w - 1) as f32);
        let v = v.clamp(0.0, (h - 1) as f32);
        // Clamped to >= 0 above, so truncation is floor (and avoids a libm call).
        let (x0, y0) = (u as i32, v as i32);
        Some(Tap {
            i00: (y0 * w + x0) as u32,
            dx: (x0 + 1 < w) as u32,
            dy: if y0 + 1 < h { w as u32 } else { 0 },
            fx: u - x0 as f32,
            fy: v - y0 as f32,
        })
    }
}

fn check_len(len: usize, width: u32, height: u32) -> Result<(), TwinError> {
    if len != width as usize * height as usize || width == 0 || height == 0 {
        return Err(TwinError::PatternBuffer { len, width, height });
    }
    Ok(())
}

/// Normalised Gaussian kernel of radius ceil(3 sigma).
pub(crate) fn gaussian_kernel(sigma: f64) -> Vec<f32> {
    let r = (3.0 * sigma).ceil().max(1.0) as i32;
    let mut k: Vec<f32> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let s: f32 = k.iter().sum();
    k.iter_mut().for_each(|x| *x /= s);
    k
}

/// Convolves each row of a w x h image with `k`, clamping at the edges.
pub(crate) fn convolve_rows(src: &[f32], w: usize, h: usize, k: &[f32]) -> Vec<f32> {
    use rayon::prelude::*;
    let r = (k.len() / 2) as isize;
    let mut out = vec![0.0f32; w * h];
    out.par_chunks_mut(w)
        .zip(src.par_chunks(w))
        .take(h)
        .for_each(|(o, s)| {
            for (x, ox) in o.iter_mut().enumerate() {
                let mut acc = 0.0;
                for (j, kv) in k.iter().enumerate() {
                    let xx = (x as isize + j as isize - r).clamp(0, w as isize - 1) as usize;
                    acc += kv * s[xx];
                }
                *ox = acc;
            }
        });
    out
}

/// Transposes a row-major w x h image into h x w.
pub(crate) fn transpose(src: &[f32], w: usize, h: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            out[x * h + y] = src[y * w + x];
        }
    }
    out
}

/// How a DMD spreads a grey pattern over its display interval.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Display {
    /// Constant intensity over the interval (binary patterns, or grey
    /// treated as steady light).
    #[default]
    Steady,
    /// 8-bit grey as 8 binary bit planes, most significant first, plane k
    /// on for 2^k / 255 of the interval (how DLPC-class controllers show
    /// an 8-bit pattern): a window that cuts the interval sees only the
    /// planes inside it, not a proportional share of the grey.
    BitPlanes,
}

/// Bit planes of an 8-bit pattern shown over `[start_s, end_s)`, MSB
/// first: (bit, plane start, plane end).
pub fn bit_plane_intervals(start_s: f64, end_s: f64) -> [(u8, f64, f64); 8] {
    let dur = end_s - start_s;
    let mut t = start_s;
    [7u8, 6, 5, 4, 3, 2, 1, 0].map(|k| {
        let a = t;
        t += dur * (1u32 << k) as f64 / 255.0;
        (k, a, t)
    })
}

impl Pattern {
    /// Bit `k` of the pattern's 8-bit grey levels as a binary pattern.
    pub fn bit_plane(&self, k: u8) -> Pattern {
        let values = self
            .values
            .iter()
            .map(|&v| (((v.clamp(0.0, 1.0) * 255.0 + 0.5) as u32 >> k) & 1) as f32)
            .collect();
        Pattern {
            width: self.width,
            height: self.height,
            values,
        }
    }
}

/// One pattern on screen for a time interval, with its LED drive.
#[derive(Clone, Debug)]
pub struct Shown {
    /// The pattern.
    pub pattern: Arc<Pattern>,
    /// When it appeared, seconds.
    pub start_s: f64,
    /// When it disappeared, seconds.
    pub end_s: f64,
    /// LED drive per band (R, G, B) in [0, 1]: white = [1, 1, 1], a
    /// colour-multiplexed binary frame lights one LED.
    pub led: [f32; 3],
    /// Steady light or 8-bit bit planes.
    pub display: Display,
}

/// Everything one projector displayed, in time order or not.
#[derive(Clone, Debug, Default)]
pub struct ProjectorTimeline {
    /// The displayed patterns.
    pub shown: Vec<Shown>,
}

impl ProjectorTimeline {
    /// A projector that shows nothing (dark).
    pub fn dark() -> ProjectorTimeline {
        ProjectorTimeline::default()
    }

    /// One white-LED pattern for `[start_s, end_s)`.
    pub fn single(pattern: Arc<Pattern>, start_s: f64, end_s: f64) -> ProjectorTimeline {
        ProjectorTimeline {
            shown: vec![Shown {
                pattern,
                start_s,
                end_s,
                led: [1.0; 3],
                display: Display::Steady,
            }],
        }
    }

    /// Patterns back to back from `start_s`, each `period_s` long, with LED drives.
    pub fn sequence(
        items: impl IntoIterator<Item = (Arc<Pattern>, [f32; 3])>,
        start_s: f64,
        period_s: f64,
    ) -> ProjectorTimeline {
        let shown = items
            .into_iter()
            .enumerate()
            .map(|(i, (pattern, led))| Shown {
                pattern,
                start_s: start_s + i as f64 * period_s,
                end_s: start_s + (i + 1) as f64 * period_s,
                led,
                display: Display::Steady,
            })
            .collect();
        ProjectorTimeline { shown }
    }
}

/// A camera exposure window, seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Exposure {
    /// Shutter opens, seconds.
    pub start_s: f64,
    /// Shutter closes, seconds.
    pub end_s: f64,
}

impl Exposure {
    /// Checks the window is finite and non-empty.
    pub fn validate(&self) -> Result<(), TwinError> {
        if !(self.start_s.is_finite() && self.end_s.is_finite() && self.end_s > self.start_s) {
            return Err(TwinError::BadInterval {
                start_s: self.start_s,
                end_s: self.end_s,
            });
        }
        Ok(())
    }

    /// Seconds of `[a, b)` that fall inside the window.
    pub fn overlap_s(&self, a: f64, b: f64) -> f64 {
        (b.min(self.end_s) - a.max(self.start_s)).max(0.0)
    }

    /// Window length, seconds.
    pub fn duration_s(&self) -> f64 {
        self.end_s - self.start_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fringe_phase_convention_decodes() {
        // 4-step fringes, decoded with DESIGN.md's formula, give 2 pi u / P.
        let n = 4;
        let pats: Vec<Pattern> = (0..n)
            .map(|k| {
                let f = Fringe {
                    period_px: 16.0,
                    angle_rad: 0.0,
                    shift_rad: std::f64::consts::TAU * k as f64 / n as f64,
                };
                Pattern::fringe(32, 2, &f, BitDepth::Eight)
            })
            .collect();
        for u in [0usize, 3, 5, 13] {
            let (mut s, mut c) = (0.0, 0.0);
            for (k, p) in pats.iter().enumerate() {
                let d = std::f64::consts::TAU * k as f64 / n as f64;
                s += p.values[u] as f64 * d.sin();
                c += p.values[u] as f64 * d.cos();
            }
            let phi = (-s).atan2(c);
            let want = std::f64::consts::TAU * u as f64 / 16.0;
            let err = (phi - want + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            assert!(err.abs() < 0.01, "u {u}: {phi} vs {want}");
        }
    }

    #[test]
    fn defocused_binary_fringe_is_quasi_sinusoidal() {
        let f = Fringe {
            period_px: 18.0,
            angle_rad: 0.0,
            shift_rad: 0.0,
        };
        let bin = Pattern::fringe(180, 40, &f, BitDepth::One);
        assert!(bin.values.iter().all(|&v| v == 0.0 || v == 1.0));
        let blurred = bin.defocused(3.0);
        let grey = Pattern::fringe(180, 40, &f, BitDepth::Eight).defocused(3.0);
        let row = 20 * 180;
        let rms: f32 = (40..140)
            .map(|u| (blurred.values[row + u] - grey.values[row + u]).powi(2))
            .sum::<f32>()
            / 100.0;
        assert!(rms.sqrt() < 0.02, "rms {}", rms.sqrt());
    }

    #[test]
    fn sample_is_exact_at_pixel_centres_and_dark_outside() {
        let p = Pattern::from_u8(2, 2, &[0, 255, 51, 102]).unwrap();
        assert_eq!(p.sample(1.0, 0.0), 1.0);
        assert!((p.sample(0.5, 0.5) - (0.0 + 1.0 + 0.2 + 0.4) / 4.0).abs() < 1e-6);
        assert_eq!(p.sample(-0.6, 0.0), 0.0);
        assert!(Pattern::from_u8(2, 2, &[0; 3]).is_err());
    }

    #[test]
    fn overlap_of_intervals() {
        let e = Exposure {
            start_s: 1.0,
            end_s: 2.0,
        };
        assert_eq!(e.overlap_s(0.5, 1.5), 0.5);
        assert_eq!(e.overlap_s(2.0, 3.0), 0.0);
        assert!(Exposure {
            start_s: 1.0,
            end_s: 1.0
        }
        .validate()
        .is_err());
    }
}

#[cfg(test)]
mod proptests {
    use super::*;
    use proptest::prelude::*;

    /// Slow reference: bilinear interpolation written from the definition
    /// (pixel centres at integers, edge pixels extended half a pixel).
    fn sample_ref(p: &Pattern, u: f32, v: f32) -> f32 {
        let (w, h) = (p.width as f64, p.height as f64);
        let (u, v) = (u as f64, v as f64);
        if u < -0.5 || v < -0.5 || u >= w - 0.5 || v >= h - 0.5 {
            return 0.0;
        }
        let (u, v) = (u.clamp(0.0, w - 1.0), v.clamp(0.0, h - 1.0));
        let mut acc = 0.0;
        for y in 0..p.height as i64 {
            for x in 0..p.width as i64 {
                let wx = (1.0 - (u - x as f64).abs()).max(0.0);
                let wy = (1.0 - (v - y as f64).abs()).max(0.0);
                acc += wx * wy * p.values[(y * p.width as i64 + x) as usize] as f64;
            }
        }
        acc as f32
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]
        #[test]
        fn sample_matches_reference(w in 1u32..9, h in 1u32..9, seed in 0u64..1000, u in -1.0f32..10.0, v in -1.0f32..10.0) {
            let values: Vec<f32> = (0..w * h).map(|i| ((i as u64 * 7919 + seed) % 256) as f32 / 255.0).collect();
            let p = Pattern { width: w, height: h, values };
            prop_assert!((p.sample(u, v) - sample_ref(&p, u, v)).abs() < 1e-5);
        }
    }
}
