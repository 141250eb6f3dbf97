//! One head's reconstruction inside a scan: its reconstructor from the
//! calibration, and its captured fringe sets turned into one result with
//! what the exposure left.

use super::underwater::LeftOut;
use super::{
    capture, exposure, ExposureFigures, Exposures, Mode, ScanConfig, ScanError, HEAD_NAMES,
};
use crate::calibration::RigCalibration;
use crate::raster::Raster;
use crate::reconstruct::{ReconstructConfig, Reconstruction, Reconstructor};

/// The reconstruction of head `h` with the scan's periods and noise, for
/// frames of `steps` shifts whose phase noise is `noise_factor` times a raw
/// frame's.
pub(crate) fn head_reconstructor(
    calibration: &RigCalibration,
    h: usize,
    config: &ScanConfig,
    steps: usize,
    noise_factor: f32,
) -> Result<Reconstructor, ScanError> {
    let mut rc_config = ReconstructConfig::new(config.periods_px.clone());
    rc_config.steps = steps;
    rc_config.noise_sigma = config.noise_sigma * noise_factor;
    rc_config.shot_noise_share = config.shot_noise_share;
    Reconstructor::from_head(&calibration.heads[h], rc_config).map_err(|source| {
        ScanError::Reconstruct {
            head: HEAD_NAMES[h],
            source,
        }
    })
}

/// Head `h`'s reconstruction from its captured fringe sets: each set
/// reconstructed (in the sequential mode its saturated pixels masked),
/// several merged per pixel, an adaptive scan's pixels over a step of its
/// DMD level map left out ([`crate::adaptive::edges`]); with what the
/// exposure left, and warnings for lost pixels. Under water the decoded
/// pixels are triangulated through the head's port and those within the
/// blur margin of a silhouette left out ([`super::underwater::finish_head`]);
/// the last value counts what that left out (nothing in air).
pub(super) fn reconstruct_head(
    calibration: &RigCalibration,
    config: &ScanConfig,
    captured: &mut capture::Captured,
    h: usize,
    record: Option<&capture::AdaptiveRecord>,
    warnings: &mut Vec<String>,
) -> Result<(Reconstruction, ExposureFigures, LeftOut), ScanError> {
    let head = HEAD_NAMES[h];
    let rc = head_reconstructor(
        calibration,
        h,
        config,
        captured.steps,
        captured.noise_factor,
    )?;
    let sets = captured.set_scales[h].len().max(1);
    let raw = &captured.raw[h];
    let raw_sets: Vec<&[Raster<f32>]> = raw.chunks(raw.len().div_ceil(sets).max(1)).collect();
    let frames = &mut captured.frames[h];
    let per_set = frames.len().div_ceil(sets).max(1);
    let mut frame_sets: Vec<&mut [Raster<f32>]> = frames.chunks_mut(per_set).collect();
    let (r, saturated) = exposure::reconstruct_sets(
        &rc,
        &raw_sets,
        &mut frame_sets,
        config.saturation_level,
        config.mode == Mode::Sequential,
    )
    .map_err(|source| ScanError::Reconstruct { head, source })?;
    let mut level_step_px = 0;
    let r = match record {
        Some(rec) => {
            let guard = match &config.exposures {
                Exposures::AdaptiveHdr(params) => params.clone(),
                _ => crate::adaptive::hdr::HdrParams::default(),
            };
            let mut maps = r.pixels;
            level_step_px = crate::adaptive::edges::mark_level_steps(
                &mut maps,
                &rec.level_map,
                &calibration.heads[h].projector,
                guard.step_radius_px,
                guard.max_step_ratio,
            );
            rc.from_maps(maps)
        }
        None => r,
    };
    let (r, left_out) = match (&config.medium, &calibration.heads[h].port) {
        (super::underwater::Medium::Water(water), Some(port)) => {
            super::underwater::finish_head(&rc, &calibration.heads[h], port, water, r)?
        }
        _ => (r, LeftOut::default()),
    };
    if config.mode == Mode::Sequential {
        exposure::warn(head, &saturated, record.map(|r| &r.stats), warnings);
    }
    let figures = ExposureFigures {
        images: captured.images[h],
        scales: captured.set_scales[h].clone(),
        saturated_px: saturated.iter().filter(|&&s| s).count(),
        below_floor_px: exposure::below_floor(&r, exposure::modulation_floor(&rc), &saturated),
        pixels: saturated.len(),
        adaptive: record.map(|a| exposure::AdaptiveFigures {
            exposure: a.exposure,
            stats: a.stats,
            before_saturated_px: a.before_saturated_px,
            before_below_floor_px: a.before_below_floor_px,
            level_step_px,
        }),
    };
    Ok((r, figures, left_out))
}
