//! The adaptive captures of the sequential mode, head after head: seed
//! 003's (grey floods and a full-intensity set, then the adapted set) and
//! seed 004's (floods, the Gray-code matching set, then coloured fringes),
//! each running the adaptation of [`crate::adaptive`] between its board
//! runs.

use super::capture::{for_projector, head_set, run, Captured};
use super::exposure::{below_floor, modulation_floor, saturated_pixels};
use super::{head_reconstructor, plan, Progress, ScanConfig, ScanError, HEAD_NAMES};
use crate::adaptive::colour::{
    adapt_colour, colour_response, decode_matching, flood_planes, matching_patterns, ColourParams,
    PLANE_LEDS,
};
use crate::adaptive::exposure::ExposureChoice;
use crate::adaptive::hdr::{adapt, HdrParams, HdrStats, PatternTarget};
use crate::calibration::RigCalibration;
use crate::raster::Raster;
use crate::rig::{Board, Camera, Projector};

/// What the adaptive capture took and chose for one head.
#[derive(Clone, Debug)]
pub struct AdaptiveRecord {
    /// The floods, in projection order.
    pub floods: Vec<Raster<f32>>,
    /// The adapted patterns as sent to the DMD (colour: red, green and blue
    /// planes of each image in turn).
    pub patterns: Vec<Raster<f32>>,
    /// The DMD level map (colour: the largest over the LEDs).
    pub level_map: Raster<f32>,
    /// The adapted fringes' exposure.
    pub exposure: ExposureChoice,
    /// The adaptation's counts.
    pub stats: HdrStats,
    /// Pixels saturated at full white before adapting (HDR: measured in the
    /// full-intensity fringe set; colour: predicted from the floods).
    pub before_saturated_px: usize,
    /// Pixels below the modulation floor at full white (saturated ones not
    /// counted; measured or predicted as above).
    pub before_below_floor_px: usize,
}

/// Seed 003 per head, heads one after another: the grey floods and the
/// full-intensity fringe set in one board run, the adaptation
/// ([`crate::adaptive::hdr::adapt`]) on the floods and the set's
/// reconstruction (saturated pixels masked), then the adapted set at the
/// chosen exposure.
pub(super) fn hdr<R: Board + Projector + Camera>(
    rig: &mut R,
    config: &ScanConfig,
    calibration: &RigCalibration,
    params: &HdrParams,
    progress: &mut dyn FnMut(Progress),
) -> Result<Captured, ScanError> {
    let count = config.periods_px.len() * config.steps;
    let levels = &params.levels;
    let mut preliminary = plan::floods(config.projector_px, levels);
    preliminary.extend(plan::fringe_sequence(
        config.projector_px,
        &config.periods_px,
        config.steps,
    ));
    let preliminary = for_projector(preliminary, config);
    let heads = calibration.heads.len();
    let (mut raw, mut adaptive) = (Vec::new(), Vec::new());
    for (h, &head) in HEAD_NAMES.iter().enumerate().take(heads) {
        let (set, name) = head_set(h, heads)?;
        progress(Progress::Stage { name, total: 4 });
        rig.load_sequence(h, &preliminary)?;
        run(
            rig,
            &plan::one_pattern_per_exposure(set, levels.len() + count)?,
            name,
        )?;
        let mut floods = rig.take_frames(h)?;
        let mut full = floods.split_off(levels.len().min(floods.len()));
        progress(Progress::Step);
        let rc = head_reconstructor(calibration, h, config, config.steps, 1.0)?;
        let saturated = saturated_pixels(&full, config.saturation_level);
        crate::dealias::mask_pixels(&mut full, &saturated);
        let refs: Vec<&Raster<f32>> = full.iter().collect();
        let before = rc
            .reconstruct(&refs, None)
            .map_err(|source| ScanError::Reconstruct { head, source })?;
        let flood_refs: Vec<&Raster<f32>> = floods.iter().collect();
        let adaptation = adapt(
            &flood_refs,
            &before.pixels,
            PatternTarget {
                projector: &calibration.heads[h].projector,
                dmd_px: config.projector_px,
                periods_px: &config.periods_px,
                steps: config.steps,
            },
            modulation_floor(&rc),
            params,
        )?;
        progress(Progress::Step);
        log_adaptation(h, &adaptation.exposure, &adaptation.stats);
        rig.load_sequence(h, &for_projector(adaptation.patterns.clone(), config))?;
        run(
            rig,
            &plan::one_pattern_per_scaled_exposure(set, count, adaptation.exposure.scale)?,
            name,
        )?;
        progress(Progress::Step);
        raw.push(rig.take_frames(h)?);
        progress(Progress::Step);
        progress(Progress::Done);
        adaptive.push(AdaptiveRecord {
            before_saturated_px: saturated.iter().filter(|&&s| s).count(),
            before_below_floor_px: below_floor(&before, modulation_floor(&rc), &saturated),
            floods,
            patterns: adaptation.patterns,
            level_map: adaptation.projector_levels,
            exposure: adaptation.exposure,
            stats: adaptation.stats,
        });
    }
    Ok(Captured {
        frames: raw.clone(),
        images: vec![levels.len() + 2 * count; heads],
        raw,
        set_scales: adaptive.iter().map(|a| vec![a.exposure.scale]).collect(),
        adaptive,
        steps: config.steps,
        noise_factor: 1.0,
        flat: None,
    })
}

/// Seed 004's phase steps: 3-step fringes.
pub const COLOUR_STEPS: usize = 3;

/// Shows colour images, given as their red, green and blue planes in turn,
/// on head `h` (each image one exposure of three sub-frames, one per LED)
/// in as few board runs as the plans hold; returns one frame per image.
fn colour_images<R: Board + Projector + Camera>(
    rig: &mut R,
    config: &ScanConfig,
    h: usize,
    planes: &[Raster<f32>],
    scale: f64,
) -> Result<Vec<Raster<f32>>, ScanError> {
    let (set, name) = head_set(h, h + 1)?;
    let images = planes.len() / 3;
    // The most images per run a plan holds at this exposure.
    let mut per_run = images.max(1);
    while per_run > 1 && plan::patterns_per_scaled_exposure(set, per_run, 3, scale).is_err() {
        per_run = per_run.div_ceil(2);
    }
    let mut frames = Vec::with_capacity(images);
    for chunk in planes.chunks(3 * per_run) {
        let leds: Vec<_> = (0..chunk.len()).map(|k| PLANE_LEDS[k % 3]).collect();
        rig.load_coloured_sequence(h, &for_projector(chunk.to_vec(), config), &leds)?;
        run(
            rig,
            &plan::patterns_per_scaled_exposure(set, chunk.len() / 3, 3, scale)?,
            name,
        )?;
        frames.extend(rig.take_frames(h)?);
    }
    Ok(frames)
}

/// Seed 004 per head, heads one after another: five floods (grey 0, grey
/// 100, red, green, blue), the Gray-code matching set, then 3-step
/// three-pitch fringes in the chosen colour and level per projector pixel
/// at the chosen exposure (see [`crate::adaptive::colour`]).
pub(super) fn colour<R: Board + Projector + Camera>(
    rig: &mut R,
    config: &ScanConfig,
    calibration: &RigCalibration,
    params: &ColourParams,
    progress: &mut dyn FnMut(Progress),
) -> Result<Captured, ScanError> {
    let dmd = config.projector_px;
    let flood_set: Vec<Raster<f32>> = flood_planes(dmd).into_iter().flatten().collect();
    let matching: Vec<Raster<f32>> = matching_patterns(dmd, params.block_px)
        .into_iter()
        .flat_map(|p| [p.clone(), p.clone(), p])
        .collect();
    let heads = calibration.heads.len();
    let (mut raw, mut adaptive) = (Vec::new(), Vec::new());
    let mut images = 0;
    for h in 0..heads {
        let (_, name) = head_set(h, heads)?;
        progress(Progress::Stage { name, total: 4 });
        let floods = colour_images(rig, config, h, &flood_set, 1.0)?;
        progress(Progress::Step);
        let matched = colour_images(rig, config, h, &matching, 1.0)?;
        progress(Progress::Step);
        let response = colour_response(&floods, config.saturation_level)?;
        let uv = decode_matching(&matched, &response, dmd, params)?;
        let rc = head_reconstructor(calibration, h, config, COLOUR_STEPS, 1.0)?;
        let floor = modulation_floor(&rc);
        let adaptation = adapt_colour(
            &response,
            &uv,
            dmd,
            &config.periods_px,
            COLOUR_STEPS,
            floor,
            params,
        )?;
        progress(Progress::Step);
        log_adaptation(h, &adaptation.exposure, &adaptation.stats);
        let frames = colour_images(
            rig,
            config,
            h,
            &adaptation.patterns,
            adaptation.exposure.scale,
        )?;
        progress(Progress::Step);
        progress(Progress::Done);
        images = floods.len() + matched.len() + frames.len();
        // Full white before adapting, predicted from the floods: saturated
        // where dark + white gain reaches saturation (or the grey flood
        // already did), below the floor where its fringe would be too weak.
        let (mut sat, mut dark) = (0, 0);
        for ((&o, &g), &white) in response
            .offset
            .data
            .iter()
            .zip(&response.white_gain.data)
            .zip(&floods[1].data)
        {
            if !g.is_finite()
                || o + g >= config.saturation_level
                || white >= config.saturation_level
            {
                sat += 1;
            } else if params.fringe_contrast * 0.5 * g < floor {
                dark += 1;
            }
        }
        let [r, g, b] = &adaptation.projector_levels;
        let level_map = Raster {
            width: r.width,
            height: r.height,
            data: r
                .data
                .iter()
                .zip(&g.data)
                .zip(&b.data)
                .map(|((r, g), b)| r.max(*g).max(*b))
                .collect(),
        };
        raw.push(frames);
        adaptive.push(AdaptiveRecord {
            floods,
            patterns: adaptation.patterns,
            level_map,
            exposure: adaptation.exposure,
            stats: adaptation.stats,
            before_saturated_px: sat,
            before_below_floor_px: dark,
        });
    }
    Ok(Captured {
        frames: raw.clone(),
        images: vec![images; heads],
        raw,
        set_scales: adaptive.iter().map(|a| vec![a.exposure.scale]).collect(),
        adaptive,
        steps: COLOUR_STEPS,
        noise_factor: 1.0,
        flat: None,
    })
}

/// Logs what head `h`'s adaptation chose.
fn log_adaptation(h: usize, exposure: &ExposureChoice, stats: &HdrStats) {
    tracing::info!(
        head = HEAD_NAMES[h],
        exposure_scale = exposure.scale,
        limited_by = exposure.limit.name(),
        lowered_px = stats.lowered_px,
        placed_by_phase_or_match_px = stats.mapped_by_phase_px,
        placed_by_homography_px = stats.mapped_by_homography_px,
        unplaced_px = stats.unmapped_px,
        "adapted the fringes"
    );
}
