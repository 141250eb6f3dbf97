//! Seed 003's adaptation step, whole: the floods and the reconstruction of
//! one full-intensity fringe set in, the exposure and the adapted fringe set
//! out (see the module doc of [`super`] for the flow).

use super::exposure::{choose_exposure, ExposureChoice, ExposureRule};
use super::fringes::adapted_fringes;
use super::mapping::{fill_clusters, from_points, is_mapped};
use super::projector_map::{footprint_px, projector_levels};
use super::response::{check_floods, fit_response, optimal_level, ResponseStatus};
use super::AdaptiveError;
use crate::calibration::PinholeModel;
use crate::raster::Raster;
use crate::reconstruct::PixelMaps;

/// The seed's seven uniform grey levels, 0 to full.
pub const FLOOD_LEVELS: [f32; 7] = [0.0, 1.0 / 6.0, 2.0 / 6.0, 0.5, 4.0 / 6.0, 5.0 / 6.0, 1.0];

/// Most flood levels an adaptation takes.
pub const MAX_FLOOD_LEVELS: usize = 16;

/// How to adapt.
#[derive(Clone, Debug, PartialEq)]
pub struct HdrParams {
    /// Grey levels of the floods, in projection order.
    pub levels: Vec<f32>,
    /// Frame value at and above which a sample counts as saturated.
    pub saturation: f32,
    /// The exposure's rule; its `target` is what each pixel's brightest
    /// fringe sample should reach (seed 003: 254 of 255; lower here to leave
    /// room for noise and for the mapping's blur at highlight edges), its
    /// `min_level` the lowest level still giving usable fringes.
    pub rule: ExposureRule,
    /// Lowest level of the adapted fringes (`L_min`; seed 003: 0).
    pub fringe_floor: f32,
    /// Ring around a saturated cluster whose mapped pixels fit its
    /// homography, camera pixels.
    pub ring_px: usize,
    /// Largest RMS misfit of a cluster's homography to its ring, projector
    /// pixels, before the cluster is left unmapped.
    pub max_homography_rms_px: f64,
    /// Growth of the lowered areas on the DMD, projector pixels.
    pub grow_px: usize,
    /// After the adapted scan: DMD pixels around each pixel's position
    /// looked at for a level step ([`super::edges`]).
    pub step_radius_px: usize,
    /// Largest ratio of the levels there before the pixel is unreliable.
    pub max_step_ratio: f32,
}

impl Default for HdrParams {
    /// Seven floods, saturation at 99.5 % of full scale, target 85 % of
    /// full scale, lowest usable level 0.08 (20 grey levels of swing),
    /// 96 candidate exposures between the plan's shortest and longest,
    /// rings of 3 px, homographies to 3 projector px, lowered areas grown
    /// by 3 px; pixels whose level varies by more than 1.5x within 2 DMD px
    /// unreliable.
    fn default() -> Self {
        HdrParams {
            levels: FLOOD_LEVELS.to_vec(),
            saturation: 0.995,
            rule: ExposureRule {
                target: 0.85,
                min_level: 0.08,
                min_gain: 0.02,
                range: (
                    crate::scan::plan::MIN_EXPOSURE_SCALE,
                    crate::scan::plan::MAX_EXPOSURE_SCALE,
                ),
                candidates: 96,
            },
            fringe_floor: 0.0,
            ring_px: 3,
            max_homography_rms_px: 3.0,
            grow_px: 3,
            step_radius_px: 2,
            max_step_ratio: 1.5,
        }
    }
}

impl HdrParams {
    /// Refuses parameters outside their ranges.
    pub fn validate(&self) -> Result<(), AdaptiveError> {
        if !(2..=MAX_FLOOD_LEVELS).contains(&self.levels.len()) {
            return Err(AdaptiveError::FloodLevels {
                levels: self.levels.clone(),
            });
        }
        let checks: [(&'static str, f64, bool, &'static str); 6] = [
            (
                "saturation",
                f64::from(self.saturation),
                self.saturation > 0.0 && self.saturation <= 1.0,
                "(0, 1]",
            ),
            (
                "target",
                f64::from(self.rule.target),
                self.rule.target > 0.0 && self.rule.target < self.saturation,
                "(0, saturation)",
            ),
            (
                "min_level",
                f64::from(self.rule.min_level),
                self.rule.min_level > self.fringe_floor && self.rule.min_level <= 1.0,
                "(fringe_floor, 1]",
            ),
            (
                "fringe_floor",
                f64::from(self.fringe_floor),
                (0.0..1.0).contains(&self.fringe_floor),
                "[0, 1)",
            ),
            (
                "max_step_ratio",
                f64::from(self.max_step_ratio),
                self.max_step_ratio >= 1.0,
                ">= 1",
            ),
            (
                "exposure range",
                self.rule.range.0,
                self.rule.range.0 > 0.0 && self.rule.range.0 <= self.rule.range.1,
                "0 < shortest <= longest",
            ),
        ];
        for (name, value, ok, range) in checks {
            if !ok {
                return Err(AdaptiveError::Parameter { name, value, range });
            }
        }
        Ok(())
    }
}

/// What the adaptation found, pixel counts of the camera image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HdrStats {
    /// Pixels whose response was fitted.
    pub fitted_px: usize,
    /// Pixels saturated in the brightest flood.
    pub saturated_in_full_flood_px: usize,
    /// Pixels that saturate even at the lowest lit flood (projected at the
    /// lowest usable level; masked if they still saturate).
    pub saturates_at_lowest_px: usize,
    /// Pixels the chosen exposure cannot hold under the target even at the
    /// lowest usable level (projected at it).
    pub cannot_hold_px: usize,
    /// Pixels asking for less than the full level.
    pub lowered_px: usize,
    /// Of those, placed on the DMD through their own decoded phase.
    pub mapped_by_phase_px: usize,
    /// Of those, placed by their saturated cluster's homography.
    pub mapped_by_homography_px: usize,
    /// Of those, not placed (their DMD area stays at the full level, so
    /// they may saturate again and be masked).
    pub unmapped_px: usize,
    /// Saturated clusters that needed a homography.
    pub clusters: usize,
}

/// What the optics leave of a full-swing fringe: the median over decoded,
/// lit pixels of their measured modulation over the `b1 / 2` a full-level
/// fringe would give (defocus and pixel integration blur the finer
/// periods); 1 when no pixel tells.
fn fringe_contrast(
    response: &super::response::Response,
    fringes: &PixelMaps,
    min_gain: f32,
) -> f32 {
    let mut ratios: Vec<f32> = (0..fringes.len())
        .filter(|&i| {
            fringes.status[i] == crate::unwrap::PixelStatus::Valid
                && response.status.data[i] == ResponseStatus::Fitted
                && response.gain.data[i] >= min_gain
        })
        .map(|i| fringes.modulation[i] / (0.5 * response.gain.data[i]))
        .filter(|r| r.is_finite())
        .collect();
    if ratios.is_empty() {
        return 1.0;
    }
    let k = ratios.len() / 2;
    let (_, m, _) = ratios.select_nth_unstable_by(k, f32::total_cmp);
    m.clamp(0.05, 1.0)
}

/// The adaptation's result.
#[derive(Clone, Debug, PartialEq)]
pub struct HdrAdaptation {
    /// The exposure of the adapted fringes, in units of the floods'.
    pub exposure: ExposureChoice,
    /// Optimal level per camera pixel (NaN: the full level will do).
    pub camera_levels: Raster<f32>,
    /// Level per DMD pixel.
    pub projector_levels: Raster<f32>,
    /// The adapted fringe set, period-major.
    pub patterns: Vec<Raster<f32>>,
    /// Counts.
    pub stats: HdrStats,
}

/// The projector and fringe set the adapted patterns are for.
#[derive(Clone, Copy, Debug)]
pub struct PatternTarget<'a> {
    /// The head's calibrated projector (the head's frame).
    pub projector: &'a PinholeModel,
    /// Its DMD size (width, height), pixels.
    pub dmd_px: (u32, u32),
    /// Fringe periods, projector pixels, finest first.
    pub periods_px: &'a [f64],
    /// Phase steps per period.
    pub steps: usize,
}

/// Adapts one head: fits each camera pixel's response to `floods` (taken at
/// exposure scale 1 with `params.levels`), chooses the exposure at which
/// the most pixels reach `floor` (the reconstruction's modulation floor),
/// places every pixel's optimal level on the target's DMD through
/// `fringes` (the reconstruction of the full-intensity set with its
/// saturated pixels masked) and the calibrated projector, and builds the
/// adapted fringes.
pub fn adapt(
    floods: &[&Raster<f32>],
    fringes: &PixelMaps,
    target: PatternTarget<'_>,
    floor: f32,
    params: &HdrParams,
) -> Result<HdrAdaptation, AdaptiveError> {
    params.validate()?;
    let (w, h) = check_floods(floods, &params.levels)?;
    if fringes.size() != (w, h) {
        return Err(AdaptiveError::MappingSize {
            expected: (w, h),
            got: fringes.size(),
        });
    }
    let response = fit_response(floods, &params.levels, params.saturation)?;
    let exposure = choose_exposure(
        &response,
        &params.rule,
        floor,
        fringe_contrast(&response, fringes, params.rule.min_gain),
    );
    let rule = &params.rule;
    let mut stats = HdrStats {
        fitted_px: response.count(ResponseStatus::Fitted),
        saturates_at_lowest_px: response.count(ResponseStatus::SaturatesAtLowest),
        ..HdrStats::default()
    };
    let brightest = params
        .levels
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(i, _)| i);
    stats.saturated_in_full_flood_px = floods[brightest]
        .data
        .iter()
        .filter(|&&v| v >= params.saturation)
        .count();
    let scale = exposure.scale as f32;
    let camera_levels: Vec<f32> = (0..w * h)
        .map(|i| match response.status.data[i] {
            ResponseStatus::Fitted => {
                let (b1, b2) = (response.gain.data[i], response.offset.data[i]);
                match optimal_level(b1, b2, scale, rule.target, rule.min_level) {
                    Some(l) if l >= 1.0 => f32::NAN,
                    Some(l) => l,
                    None => {
                        stats.cannot_hold_px += 1;
                        rule.min_level
                    }
                }
            }
            ResponseStatus::SaturatesAtLowest => rule.min_level,
            ResponseStatus::BadSample => f32::NAN,
        })
        .collect();
    let camera_levels = Raster::from_vec(w, h, camera_levels).expect("sized");
    let mut uv = from_points(fringes, target.projector);
    let needs = Raster {
        width: w,
        height: h,
        data: camera_levels.data.iter().map(|l| l.is_finite()).collect(),
    };
    stats.lowered_px = needs.data.iter().filter(|&&n| n).count();
    stats.mapped_by_phase_px = needs
        .data
        .iter()
        .zip(&uv.data)
        .filter(|(&n, q)| n && is_mapped(q))
        .count();
    let footprint = footprint_px(&uv);
    let fill = fill_clusters(
        &mut uv,
        &needs,
        params.ring_px,
        params.max_homography_rms_px,
    );
    stats.clusters = fill.clusters;
    stats.mapped_by_homography_px = fill.filled_px;
    stats.unmapped_px = fill.unmapped_px;
    let projector_levels = projector_levels(
        &uv,
        &camera_levels,
        target.dmd_px,
        footprint,
        params.grow_px,
    );
    let patterns = adapted_fringes(
        &projector_levels,
        params.fringe_floor,
        target.periods_px,
        target.steps,
    );
    Ok(HdrAdaptation {
        exposure,
        camera_levels,
        projector_levels,
        patterns,
        stats,
    })
}
