//! The analytic multi-carrier demultiplexer: one colour long exposure -> each
//! pattern's fringe `B_m cos(phi_m)` as wrapped phase and modulation.
//!
//! Three steps, each a switch for the ablations:
//! 1. colour-crosstalk removal: the camera's channels are a 3x3 mix of the
//!    three LEDs; its inverse gives each LED's light alone;
//! 2. zero-order removal: each LED's sum of backgrounds `sum A_m` is its low
//!    band (a Gaussian below every carrier), subtracted;
//! 3. per pattern, demodulation by its carrier and a low-pass window. The
//!    carrier is known from the plan and the calibration: the phase the pattern
//!    would have on a reference plane (`reference` demodulation, which follows
//!    the perspective chirp), or that phase's mean gradient (a linear carrier,
//!    FTP's). The window is an anisotropic Gaussian: narrow across the pattern's
//!    fringes' neighbours (the other directions of its LED sit 18 deg away on
//!    the same ring), wide along its carrier (only the zero order and the
//!    conjugates lie that way), sized so each interferer is left at `leak`;
//! 4. spatial-frequency decomposition by sibling cancellation (seed 001's
//!    second stage, by formula; `cancellations`, opt-in): each
//!    pattern demodulated again out of its LED's fringes minus its seven
//!    siblings' fringes as step 3 found them, through a window widened
//!    across. Step 3's narrow window flattens a small curved surface's phase
//!    (it cannot tell the surface's carrier shift from a sibling); with the
//!    siblings gone, the wider window keeps more of it (6 held-out twin
//!    scenes: wrapped-phase MAE 0.1169 -> 0.1067 rad, `highspeed_eval`).

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use rustfft::num_complex::Complex32;

use super::set::PatternSet;
use super::HighSpeedError;
use crate::fft2::Fft2;
use crate::huge_pages::filled_vec;
use crate::phase::{fast_atan2, fast_sin_cos, wrap_pi};
use crate::simd::{simd_run, Simd};

/// How the exposure is demultiplexed (the stages of the ablation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DemuxOptions {
    /// Camera channel <- LED mixing (column `c`: what LED `c` alone gives in R, G,
    /// B); `None` takes each channel as its LED (no crosstalk removal).
    pub crosstalk: Option<Matrix3<f64>>,
    /// Subtract each LED's zero order before demodulating.
    pub zero_order_removal: bool,
    /// Demodulate by the reference plane's phase map (true) or by its mean
    /// gradient, a linear carrier (false, FTP's way).
    pub reference_demodulation: bool,
    /// Largest share of an interfering carrier the window lets through.
    pub leak: f64,
    /// Demodulations after the first, each by the phase the one before found
    /// instead of the reference's: what is left to filter is the surface's
    /// phase minus the last estimate, so the window's flattening of it shrinks
    /// with every pass (to first order its loss `1 - H` becomes
    /// `(1 - H)^(refinements + 1)`), and its wider pass band lets in more noise.
    pub refinements: u32,
    /// Spatial-frequency decomposition by successive cancellation, passes
    /// after the first demodulation: each pattern is demodulated again out of
    /// its LED's fringes minus its seven siblings' fringes as the pass before
    /// found them (`B_k cos phi_k`), through a window widened across (the
    /// siblings it had to keep out are gone; three eighths of the way). Lower
    /// typical error, heavier tails where the pass before was wrong. With
    /// `refinements`, every cancellation pass refines its demodulation too.
    pub cancellations: u32,
}

impl Default for DemuxOptions {
    fn default() -> Self {
        Self {
            crosstalk: None,
            zero_order_removal: true,
            reference_demodulation: true,
            leak: 0.01,
            refinements: 0,
            cancellations: 0,
        }
    }
}

/// Each pattern's window, in camera cycles per pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Window {
    /// The pattern's mean carrier (fx, fy).
    pub carrier: [f32; 2],
    /// Standard deviation along the carrier.
    pub sigma_along: f32,
    /// Standard deviation across it.
    pub sigma_across: f32,
}

/// One exposure, demultiplexed.
#[derive(Clone, Debug, PartialEq)]
pub struct Demultiplexed {
    /// Per pattern, wrapped phase in (-pi, pi], row-major.
    pub wrapped: Vec<Vec<f32>>,
    /// Per pattern, modulation `B_m` (LED signal units).
    pub modulation: Vec<Vec<f32>>,
    /// Per LED, the zero order `sum_n A_n` (LED signal units).
    pub zero_order: [Vec<f32>; 3],
}

/// Each LED's light split into its fringes and its zero order (steps 1 and
/// 2), row-major, LED signal units (what LED `c` alone gives in channel `c`).
#[derive(Clone, Debug, PartialEq)]
pub struct ZeroOrderRemoved {
    /// Per LED, the sum of its patterns' `B_m cos(phi_m)`.
    pub fringes: [Vec<f32>; 3],
    /// Per LED, `sum_n A_n` (background and ambient light).
    pub zero_order: [Vec<f32>; 3],
}

/// The demultiplexer of one head's set at one image size.
pub struct Demultiplexer {
    fft: Fft2,
    /// Per pixel, the DMD position (u, v) of the reference plane.
    reference_dmd: Vec<[f64; 2]>,
    frequencies: Vec<[f64; 2]>,
    colours: Vec<usize>,
    windows: Vec<Window>,
    /// Each pattern's window once its siblings are cancelled.
    wide_windows: Vec<Window>,
    options: DemuxOptions,
    /// Which build of the per-pixel loops runs (both give the same bits).
    simd: Simd,
}

impl Demultiplexer {
    /// For `set` on a camera of `width` x `height` whose pixel `i` sees DMD position
    /// `reference_dmd[i]` on the reference plane.
    pub fn new(
        set: &PatternSet,
        width: usize,
        height: usize,
        reference_dmd: Vec<[f64; 2]>,
        options: DemuxOptions,
    ) -> Result<Self, HighSpeedError> {
        if reference_dmd.len() != width * height || width < 8 || height < 8 {
            return Err(HighSpeedError::WrongSize {
                what: "reference plane map".into(),
                expected: (width, height),
                got: (reference_dmd.len(), 1),
            });
        }
        if let Some(m) = options.crosstalk {
            check_crosstalk(&m)?;
        }
        let frequencies: Vec<[f64; 2]> = set.patterns().iter().map(|p| p.frequency).collect();
        let colours: Vec<usize> = set.patterns().iter().map(|p| p.colour).collect();
        let carriers: Vec<[f32; 2]> = frequencies
            .iter()
            .map(|g| mean_carrier(&reference_dmd, width, height, g))
            .collect();
        let windows: Vec<Window> = (0..carriers.len())
            .map(|m| window(m, &carriers, &colours, options.leak))
            .collect();
        let wide_windows = windows
            .iter()
            .enumerate()
            .map(|(m, narrow)| cancelled_window(narrow, m, &carriers, &colours, options.leak))
            .collect();
        Ok(Self {
            fft: Fft2::new(width, height),
            reference_dmd,
            frequencies,
            colours,
            windows,
            wide_windows,
            options,
            simd: Simd::best(),
        })
    }

    /// The same demultiplexer undoing the camera's colour crosstalk `m`
    /// (measured from LED flats once the rig is up): the windows and the
    /// FFT plans do not depend on it, so nothing else is rebuilt.
    pub fn with_crosstalk(mut self, m: Matrix3<f64>) -> Result<Self, HighSpeedError> {
        check_crosstalk(&m)?;
        self.options.crosstalk = Some(m);
        Ok(self)
    }

    /// The same demultiplexer with its per-pixel loops built for `simd`.
    pub fn with_simd(mut self, simd: Simd) -> Self {
        self.simd = simd;
        self
    }

    /// Each pattern's window.
    pub fn windows(&self) -> &[Window] {
        &self.windows
    }

    /// Pattern `m`'s carrier phase at every pixel, the phase it demodulates
    /// by (radians in [0, 2 pi); NaN where the reference is unknown).
    pub fn carrier(&self, m: usize) -> Vec<f32> {
        let (w, h) = self.fft.size();
        let mut out = vec![0.0; w * h];
        self.carrier_phase(m, None, &mut out);
        out
    }

    /// Splits one exposure (camera channels R, G, B, row-major, same size as
    /// the demultiplexer) into the patterns' wrapped phases and modulations.
    pub fn demultiplex(&self, channels: [&[f32]; 3]) -> Demultiplexed {
        self.demodulate_all(self.remove_zero_order(channels))
    }

    /// Steps 1 and 2, analytically: each LED's light (the crosstalk undone),
    /// its zero order (the low band), and its fringes without it (or with it,
    /// when the options keep the zero order). ZOCR-Net's job, done by formula.
    pub fn remove_zero_order(&self, channels: [&[f32]; 3]) -> ZeroOrderRemoved {
        let leds = unmix(channels, self.options.crosstalk);
        let min_carrier = self
            .windows
            .iter()
            .map(|w| w.carrier[0].hypot(w.carrier[1]))
            .fold(f32::INFINITY, f32::min);
        let zero_order: Vec<Vec<f32>> = leds
            .par_iter()
            .map(|s| self.low_band(s, min_carrier / 4.0))
            .collect();
        let fringes: Vec<Vec<f32>> = if self.options.zero_order_removal {
            leds.iter()
                .zip(&zero_order)
                .map(|(s, z)| s.iter().zip(z).map(|(a, b)| a - b).collect())
                .collect()
        } else {
            leds.to_vec()
        };
        let [r, g, b]: [Vec<f32>; 3] = zero_order.try_into().expect("three LEDs");
        let [fr, fg, fb]: [Vec<f32>; 3] = fringes.try_into().expect("three LEDs");
        ZeroOrderRemoved {
            fringes: [fr, fg, fb],
            zero_order: [r, g, b],
        }
    }

    /// Step 3: every pattern demodulated out of its LED's fringes, however
    /// steps 1 and 2 were done (by formula or by ZOCR-Net).
    pub fn demodulate_all(&self, cleaned: ZeroOrderRemoved) -> Demultiplexed {
        let n = self.fft.size().0 * self.fft.size().1;
        let (mut wrapped, modulation): (Vec<_>, Vec<_>) = (0..self.windows.len())
            .into_par_iter()
            .map_init(
                || DemodScratch::new(n),
                |scratch, m| self.demodulate(&cleaned.fringes[self.colours[m]], m, scratch),
            )
            .unzip();
        for _ in 0..self.options.cancellations {
            self.cancel_siblings(&cleaned.fringes, &mut wrapped, &modulation);
        }
        Demultiplexed {
            wrapped,
            modulation,
            zero_order: cleaned.zero_order,
        }
    }

    /// One pass of spatial-frequency decomposition by successive
    /// cancellation: every pattern demodulated again, through its widened
    /// window, out of its LED's fringes minus its siblings' as `wrapped` and
    /// `modulation` give them; the new phases replace `wrapped`'s.
    fn cancel_siblings(
        &self,
        fringes: &[Vec<f32>; 3],
        wrapped: &mut [Vec<f32>],
        modulation: &[Vec<f32>],
    ) {
        let n = self.fft.size().0 * self.fft.size().1;
        let found = self.found_per_led(wrapped, modulation);
        wrapped
            .par_iter_mut()
            .zip(modulation)
            .enumerate()
            .for_each_init(
                || (DemodScratch::new(n), filled_vec(n, 0.0f32)),
                |(scratch, alone), (m, (phase, b))| {
                    let c = self.colours[m];
                    // Its own fringe back in: only the siblings go.
                    for ((((a, &f), &all), &p), &b) in alone
                        .iter_mut()
                        .zip(&fringes[c])
                        .zip(&found[c])
                        .zip(phase.iter())
                        .zip(b)
                    {
                        *a = f - all + fringe_at(p, b);
                    }
                    let window = (&self.wide_windows[m], CANCELLED_FLOOR);
                    self.carrier_phase(m, None, &mut scratch.carrier);
                    self.demodulate_into(alone, window, scratch, phase, Modulation::None);
                },
            );
    }

    /// Every pattern demodulated again out of its LED's `fringes` (steps 1
    /// and 2's), on the carrier it has where pixel `i` sees DMD position
    /// `at[i]` (the reference plane's where `at[i]` is NaN) and through its
    /// first window. With `at` from a depth all patterns agree on, what the
    /// window filters is only each pattern's phase minus that prediction, so
    /// a small curved surface is no longer flattened towards the reference
    /// plane. The new phase replaces `wrapped`'s only where its modulation
    /// keeps at least [`KEEP_SHARE`] of `first`'s (the first pass's
    /// modulation, through the same window): where the prediction is wrong
    /// (at depth edges the 24 depths disagree and the carrier comes from
    /// around them) the baseband it leaves is not smooth, and the window cuts
    /// part of it. On the training stream that choice took the MAE within 2
    /// px of a depth edge from 1.05 rad to 0.98 (first pass 0.89) and left
    /// the smooth surface's at 0.041. (Against the best modulation so far
    /// instead, a second pass lost the spheres' interiors' gain: fits 0.47 /
    /// 0.34 -> 0.58 / 0.56 mm.)
    pub fn demodulate_at(
        &self,
        fringes: &[Vec<f32>; 3],
        at: &[[f64; 2]],
        wrapped: &mut [Vec<f32>],
        first: &[Vec<f32>],
    ) {
        let n = self.fft.size().0 * self.fft.size().1;
        wrapped.par_iter_mut().zip(first).enumerate().for_each_init(
            || DemodScratch::new(n),
            |scratch, (m, (phase, first))| {
                self.carrier_phase(m, Some(at), &mut scratch.carrier);
                let window = (&self.windows[m], EXP_UNDERFLOW);
                let signal = &fringes[self.colours[m]];
                self.demodulate_into(signal, window, scratch, phase, Modulation::Stronger(first));
            },
        );
    }

    /// Per LED, the sum of its patterns' fringes `B_m cos phi_m` as
    /// `wrapped` and `modulation` give them.
    fn found_per_led(&self, wrapped: &[Vec<f32>], modulation: &[Vec<f32>]) -> [Vec<f32>; 3] {
        let n = self.fft.size().0 * self.fft.size().1;
        [0, 1, 2].map(|c| {
            let mine: Vec<usize> = (0..wrapped.len())
                .filter(|&k| self.colours[k] == c)
                .collect();
            const CHUNK: usize = 4096;
            let mut sum = filled_vec(n, 0.0f32);
            sum.par_chunks_mut(CHUNK)
                .enumerate()
                .for_each(|(chunk, out)| {
                    let start = chunk * CHUNK;
                    for &k in &mine {
                        let (p, b) = (&wrapped[k][start..], &modulation[k][start..]);
                        for ((o, &p), &b) in out.iter_mut().zip(p).zip(b) {
                            *o += fringe_at(p, b);
                        }
                    }
                });
            sum
        })
    }

    /// The band below `sigma` cycles per pixel (a Gaussian at DC).
    fn low_band(&self, signal: &[f32], sigma: f32) -> Vec<f32> {
        let mut image: Vec<Complex32> = signal.iter().map(|&v| Complex32::new(v, 0.0)).collect();
        let mut spectrum = vec![Complex32::default(); image.len()];
        let max_kx = self.window_reach_columns(sigma, sigma, [1.0, 0.0], EXP_UNDERFLOW);
        self.fft.forward_band(&mut image, &mut spectrum, max_kx);
        let k = -0.5 / (sigma * sigma);
        self.apply_gaussian(&mut spectrum, max_kx, EXP_UNDERFLOW, |fx, fy| {
            k * (fx * fx + fy * fy)
        });
        self.fft.inverse_band(&mut spectrum, &mut image, max_kx);
        image.iter().map(|z| z.re).collect()
    }

    /// The half-width, in columns, of the band where a Gaussian window at DC
    /// (standard deviations `along` the unit direction `axis` and `across`
    /// it) is above [`EXP_UNDERFLOW`]: the window's ellipse at that level
    /// reaches `|fx| = sqrt(2 E (along^2 ax^2 + across^2 ay^2))`. One column
    /// of margin for rounding; outside the band every bin would be set to
    /// zero, so its column transforms are skipped (about four in five here).
    fn window_reach_columns(&self, along: f32, across: f32, axis: [f32; 2], floor: f32) -> usize {
        let w = self.fft.size().0;
        let e = -floor;
        let reach =
            (2.0 * e * (along * along * axis[0] * axis[0] + across * across * axis[1] * axis[1]))
                .sqrt();
        (reach * w as f32).ceil() as usize + 1
    }

    /// Multiplies the (transposed) spectrum by `exp(exponent(fx, fy))` in the
    /// columns `|kx| <= max_kx` (the others are zero already). Bins
    /// where that underflows ([`EXP_UNDERFLOW`]) are set to zero without
    /// calling `exp`: the windows are narrow, so most of the spectrum is such bins.
    fn apply_gaussian(
        &self,
        spectrum: &mut [Complex32],
        max_kx: usize,
        floor: f32,
        exponent: impl Fn(f32, f32) -> f32,
    ) {
        let (w, h) = self.fft.size();
        for (kx, column) in spectrum.chunks_mut(h).enumerate() {
            if kx.min(w - kx) > max_kx {
                continue;
            }
            let fx = Fft2::frequency(kx, w);
            for (ky, z) in column.iter_mut().enumerate() {
                let e = exponent(fx, Fft2::frequency(ky, h));
                *z = if e > floor {
                    *z * e.exp()
                } else {
                    Complex32::default()
                };
            }
        }
    }

    /// Pattern `m` out of its LED's signal through its own window (the first
    /// pass): (wrapped phase, modulation).
    fn demodulate(
        &self,
        signal: &[f32],
        m: usize,
        scratch: &mut DemodScratch,
    ) -> (Vec<f32>, Vec<f32>) {
        let (w, h) = self.fft.size();
        let mut phase = filled_vec(w * h, 0.0);
        let mut modulation = filled_vec(w * h, 0.0);
        self.carrier_phase(m, None, &mut scratch.carrier);
        self.demodulate_into(
            signal,
            (&self.windows[m], EXP_UNDERFLOW),
            scratch,
            &mut phase,
            Modulation::Into(&mut modulation),
        );
        (phase, modulation)
    }

    /// A pattern out of its LED's signal, on the carrier in
    /// `scratch.carrier` ([`Self::carrier_phase`]) and through `win`, into
    /// `phase` (wrapped) and as `modulation` says.
    fn demodulate_into(
        &self,
        signal: &[f32],
        (win, floor): (&Window, f32),
        scratch: &mut DemodScratch,
        phase: &mut [f32],
        modulation: Modulation,
    ) {
        let DemodScratch {
            carrier,
            image,
            spectrum,
        } = scratch;
        simd_run!(self.simd, shift_to_baseband(signal, carrier, image));
        self.low_pass(win, floor, image, spectrum);
        match modulation {
            Modulation::Into(modulation) => simd_run!(
                self.simd,
                phase_and_modulation(image, carrier, phase, modulation)
            ),
            Modulation::None => simd_run!(self.simd, phase_on_carrier(image, carrier, phase)),
            Modulation::Stronger(first) => {
                simd_run!(
                    self.simd,
                    phase_where_stronger(image, carrier, phase, first)
                )
            }
        }
        // The modulation stays the first pass's: the decoder's gate on it was
        // set for that pass, and a refined window holds more of each fringe,
        // which let in pixels the gate keeps out (6 held-out scenes: 3 % more
        // decoded, 1 % fewer of them unwrapped right).
        for _ in 0..self.options.refinements {
            carrier.copy_from_slice(phase);
            simd_run!(self.simd, shift_to_baseband(signal, carrier, image));
            self.low_pass(win, floor, image, spectrum);
            simd_run!(self.simd, phase_on_carrier(image, carrier, phase));
        }
    }

    /// Pattern `m`'s window applied to a baseband `image` in place (`spectrum`
    /// is scratch).
    fn low_pass(
        &self,
        win: &Window,
        floor: f32,
        image: &mut [Complex32],
        spectrum: &mut [Complex32],
    ) {
        let n = win.carrier[0].hypot(win.carrier[1]).max(f32::EPSILON);
        let (ax, ay) = (win.carrier[0] / n, win.carrier[1] / n);
        let max_kx = self.window_reach_columns(win.sigma_along, win.sigma_across, [ax, ay], floor);
        self.fft.forward_band(image, spectrum, max_kx);
        let (ka, kc) = (
            -0.5 / (win.sigma_along * win.sigma_along),
            -0.5 / (win.sigma_across * win.sigma_across),
        );
        self.apply_gaussian(spectrum, max_kx, floor, |fx, fy| {
            let along = fx * ax + fy * ay;
            let across = -fx * ay + fy * ax;
            ka * along * along + kc * across * across
        });
        self.fft.inverse_band(spectrum, image, max_kx);
    }

    /// Pattern `m`'s carrier phase at every pixel into `out` (radians in
    /// [0, 2 pi); NaN where the reference is unknown): the phase it has where
    /// the pixel sees DMD position `at[i]`, where given and known, else the
    /// phase on the reference plane (or its linear carrier).
    fn carrier_phase(&self, m: usize, at: Option<&[[f64; 2]]>, out: &mut [f32]) {
        let g = self.frequencies[m];
        let w = self.fft.size().0;
        if self.options.reference_demodulation {
            simd_run!(self.simd, {
                for (o, p) in out.iter_mut().zip(&self.reference_dmd) {
                    *o = cycles_to_radians(g[0] * p[0] + g[1] * p[1]);
                }
            });
        } else {
            let win = self.windows[m];
            for (i, o) in out.iter_mut().enumerate() {
                *o = cycles_to_radians(
                    f64::from(win.carrier[0]) * (i % w) as f64
                        + f64::from(win.carrier[1]) * (i / w) as f64,
                );
            }
        }
        if let Some(at) = at {
            for (o, p) in out.iter_mut().zip(at) {
                if p[0].is_finite() && p[1].is_finite() {
                    *o = cycles_to_radians(g[0] * p[0] + g[1] * p[1]);
                }
            }
        }
    }
}

/// What a demodulation writes besides the wrapped phase.
enum Modulation<'a> {
    /// Nothing: the phase alone.
    None,
    /// The modulation `B_m`, into this map.
    Into(&'a mut [f32]),
    /// The phase only where its modulation is at least [`KEEP_SHARE`] of
    /// this map's ([`phase_where_stronger`]).
    Stronger(&'a [f32]),
}

/// One worker's buffers for [`Demultiplexer::demodulate`], reused from
/// pattern to pattern: fresh ones cost ~25 MB of page faults per pattern at
/// 1280x1024.
struct DemodScratch {
    carrier: Vec<f32>,
    image: Vec<Complex32>,
    spectrum: Vec<Complex32>,
}

impl DemodScratch {
    fn new(len: usize) -> Self {
        Self {
            carrier: filled_vec(len, 0.0),
            image: filled_vec(len, Complex32::default()),
            spectrum: filled_vec(len, Complex32::default()),
        }
    }
}

/// A phase in cycles as radians in [0, 2 pi), the whole cycles dropped in
/// f64 so that f32 keeps the fraction's precision.
#[inline(always)]
pub(crate) fn cycles_to_radians(cycles: f64) -> f32 {
    (std::f64::consts::TAU * (cycles - cycles.floor())) as f32
}

/// Below this exponent `f32::exp` gives 0.
const EXP_UNDERFLOW: f32 = -104.0;

/// Where the cancellation pass's windows stop: `exp(-20)`, 2e-9 of the pass
/// band, is below what f32 keeps of a baseband beside its carrier, and
/// cutting there instead of at [`EXP_UNDERFLOW`] transforms about half the
/// columns (the cancellation pass is new, so it has no earlier bits to keep).
const CANCELLED_FLOOR: f32 = -20.0;

/// `signal * exp(-i carrier)` (zero where either is not finite): the pattern's
/// fringe moved to the spectrum's centre.
#[inline(always)]
fn shift_to_baseband(signal: &[f32], carrier: &[f32], image: &mut [Complex32]) {
    for ((z, &v), &phase) in image.iter_mut().zip(signal).zip(carrier) {
        let (s, c) = fast_sin_cos(phase);
        let keep = phase.is_finite() && v.is_finite();
        *z = if keep {
            Complex32::new(v * c, -v * s)
        } else {
            Complex32::default()
        };
    }
}

/// A pattern's fringe `B cos phi` at one pixel from its wrapped phase and
/// modulation (0 where it has none).
#[inline(always)]
fn fringe_at(phase: f32, modulation: f32) -> f32 {
    if phase.is_finite() && modulation.is_finite() {
        modulation * fast_sin_cos(phase).1
    } else {
        0.0
    }
}

/// The filtered baseband back on its carrier: wrapped phase and modulation `2 |z|`.
#[inline(always)]
fn phase_and_modulation(
    image: &[Complex32],
    carrier: &[f32],
    phase: &mut [f32],
    modulation: &mut [f32],
) {
    for (((z, &c), p), b) in image.iter().zip(carrier).zip(phase).zip(modulation) {
        *p = phase_on(z, c);
        *b = modulation_of(z);
    }
}

/// A filtered baseband's modulation `B = 2 |z|` (the fringe `B cos phi`
/// shifted to DC keeps half its amplitude).
#[inline(always)]
fn modulation_of(z: &Complex32) -> f32 {
    2.0 * (z.re * z.re + z.im * z.im).sqrt()
}

/// How much of the first pass's modulation a consensus demodulation must
/// keep to replace its phase ([`Demultiplexer::demodulate_at`]). Below 1 because the
/// modulation falls only to second order in a carrier's error while the
/// phase's bias is first order: at 1 the noisy comparison handed the smooth
/// curved parts back to the flattened first pass half the time (`spheres`
/// interiors' fits 0.52 / 0.42 -> 0.62 / 0.59 mm). Training stream
/// (`highspeed_eval --seed 1`, one pass): 1, 0.9, 0.75, 0.5, 0 (always the
/// new phase) gave 0.0680, 0.0681, 0.0690, 0.0707, 0.0716 rad; of those,
/// 0.75 is the largest that left the spheres' interiors as they were (0.9:
/// 0.54 / 0.43 mm).
const KEEP_SHARE: f32 = 0.75;

/// [`phase_on_carrier`] only where the modulation is at least
/// [`KEEP_SHARE`] of `first`'s (or the phase held is unknown).
#[inline(always)]
fn phase_where_stronger(image: &[Complex32], carrier: &[f32], phase: &mut [f32], first: &[f32]) {
    for (((z, &c), p), &b) in image.iter().zip(carrier).zip(phase).zip(first) {
        if modulation_of(z) >= KEEP_SHARE * b || !p.is_finite() {
            *p = phase_on(z, c);
        }
    }
}

/// The filtered baseband back on its carrier: wrapped phase alone.
#[inline(always)]
fn phase_on_carrier(image: &[Complex32], carrier: &[f32], phase: &mut [f32]) {
    for ((z, &c), p) in image.iter().zip(carrier).zip(phase) {
        *p = phase_on(z, c);
    }
}

/// One pixel's filtered baseband `z` back on its carrier phase `c`, wrapped.
#[inline(always)]
fn phase_on(z: &Complex32, c: f32) -> f32 {
    wrap_pi(c + fast_atan2(z.im, z.re))
}

/// A crosstalk matrix must be finite and invertible: its inverse unmixes.
fn check_crosstalk(m: &Matrix3<f64>) -> Result<(), HighSpeedError> {
    if m.try_inverse().is_none() || m.iter().any(|v| !v.is_finite()) {
        return Err(HighSpeedError::BadCrosstalk);
    }
    Ok(())
}

/// The LEDs' light from the camera channels.
fn unmix(channels: [&[f32]; 3], crosstalk: Option<Matrix3<f64>>) -> [Vec<f32>; 3] {
    let Some(inv) = crosstalk.and_then(|m| m.try_inverse()) else {
        return channels.map(|c| c.to_vec());
    };
    let inv = inv.cast::<f32>();
    let n = channels[0].len();
    let mut out = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
    for i in 0..n {
        let led = inv * Vector3::new(channels[0][i], channels[1][i], channels[2][i]);
        for c in 0..3 {
            out[c][i] = led[c];
        }
    }
    out
}

/// The mean gradient of `g . p(x)` over the image, cycles per camera pixel.
fn mean_carrier(reference: &[[f64; 2]], width: usize, height: usize, g: &[f64; 2]) -> [f32; 2] {
    let cycles = |x: usize, y: usize| {
        let p = reference[y * width + x];
        g[0] * p[0] + g[1] * p[1]
    };
    let (mut sx, mut sy, mut n) = (0.0, 0.0, 0usize);
    let step = (width.min(height) / 32).max(1);
    for y in (0..height - 1).step_by(step) {
        for x in (0..width - 1).step_by(step) {
            let (c, cx, cy) = (cycles(x, y), cycles(x + 1, y), cycles(x, y + 1));
            if c.is_finite() && cx.is_finite() && cy.is_finite() {
                sx += cx - c;
                sy += cy - c;
                n += 1;
            }
        }
    }
    let n = n.max(1) as f64;
    [(sx / n) as f32, (sy / n) as f32]
}

/// Pattern `m`'s window: along its carrier a quarter of the carrier (the zero order
/// lies at the carrier's length), across it as wide as every other carrier of its
/// LED (and every conjugate) allows at `leak`.
fn window(m: usize, carriers: &[[f32; 2]], colours: &[usize], leak: f64) -> Window {
    let f = carriers[m];
    let n = f[0].hypot(f[1]).max(1e-6);
    let (ax, ay) = (f[0] / n, f[1] / n);
    let sigma_along = n / 4.0;
    let budget = 2.0 * (1.0 / leak.clamp(1e-9, 0.5)).ln() as f32;
    let mut sigma_across = sigma_along;
    for (j, c) in carriers.iter().enumerate() {
        if j == m || colours[j] != colours[m] {
            continue;
        }
        for sign in [1.0f32, -1.0] {
            let (dx, dy) = (sign * c[0] - f[0], sign * c[1] - f[1]);
            let along = dx * ax + dy * ay;
            let across = (-dx * ay + dy * ax).abs();
            let left = budget - (along / sigma_along).powi(2);
            if left > 0.0 {
                sigma_across = sigma_across.min(across / left.sqrt());
            }
        }
    }
    Window {
        carrier: f,
        sigma_along,
        sigma_across: sigma_across.max(1e-4),
    }
}

/// How far a pattern's window widens across once its siblings are
/// cancelled, from its own window (0) to one as wide across as along (1).
/// Chosen on six random twin scenes of the training stream (seed 1): 0.125,
/// 0.25, 0.375, 0.5 and 1 gave wrapped-phase MAE 0.0912, 0.0894, 0.0892,
/// 0.0899 and 0.0913 rad after one pass (0.0982 without); what the
/// cancellation leaves of the siblings still leaks through a full width.
const CANCELLED_WIDENING: f32 = 0.375;

/// Pattern `m`'s window once its siblings are cancelled: along as its
/// `narrow` one, across [`CANCELLED_WIDENING`] of the way to a window that
/// keeps out only the zero order and its own conjugate.
fn cancelled_window(
    narrow: &Window,
    m: usize,
    carriers: &[[f32; 2]],
    colours: &[usize],
    leak: f64,
) -> Window {
    let alone = window(0, &carriers[m..=m], &colours[m..=m], leak);
    Window {
        sigma_across: narrow.sigma_across
            + CANCELLED_WIDENING * (alone.sigma_across - narrow.sigma_across),
        ..*narrow
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fronto-parallel plane seen 1:1 (DMD = camera pixel, shifted).
    fn identity_reference(w: usize, h: usize) -> Vec<[f64; 2]> {
        (0..w * h)
            .map(|i| [(i % w) as f64 + 100.0, (i / w) as f64 + 50.0])
            .collect()
    }

    #[test]
    fn a_new_phase_replaces_the_held_one_only_where_it_keeps_its_modulation() {
        // Baseband values of modulation 2 |z|: 2.0, 1.0, 1.4, 0.2; the first
        // pass's 1.6 each, and an unknown held phase, which any new one replaces.
        let image = [
            Complex32::new(1.0, 0.0),
            Complex32::new(0.0, 0.5),
            Complex32::new(0.7, 0.0),
            Complex32::new(0.1, 0.0),
        ];
        let carrier = [0.5f32; 4];
        let mut phase = [0.1, 0.2, 0.3, f32::NAN];
        phase_where_stronger(&image, &carrier, &mut phase, &[1.6; 4]);
        assert_eq!(phase[0], phase_on(&image[0], 0.5));
        assert_eq!(phase[1], 0.2, "1.0 < 0.75 x 1.6");
        assert_eq!(phase[2], phase_on(&image[2], 0.5), "1.4 >= 0.75 x 1.6");
        assert_eq!(phase[3], phase_on(&image[3], 0.5));
    }

    #[test]
    fn eight_directions_of_one_led_come_apart() {
        let set = PatternSet::seed001((1280, 800)).unwrap();
        let (w, h) = (320, 256);
        let reference = identity_reference(w, h);
        // The single demodulation (sibling cancellation is measured on the
        // bump below).
        let options = DemuxOptions {
            cancellations: 0,
            ..DemuxOptions::default()
        };
        let demux = Demultiplexer::new(&set, w, h, reference.clone(), options).unwrap();
        // Each LED's 8 patterns summed, each with its own smooth phase offset
        // (a surface off the reference plane) and albedo 0.7.
        let offset =
            |m: usize, x: f64, y: f64| 0.3 * (m as f64 + 1.0).sqrt() * (x / 70.0 + y / 90.0);
        let mut channels = vec![vec![0.0f32; w * h]; 3];
        for p in set.patterns() {
            for i in 0..w * h {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                let q = reference[i];
                let phase = PatternSet::phase_at(p, q[0], q[1]) + offset(p.index, x, y);
                channels[p.colour][i] += (0.7 * (0.5 + 0.5 * phase.cos())) as f32;
            }
        }
        let out = demux.demultiplex([&channels[0], &channels[1], &channels[2]]);
        // Measured (noise-free, 48 px from the edges): wrapped-phase MAE
        // 0.003-0.070 rad per pattern, 0.020 on average; median modulation
        // 0.3-30 % low, worst for directions 7 and 8, whose windows are
        // narrowest across and clip the carrier shift the surface adds. The
        // bounds leave room for noise in the FFT, not for a broken window.
        let mut mae_sum = 0.0f32;
        for p in set.patterns() {
            let mut err = Vec::new();
            let mut modulation = Vec::new();
            for y in 48..h - 48 {
                for x in 48..w - 48 {
                    let i = y * w + x;
                    let q = reference[i];
                    let truth =
                        PatternSet::phase_at(p, q[0], q[1]) + offset(p.index, x as f64, y as f64);
                    err.push(wrap_pi((f64::from(out.wrapped[p.index][i]) - truth) as f32).abs());
                    modulation.push(out.modulation[p.index][i]);
                }
            }
            let mae = err.iter().sum::<f32>() / err.len() as f32;
            mae_sum += mae;
            assert!(mae < 0.1, "pattern {}: MAE {mae} rad", p.index);
            modulation.sort_by(f32::total_cmp);
            let median = modulation[modulation.len() / 2];
            assert!(
                (median - 0.35).abs() < 0.12,
                "pattern {}: median modulation {median}, 0.35 true",
                p.index
            );
        }
        let mean = mae_sum / set.patterns().len() as f32;
        assert!(mean < 0.03, "mean MAE over the 24 patterns {mean} rad");
        assert!((out.zero_order[1][128 * w + 160] - 8.0 * 0.35).abs() < 0.05);
    }

    /// Each LED's 8 patterns on a bump before a flat reference: the bump
    /// shifts what each pixel sees on the DMD along u by up to 4 px, a
    /// Gaussian 12 px wide (a small curved part's parallax). The windows are
    /// about as wide as the bump (across their carriers ~30 px), so the single
    /// pass keeps a fraction H of its phase; each refinement leaves (1 - H)
    /// of what the pass before missed.
    #[test]
    fn each_refinement_and_sibling_cancellation_flatten_a_bump_less() {
        let set = PatternSet::seed001((1280, 800)).unwrap();
        let (w, h) = (256, 192);
        let reference = identity_reference(w, h);
        let (cx, cy, sigma) = (128.0, 96.0, 12.0);
        let truth = |p: &crate::highspeed::SetPattern, i: usize| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            let r2 = (x - cx).powi(2) + (y - cy).powi(2);
            let q = reference[i];
            PatternSet::phase_at(p, q[0] + 4.0 * (-0.5 * r2 / (sigma * sigma)).exp(), q[1])
        };
        let mut channels = vec![vec![0.0f32; w * h]; 3];
        for p in set.patterns() {
            for (i, v) in channels[p.colour].iter_mut().enumerate() {
                *v += (0.7 * (0.5 + 0.5 * truth(p, i).cos())) as f32;
            }
        }
        // MAE within one sigma of the bump's top, all patterns.
        let bump_mae = |refinements: u32, cancellations: u32| {
            let options = DemuxOptions {
                refinements,
                cancellations,
                ..DemuxOptions::default()
            };
            let demux = Demultiplexer::new(&set, w, h, reference.clone(), options).unwrap();
            let out = demux.demultiplex([&channels[0], &channels[1], &channels[2]]);
            let (mut sum, mut n) = (0.0f64, 0usize);
            for p in set.patterns() {
                for i in 0..w * h {
                    let (x, y) = ((i % w) as f64, (i / w) as f64);
                    if (x - cx).hypot(y - cy) < sigma {
                        let e = f64::from(out.wrapped[p.index][i]) - truth(p, i);
                        sum += f64::from(wrap_pi(e as f32).abs());
                        n += 1;
                    }
                }
            }
            (sum / n as f64, out.modulation)
        };
        let (single, modulation) = bump_mae(0, 0);
        let (once, once_modulation) = bump_mae(1, 0);
        let (twice, _) = bump_mae(2, 0);
        let (cancelled, cancelled_modulation) = bump_mae(0, 1);
        // Measured: 0.497, 0.413, 0.371 rad; siblings cancelled 0.458 rad
        // (its window widens across only, and this bump is narrower than
        // either).
        println!("bump MAE: single pass {single:.4} rad, refined once {once:.4}, twice {twice:.4}, siblings cancelled once {cancelled:.4}");
        assert!(
            single > 0.3,
            "the single pass should flatten the bump: {single} rad"
        );
        assert!(
            once < 0.9 * single,
            "refined once {once} rad, single {single} rad"
        );
        assert!(
            twice < 0.95 * once,
            "refined twice {twice} rad, once {once} rad"
        );
        // Its wider window keeps more of the bump.
        assert!(
            cancelled < 0.95 * single,
            "siblings cancelled {cancelled} rad, single {single} rad"
        );
        // The decoder's gate reads the first pass's modulation either way.
        assert_eq!(modulation, once_modulation);
        assert_eq!(modulation, cancelled_modulation);
    }

    #[test]
    fn crosstalk_is_undone_and_a_singular_matrix_refused() {
        let m = Matrix3::new(0.9, 0.12, 0.03, 0.1, 0.85, 0.1, 0.03, 0.15, 0.88);
        let leds = [0.2f64, 0.5, 0.9];
        let ch = m * Vector3::from(leds);
        let out = unmix([&[ch[0] as f32], &[ch[1] as f32], &[ch[2] as f32]], Some(m));
        for c in 0..3 {
            assert!((f64::from(out[c][0]) - leds[c]).abs() < 1e-5);
        }
        let set = PatternSet::seed001((1280, 800)).unwrap();
        let options = DemuxOptions {
            crosstalk: Some(Matrix3::zeros()),
            ..DemuxOptions::default()
        };
        assert!(matches!(
            Demultiplexer::new(&set, 16, 16, identity_reference(16, 16), options),
            Err(HighSpeedError::BadCrosstalk)
        ));
        // Adding the crosstalk to a built demultiplexer is the same as
        // building it with it, and refuses the same matrices.
        let plain = || {
            Demultiplexer::new(
                &set,
                16,
                16,
                identity_reference(16, 16),
                DemuxOptions::default(),
            )
            .unwrap()
        };
        let built = Demultiplexer::new(
            &set,
            16,
            16,
            identity_reference(16, 16),
            DemuxOptions {
                crosstalk: Some(m),
                ..DemuxOptions::default()
            },
        )
        .unwrap();
        let added = plain().with_crosstalk(m).unwrap();
        assert_eq!(added.options, built.options);
        assert_eq!(added.windows(), built.windows());
        assert!(matches!(
            plain().with_crosstalk(Matrix3::zeros()),
            Err(HighSpeedError::BadCrosstalk)
        ));
        assert!(matches!(
            plain().with_crosstalk(Matrix3::from_element(f64::NAN)),
            Err(HighSpeedError::BadCrosstalk)
        ));
    }
}
