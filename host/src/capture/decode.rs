//! Frames of any described capture -> absolute projector coordinates per axis.
//!
//! Each fringe set is decoded with the N-step estimator and turned into the DESIGN.md
//! convention at once (`phi = s_p (s_d phi_est - psi_0)`, see [`super::FringeSet`]);
//! Gray sets are read against their inverses, the white/black mean, or the fringe
//! frames' mean; pixels that are saturated, in shadow, or too weakly modulated are
//! masked; then each axis is unwrapped by the described method, checked
//! ([`super::checks`]) and turned into projector pixels with a predicted noise.

use std::f32::consts::TAU;

use super::checks::{self, Alternative, CheckResult};
use super::{axis_name, CaptureError, CaptureSpec, Frames, GraySet, ProjectorAxis, Unwrapping};
use crate::phase::{check_sizes, PhaseShift};
use crate::raster::Raster;
use crate::unwrap::complementary_gray::unwrap_complementary;
use crate::unwrap::gray_code::{decode_with_inverse, decode_with_threshold, GrayDecoded};
use crate::unwrap::heterodyne::Heterodyne;
use crate::unwrap::pdm::Pdm;
use crate::unwrap::quality_guided::{unwrap_quality_guided, Seed};
use crate::unwrap::{gray_code, AbsolutePhase, PixelStatus};

/// Largest sample the alternative conventions are tried on.
const ALTERNATIVE_SAMPLE: usize = 20_000;

/// One axis's absolute projector coordinate per camera pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisCoordinates {
    /// The axis.
    pub axis: ProjectorAxis,
    /// Projector pixels (centres at integers); NaN unless valid.
    pub coord_px: Raster<f32>,
    /// Valid, masked (thresholds), unreliable (the method's or a check's refusal).
    pub status: Raster<PixelStatus>,
    /// Smallest fringe modulation over the axis's sets (the code contrast with Gray
    /// codes alone), full-scale units.
    pub modulation: Raster<f32>,
    /// Mean intensity of the finest set (white/black mean with codes alone).
    pub background: Raster<f32>,
    /// Predicted standard deviation of the coordinate, projector pixels.
    pub sigma_px: Raster<f32>,
    /// The finest fringe period (the Gray block with codes alone), projector pixels.
    pub reference_period_px: f64,
    /// The self-checks as measured (all passed, or decoding was refused).
    pub checks: Vec<CheckResult>,
}

/// A fringe set's one period, decoded into the DESIGN.md convention.
struct PeriodPhase {
    period_px: f64,
    steps: usize,
    phi: Raster<f32>,
    modulation: Raster<f32>,
    background: Raster<f32>,
}

/// The captured frames split by element.
struct Split<'a> {
    periods: Vec<(ProjectorAxis, PeriodPhase)>,
    grays: Vec<(ProjectorAxis, &'a GraySet, Vec<&'a Raster<f32>>)>,
    white: Option<&'a Raster<f32>>,
    black: Option<&'a Raster<f32>>,
}

/// Decodes every axis of `frames` (in the described order) for a projector of
/// `projector` (width, height) pixels. `noise_sigma` is the intensity noise at half
/// scale (full-scale units) for the coordinate noise prediction.
pub fn decode(
    spec: &CaptureSpec,
    frames: &[&Raster<f32>],
    projector: (u32, u32),
    noise_sigma: f32,
) -> Result<Vec<AxisCoordinates>, CaptureError> {
    spec.validate(projector)?;
    spec.check_frame_count(frames.len())?;
    let (width, height) = check_sizes(frames)?;
    let split = split(spec, frames)?;
    let base = base_mask(spec, frames, &split, width, height);
    spec.axes()
        .into_iter()
        .map(|axis| {
            decode_axis(
                spec,
                &split,
                &base,
                axis,
                super::extent(axis, projector),
                noise_sigma,
            )
        })
        .collect()
}

/// Decodes each fringe set's periods and groups the Gray frames.
fn split<'a>(spec: &'a CaptureSpec, frames: &[&'a Raster<f32>]) -> Result<Split<'a>, CaptureError> {
    let mut out = Split {
        periods: Vec::new(),
        grays: Vec::new(),
        white: None,
        black: None,
    };
    let mut at = 0;
    for element in &spec.sequence {
        let n = element.count();
        let mine = &frames[at..at + n];
        at += n;
        match element {
            Frames::Fringes(set) => {
                let shift = PhaseShift::new(set.steps)?;
                for (k, &period_px) in set.periods_px.iter().enumerate() {
                    let w = shift.wrapped_phase(&mine[k * set.steps..(k + 1) * set.steps])?;
                    let (sp, sd) = (f32::from(set.phase_sign), f32::from(set.shift_sign));
                    let offset = set.phase_offset_rad as f32;
                    let phi = Raster {
                        width: w.phase.width,
                        height: w.phase.height,
                        data: w
                            .phase
                            .data
                            .iter()
                            .map(|&p| crate::phase::wrap_pi(sp * (sd * p - offset)))
                            .collect(),
                    };
                    out.periods.push((
                        set.axis,
                        PeriodPhase {
                            period_px,
                            steps: set.steps,
                            phi,
                            modulation: w.modulation,
                            background: w.background,
                        },
                    ));
                }
            }
            Frames::Gray(set) => out.grays.push((set.axis, set, mine.to_vec())),
            Frames::White => out.white = mine.first().copied(),
            Frames::Black => out.black = mine.first().copied(),
        }
    }
    Ok(out)
}

/// Pixels usable on every axis: not saturated in any frame, not in shadow (white -
/// black too small, where both are captured).
fn base_mask(
    spec: &CaptureSpec,
    frames: &[&Raster<f32>],
    split: &Split,
    width: usize,
    height: usize,
) -> Raster<bool> {
    let t = &spec.thresholds;
    Raster::from_fn(width, height, |x, y| {
        let i = y * width + x;
        let saturated = frames
            .iter()
            .any(|f| f.data[i] >= t.saturation || !f.data[i].is_finite());
        let shadow = match (split.white, split.black) {
            (Some(w), Some(b)) => w.data[i] - b.data[i] < t.min_code_contrast,
            _ => false,
        };
        !saturated && !shadow
    })
}

/// One axis: masks, unwrapping, checks, coordinates.
fn decode_axis(
    spec: &CaptureSpec,
    split: &Split,
    base: &Raster<bool>,
    axis: ProjectorAxis,
    extent: u32,
    noise_sigma: f32,
) -> Result<AxisCoordinates, CaptureError> {
    let t = &spec.thresholds;
    let mut periods: Vec<&PeriodPhase> = split
        .periods
        .iter()
        .filter(|(a, _)| *a == axis)
        .map(|(_, p)| p)
        .collect();
    let (width, height) = base.size();
    let n = width * height;
    // Mask: base, and every set of the axis modulated and lit enough.
    let mut mask = base.clone();
    let mut modulation = Raster::filled(width, height, f32::INFINITY);
    for p in &periods {
        for i in 0..n {
            let b = p.modulation.data[i];
            modulation.data[i] = modulation.data[i].min(b);
            if !(b >= t.min_modulation && p.background.data[i] >= t.min_mean) {
                mask.data[i] = false;
            }
        }
    }
    let gray = split.grays.iter().find(|(a, _, _)| *a == axis);
    let code = match gray {
        Some((_, set, bits)) => Some(read_code(spec, split, set, bits, axis)?),
        None => None,
    };
    let mut checks_done = Vec::new();
    let (absolute, reference_period_px) = match spec.unwrapping {
        Unwrapping::Heterodyne | Unwrapping::Pdm => {
            // Finest first, as both methods want; the maps follow their periods.
            periods.sort_by(|a, b| a.period_px.total_cmp(&b.period_px));
            mask_noisy_orders(spec, &periods, &mut mask, extent, noise_sigma)?;
            let abs = unwrap_temporal(spec, &periods, &mask, extent)?;
            let (share, pixels) = checks::wrong_order_share(&abs.status, &mask);
            let result = CheckResult {
                axis,
                check: checks::WRONG_ORDER,
                share,
                pixels,
                limit: spec.checks.max_wrong_order,
            };
            if !result.passed() {
                let cause = diagnose_temporal(spec, &periods, &mask, extent);
                return Err(refusal(&result, cause));
            }
            checks_done.push(result);
            (abs, periods[0].period_px)
        }
        Unwrapping::GrayCode | Unwrapping::ComplementaryGrayCode => {
            let (_, set, _) = gray.expect("validated: one Gray set");
            let code = code.as_ref().expect("decoded above");
            match periods.first() {
                None => (code_only(code, set, &mask), f64::from(set.block_px)),
                Some(p) => {
                    for result in gray_phase_checks(spec, axis, p, code, set, &mask) {
                        if !result.passed() {
                            let cause = diagnose_gray_phase(p, code, set, &mask);
                            return Err(refusal(&result, cause));
                        }
                        checks_done.push(result);
                    }
                    let abs = if spec.unwrapping == Unwrapping::GrayCode {
                        gray_code::unwrap_with_blocks(
                            &p.phi,
                            code,
                            f64::from(set.block_px),
                            p.period_px,
                            Some(&mask),
                        )?
                    } else {
                        unwrap_complementary(&p.phi, code, p.period_px, Some(&mask))?
                    };
                    (abs, p.period_px)
                }
            }
        }
        Unwrapping::QualityGuided { seed, order } => {
            let p = periods[0];
            let quality = Raster::from_fn(width, height, |x, y| {
                let i = y * width + x;
                if mask.data[i] {
                    p.modulation.data[i]
                } else {
                    0.0
                }
            });
            let abs = unwrap_quality_guided(
                &p.phi,
                &quality,
                t.min_modulation.max(f32::MIN_POSITIVE),
                Seed {
                    at: Some(seed),
                    order,
                },
                p.period_px,
            )?;
            (abs, p.period_px)
        }
        Unwrapping::None => {
            let p = periods[0];
            let mut abs = AbsolutePhase {
                phase: Raster::filled(width, height, f32::NAN),
                status: Raster::filled(width, height, PixelStatus::Masked),
                period_px: p.period_px,
            };
            for i in 0..n {
                if mask.data[i] {
                    abs.phase.data[i] = p.phi.data[i].rem_euclid(TAU);
                    abs.status.data[i] = PixelStatus::Valid;
                }
            }
            (abs, p.period_px)
        }
    };
    let mut out = coordinates(axis, &absolute, extent);
    let (share, pixels) = checks::outside_share(
        absolute
            .phase
            .data
            .iter()
            .zip(&absolute.status.data)
            .filter(|(_, s)| **s == PixelStatus::Valid)
            .map(|(p, _)| p * (absolute.period_px / f64::from(TAU)) as f32),
        extent,
    );
    let outside = CheckResult {
        axis,
        check: checks::OUTSIDE,
        share,
        pixels,
        limit: spec.checks.max_outside,
    };
    if !outside.passed() {
        return Err(refusal(&outside, Alternative::Reversed.cause().to_string()));
    }
    checks_done.push(outside);
    out.checks = checks_done;
    // Modulation, background and noise per pixel.
    match periods.first() {
        Some(finest) => {
            out.background = finest.background.clone();
            let crb = noise_sigma * (2.0 / finest.steps as f32).sqrt();
            let px_per_rad = (finest.period_px / f64::from(TAU)) as f32;
            for i in 0..n {
                out.modulation.data[i] = modulation.data[i];
                out.sigma_px.data[i] = crb / finest.modulation.data[i] * px_per_rad;
            }
        }
        None => {
            let (_, set, _) = gray.expect("an axis has fringes or a Gray set");
            let quantisation = (f64::from(set.block_px) / 12f64.sqrt()) as f32;
            out.sigma_px.data.fill(quantisation);
            if let (Some(w), Some(b)) = (split.white, split.black) {
                for i in 0..n {
                    out.modulation.data[i] = w.data[i] - b.data[i];
                    out.background.data[i] = 0.5 * (w.data[i] + b.data[i]);
                }
            }
        }
    }
    out.reference_period_px = reference_period_px;
    Ok(out)
}

/// The Gray code of an axis, read against its inverses, the white/black mean, or the
/// mean of the axis's (else any) fringe frames.
fn read_code(
    spec: &CaptureSpec,
    split: &Split,
    set: &GraySet,
    bits: &[&Raster<f32>],
    axis: ProjectorAxis,
) -> Result<GrayDecoded, CaptureError> {
    let contrast = spec.thresholds.min_code_contrast;
    if set.inverse {
        let plain: Vec<&Raster<f32>> = bits.iter().step_by(2).copied().collect();
        let inverse: Vec<&Raster<f32>> = bits.iter().skip(1).step_by(2).copied().collect();
        return Ok(decode_with_inverse(&plain, &inverse, contrast)?);
    }
    let threshold = match (split.white, split.black) {
        (Some(w), Some(b)) => Raster {
            width: w.width,
            height: w.height,
            data: w
                .data
                .iter()
                .zip(&b.data)
                .map(|(w, b)| 0.5 * (w + b))
                .collect(),
        },
        _ => {
            let fringes = split
                .periods
                .iter()
                .find(|(a, _)| *a == axis)
                .or_else(|| split.periods.first())
                .map(|(_, p)| p)
                .ok_or(CaptureError::NoGrayThreshold { set: 0 })?;
            fringes.background.clone()
        }
    };
    Ok(decode_with_threshold(bits, &threshold, contrast)?)
}

/// Heterodyne or PDM over `periods` (finest first).
fn unwrap_temporal(
    spec: &CaptureSpec,
    periods: &[&PeriodPhase],
    mask: &Raster<bool>,
    extent: u32,
) -> Result<AbsolutePhase, CaptureError> {
    let maps: Vec<&Raster<f32>> = periods.iter().map(|p| &p.phi).collect();
    let list: Vec<f64> = periods.iter().map(|p| p.period_px).collect();
    Ok(match spec.unwrapping {
        Unwrapping::Pdm => {
            let ints = super::integer_periods(&list).expect("validated whole periods");
            Pdm::new(&ints, f64::from(extent))?.unwrap(&maps, Some(mask))?
        }
        _ => Heterodyne::new(&list, f64::from(extent), std::f64::consts::FRAC_PI_2)?
            .unwrap(&maps, Some(mask))?,
    })
}

/// Standard deviations between a pixel's phase noise and a miscounted order, as the
/// fused pipeline's default ([`crate::reconstruct::ReconstructConfig::order_sigmas`]).
const ORDER_SIGMAS: f64 = 5.0;

/// Masks pixels too noisy to count fringe orders: a miscount can pass the methods'
/// residual votes, so a phase noise (the Cramer-Rao bound at the pixel's modulation)
/// within [`ORDER_SIGMAS`] of one is refused beforehand, as the fused pipeline does.
fn mask_noisy_orders(
    spec: &CaptureSpec,
    periods: &[&PeriodPhase],
    mask: &mut Raster<bool>,
    extent: u32,
    noise_sigma: f32,
) -> Result<(), CaptureError> {
    let list: Vec<f64> = periods.iter().map(|p| p.period_px).collect();
    let max_sigma_rad = match spec.unwrapping {
        Unwrapping::Pdm => {
            let ints = super::integer_periods(&list).expect("validated whole periods");
            Pdm::new(&ints, f64::from(extent))?.max_phase_sigma_rad(ORDER_SIGMAS)
        }
        _ => {
            let h = Heterodyne::new(&list, f64::from(extent), std::f64::consts::FRAC_PI_2)?;
            std::f64::consts::PI / (h.order_noise_gain() * ORDER_SIGMAS)
        }
    } as f32;
    for (i, keep) in mask.data.iter_mut().enumerate() {
        let noisy = periods.iter().any(|p| {
            let sigma = noise_sigma * (2.0 / p.steps as f32).sqrt() / p.modulation.data[i];
            sigma.is_nan() || sigma > max_sigma_rad
        });
        if noisy {
            *keep = false;
        }
    }
    Ok(())
}

/// One pixel's wrapped phases (finest first) -> absolute phase of the finest period.
type PixelUnwrapper = dyn Fn(&[f32]) -> Option<f32>;

/// Which alternative convention makes the temporal unwrapping agree (tried on a
/// sample), as the cause to report.
fn diagnose_temporal(
    spec: &CaptureSpec,
    periods: &[&PeriodPhase],
    mask: &Raster<bool>,
    extent: u32,
) -> String {
    let pixels: Vec<usize> = (0..mask.data.len()).filter(|&i| mask.data[i]).collect();
    let pixels = checks::sample(&pixels, ALTERNATIVE_SAMPLE);
    let list: Vec<f64> = periods.iter().map(|p| p.period_px).collect();
    let unwrapper: Box<PixelUnwrapper> = match spec.unwrapping {
        Unwrapping::Pdm => match super::integer_periods(&list)
            .and_then(|ints| Pdm::new(&ints, f64::from(extent)).ok())
        {
            Some(pdm) => Box::new(move |w: &[f32]| pdm.unwrap_pixel(w)),
            None => return checks::UNKNOWN_CAUSE.into(),
        },
        _ => match Heterodyne::new(&list, f64::from(extent), std::f64::consts::FRAC_PI_2) {
            Ok(h) => Box::new(move |w: &[f32]| h.unwrap_pixel(w)),
            Err(_) => return checks::UNKNOWN_CAUSE.into(),
        },
    };
    let finest = list[0];
    let k = periods.len();
    for alternative in Alternative::MULTI {
        let (mut agree, mut inside) = (0usize, 0usize);
        for &i in &pixels {
            let wrapped: Vec<f32> = (0..k)
                .map(|p| {
                    // Reversed frame order: the maps belong to the periods reversed.
                    let from = if alternative == Alternative::PeriodOrderReversed {
                        k - 1 - p
                    } else {
                        p
                    };
                    alternative.apply(periods[from].phi.data[i])
                })
                .collect();
            if let Some(abs) = unwrapper(&wrapped) {
                agree += 1;
                let u = abs * (finest / f64::from(TAU)) as f32;
                inside += usize::from(checks::inside(u, extent));
            }
        }
        let n = pixels.len().max(1) as f64;
        let wrong = 1.0 - agree as f64 / n;
        let outside = 1.0 - inside as f64 / agree.max(1) as f64;
        if wrong <= spec.checks.max_wrong_order / 2.0 && outside <= spec.checks.max_outside {
            return alternative.cause().into();
        }
    }
    checks::UNKNOWN_CAUSE.into()
}

/// Pixels where both the phase and the code were read.
fn read_pixels(code: &GrayDecoded, mask: &Raster<bool>) -> Vec<usize> {
    (0..mask.data.len())
        .filter(|&i| mask.data[i] && code.status.data[i] == PixelStatus::Valid)
        .collect()
}

/// The Gray + phase self-checks: half-period disagreement and direction.
fn gray_phase_checks(
    spec: &CaptureSpec,
    axis: ProjectorAxis,
    p: &PeriodPhase,
    code: &GrayDecoded,
    set: &GraySet,
    mask: &Raster<bool>,
) -> [CheckResult; 2] {
    let pixels = read_pixels(code, mask);
    let half = checks::half_period_share(
        &p.phi,
        code,
        f64::from(set.block_px),
        p.period_px,
        &pixels,
        None,
    );
    let (against, pairs) = checks::direction_share(&p.phi, code, &read_map(&pixels, mask));
    let limit = spec.checks.max_half_period;
    [
        CheckResult {
            axis,
            check: checks::HALF_PERIOD,
            share: half,
            pixels: pixels.len(),
            limit,
        },
        CheckResult {
            axis,
            check: checks::DIRECTION,
            share: against,
            pixels: pairs,
            limit,
        },
    ]
}

/// `read_pixels` as a per-pixel flag.
fn read_map(pixels: &[usize], mask: &Raster<bool>) -> Vec<bool> {
    let mut read = vec![false; mask.data.len()];
    for &i in pixels {
        read[i] = true;
    }
    read
}

/// Which alternative convention makes phase and code agree: a phase running against
/// the code is reversed (with or without a half-period origin), else the origin.
fn diagnose_gray_phase(
    p: &PeriodPhase,
    code: &GrayDecoded,
    set: &GraySet,
    mask: &Raster<bool>,
) -> String {
    let all = read_pixels(code, mask);
    let (against, _) = checks::direction_share(&p.phi, code, &read_map(&all, mask));
    let candidates: &[Alternative] = if against > 0.5 {
        &[Alternative::Reversed, Alternative::ReversedHalfPeriod]
    } else {
        &[Alternative::HalfPeriodOrigin]
    };
    let pixels = checks::sample(&all, ALTERNATIVE_SAMPLE);
    let block = f64::from(set.block_px);
    candidates
        .iter()
        .map(|&a| {
            let share =
                checks::half_period_share(&p.phi, code, block, p.period_px, &pixels, Some(a));
            (a, share)
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .filter(|(_, share)| *share < 0.02)
        .map_or_else(|| checks::UNKNOWN_CAUSE.into(), |(a, _)| a.cause().into())
}

/// The error for a failed check.
fn refusal(result: &CheckResult, cause: String) -> CaptureError {
    CaptureError::SelfCheck {
        axis: result.axis,
        check: result.check,
        share: 100.0 * result.share,
        limit: 100.0 * result.limit,
        cause,
    }
}

/// Gray code alone: each pixel at its block's centre.
fn code_only(code: &GrayDecoded, set: &GraySet, mask: &Raster<bool>) -> AbsolutePhase {
    let block = f64::from(set.block_px);
    let (width, height) = code.block.size();
    let mut abs = AbsolutePhase {
        phase: Raster::filled(width, height, f32::NAN),
        status: code.status.clone(),
        period_px: block,
    };
    for i in 0..width * height {
        if !mask.data[i] {
            abs.status.data[i] = PixelStatus::Masked;
        }
        if abs.status.data[i] == PixelStatus::Valid {
            let centre = f64::from(code.block.data[i]) * block + (block - 1.0) / 2.0;
            abs.phase.data[i] = (std::f64::consts::TAU * centre / block) as f32;
        }
    }
    abs
}

/// Absolute phase -> projector pixels; coordinates off the projector are unreliable.
fn coordinates(axis: ProjectorAxis, abs: &AbsolutePhase, extent: u32) -> AxisCoordinates {
    let (width, height) = abs.phase.size();
    let scale = (abs.period_px / f64::from(TAU)) as f32;
    let mut coord = Raster::filled(width, height, f32::NAN);
    let mut status = abs.status.clone();
    for i in 0..width * height {
        if status.data[i] != PixelStatus::Valid {
            continue;
        }
        let u = abs.phase.data[i] * scale;
        if checks::inside(u, extent) {
            coord.data[i] = u;
        } else {
            status.data[i] = PixelStatus::Unreliable;
        }
    }
    AxisCoordinates {
        axis,
        coord_px: coord,
        status,
        modulation: Raster::filled(width, height, f32::NAN),
        background: Raster::filled(width, height, f32::NAN),
        sigma_px: Raster::filled(width, height, f32::NAN),
        reference_period_px: abs.period_px,
        checks: Vec::new(),
    }
}

impl AxisCoordinates {
    /// The axis in words.
    pub fn name(&self) -> &'static str {
        axis_name(self.axis)
    }

    /// Pixels with a valid coordinate.
    pub fn valid(&self) -> usize {
        self.status
            .data
            .iter()
            .filter(|&&s| s == PixelStatus::Valid)
            .count()
    }
}
