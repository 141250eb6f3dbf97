//! Epipolar de-aliasing of one overlap pixel: the calibrated rig ties both
//! projectors' columns to one unknown, the range `s` along the camera
//! pixel's ray.
//!
//! The analytic solver ([`super::analytic`]) treats the two columns as free:
//! four unknowns `(x_A, x_B, a, b)` for the 2K reals of K phasors, and it
//! must refuse every pixel whose two phasors look alike. A calibrated
//! scanner knows more: the surface point on the ray at range `s` projects
//! to column `x_own(s)` of its own projector and `x_other(s)` of the other,
//! so
//!
//! ```text
//! Z_p = a e^{i 2 pi x_own(s) / P_p} + b e^{i 2 pi x_other(s) / P_p}
//! ```
//!
//! has three unknowns `(s, a, b)`, and for a given `s` the modulations
//! follow by linear least squares. The solver walks the ray through the
//! volume both projectors light, in steps that move either column by a
//! fraction of the finest period, keeps the deepest local minima of the
//! least-squares misfit, refines each by Gauss-Newton on `(s, a, b)` with
//! the exact (distorted) projections, and takes the best. Where the two
//! phasors coincide, `s` is still fixed by their sum; only the split of
//! `a` and `b` is not, and a loose prior from the flat fields settles it.
//! A pixel is refused when another range fits nearly as well (ambiguous),
//! when the model does not fit its samples, or when its own column is much
//! less certain than that of a pixel lit by its own projector alone.

use nalgebra::{Matrix3, Vector3};

use super::analytic::{dft_bin, Refused, Separated, MAX_PERIODS, MIN_PERIODS};
use super::Separator;
use crate::calibration::{CameraModel, Pose, ProjectorModel, RigCalibration};

/// Thresholds and effort of the per-pixel solution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EpipolarParams {
    /// Largest ratio of the solution's predicted sigma of the own column to
    /// that of the same pixel lit by its own projector alone.
    pub max_sigma_ratio: f64,
    /// Largest RMS misfit of the 2K measurements, in units of their noise.
    pub max_misfit_sigma: f64,
    /// Least cost (chi-square units) by which the best range must beat any
    /// other whose own column differs by more than half a pixel.
    pub min_cost_gap: f64,
    /// Walk step: the most either column moves per step, as a share of the
    /// finest period (a minimum of the misfit is about a quarter period wide).
    pub step_share: f64,
    /// Local minima of the walk refined per pixel.
    pub minima: usize,
    /// Gauss-Newton iterations per minimum.
    pub iterations: usize,
    /// Prior on each fringe modulation: `fringe_share` of half the flat
    /// field's signal, with a relative sigma of `prior_sigma` (loose: it only
    /// settles the split of `a` and `b` where the two phasors coincide).
    pub fringe_share: f64,
    /// See `fringe_share`.
    pub prior_sigma: f64,
}

impl Default for EpipolarParams {
    fn default() -> Self {
        EpipolarParams {
            max_sigma_ratio: 2.0,
            max_misfit_sigma: 4.0,
            min_cost_gap: 9.0,
            step_share: 0.2,
            minima: 4,
            iterations: 8,
            fringe_share: 0.9,
            prior_sigma: 0.25,
        }
    }
}

/// Why an epipolar de-aliaser cannot be set up for a rig.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EpipolarError {
    /// The simultaneous mode's two projectors are needed.
    #[error("epipolar de-aliasing needs a rig of two heads with their pose, got {heads} heads")]
    NotTwoHeads {
        /// Heads in the rig file.
        heads: usize,
    },
    /// Fewer or more periods than the solver takes, or fewer than 3 steps.
    #[error(
        "epipolar de-aliasing needs {MIN_PERIODS} to {MAX_PERIODS} periods of at least 3 steps, \
         got {periods} periods of {steps} steps"
    )]
    BadPeriods {
        /// Periods given.
        periods: usize,
        /// Steps per period.
        steps: usize,
    },
}

/// One projector's view of a camera ray: the ray's point at range `s` is
/// `q + s e` in the projector's frame.
#[derive(Clone, Copy, Debug)]
struct RayInProjector {
    q: Vector3<f64>,
    e: Vector3<f64>,
}

/// The per-pixel solver for one camera of a two-head rig, set up once.
#[derive(Clone, Debug)]
pub struct EpipolarDealiaser {
    periods_px: Vec<f64>,
    /// `1 / periods_px`.
    inv_periods: Vec<f64>,
    steps: usize,
    camera: CameraModel,
    /// The camera's own projector, in the camera head's frame.
    own: ProjectorModel,
    /// The other head's projector, in the camera head's frame.
    other: ProjectorModel,
    params: EpipolarParams,
}

impl EpipolarDealiaser {
    /// For head `own`'s camera of a two-head `rig`, with `steps`-step
    /// fringes of `periods_px` (finest first).
    pub fn new(
        rig: &RigCalibration,
        own: usize,
        periods_px: &[f64],
        steps: usize,
        params: EpipolarParams,
    ) -> Result<Self, EpipolarError> {
        let heads = rig.heads.len();
        let other = 1 - own.min(1);
        let (Some(to_own), Some(to_other)) = (rig.pose_from_first(own), rig.pose_from_first(other))
        else {
            return Err(EpipolarError::NotTwoHeads { heads });
        };
        if heads != 2 || own > 1 {
            return Err(EpipolarError::NotTwoHeads { heads });
        }
        if !(MIN_PERIODS..=MAX_PERIODS).contains(&periods_px.len()) || steps < 3 {
            return Err(EpipolarError::BadPeriods {
                periods: periods_px.len(),
                steps,
            });
        }
        // Own head's frame -> first head's -> other head's -> its projector.
        let own_to_other: Pose = to_other.compose(&to_own.inverse());
        let mut other_projector = rig.heads[other].projector;
        other_projector.pose = other_projector.pose.compose(&own_to_other);
        Ok(EpipolarDealiaser {
            periods_px: periods_px.to_vec(),
            inv_periods: periods_px.iter().map(|p| 1.0 / p).collect(),
            steps,
            camera: rig.heads[own].camera,
            own: rig.heads[own].projector,
            other: other_projector,
            params,
        })
    }

    /// Separates camera pixel `index`: `samples[p * steps + n]`
    /// (period-major), `a0`, `b0` the own and other modulations the flat
    /// fields give, `sigma` the noise of one sample. Walks the whole ray.
    pub fn separate(
        &self,
        index: usize,
        samples: &[f32],
        a0: f64,
        b0: f64,
        sigma: f64,
    ) -> Result<Separated, Refused> {
        let pixel = self.pixel_problem(index, samples, a0, b0, sigma)?;
        self.walk_and_finish(&pixel)
    }

    /// Walks the pixel's ray, refines the deepest minima and keeps the best
    /// unless another range fits nearly as well.
    fn walk_and_finish(&self, pixel: &PixelProblem) -> Result<Separated, Refused> {
        let starts = self.walk(&pixel.rays, pixel.z());
        let solutions = self.solutions(pixel, starts);
        let Some(&(best_cost, best_own, theta)) = solutions.first() else {
            return Err(Refused::NoSolution);
        };
        // Another range (another own column) nearly as good: ambiguous.
        if solutions.iter().skip(1).any(|(cost, x, _)| {
            (x - best_own).abs() > 0.5 && cost - best_cost < self.params.min_cost_gap
        }) {
            return Err(Refused::IllPosed);
        }
        self.finish(pixel, &theta)
    }

    /// As [`Self::separate`], starting from the ranges `hints_m` of
    /// separated neighbours (nearest first) instead of walking the ray: on a
    /// smooth surface the first leads to the pixel's own range, and the
    /// first solution that passes is taken. Walks the ray when none does.
    pub fn separate_near(
        &self,
        index: usize,
        samples: &[f32],
        a0: f64,
        b0: f64,
        sigma: f64,
        hints_m: &[f64],
    ) -> Result<Separated, Refused> {
        let pixel = self.pixel_problem(index, samples, a0, b0, sigma)?;
        let zz: f64 = pixel.z().iter().map(|(re, im)| re * re + im * im).sum();
        for &s in hints_m {
            let Some((x_own, x_other)) = self.columns(&pixel.rays, s) else {
                continue;
            };
            let (_, a, b) = self.fit_modulations(pixel.z(), zz, x_own, x_other);
            if let Some((_, _, theta)) = self.solutions(&pixel, [[s, a, b]]).first() {
                if let Ok(separated) = self.finish(&pixel, theta) {
                    return Ok(separated);
                }
            }
        }
        self.walk_and_finish(&pixel)
    }

    /// The pixel's ray in both projectors, its phasors and its priors.
    fn pixel_problem(
        &self,
        index: usize,
        samples: &[f32],
        a0: f64,
        b0: f64,
        sigma: f64,
    ) -> Result<PixelProblem, Refused> {
        let k = self.periods_px.len();
        if samples.len() != k * self.steps || samples.iter().any(|s| !s.is_finite()) {
            return Err(Refused::NoSolution);
        }
        let width = self.camera.width_px as usize;
        let ray = self
            .camera
            .pixel_ray((index % width) as f64, (index / width) as f64)
            .ok_or(Refused::NoSolution)?;
        let in_projector = |p: &ProjectorModel| RayInProjector {
            q: p.pose.apply(&ray.origin_m).coords,
            e: p.pose.rotation * ray.direction,
        };
        let mut z = [(0.0, 0.0); MAX_PERIODS];
        for (zp, chunk) in z.iter_mut().zip(samples.chunks(self.steps)) {
            *zp = dft_bin(chunk);
        }
        let sigma_z2 = 2.0 / self.steps as f64 * sigma * sigma;
        Ok(PixelProblem {
            rays: [in_projector(&self.own), in_projector(&self.other)],
            z,
            periods: k,
            prior: Prior {
                a: self.params.fringe_share * a0.max(0.0),
                b: self.params.fringe_share * b0.max(0.0),
                sigma: self.params.prior_sigma * (a0.max(b0)).max(1e-6),
                sigma_z2,
            },
        })
    }

    /// Refines each start and keeps the solutions on both DMDs with a
    /// positive own modulation, distinct in the own column, as
    /// `(chi-square, own column, theta)`, best first.
    fn solutions(
        &self,
        pixel: &PixelProblem,
        starts: impl IntoIterator<Item = [f64; 3]>,
    ) -> Vec<(f64, f64, [f64; 3])> {
        let (rays, z) = (&pixel.rays, pixel.z());
        let mut solutions: Vec<(f64, f64, [f64; 3])> = Vec::new();
        for start in starts {
            let Some(theta) = self.refine(rays, z, start, &pixel.prior) else {
                continue;
            };
            let Some((x_own, x_other)) = self.columns(rays, theta[0]) else {
                continue;
            };
            if !(self.on_dmd(&self.own, &rays[0], theta[0], x_own)
                && self.on_dmd(&self.other, &rays[1], theta[0], x_other)
                && theta[1] > 0.0)
            {
                continue;
            }
            let (_, _, sum_r2) = self.normal_equations(rays, z, &theta, &pixel.prior);
            solutions.push((sum_r2, x_own, theta));
        }
        solutions.sort_by(|x, y| x.0.total_cmp(&y.0));
        solutions
    }

    /// The separated pixel at `theta`, or why it is refused: the model must
    /// fit the samples, and the own column must be nearly as certain as
    /// with the own projector alone.
    fn finish(&self, pixel: &PixelProblem, theta: &[f64; 3]) -> Result<Separated, Refused> {
        let (rays, z) = (&pixel.rays, pixel.z());
        let sigma_z2 = pixel.prior.sigma_z2;
        let measured_r2 = self.misfit(rays, z, theta);
        let misfit = (measured_r2 / (2 * pixel.periods) as f64 / sigma_z2).sqrt();
        if misfit.is_nan() || misfit > self.params.max_misfit_sigma {
            return Err(Refused::Misfit);
        }
        // Residuals are in sigma units: the inverse is the covariance.
        let (jtj, _, _) = self.normal_equations(rays, z, theta, &pixel.prior);
        let var_s = Matrix3::from_fn(|i, j| jtj[i][j])
            .try_inverse()
            .map(|inv| inv[(0, 0)])
            .ok_or(Refused::IllPosed)?;
        let ((x_own, d_own), (x_other, _)) = self
            .columns_and_rates(rays, theta[0])
            .ok_or(Refused::NoSolution)?;
        let var_own = var_s * d_own * d_own;
        let alone: f64 = self
            .periods_px
            .iter()
            .map(|p| (theta[1] * std::f64::consts::TAU / p).powi(2))
            .sum();
        let var_alone = sigma_z2 / alone;
        let sigma_ratio = (var_own / var_alone).sqrt();
        if !(var_own.is_finite() && sigma_ratio <= self.params.max_sigma_ratio) {
            return Err(Refused::IllPosed);
        }
        Ok(Separated {
            x_own_px: x_own,
            x_other_px: x_other,
            a: theta[1],
            b: theta[2],
            sigma_own_px: var_own.sqrt(),
            sigma_ratio,
            range_m: Some(theta[0]),
        })
    }

    /// Walks the ray through the range both projectors light (within a
    /// margin for their distortion) and returns the deepest local minima of
    /// the misfit with `a`, `b` fitted by least squares, as `(s, a, b)`.
    fn walk(&self, rays: &[RayInProjector; 2], z: &[(f64, f64)]) -> Vec<[f64; 3]> {
        let Some((mut s, s_end)) = self.lit_range(rays) else {
            return Vec::new();
        };
        let step_px = self.params.step_share * self.periods_px[0];
        let zz: f64 = z.iter().map(|(re, im)| re * re + im * im).sum();
        let mut minima: Vec<(f64, [f64; 3])> = Vec::with_capacity(self.params.minima + 1);
        // (cost, s, a, b) of the last two samples.
        let mut before: Option<(f64, [f64; 3])> = None;
        let mut last: Option<(f64, [f64; 3])> = None;
        let mut samples = 0;
        while s <= s_end && samples < MAX_WALK_SAMPLES {
            samples += 1;
            let (Some((x_own, d_own)), Some((x_other, d_other))) = (
                column_and_rate(&self.own, &rays[0], s),
                column_and_rate(&self.other, &rays[1], s),
            ) else {
                break;
            };
            let (cost, a, b) = self.fit_modulations(z, zz, x_own, x_other);
            let here = (cost, [s, a, b]);
            if let (Some(b0), Some(l)) = (before, last) {
                if l.0 <= b0.0 && l.0 <= cost {
                    keep_minimum(&mut minima, l, self.params.minima);
                }
            }
            before = last;
            last = Some(here);
            let rate = d_own.abs().max(d_other.abs()).max(1e-9);
            s += step_px / rate;
        }
        // A minimum at the end of the range.
        if let (Some(b0), Some(l)) = (before, last) {
            if l.0 <= b0.0 {
                keep_minimum(&mut minima, l, self.params.minima);
            }
        }
        minima.into_iter().map(|(_, t)| t).collect()
    }

    /// `(cost, a, b)` of the best non-negative modulations for columns
    /// `x_own`, `x_other`: linear least squares on the K phasors.
    fn fit_modulations(
        &self,
        z: &[(f64, f64)],
        zz: f64,
        x_own: f64,
        x_other: f64,
    ) -> (f64, f64, f64) {
        let k = z.len() as f64;
        let (mut suv, mut suz, mut svz) = (0.0, 0.0, 0.0);
        for (&(re, im), inv_p) in z.iter().zip(&self.inv_periods) {
            // A table: the walk only ranks samples a fifth of a period apart.
            let (cu, su) = unit_phasor(x_own * inv_p);
            let (cv, sv) = unit_phasor(x_other * inv_p);
            suv += cu * cv + su * sv;
            suz += cu * re + su * im;
            svz += cv * re + sv * im;
        }
        let det = k * k - suv * suv;
        if det > 1e-9 * k * k {
            let a = (k * suz - suv * svz) / det;
            let b = (k * svz - suv * suz) / det;
            if a >= 0.0 && b >= 0.0 {
                return (zz - (a * suz + b * svz), a, b);
            }
        }
        // On the boundary: one projector alone explains the pixel best.
        let (a, b) = (suz.max(0.0) / k, svz.max(0.0) / k);
        if a * suz >= b * svz {
            (zz - a * suz, a, 0.0)
        } else {
            (zz - b * svz, 0.0, b)
        }
    }

    /// Gauss-Newton on `(s, a, b)` from `start`, the step in `s` limited to
    /// a quarter period of either column; `None` when a step cannot be
    /// solved or the range leaves both devices' fronts.
    fn refine(
        &self,
        rays: &[RayInProjector; 2],
        z: &[(f64, f64)],
        start: [f64; 3],
        prior: &Prior,
    ) -> Option<[f64; 3]> {
        let mut theta = start;
        let quarter = 0.25 * self.periods_px[0];
        for _ in 0..self.params.iterations {
            let (jtj, jtr, _) = self.normal_equations(rays, z, &theta, prior);
            let m = Matrix3::from_fn(|i, j| jtj[i][j]);
            let step = m.lu().solve(&Vector3::from(jtr))?;
            let ((_, d_own), (_, d_other)) = self.columns_and_rates(rays, theta[0])?;
            let rate = d_own.abs().max(d_other.abs()).max(1e-12);
            let ds = step[0].clamp(-quarter / rate, quarter / rate);
            theta = [theta[0] - ds, theta[1] - step[1], theta[2] - step[2]];
            if !theta.iter().all(|t| t.is_finite()) {
                return None;
            }
            if (ds * rate).abs() < 1e-5 {
                break;
            }
        }
        self.columns(rays, theta[0]).map(|_| theta)
    }

    /// `J^T J`, `J^T r` and `sum r^2` at `theta = (s, a, b)` of the 2K
    /// measurements and the two modulation priors, all in units of their
    /// sigma.
    fn normal_equations(
        &self,
        rays: &[RayInProjector; 2],
        z: &[(f64, f64)],
        theta: &[f64; 3],
        prior: &Prior,
    ) -> ([[f64; 3]; 3], [f64; 3], f64) {
        let [s, a, b] = *theta;
        let mut jtj = [[0.0; 3]; 3];
        let mut jtr = [0.0; 3];
        let mut sum_r2 = 0.0;
        let mut add = |r: f64, j: [f64; 3]| {
            sum_r2 += r * r;
            for u in 0..3 {
                jtr[u] += j[u] * r;
                for v in 0..3 {
                    jtj[u][v] += j[u] * j[v];
                }
            }
        };
        let Some(((xa, da), (xb, db))) = self.columns_and_rates(rays, s) else {
            return (jtj, jtr, f64::INFINITY);
        };
        let inv = 1.0 / prior.sigma_z2.sqrt();
        for (&(re, im), p) in z.iter().zip(&self.periods_px) {
            let w = std::f64::consts::TAU / p;
            let (sa, ca) = (w * xa).sin_cos();
            let (sb, cb) = (w * xb).sin_cos();
            add(
                (a * ca + b * cb - re) * inv,
                [
                    (-a * w * sa * da - b * w * sb * db) * inv,
                    ca * inv,
                    cb * inv,
                ],
            );
            add(
                (a * sa + b * sb - im) * inv,
                [
                    (a * w * ca * da + b * w * cb * db) * inv,
                    sa * inv,
                    sb * inv,
                ],
            );
        }
        add((a - prior.a) / prior.sigma, [0.0, 1.0 / prior.sigma, 0.0]);
        add((b - prior.b) / prior.sigma, [0.0, 0.0, 1.0 / prior.sigma]);
        (jtj, jtr, sum_r2)
    }

    /// `sum r^2` of the 2K measurements alone (frame units squared).
    fn misfit(&self, rays: &[RayInProjector; 2], z: &[(f64, f64)], theta: &[f64; 3]) -> f64 {
        let [s, a, b] = *theta;
        let Some((xa, xb)) = self.columns(rays, s) else {
            return f64::INFINITY;
        };
        z.iter()
            .zip(&self.periods_px)
            .map(|(&(re, im), p)| {
                let w = std::f64::consts::TAU / p;
                let (sa, ca) = (w * xa).sin_cos();
                let (sb, cb) = (w * xb).sin_cos();
                (a * ca + b * cb - re).powi(2) + (a * sa + b * sb - im).powi(2)
            })
            .sum()
    }

    /// Own and other columns (distorted pixels) of the ray's point at
    /// range `s`; `None` behind either projector.
    fn columns(&self, rays: &[RayInProjector; 2], s: f64) -> Option<(f64, f64)> {
        Some((
            pixel(&self.own, &rays[0], s)?.0,
            pixel(&self.other, &rays[1], s)?.0,
        ))
    }

    /// `((own column, its rate), (other column, its rate))` at range `s`.
    fn columns_and_rates(
        &self,
        rays: &[RayInProjector; 2],
        s: f64,
    ) -> Option<((f64, f64), (f64, f64))> {
        Some((
            column_and_rate(&self.own, &rays[0], s)?,
            column_and_rate(&self.other, &rays[1], s)?,
        ))
    }

    /// Whether the point at `s` lies on `projector`'s DMD (within a pixel).
    fn on_dmd(
        &self,
        projector: &ProjectorModel,
        ray: &RayInProjector,
        s: f64,
        column: f64,
    ) -> bool {
        let Some((_, row)) = pixel(projector, ray, s) else {
            return false;
        };
        let (w, h) = (
            f64::from(projector.width_px),
            f64::from(projector.height_px),
        );
        (-1.0..=w).contains(&column) && (-1.0..=h).contains(&row)
    }

    /// The range of `s` where the ray lies in front of both projectors and
    /// inside both frusta widened by [`FRUSTUM_MARGIN`] (pinhole, so
    /// distortion stays inside the margin); `None` when empty.
    fn lit_range(&self, rays: &[RayInProjector; 2]) -> Option<(f64, f64)> {
        let (mut lo, mut hi) = (MIN_RANGE_M, MAX_RANGE_M);
        for (p, ray) in [(&self.own, &rays[0]), (&self.other, &rays[1])] {
            let k = &p.intrinsics;
            let (w, h) = (f64::from(p.width_px), f64::from(p.height_px));
            let mx = FRUSTUM_MARGIN * w;
            let my = FRUSTUM_MARGIN * h;
            let bounds = [
                (0, (-mx - k.cx) / k.fx, 1.0),
                (0, (w + mx - k.cx) / k.fx, -1.0),
                (1, (-my - k.cy) / k.fy, 1.0),
                (1, (h + my - k.cy) / k.fy, -1.0),
            ];
            // z > 0, and sign (P[axis] - bound P.z) >= 0 for each side.
            let mut constraints = vec![(ray.q.z, ray.e.z)];
            for (axis, bound, sign) in bounds {
                constraints.push((
                    sign * (ray.q[axis] - bound * ray.q.z),
                    sign * (ray.e[axis] - bound * ray.e.z),
                ));
            }
            for (c0, c1) in constraints {
                // c0 + s c1 >= 0.
                if c1.abs() < 1e-15 {
                    if c0 < 0.0 {
                        return None;
                    }
                } else if c1 > 0.0 {
                    lo = lo.max(-c0 / c1);
                } else {
                    hi = hi.min(-c0 / c1);
                }
            }
        }
        (lo < hi).then_some((lo, hi))
    }
}

impl Separator for EpipolarDealiaser {
    fn periods_px(&self) -> &[f64] {
        &self.periods_px
    }

    fn steps(&self) -> usize {
        self.steps
    }

    fn separate_pixel(
        &self,
        index: usize,
        samples: &[f32],
        a0: f64,
        b0: f64,
        sigma: f64,
    ) -> Result<Separated, Refused> {
        self.separate(index, samples, a0, b0, sigma)
    }

    fn separate_near(
        &self,
        index: usize,
        samples: &[f32],
        a0: f64,
        b0: f64,
        sigma: f64,
        hints: &[Separated],
    ) -> Result<Separated, Refused> {
        let mut ranges: Vec<f64> = Vec::with_capacity(hints.len());
        for r in hints.iter().filter_map(|h| h.range_m) {
            // Neighbours on one surface give nearly one range: try it once.
            if ranges.iter().all(|q| (q - r).abs() > 1e-4) {
                ranges.push(r);
            }
        }
        EpipolarDealiaser::separate_near(self, index, samples, a0, b0, sigma, &ranges)
    }
}

/// Nearest range searched, metres (in front of the camera's glass).
const MIN_RANGE_M: f64 = 1e-3;
/// Farthest range searched, metres.
const MAX_RANGE_M: f64 = 1e3;
/// Frusta are widened by this share of the DMD for the walk: distortion
/// bends their edges, and a point just off the DMD is refused later.
const FRUSTUM_MARGIN: f64 = 0.1;
/// Most samples of one walk (a column moves at most the DMD width, in
/// steps of a fifth of the finest period: about 370 for 73 fringes).
const MAX_WALK_SAMPLES: usize = 4000;

/// One pixel's ray in (own, other) projector, its K phasors and priors.
struct PixelProblem {
    rays: [RayInProjector; 2],
    z: [(f64, f64); MAX_PERIODS],
    periods: usize,
    prior: Prior,
}

impl PixelProblem {
    fn z(&self) -> &[(f64, f64)] {
        &self.z[..self.periods]
    }
}

/// The modulation priors (frame units) and the measurement noise.
struct Prior {
    a: f64,
    b: f64,
    sigma: f64,
    sigma_z2: f64,
}

/// Keeps the `n` lowest minima.
fn keep_minimum(minima: &mut Vec<(f64, [f64; 3])>, m: (f64, [f64; 3]), n: usize) {
    let at = minima.partition_point(|x| x.0 <= m.0);
    if at < n {
        minima.insert(at, m);
        minima.truncate(n);
    }
}

/// `(column, row)` of the ray's point at range `s` on `projector`'s DMD
/// (distorted); `None` behind it.
fn pixel(projector: &ProjectorModel, ray: &RayInProjector, s: f64) -> Option<(f64, f64)> {
    let p = ray.q + ray.e * s;
    if p.z <= 0.0 {
        return None;
    }
    let px = projector.normalised_to_pixel(p.x / p.z, p.y / p.z);
    Some((px.x, px.y))
}

/// `(column, d column / d s)` of the ray's point at range `s`, through the
/// projector's distortion; `None` behind the projector.
#[inline]
fn column_and_rate(projector: &ProjectorModel, ray: &RayInProjector, s: f64) -> Option<(f64, f64)> {
    let p = ray.q + ray.e * s;
    if p.z <= 0.0 {
        return None;
    }
    let inv_z = 1.0 / p.z;
    let (x, y) = (p.x * inv_z, p.y * inv_z);
    let (dx, dy) = (
        (ray.e.x - x * ray.e.z) * inv_z,
        (ray.e.y - y * ray.e.z) * inv_z,
    );
    let (xd, _) = projector.distortion.distort(x, y);
    let [dxd_dx, dxd_dy, _, _] = projector.distortion.jacobian(x, y);
    let k = &projector.intrinsics;
    Some((k.fx * xd + k.cx, k.fx * (dxd_dx * dx + dxd_dy * dy)))
}

/// Entries of [`PHASOR_TABLE`] per turn.
const TABLE_SIZE: usize = 1024;

/// `(cos, sin)` of `2 pi t` to about 3e-3 (nearest of [`TABLE_SIZE`] per
/// turn).
#[inline]
fn unit_phasor(t: f64) -> (f64, f64) {
    let table = PHASOR_TABLE.get_or_init(|| {
        (0..TABLE_SIZE)
            .map(|i| {
                let (s, c) = (std::f64::consts::TAU * i as f64 / TABLE_SIZE as f64).sin_cos();
                (c, s)
            })
            .collect()
    });
    let i = ((t - t.floor()) * TABLE_SIZE as f64 + 0.5) as usize % TABLE_SIZE;
    table[i]
}

static PHASOR_TABLE: std::sync::OnceLock<Vec<(f64, f64)>> = std::sync::OnceLock::new();

#[cfg(test)]
mod tests {
    use super::super::analytic::tests::{samples, scatter_over_prediction, PERIODS};
    use super::*;
    use crate::calibration::{Head, PinholeModel};
    use nalgebra::{Matrix3, Point3};

    /// A device at `centre` looking at `target` (y down), world -> device.
    fn look_at(centre: Point3<f64>, target: Point3<f64>) -> Pose {
        let z = (target - centre).normalize();
        let x = Vector3::y().cross(&z).normalize();
        let y = z.cross(&x);
        let rotation = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
        Pose {
            rotation,
            translation_m: -(rotation * centre.coords),
        }
    }

    fn device(w: u32, h: u32, f: f64, pose: Pose) -> PinholeModel {
        let mut d = PinholeModel::ideal(w, h, f);
        d.pose = pose;
        d
    }

    /// Head A at the origin, head B 0.5 m to the side, both aimed at a
    /// point 0.6 m ahead; head B's devices are stored in its own frame, as
    /// a rig file holds them (`to_b`: head A's frame -> head B's).
    fn rig() -> RigCalibration {
        let target = Point3::new(0.0, 0.0, 0.6);
        let to_b = look_at(Point3::new(0.5, 0.05, 0.2), target);
        let in_b = |pose: Pose| pose.compose(&to_b.inverse());
        let mut projector_a = device(
            1280,
            800,
            1500.0,
            look_at(Point3::new(0.15, 0.0, 0.0), target),
        );
        projector_a.distortion.k1 = -0.1;
        let heads = vec![
            Head {
                name: "A".into(),
                camera: device(64, 48, 80.0, look_at(Point3::origin(), target)),
                projector: projector_a,
                view_errors: vec![],
                port: None,
            },
            Head {
                name: "B".into(),
                camera: device(64, 48, 80.0, in_b(to_b)),
                projector: device(
                    1280,
                    800,
                    1500.0,
                    in_b(look_at(Point3::new(0.35, 0.05, 0.1), target)),
                ),
                view_errors: vec![],
                port: None,
            },
        ];
        RigCalibration {
            heads,
            head_poses: vec![to_b],
            stereo_heads: vec![],
        }
    }

    fn solver() -> EpipolarDealiaser {
        EpipolarDealiaser::new(&rig(), 0, &PERIODS, 4, EpipolarParams::default()).unwrap()
    }

    /// The two columns of camera A's pixel `index` at range `s`.
    fn columns_at(s: &EpipolarDealiaser, index: usize, range: f64) -> (f64, f64) {
        let ray = s
            .camera
            .pixel_ray((index % 64) as f64, (index / 64) as f64)
            .unwrap();
        let x = ray.origin_m + ray.direction * range;
        (s.own.project(&x).unwrap().x, s.other.project(&x).unwrap().x)
    }

    #[test]
    fn noise_free_pixels_come_back_at_their_range() {
        let s = solver();
        for (index, range) in [
            (24 * 64 + 32, 0.5),
            (5 * 64 + 7, 0.62),
            (40 * 64 + 60, 0.58),
        ] {
            let (xa, xb) = columns_at(&s, index, range);
            // Columns apart: near each other the split of a and b trades
            // against the range (see the next test).
            assert!((xa - xb).abs() > 20.0, "{xa} {xb}");
            assert!((0.0..1279.0).contains(&xa) && (0.0..1279.0).contains(&xb));
            let got = s
                .separate(index, &samples(xa, xb, 0.3, 0.2, 0.0, 0), 0.33, 0.22, 0.005)
                .unwrap();
            assert!((got.x_own_px - xa).abs() < 1e-4, "{got:?} vs {xa}");
            assert!((got.x_other_px - xb).abs() < 1e-4, "{got:?} vs {xb}");
            assert!((got.range_m.unwrap() - range).abs() < 1e-7, "{got:?}");
            assert!((got.a - 0.3).abs() < 1e-4 && (got.b - 0.2).abs() < 1e-4);
        }
    }

    #[test]
    fn alike_columns_that_the_free_solver_refuses_are_separated() {
        let s = solver();
        let index = 24 * 64 + 32;
        // The range where both projectors show the same column.
        let (mut lo, mut hi) = (0.4, 0.9);
        let gap = |r: f64| {
            let (a, b) = columns_at(&s, index, r);
            a - b
        };
        assert!(gap(lo).signum() != gap(hi).signum());
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if gap(mid).signum() == gap(lo).signum() {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let (xa, xb) = columns_at(&s, index, lo);
        assert!((xa - xb).abs() < 1e-6);
        let got = s
            .separate(index, &samples(xa, xb, 0.3, 0.3, 0.0, 0), 0.33, 0.33, 0.005)
            .unwrap();
        assert!((got.x_own_px - xa).abs() < 1e-3, "{got:?} vs {xa}");
        let free = super::super::AnalyticDealiaser::new(
            &PERIODS,
            4,
            1280,
            super::super::AnalyticParams::default(),
        )
        .unwrap();
        assert!(free
            .separate(&samples(xa, xb, 0.3, 0.3, 0.0, 0), 0.33, 0.33, 0.005)
            .is_err());
    }

    #[test]
    fn noisy_pixels_scatter_as_predicted() {
        let s = solver();
        let index = 20 * 64 + 30;
        let (xa, xb) = columns_at(&s, index, 0.63);
        let sigma = 0.005;
        let (n, ratio) = scatter_over_prediction(xa, |seed| {
            s.separate(
                index,
                &samples(xa, xb, 0.3, 0.2, sigma, seed),
                0.3,
                0.2,
                sigma,
            )
        });
        assert!(n > 390, "{n} of 400 separated");
        assert!(
            (0.85..1.15).contains(&ratio),
            "measured / predicted {ratio}"
        );
    }

    #[test]
    fn a_neighbours_range_leads_to_the_same_solution_without_a_walk() {
        let s = solver();
        let index = 24 * 64 + 33;
        let (xa, xb) = columns_at(&s, index, 0.7);
        let px = samples(xa, xb, 0.3, 0.2, 0.0, 0);
        let walked = s.separate(index, &px, 0.33, 0.22, 0.005).unwrap();
        // A neighbour 2 mm nearer, and one on another surface far behind.
        let near = s
            .separate_near(index, &px, 0.33, 0.22, 0.005, &[0.698, 0.95])
            .unwrap();
        assert!(
            (near.x_own_px - walked.x_own_px).abs() < 1e-6,
            "{near:?} vs {walked:?}"
        );
        // Hints that lead nowhere: the walk still finds it.
        let lost = s
            .separate_near(index, &px, 0.33, 0.22, 0.005, &[0.3])
            .unwrap();
        assert!((lost.x_own_px - walked.x_own_px).abs() < 1e-6);
    }

    #[test]
    fn samples_the_model_cannot_explain_are_refused() {
        let s = solver();
        let index = 24 * 64 + 32;
        let (xa, xb) = columns_at(&s, index, 0.6);
        let mut bad = samples(xa, xb, 0.3, 0.1, 0.0, 0);
        bad[5] += 0.3;
        assert_eq!(
            s.separate(index, &bad, 0.3, 0.1, 0.003),
            Err(Refused::Misfit)
        );
        bad[5] = f32::NAN;
        assert_eq!(
            s.separate(index, &bad, 0.3, 0.1, 0.003),
            Err(Refused::NoSolution)
        );
        assert_eq!(
            s.separate(index, &bad[..12], 0.3, 0.1, 0.003),
            Err(Refused::NoSolution)
        );
    }

    #[test]
    fn rigs_and_period_sets_it_cannot_use_are_refused() {
        let mut one = rig();
        one.heads.truncate(1);
        one.head_poses.clear();
        let err = EpipolarDealiaser::new(&one, 0, &PERIODS, 4, EpipolarParams::default());
        assert_eq!(err.unwrap_err(), EpipolarError::NotTwoHeads { heads: 1 });
        let err = EpipolarDealiaser::new(&rig(), 0, &PERIODS[..3], 4, EpipolarParams::default());
        assert_eq!(
            err.unwrap_err(),
            EpipolarError::BadPeriods {
                periods: 3,
                steps: 4
            }
        );
        assert!(EpipolarDealiaser::new(&rig(), 1, &PERIODS, 4, EpipolarParams::default()).is_ok());
    }
}
