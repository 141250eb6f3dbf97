//! Analytic de-aliasing of one overlap pixel: the two projectors' fringes
//! separated by their phasors, with no network.
//!
//! With K periods and N steps, each period's N samples give one complex
//! amplitude (the N-step DFT bin, [`crate::phase`]'s convention):
//!
//! ```text
//! Z_p = (2/N) sum_n I_n e^{-i delta_n} = a e^{i 2 pi x_A / P_p} + b e^{i 2 pi x_B / P_p}
//! ```
//!
//! 2K real numbers for four unknowns: the two projector columns `x_A`,
//! `x_B` and the two modulations `a`, `b`. The flat fields give `a` and `b`
//! to start (half of each projector's full-on signal, the fringes being full
//! contrast). Then, per period, the two circles `|Z_p - a e^{i phi_A}| = b`
//! and `|a e^{i phi_A}| = a` meet in two points: two candidate phase pairs.
//! Of the `2^K` choices, the one whose phases unwrap (heterodyne) to one
//! `x_A` and one `x_B` most consistently wins; Gauss-Newton on all four
//! unknowns against the 2K measurements refines it. A pixel is refused when
//! the model does not fit its samples (chi-square), or when the two
//! projectors' phasors are too close to tell apart (`x_A` near `x_B` for
//! every period): the solution's predicted sigma of `x_A` is then many times
//! that of a pixel lit by its own projector alone.

use nalgebra::{Matrix4, Vector4};

use crate::unwrap::heterodyne::Heterodyne;
use crate::unwrap::UnwrapError;

/// Most periods a pixel may have (`2^K` candidate choices are searched).
pub const MAX_PERIODS: usize = 6;

/// Fewest periods: with three (6 reals for 4 unknowns) about a fifth of the
/// twin's overlap pixels had several solutions on the DMD and 1.4 % came
/// out wrong; four leave a handful.
pub const MIN_PERIODS: usize = 4;

/// Scales of the flat fields' modulations the candidate search tries.
const MODULATION_SCALES: [f64; 6] = [0.8, 0.85, 0.9, 0.95, 1.0, 1.05];

/// Thresholds of the per-pixel solution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnalyticParams {
    /// Largest ratio of the solution's predicted sigma of the own column to
    /// that of the same pixel lit by its own projector alone: beyond it the
    /// two phasors are too alike (ill-posed) and the pixel is refused.
    pub max_sigma_ratio: f64,
    /// Largest RMS misfit of the 2K measurements, in units of their noise:
    /// beyond it the two-projector model does not explain the pixel (an
    /// edge, a saturated sample) and the pixel is refused.
    pub max_misfit_sigma: f64,
    /// Gauss-Newton iterations after the candidate search.
    pub iterations: usize,
    /// Starts refined per pixel (the most consistent candidate choices).
    pub starts: usize,
    /// Tolerance of the modulation ratio `a / b` against the flat fields'
    /// (on its logarithm): what tells a solution from its swap.
    pub ratio_tolerance: f64,
    /// Least cost (chi-square units) by which the best solution must beat
    /// any other with another own column; closer is ambiguous.
    pub min_cost_gap: f64,
}

impl Default for AnalyticParams {
    fn default() -> Self {
        AnalyticParams {
            max_sigma_ratio: 2.0,
            max_misfit_sigma: 4.0,
            iterations: 6,
            starts: 4,
            ratio_tolerance: 0.1,
            min_cost_gap: 9.0,
        }
    }
}

/// One pixel's separated fringes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Separated {
    /// Own projector's column, pixels.
    pub x_own_px: f64,
    /// The other projector's column, pixels.
    pub x_other_px: f64,
    /// Own fringe modulation (frame units).
    pub a: f64,
    /// The other projector's fringe modulation.
    pub b: f64,
    /// Predicted standard deviation of `x_own_px`, pixels.
    pub sigma_own_px: f64,
    /// `sigma_own_px` over that of the own projector alone.
    pub sigma_ratio: f64,
    /// Range along the camera pixel's ray, metres, where the solver knows
    /// it ([`super::epipolar`]; the free-column solver does not).
    pub range_m: Option<f64>,
}

/// Why a pixel was not separated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refused {
    /// No candidate choice unwraps to one column per projector, or a sample is not finite.
    NoSolution,
    /// The two phasors are too alike to tell apart.
    IllPosed,
    /// The two-projector model does not fit the samples.
    Misfit,
}

/// The per-pixel solver for one period set, set up once.
#[derive(Clone, Debug)]
pub struct AnalyticDealiaser {
    periods_px: Vec<f64>,
    steps: usize,
    heterodyne: Heterodyne,
    params: AnalyticParams,
    /// DMD width, pixels: solutions outside it are aliases, not columns.
    range_px: f64,
}

impl AnalyticDealiaser {
    /// For `steps`-step fringes of `periods_px` (finest first) over a DMD
    /// `dmd_width_px` wide.
    pub fn new(
        periods_px: &[f64],
        steps: usize,
        dmd_width_px: u32,
        params: AnalyticParams,
    ) -> Result<Self, UnwrapError> {
        if !(MIN_PERIODS..=MAX_PERIODS).contains(&periods_px.len()) || steps < 3 {
            return Err(UnwrapError::BadPeriods {
                periods_px: periods_px.to_vec(),
            });
        }
        // A loose rounding bound: the search compares choices by their
        // residuals, and a wrong choice must still unwrap to be compared.
        let heterodyne = Heterodyne::new(periods_px, f64::from(dmd_width_px), 2.5)?;
        Ok(AnalyticDealiaser {
            periods_px: periods_px.to_vec(),
            steps,
            heterodyne,
            params,
            range_px: f64::from(dmd_width_px),
        })
    }

    /// Periods, finest first.
    pub fn periods_px(&self) -> &[f64] {
        &self.periods_px
    }

    /// Steps per period.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Separates one pixel: `samples[p * steps + n]` (period-major, as the
    /// frames are), `a0`, `b0` the own and other modulations the flat fields
    /// give, `sigma` the noise of one sample.
    pub fn separate(
        &self,
        samples: &[f32],
        a0: f64,
        b0: f64,
        sigma: f64,
    ) -> Result<Separated, Refused> {
        let k = self.periods_px.len();
        if samples.len() != k * self.steps || samples.iter().any(|s| !s.is_finite()) {
            return Err(Refused::NoSolution);
        }
        let z: Vec<(f64, f64)> = samples.chunks(self.steps).map(dft_bin).collect();
        let (a0, b0) = (a0.max(1e-6), b0.max(1e-6));
        // One component of Z_p has variance (2/N) sigma^2.
        let sigma_z2 = 2.0 / self.steps as f64 * sigma * sigma;
        // Refine the most consistent starts; keep the solution that fits the
        // samples best with its modulation ratio nearest the flat fields'
        // (the swapped solution fits the samples exactly as well).
        let mut solutions: Vec<(f64, [f64; 4])> = Vec::new();
        for (xa, xb, m) in self.starts(&z, a0, b0) {
            let mut theta = [xa, xb, m * a0, m * b0];
            if !self.refine(&z, &mut theta) {
                continue;
            }
            let (_, _, sum_r2) = self.normal_equations(&z, &theta);
            let [xa, xb, a, b] = theta;
            // Gauss-Newton may walk to a near-alias far outside the DMD.
            let on_dmd = |x: f64| (-1.0..=self.range_px + 1.0).contains(&x);
            if !(a > 0.0 && b > 0.0 && on_dmd(xa) && on_dmd(xb)) {
                continue;
            }
            let ratio = ((a / b).ln() - (a0 / b0).ln()) / self.params.ratio_tolerance;
            solutions.push((sum_r2 / sigma_z2 + ratio * ratio, theta));
        }
        solutions.sort_by(|x, y| x.0.total_cmp(&y.0));
        let Some(&(best_cost, theta)) = solutions.first() else {
            return Err(Refused::NoSolution);
        };
        // Another solution (a different own column) nearly as good: ambiguous.
        if solutions.iter().skip(1).any(|(cost, other)| {
            (other[0] - theta[0]).abs() > 0.5 && cost - best_cost < self.params.min_cost_gap
        }) {
            return Err(Refused::IllPosed);
        }
        let (jtj, _, sum_r2) = self.normal_equations(&z, &theta);
        let misfit = (sum_r2 / (2 * k) as f64 / sigma_z2).sqrt();
        // NaN fails this too.
        if misfit.is_nan() || misfit > self.params.max_misfit_sigma {
            return Err(Refused::Misfit);
        }
        let var_own = inverse_00(&jtj).ok_or(Refused::IllPosed)? * sigma_z2;
        // The own projector alone: var(x) = sigma_z^2 / sum (a 2 pi / P)^2.
        let alone: f64 = self
            .periods_px
            .iter()
            .map(|p| (theta[2] * std::f64::consts::TAU / p).powi(2))
            .sum();
        let var_alone = sigma_z2 / alone;
        let sigma_ratio = (var_own / var_alone).sqrt();
        if !(var_own.is_finite() && sigma_ratio <= self.params.max_sigma_ratio && theta[2] > 0.0) {
            return Err(Refused::IllPosed);
        }
        Ok(Separated {
            x_own_px: theta[0],
            x_other_px: theta[1],
            a: theta[2],
            b: theta[3],
            sigma_own_px: var_own.sqrt(),
            sigma_ratio,
            range_m: None,
        })
    }

    /// Starting points `(x_own, x_other, modulation scale)`: over a few
    /// scales of the flat fields' modulations (pixel integration and blur
    /// lower the fringes' modulation below half the flat signal), the
    /// candidate choices whose phases unwrap most consistently, best first,
    /// distinct in `x_own`.
    fn starts(&self, z: &[(f64, f64)], a0: f64, b0: f64) -> Vec<(f64, f64, f64)> {
        let mut all: Vec<(f64, (f64, f64, f64))> = Vec::new();
        for m in MODULATION_SCALES {
            for (score, xa, xb) in self.choices(z, m * a0, m * b0) {
                all.push((score, (xa, xb, m)));
            }
        }
        all.sort_by(|x, y| x.0.total_cmp(&y.0));
        let mut out: Vec<(f64, f64, f64)> = Vec::new();
        for (_, start) in all {
            if out
                .iter()
                .all(|s| (s.0 - start.0).abs() > 0.5 || (s.1 - start.1).abs() > 0.5)
            {
                out.push(start);
                if out.len() == self.params.starts {
                    break;
                }
            }
        }
        out
    }

    /// Gauss-Newton on `theta`; false when a step cannot be solved.
    fn refine(&self, z: &[(f64, f64)], theta: &mut [f64; 4]) -> bool {
        for _ in 0..self.params.iterations {
            let (jtj, jtr, _) = self.normal_equations(z, theta);
            let Some(step) = solve4(&jtj, &jtr) else {
                return false;
            };
            for (t, s) in theta.iter_mut().zip(step) {
                *t -= s;
            }
            if step[0].abs() < 1e-6 && step[1].abs() < 1e-6 {
                break;
            }
        }
        theta.iter().all(|t| t.is_finite())
    }

    /// Every candidate choice that unwraps, as (inconsistency, x_own, x_other),
    /// for modulations `a`, `b`.
    fn choices(&self, z: &[(f64, f64)], a: f64, b: f64) -> Vec<(f64, f64, f64)> {
        let k = z.len();
        let mut pairs = [[(0.0f64, 0.0f64); 2]; MAX_PERIODS];
        for (p, &(re, im)) in z.iter().enumerate() {
            let r = (re * re + im * im).sqrt();
            let arg = im.atan2(re);
            // Law of cosines: angle between Z and the own phasor.
            let cos = ((r * r + a * a - b * b) / (2.0 * a * r.max(1e-12))).clamp(-1.0, 1.0);
            let alpha = cos.acos();
            for (slot, sign) in pairs[p].iter_mut().zip([1.0, -1.0]) {
                let phi_a = arg + sign * alpha;
                let (ore, oim) = (re - a * phi_a.cos(), im - a * phi_a.sin());
                *slot = (phi_a, oim.atan2(ore));
            }
        }
        let mut out = Vec::with_capacity(1 << k);
        let mut wrapped_a = [0.0f32; MAX_PERIODS];
        let mut wrapped_b = [0.0f32; MAX_PERIODS];
        for choice in 0..(1usize << k) {
            for p in 0..k {
                let (pa, pb) = pairs[p][(choice >> p) & 1];
                wrapped_a[p] = wrap(pa) as f32;
                wrapped_b[p] = wrap(pb) as f32;
            }
            let (Some(xa), Some(xb)) = (self.column(&wrapped_a[..k]), self.column(&wrapped_b[..k]))
            else {
                continue;
            };
            let score =
                self.inconsistency(&wrapped_a[..k], xa) + self.inconsistency(&wrapped_b[..k], xb);
            out.push((score, xa, xb));
        }
        out
    }

    /// The column whose phases these wrapped ones are, by heterodyne.
    fn column(&self, wrapped: &[f32]) -> Option<f64> {
        let abs = self.heterodyne.unwrap_pixel(wrapped)?;
        Some(f64::from(abs) * self.periods_px[0] / std::f64::consts::TAU)
    }

    /// Sum of squared wrapped differences between `wrapped` and column `x`'s phases.
    fn inconsistency(&self, wrapped: &[f32], x: f64) -> f64 {
        wrapped
            .iter()
            .zip(&self.periods_px)
            .map(|(&w, p)| wrap(f64::from(w) - std::f64::consts::TAU * x / p).powi(2))
            .sum()
    }

    /// `J^T J`, `J^T r` and `sum r^2` of the 2K residuals at `theta` =
    /// (x_own, x_other, a, b).
    fn normal_equations(
        &self,
        z: &[(f64, f64)],
        theta: &[f64; 4],
    ) -> ([[f64; 4]; 4], [f64; 4], f64) {
        let [xa, xb, a, b] = *theta;
        let mut jtj = [[0.0; 4]; 4];
        let mut jtr = [0.0; 4];
        let mut sum_r2 = 0.0;
        for (&(re, im), p) in z.iter().zip(&self.periods_px) {
            let w = std::f64::consts::TAU / p;
            let (sa, ca) = (w * xa).sin_cos();
            let (sb, cb) = (w * xb).sin_cos();
            // Model minus measurement, real and imaginary parts.
            let rows = [
                (a * ca + b * cb - re, [-a * w * sa, -b * w * sb, ca, cb]),
                (a * sa + b * sb - im, [a * w * ca, b * w * cb, sa, sb]),
            ];
            for (r, j) in rows {
                sum_r2 += r * r;
                for u in 0..4 {
                    jtr[u] += j[u] * r;
                    for v in 0..4 {
                        jtj[u][v] += j[u] * j[v];
                    }
                }
            }
        }
        (jtj, jtr, sum_r2)
    }
}

impl super::Separator for AnalyticDealiaser {
    fn periods_px(&self) -> &[f64] {
        &self.periods_px
    }

    fn steps(&self) -> usize {
        self.steps
    }

    /// The pixel's place does not matter: the columns are free unknowns.
    fn separate_pixel(
        &self,
        _index: usize,
        samples: &[f32],
        a0: f64,
        b0: f64,
        sigma: f64,
    ) -> Result<Separated, Refused> {
        self.separate(samples, a0, b0, sigma)
    }
}

/// The N-step DFT bin `(2/N) sum I_n e^{-i 2 pi n / N}` as (re, im).
pub(super) fn dft_bin(samples: &[f32]) -> (f64, f64) {
    let n = samples.len() as f64;
    let (mut re, mut im) = (0.0, 0.0);
    for (k, &s) in samples.iter().enumerate() {
        let (sin, cos) = (std::f64::consts::TAU * k as f64 / n).sin_cos();
        re += f64::from(s) * cos;
        im -= f64::from(s) * sin;
    }
    (2.0 / n * re, 2.0 / n * im)
}

fn wrap(a: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    a - tau * ((a + std::f64::consts::PI) / tau).floor()
}

/// Solves the 4x4 system `m x = r` (LU); `None` when `m` is singular.
fn solve4(m: &[[f64; 4]; 4], r: &[f64; 4]) -> Option<[f64; 4]> {
    let x = matrix4(m).lu().solve(&Vector4::from(*r))?;
    x.iter()
        .all(|v| v.is_finite())
        .then(|| [x[0], x[1], x[2], x[3]])
}

/// Element (0, 0) of the inverse of `m`.
fn inverse_00(m: &[[f64; 4]; 4]) -> Option<f64> {
    matrix4(m).try_inverse().map(|inv| inv[(0, 0)])
}

fn matrix4(m: &[[f64; 4]; 4]) -> Matrix4<f64> {
    Matrix4::from_fn(|i, j| m[i][j])
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// 73, 64, 56, 50 fringes over 1280 px (`scan::dealias_periods_px`).
    pub(in crate::dealias) const PERIODS: [f64; 4] = [1280.0 / 73.0, 20.0, 1280.0 / 56.0, 25.6];

    fn solver() -> AnalyticDealiaser {
        AnalyticDealiaser::new(&PERIODS, 4, 1280, AnalyticParams::default()).unwrap()
    }

    /// The 16 samples of a pixel lit by both projectors.
    pub(in crate::dealias) fn samples(
        xa: f64,
        xb: f64,
        a: f64,
        b: f64,
        noise: f64,
        seed: u64,
    ) -> Vec<f32> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let n = Normal::new(0.0, noise.max(1e-12)).unwrap();
        let mut out = Vec::new();
        for p in PERIODS {
            for step in 0..4 {
                let d = std::f64::consts::FRAC_PI_2 * step as f64;
                let tau = std::f64::consts::TAU;
                let v = 0.1
                    + a
                    + b
                    + a * (tau * xa / p + d).cos()
                    + b * (tau * xb / p + d).cos()
                    + if noise > 0.0 { n.sample(&mut rng) } else { 0.0 };
                out.push(v as f32);
            }
        }
        out
    }

    #[test]
    fn noise_free_pixels_come_back_exactly_over_the_field() {
        let s = solver();
        let mut worst = 0.0f64;
        for (k, (xa, xb)) in [
            (100.3, 700.8),
            (1200.0, 15.5),
            (640.0, 655.0),
            (3.2, 1200.0),
        ]
        .into_iter()
        .enumerate()
        {
            let (a, b) = (0.3, 0.12 + 0.05 * k as f64);
            // The flat fields overstate both modulations alike (pixel
            // integration lowers the fringes', not the flat signal).
            let got = s
                .separate(&samples(xa, xb, a, b, 0.0, 0), a / 0.9, b / 0.9, 0.005)
                .unwrap();
            worst = worst.max((got.x_own_px - xa).abs());
            assert!((got.x_other_px - xb).abs() < 1e-3, "{got:?}");
            assert!(
                (got.a - a).abs() < 1e-5 && (got.b - b).abs() < 1e-5,
                "{got:?}"
            );
        }
        assert!(worst < 1e-3, "{worst}");
    }

    #[test]
    fn noisy_pixels_scatter_as_predicted() {
        let s = solver();
        let (xa, xb, a, b, sigma) = (333.3, 901.7, 0.3, 0.2, 0.005);
        let (n, ratio) = scatter_over_prediction(xa, |seed| {
            s.separate(&samples(xa, xb, a, b, sigma, seed), a, b, sigma)
        });
        assert!(n > 390, "{n} of 400 separated");
        assert!(
            (0.85..1.15).contains(&ratio),
            "measured / predicted {ratio}"
        );
    }

    /// Separates seeds 0..400 of one pixel and returns how many were
    /// separated and the RMS error of their own column (true `xa`) over
    /// their RMS predicted sigma.
    pub(in crate::dealias) fn scatter_over_prediction(
        xa: f64,
        separate: impl Fn(u64) -> Result<Separated, Refused>,
    ) -> (usize, f64) {
        let (mut e2, mut pred2, mut n) = (0.0, 0.0, 0);
        for got in (0..400).filter_map(|seed| separate(seed).ok()) {
            e2 += (got.x_own_px - xa).powi(2);
            pred2 += got.sigma_own_px.powi(2);
            n += 1;
        }
        (n, (e2 / pred2).sqrt())
    }

    #[test]
    fn alike_phasors_are_refused() {
        let s = solver();
        // The same column on both projectors: one phasor, no way to tell the
        // two apart (refused as ill-posed, or as fitting no separated pair).
        let got = s.separate(&samples(500.0, 500.0, 0.3, 0.3, 0.0, 0), 0.3, 0.3, 0.005);
        assert!(got.is_err(), "{got:?}");
        // Nearly the same column everywhere: the solution would be noise.
        let got = s.separate(&samples(500.0, 500.2, 0.3, 0.29, 0.0, 0), 0.3, 0.29, 0.005);
        assert!(got.is_err(), "{got:?}");
    }

    #[test]
    fn samples_the_model_cannot_explain_are_refused() {
        let s = solver();
        let mut bad = samples(100.0, 800.0, 0.3, 0.1, 0.0, 0);
        bad[5] += 0.3;
        assert_eq!(s.separate(&bad, 0.3, 0.1, 0.003), Err(Refused::Misfit));
        bad[5] = f32::NAN;
        assert_eq!(s.separate(&bad, 0.3, 0.1, 0.003), Err(Refused::NoSolution));
    }
}
