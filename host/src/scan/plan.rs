//! What a sequential dual-head scan shows and when: the fringe set of each
//! head and the board plan that triggers it (one exposure per pattern).

use protocol::limits::{CameraModel, ProjectorModel, MAX_EXPOSURES};
use protocol::plan::examples::{
    head, CYCLE_LEAD_NS, SLOW_DISPLAY_NS, SLOW_EXPOSURE_NS, SLOW_FRAME_NS, SLOW_SLOT_OFFSET_NS,
};
use protocol::{HeadSet, PatternSlot, ScanPlan};

use crate::patterns::{multi_frequency_set, FringeAxis, FringeSpec};
use crate::raster::Raster;

/// Guard kept between each pattern's light and its exposure's edges.
const MARGIN_NS: u32 = 1_000;

/// The fringe frames of one head: `periods_px.len() x steps` column fringes,
/// period-major, 8-bit grey (as a DMD shows them), full contrast.
pub fn fringe_sequence(dmd_px: (u32, u32), periods_px: &[f64], steps: usize) -> Vec<Raster<f32>> {
    let spec = FringeSpec::full_contrast(dmd_px.0, dmd_px.1, periods_px[0], steps, FringeAxis::X);
    let mut frames = multi_frequency_set(&spec, periods_px);
    for f in &mut frames {
        f.data
            .iter_mut()
            .for_each(|v| *v = (*v * 255.0).round() / 255.0);
    }
    frames
}

/// Column fringes with arbitrary shifts (radians), period-major: for each
/// period, one frame per shift; 8-bit grey, full contrast.
pub fn shifted_fringes(
    dmd_px: (u32, u32),
    periods_px: &[f64],
    shifts_rad: &[f64],
) -> Vec<Raster<f32>> {
    let (w, h) = (dmd_px.0 as usize, dmd_px.1 as usize);
    let mut frames = Vec::with_capacity(periods_px.len() * shifts_rad.len());
    for &period in periods_px {
        for &shift in shifts_rad {
            // One row, repeated: column fringes do not change down the DMD.
            let row: Vec<f32> = (0..w)
                .map(|u| {
                    let v = 0.5 + 0.5 * (std::f64::consts::TAU * u as f64 / period + shift).cos();
                    (v as f32 * 255.0).round() / 255.0
                })
                .collect();
            frames.push(Raster {
                width: w,
                height: h,
                data: row.repeat(h),
            });
        }
    }
    frames
}

/// Uniform grey floods at `levels` (each in [0, 1]), as the DMD shows them
/// (8-bit): the preliminary exposures of adaptive projection.
pub fn floods(dmd_px: (u32, u32), levels: &[f32]) -> Vec<Raster<f32>> {
    levels
        .iter()
        .map(|&l| {
            let grey = (l.clamp(0.0, 1.0) * 255.0).round() / 255.0;
            Raster::filled(dmd_px.0 as usize, dmd_px.1 as usize, grey)
        })
        .collect()
}

/// Flat-field exposures after the simultaneous mode's fringes.
pub const FLAT_FIELDS: usize = 3;

/// Projector `projector`'s flat-field frames, in exposure order: both
/// projectors dark, projector A (0) alone full on, projector B (1) alone
/// full on.
pub fn flat_fields(dmd_px: (u32, u32), projector: usize) -> Vec<Raster<f32>> {
    let (w, h) = (dmd_px.0 as usize, dmd_px.1 as usize);
    (0..FLAT_FIELDS)
        .map(|k| Raster::filled(w, h, if k == projector + 1 { 1.0 } else { 0.0 }))
        .collect()
}

/// Patterns pre-distorted for a projector whose intensity is g^gamma for
/// a displayed grey g (the standard remedy for a video-input projector's
/// response): each level becomes g^(1/gamma), re-quantised to 8 bits, so
/// the light on the scene is the intended sinusoid again. Its harmonics
/// would otherwise put head A's 2nd harmonic on head B's temporal bin in
/// the multiplexed mode. (The double 8-bit rounding adds well under the
/// 12-bit sensor's noise.)
pub fn precompensate_gamma(patterns: &mut [Raster<f32>], gamma: f64) {
    let inv = (1.0 / gamma) as f32;
    for f in patterns {
        f.data
            .iter_mut()
            .for_each(|v| *v = (v.max(0.0).powf(inv) * 255.0).round() / 255.0);
    }
}

/// Why a plan cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanBuildError {
    /// More patterns than a plan's cycle holds exposures.
    #[error("{patterns} patterns need {patterns} exposures; a plan holds at most {max}")]
    TooManyPatterns {
        /// Patterns asked for.
        patterns: usize,
        /// Exposures a plan holds.
        max: usize,
    },
    /// An exposure scale the frame period cannot hold or the devices cannot
    /// show (the pattern would be shorter than the projector's shortest).
    #[error("exposure scale {scale} is outside {MIN_EXPOSURE_SCALE}..={MAX_EXPOSURE_SCALE} standard exposures of {} ms (a pattern must last at least the projector's shortest, a plan's cycle at most {} s)", SLOW_EXPOSURE_NS / 1_000_000, u32::MAX / 1_000_000_000)]
    ExposureScale {
        /// The scale asked for.
        scale: f64,
    },
}

/// Longest exposure, in standard exposures: 8 x 12 ms = 96 ms (the frame
/// period stretches to 118 ms, 8.5 frames per second), so a 36-pattern plan
/// still fits the plan's 4.29 s cycle.
pub const MAX_EXPOSURE_SCALE: f64 = 8.0;
/// Shortest exposure, in standard exposures: 1/32 of 10 ms = 312 us of
/// pattern, over the DLPC350's shortest pattern period (235 us).
pub const MIN_EXPOSURE_SCALE: f64 = 1.0 / 32.0;

/// The two-head rig wiring (DLPC350 projectors, 6 MP mono cameras) with
/// `patterns` exposures on `heads`, one pattern each, one frame period
/// apart: the seed 000 reference run of one head when `heads` is one head,
/// or both heads at once when it is [`HeadSet::BOTH`].
pub fn one_pattern_per_exposure(
    heads: HeadSet,
    patterns: usize,
) -> Result<ScanPlan, PlanBuildError> {
    one_pattern_per_scaled_exposure(heads, patterns, 1.0)
}

/// [`one_pattern_per_exposure`] with each exposure and its pattern's time on
/// the mirrors `scale` times the standard ones (a camera's exposure time with
/// the projector lit throughout it: the light of both the pattern and the
/// ambient scales by `scale`), for multi-exposure and adaptive capture.
pub fn one_pattern_per_scaled_exposure(
    heads: HeadSet,
    patterns: usize,
    scale: f64,
) -> Result<ScanPlan, PlanBuildError> {
    patterns_per_scaled_exposure(heads, patterns, 1, scale)
}

/// Gap between two patterns shown in one exposure (the DMD's next trigger).
const SLOT_GAP_NS: u32 = 500_000;

/// `exposures` exposures of `slots` patterns each (pattern indices in
/// order, each on the mirrors for `scale` standard display times, 0.5 ms
/// apart), the exposure `scale` standard exposures longer for each pattern
/// beyond the first: an RGB projector shows a colour pattern as its red,
/// green and blue planes one after another inside one camera exposure.
pub fn patterns_per_scaled_exposure(
    heads: HeadSet,
    exposures: usize,
    slots: usize,
    scale: f64,
) -> Result<ScanPlan, PlanBuildError> {
    if !(MIN_EXPOSURE_SCALE..=MAX_EXPOSURE_SCALE).contains(&scale) {
        return Err(PlanBuildError::ExposureScale { scale });
    }
    let slots = slots.max(1);
    let display_ns = (f64::from(SLOW_DISPLAY_NS) * scale).round() as u32;
    let extra_ns = (slots as u32 - 1) * (display_ns + SLOT_GAP_NS);
    let exposure_ns = (f64::from(SLOW_EXPOSURE_NS) * scale).round() as u32 + extra_ns;
    // A longer exposure stretches the frame period by as much (the camera's
    // read-out and re-arm time after the exposure stays the same).
    let frame_ns = SLOW_FRAME_NS.max(exposure_ns + (SLOW_FRAME_NS - SLOW_EXPOSURE_NS));
    let patterns = exposures;
    if patterns > MAX_EXPOSURES || patterns * slots > protocol::limits::MAX_SLOTS_PER_CYCLE {
        return Err(PlanBuildError::TooManyPatterns {
            patterns: patterns * slots,
            max: MAX_EXPOSURES.min(protocol::limits::MAX_SLOTS_PER_CYCLE / slots),
        });
    }
    // Heads A and B are always wired (the dual-head board's plan, which a
    // one-head rig runs too); a plan for head C or D wires up to it, so a
    // board with lines for two heads refuses it before anything runs.
    let wired = (0..protocol::limits::MAX_HEADS)
        .filter(|&h| heads.contains(h))
        .max()
        .map_or(2, |last| (last + 1).max(2));
    let wiring: Vec<_> = (0..wired as u8)
        .map(|h| head(h, ProjectorModel::Dlpc350, CameraModel::Mono6Mp))
        .collect();
    let period_ns = u32::try_from(patterns as u64 * u64::from(frame_ns))
        .map_err(|_| PlanBuildError::ExposureScale { scale })?;
    let mut plan = ScanPlan::new(&wiring, 1, period_ns, MARGIN_NS).map_err(|_| {
        PlanBuildError::TooManyPatterns {
            patterns,
            max: MAX_EXPOSURES,
        }
    })?;
    for k in 0..patterns {
        let shown: Vec<PatternSlot> = (0..slots)
            .map(|j| PatternSlot {
                pattern_index: (k * slots + j) as u16,
                offset_ns: SLOW_SLOT_OFFSET_NS + j as u32 * (display_ns + SLOT_GAP_NS),
                display_ns,
            })
            .collect();
        plan.push_exposure(
            heads,
            CYCLE_LEAD_NS + k as u32 * frame_ns,
            exposure_ns,
            &shown,
        )
        .map_err(|_| PlanBuildError::TooManyPatterns {
            patterns,
            max: MAX_EXPOSURES,
        })?;
    }
    Ok(plan)
}

/// Seconds each pattern is on the mirrors (sets the sensor's exposure scale).
pub fn display_s() -> f64 {
    SLOW_DISPLAY_NS as f64 * 1e-9
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::BoardLimits;

    #[test]
    fn head_only_plans_validate_on_the_board_limits() {
        for heads in [HeadSet::A, HeadSet::B, HeadSet::BOTH] {
            let plan = one_pattern_per_exposure(heads, 16).unwrap();
            assert_eq!(plan.exposures.len(), 16);
            plan.clone()
                .validate(&BoardLimits::STM32G474)
                .expect("valid");
        }
        assert!(one_pattern_per_exposure(HeadSet::A, MAX_EXPOSURES + 1).is_err());
    }

    #[test]
    fn plans_for_heads_c_and_d_wire_up_to_them_and_need_a_board_with_their_lines() {
        let eight_lines = BoardLimits {
            output_channels: 8,
            feedback_channels: 8,
            ..BoardLimits::STM32G474
        };
        for (set, wired) in [
            (HeadSet::C, 3),
            (HeadSet::D, 4),
            (HeadSet::all(3).unwrap(), 3),
            (HeadSet::all(4).unwrap(), 4),
        ] {
            let plan = one_pattern_per_exposure(set, 12).unwrap();
            assert_eq!(plan.heads.len(), wired);
            plan.clone()
                .validate(&eight_lines)
                .expect("valid on 8 lines");
            assert!(plan.validate(&BoardLimits::STM32G474).is_err());
        }
    }

    #[test]
    fn scaled_exposures_validate_and_out_of_range_scales_are_refused() {
        for scale in [MIN_EXPOSURE_SCALE, 0.25, 1.0, 2.5, MAX_EXPOSURE_SCALE] {
            let plan = one_pattern_per_scaled_exposure(HeadSet::A, 36, scale).unwrap();
            assert_eq!(
                plan.exposures[0].duration_ns,
                (f64::from(SLOW_EXPOSURE_NS) * scale).round() as u32
            );
            plan.validate(&BoardLimits::STM32G474)
                .unwrap_or_else(|err| panic!("scale {scale}: {err:?}"));
        }
        for scale in [0.0, MAX_EXPOSURE_SCALE * 1.01, f64::NAN, -1.0] {
            assert!(matches!(
                one_pattern_per_scaled_exposure(HeadSet::A, 12, scale),
                Err(PlanBuildError::ExposureScale { .. })
            ));
        }
        // The longest exposure's cycle no longer fits 64 patterns.
        assert!(matches!(
            one_pattern_per_scaled_exposure(HeadSet::A, 64, MAX_EXPOSURE_SCALE),
            Err(PlanBuildError::ExposureScale { .. })
        ));
    }

    #[test]
    fn three_patterns_per_exposure_validate() {
        for scale in [0.25, 1.0, 2.5] {
            let plan = patterns_per_scaled_exposure(HeadSet::A, 34, 3, scale).unwrap();
            assert_eq!(plan.exposures.len(), 34);
            assert_eq!(plan.slots.len(), 102);
            assert_eq!(plan.slots[5].pattern_index, 5);
            plan.validate(&BoardLimits::STM32G474)
                .unwrap_or_else(|err| panic!("scale {scale}: {err:?}"));
        }
        assert!(patterns_per_scaled_exposure(HeadSet::A, 86, 3, 1.0).is_err());
    }

    #[test]
    fn floods_are_8_bit_uniform_levels() {
        let f = floods((4, 2), &[0.0, 0.5, 1.0]);
        assert_eq!(f.len(), 3);
        assert!(f[1].data.iter().all(|&v| v == 128.0 / 255.0));
        assert!(f[2].data.iter().all(|&v| v == 1.0));
    }

    #[test]
    fn flat_fields_light_one_projector_at_a_time() {
        let level =
            |p: usize| -> Vec<f32> { flat_fields((4, 2), p).iter().map(|r| r.data[0]).collect() };
        assert_eq!(level(0), [0.0, 1.0, 0.0]);
        assert_eq!(level(1), [0.0, 0.0, 1.0]);
    }

    #[test]
    fn precompensated_levels_come_back_linear_under_the_gamma() {
        let mut f = fringe_sequence((256, 1), &[32.0], 4);
        let want = f.clone();
        precompensate_gamma(&mut f, 2.2);
        for (got, want) in f.iter().zip(&want) {
            for (g, w) in got.data.iter().zip(&want.data) {
                // 8-bit rounding of g^(1/2.2) near g = 1 moves the light by
                // up to 2.2 / 2 / 255.
                assert!(
                    (g.powf(2.2) - w).abs() <= 0.0045,
                    "{g} -> {} vs {w}",
                    g.powf(2.2)
                );
            }
        }
        // Mid-grey is sent brighter.
        assert!(f[0].data[8] > want[0].data[8]);
    }

    #[test]
    fn fringes_are_period_major_8_bit() {
        let f = fringe_sequence((64, 4), &[16.0, 20.0], 4);
        assert_eq!(f.len(), 8);
        // Step 0 of period 16 at u = 0: cos 0 = 1; step 2 (shift pi): 0.
        assert_eq!(f[0].data[0], 1.0);
        assert_eq!(f[2].data[0], 0.0);
        assert!(f
            .iter()
            .flat_map(|r| &r.data)
            .all(|v| (v * 255.0).fract() == 0.0));
    }
}
