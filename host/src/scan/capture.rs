//! Capture of the heads' frames for each mode, and their reduction to the
//! plain N-step frames the per-head reconstruction reads.
//!
//! - sequential: head A alone, then head B alone, and so on (a board run
//!   each; a one-head rig has head A's alone).
//! - simultaneous-multiplexed: one board run, every head at once, each
//!   head's shifts on its own temporal bin ([`multiplex_bins`]: two heads
//!   N = 8 on bins 1 and 2; three N = 12 on 1, 4, 5; four N = 15 on 1, 4,
//!   5, 6). Each camera's N samples per period are demultiplexed per pixel
//!   ([`crate::demultiplex::demultiplex_heads`]); its own head's (phase,
//!   modulation, background) is re-expressed as 4 equivalent 4-step frames
//!   (`A + B cos(phi + pi n/2)`, which the 4-step decoder returns exactly),
//!   so the unchanged reconstruction runs on them.
//! - simultaneous: one run, both heads show identical 4-step sequences at
//!   once, then three flat fields (both dark, A alone full on, B alone
//!   full on); pixels the flat fields show lit by both projectors are
//!   aliased: de-aliased ([`crate::dealias`]) or masked out
//!   ([`super::aliasing`]).

use protocol::HeadSet;

use super::adaptive_capture;
pub use super::adaptive_capture::AdaptiveRecord;
use super::aliasing::{camera_lighting, AliasParams, FlatFields};
use super::dealias_picture::DealiasSample;
use super::exposure::{auto_exposure_scale, AutoExposure, Exposures};
use super::{plan, Mode, Progress, ScanConfig, ScanError, HEAD_NAMES};
use crate::calibration::RigCalibration;
use crate::dealias::{
    dealias_frames, dealias_frames_learned, mask_pixels, AnalyticDealiaser, AnalyticParams,
    DealiasMethod, DealiasStats, EpipolarDealiaser, EpipolarParams,
};
use crate::demultiplex::{
    demultiplex_head, smallest_safe_head_bins, DemuxError, HeadBins, GAMMA_HARMONICS,
};
use crate::raster::Raster;
use crate::rig::{Board, Camera, Projector, RigError};

/// Frames ready for the 4-step (or N-step) reconstruction, per head.
pub struct Captured {
    /// Per head: the fringe frames its camera took, in trigger order (for
    /// pictures and the saturation check), `set_scales.len()` sets of them;
    /// with frames averaged, each pattern's mean ([`average_takes`]: a pixel
    /// clipped in any take keeps its clipped value).
    pub raw: Vec<Vec<Raster<f32>>>,
    /// Per head: period-major frames of `steps` shifts for the
    /// reconstruction, `set_scales.len()` sets of them one after another.
    pub frames: Vec<Vec<Raster<f32>>>,
    /// Per head: exposure scale of each fringe set in `raw` and `frames`.
    pub set_scales: Vec<Vec<f64>>,
    /// Per head: camera images taken in all (preliminaries included).
    pub images: Vec<usize>,
    /// Per head: the adaptive capture's preliminaries and choice (empty
    /// unless adaptive).
    pub adaptive: Vec<AdaptiveRecord>,
    /// Steps per period in `frames`.
    pub steps: usize,
    /// Phase-noise factor of `frames` relative to raw `steps`-step frames
    /// (demultiplexed 8 samples into 4 equivalent frames: sqrt(4/8)).
    pub noise_factor: f32,
    /// Per head: its camera's flat fields (simultaneous mode only).
    pub flat: Option<Vec<FlatFields>>,
}

/// Runs the board and cameras of the calibration's heads for
/// `config.mode` (the simultaneous modes take two;
/// [`super::check_before_capture`] says so) and `config.exposures`.
pub fn capture<R: Board + Projector + Camera>(
    rig: &mut R,
    config: &ScanConfig,
    calibration: &RigCalibration,
    progress: &mut dyn FnMut(Progress),
) -> Result<Captured, ScanError> {
    let heads = calibration.heads.len();
    match config.mode {
        Mode::Sequential => match &config.exposures {
            Exposures::Single => sequential(rig, config, heads, &Fixed(&[1.0]), progress),
            Exposures::Multi(scales) => sequential(rig, config, heads, &Fixed(scales), progress),
            Exposures::Auto(rule) => sequential(rig, config, heads, &Auto(rule), progress),
            Exposures::AdaptiveHdr(params) => {
                adaptive_capture::hdr(rig, config, calibration, params, progress)
            }
            Exposures::AdaptiveColour(params) => {
                adaptive_capture::colour(rig, config, calibration, params, progress)
            }
        },
        mode if config.exposures != Exposures::Single => Err(ScanError::ExposuresNeedSequential {
            mode,
            exposures: config.exposures.name(),
        }),
        Mode::Simultaneous => simultaneous(rig, config, progress),
        Mode::SimultaneousMultiplexed => multiplexed(rig, config, heads, progress),
    }
}

/// Patterns as the projector should receive them: pre-compensated for its
/// response when the config asks.
pub(super) fn for_projector(
    mut patterns: Vec<Raster<f32>>,
    config: &ScanConfig,
) -> Vec<Raster<f32>> {
    if let Some(gamma) = config.precompensate_gamma {
        plan::precompensate_gamma(&mut patterns, gamma);
    }
    patterns
}

/// Runs `plan` on the board, clean or an error.
pub(super) fn run(
    rig: &mut impl Board,
    plan: &protocol::ScanPlan,
    what: &str,
) -> Result<(), ScanError> {
    let outcome = rig.run_plan(plan)?;
    tracing::info!(
        run = what,
        start_tick = outcome.start_tick,
        worst_error_ticks = outcome.report.worst_error_ticks,
        "board ran the plan clean"
    );
    Ok(())
}

/// The exposure scales of a sequential head's fringe sets.
enum SequentialExposure<'a> {
    /// The same scales for every head.
    Fixed(&'a [f64]),
    /// One scale per head, from a white flood ([`auto_exposure_scale`]).
    Auto(&'a AutoExposure),
}
use SequentialExposure::{Auto, Fixed};

impl SequentialExposure<'_> {
    /// Head `h`'s scales and the preliminary images taken to choose them
    /// (the white flood leaves the projector loaded with it).
    fn scales<R: Board + Projector + Camera>(
        &self,
        rig: &mut R,
        config: &ScanConfig,
        h: usize,
        set: HeadSet,
        name: &str,
    ) -> Result<(Vec<f64>, usize), ScanError> {
        let rule = match self {
            Fixed(scales) => return Ok((scales.to_vec(), 0)),
            Auto(rule) => rule,
        };
        rig.load_sequence(
            h,
            &for_projector(plan::floods(config.projector_px, &[1.0]), config),
        )?;
        run(rig, &plan::one_pattern_per_exposure(set, 1)?, name)?;
        let white = rig.take_frames(h)?;
        let white = white.first().ok_or(RigError::FrameCount {
            head: h,
            expected: 1,
            got: 0,
            missed: Vec::new(),
        })?;
        let range = (plan::MIN_EXPOSURE_SCALE, plan::MAX_EXPOSURE_SCALE);
        let scale = auto_exposure_scale(white, rule, range);
        tracing::info!(head = HEAD_NAMES[h], scale, "auto exposure");
        Ok((vec![scale], 1))
    }
}

/// Head A alone, then head B alone, and so on, each taking the fringe set
/// once per exposure scale (one board run each), the scales fixed or
/// chosen per head.
fn sequential<R: Board + Projector + Camera>(
    rig: &mut R,
    config: &ScanConfig,
    heads: usize,
    exposure: &SequentialExposure,
    progress: &mut dyn FnMut(Progress),
) -> Result<Captured, ScanError> {
    let count = config.periods_px.len() * config.steps;
    let patterns = for_projector(
        plan::fringe_sequence(config.projector_px, &config.periods_px, config.steps),
        config,
    );
    let (mut raw, mut set_scales, mut images) = (Vec::new(), Vec::new(), Vec::new());
    for h in 0..heads {
        let (set, name) = head_set(h, heads)?;
        let (scales, preliminary) = exposure.scales(rig, config, h, set, name)?;
        let repeats = config.frames_per_pattern.max(1);
        progress(Progress::Stage {
            name,
            total: (2 * scales.len() * repeats) as u64,
        });
        rig.load_sequence(h, &patterns)?;
        let mut taken = Vec::with_capacity(count * scales.len());
        for &scale in &scales {
            let plan = plan::one_pattern_per_scaled_exposure(set, count, scale)?;
            let mut takes = Vec::with_capacity(repeats);
            for _ in 0..repeats {
                run(rig, &plan, name)?;
                progress(Progress::Step);
                takes.push(rig.take_frames(h)?);
                progress(Progress::Step);
            }
            taken.extend(average_takes(h, takes, config.saturation_level)?);
        }
        raw.push(taken);
        images.push(preliminary + count * scales.len() * repeats);
        set_scales.push(scales);
        progress(Progress::Done);
    }
    Ok(Captured {
        frames: raw.clone(),
        images,
        raw,
        set_scales,
        adaptive: Vec::new(),
        steps: config.steps,
        noise_factor: 1.0 / (config.frames_per_pattern.max(1) as f32).sqrt(),
        flat: None,
    })
}

/// The per-pattern mean of several takes of the same frames (each take one
/// run of the same plan). A pixel saturated in any take keeps its largest
/// value, so the saturation mask still sees it: a mean of clipped and
/// unclipped samples would pass as a true level. One take passes through.
pub(super) fn average_takes(
    head: usize,
    mut takes: Vec<Vec<Raster<f32>>>,
    saturation_level: f32,
) -> Result<Vec<Raster<f32>>, ScanError> {
    let Some(first) = takes.first() else {
        return Ok(Vec::new());
    };
    let shape = |t: &[Raster<f32>]| t.iter().map(|f| (f.width, f.height)).collect::<Vec<_>>();
    let want = shape(first);
    if let Some(take) = takes.iter().position(|t| shape(t) != want) {
        return Err(ScanError::TakesDiffer {
            head,
            take,
            frames: takes[take].len(),
            expected: want.len(),
        });
    }
    if takes.len() == 1 {
        return Ok(takes.swap_remove(0));
    }
    let n = takes.len() as f32;
    let mut mean = takes.swap_remove(0);
    let mut peak = mean.clone();
    for take in &takes {
        for (acc, (top, frame)) in mean.iter_mut().zip(peak.iter_mut().zip(take)) {
            for ((a, t), &v) in acc
                .data
                .iter_mut()
                .zip(top.data.iter_mut())
                .zip(&frame.data)
            {
                *a += v;
                *t = t.max(v);
            }
        }
    }
    for (acc, top) in mean.iter_mut().zip(&peak) {
        for (a, &t) in acc.data.iter_mut().zip(&top.data) {
            *a = if t >= saturation_level { t } else { *a / n };
        }
    }
    Ok(mean)
}

fn simultaneous<R: Board + Projector + Camera>(
    rig: &mut R,
    config: &ScanConfig,
    progress: &mut dyn FnMut(Progress),
) -> Result<Captured, ScanError> {
    let count = config.periods_px.len() * config.steps;
    let fringes = plan::fringe_sequence(config.projector_px, &config.periods_px, config.steps);
    progress(Progress::Stage {
        name: "capture A+B",
        total: 3,
    });
    for h in 0..2 {
        // After the fringes: both dark, then A alone, then B alone.
        let mut patterns = fringes.clone();
        patterns.extend(plan::flat_fields(config.projector_px, h));
        rig.load_sequence(h, &for_projector(patterns, config))?;
    }
    run(
        rig,
        &plan::one_pattern_per_exposure(HeadSet::BOTH, count + plan::FLAT_FIELDS)?,
        "A+B",
    )?;
    progress(Progress::Step);
    let mut raw = Vec::new();
    let mut frames = Vec::new();
    let mut flat = Vec::new();
    // Simultaneous modes run heads A and B (check_before_capture), whatever
    // the length of HEAD_NAMES.
    for (h, head) in HEAD_NAMES.into_iter().enumerate().take(2) {
        let mut taken = rig.take_frames(h)?;
        let flats = taken.split_off(count);
        let [dark, lit_a, lit_b]: [Raster<f32>; 3] =
            flats
                .try_into()
                .map_err(|f: Vec<_>| ScanError::FlatFields {
                    head,
                    frames: f.len(),
                })?;
        flat.push(FlatFields { dark, lit_a, lit_b });
        frames.push(taken.clone());
        raw.push(taken);
        progress(Progress::Step);
    }
    progress(Progress::Done);
    Ok(Captured {
        frames,
        raw,
        set_scales: vec![vec![1.0]; 2],
        images: vec![count + plan::FLAT_FIELDS; 2],
        adaptive: Vec::new(),
        steps: config.steps,
        noise_factor: 1.0,
        flat: Some(flat),
    })
}

/// Head `h`'s trigger set and progress stage name in a capture of `heads`
/// heads one after another; past the protocol's heads, a typed error.
pub(super) fn head_set(h: usize, heads: usize) -> Result<(HeadSet, &'static str), ScanError> {
    let set = HeadSet::single(h).ok_or(ScanError::HeadCount { heads })?;
    Ok((set, CAPTURE_STAGES[h]))
}

/// Progress stage names of the sequential capture, per head.
const CAPTURE_STAGES: [&str; protocol::limits::MAX_HEADS] =
    ["capture A", "capture B", "capture C", "capture D"];

/// The temporal bins of a multiplexed scan of `heads` heads: two heads keep
/// DESIGN.md's N = 8 on bins 1 and 2 (safe against odd harmonics; gamma
/// needs pre-compensated patterns, as measured); three or four take the
/// fewest steps whose bins are safe against gamma's 2nd and 3rd harmonics
/// too (12 steps for three, 15 for four), since more heads leave no safe
/// choice as short as 8.
pub fn multiplex_bins(heads: usize) -> Result<HeadBins, ScanError> {
    match heads {
        2 => Ok(HeadBins::design_default()),
        _ => smallest_safe_head_bins(heads, &GAMMA_HARMONICS, 32)
            .ok_or(ScanError::HeadCount { heads }),
    }
}

fn multiplexed<R: Board + Projector + Camera>(
    rig: &mut R,
    config: &ScanConfig,
    heads: usize,
    progress: &mut dyn FnMut(Progress),
) -> Result<Captured, ScanError> {
    let bins = multiplex_bins(heads)?;
    let n = bins.steps();
    let count = config.periods_px.len() * n;
    let all = HeadSet::all(heads).ok_or(ScanError::HeadCount { heads })?;
    progress(Progress::Stage {
        name: "capture multiplexed",
        total: 1 + heads as u64,
    });
    for h in 0..heads {
        let shifts = bins.shifts_rad(h).ok_or(ScanError::HeadCount { heads })?;
        let patterns = for_projector(
            plan::shifted_fringes(config.projector_px, &config.periods_px, &shifts),
            config,
        );
        rig.load_sequence(h, &patterns)?;
    }
    run(
        rig,
        &plan::one_pattern_per_exposure(all, count)?,
        "all heads multiplexed",
    )?;
    progress(Progress::Step);
    let mut raw = Vec::new();
    let mut frames = Vec::new();
    for (h, head) in HEAD_NAMES.into_iter().enumerate().take(heads) {
        let taken = rig.take_frames(h)?;
        frames.push(
            demultiplexed_frames(&bins, &taken, h)
                .map_err(|source| ScanError::Demultiplex { head, source })?,
        );
        raw.push(taken);
        progress(Progress::Step);
    }
    progress(Progress::Done);
    Ok(Captured {
        raw,
        frames,
        set_scales: vec![vec![1.0]; heads],
        images: vec![count; heads],
        adaptive: Vec::new(),
        steps: 4,
        noise_factor: (4.0f32 / n as f32).sqrt(),
        flat: None,
    })
}

/// Head `head`'s 4 equivalent frames per period from a camera's N samples
/// per period (period-major).
fn demultiplexed_frames(
    bins: &HeadBins,
    taken: &[Raster<f32>],
    head: usize,
) -> Result<Vec<Raster<f32>>, DemuxError> {
    let n = bins.steps();
    let mut out = Vec::new();
    for period in taken.chunks(n) {
        let slices: Vec<&[f32]> = period.iter().map(|r| r.data.as_slice()).collect();
        let mut images = demultiplex_head(bins, &slices, head)?;
        let own = images.heads.swap_remove(0);
        let (w, h) = period[0].size();
        for step in 0..4 {
            let shift = std::f32::consts::FRAC_PI_2 * step as f32;
            let data = images
                .background
                .iter()
                .zip(&own.phase_rad)
                .zip(&own.modulation)
                .map(|((a, phi), b)| a + b * (phi + shift).cos())
                .collect();
            out.push(Raster {
                width: w,
                height: h,
                data,
            });
        }
    }
    Ok(out)
}

/// Simultaneous mode with identical sequences: pixels lit by both
/// projectors see aliased fringes, and pixels lit by the other head's
/// projector alone see fringes of the wrong projector, as the flat fields
/// show them ([`super::aliasing::unusable_mask`]). With
/// [`DealiasMethod::Epipolar`] (through `calibration`),
/// [`DealiasMethod::Analytic`] or [`DealiasMethod::Learned`] each camera's
/// own fringe is separated where both light the pixel ([`crate::dealias`])
/// and the rest masked; with [`DealiasMethod::Mask`]
/// all of them are masked (frames zeroed there, so the reconstruction masks
/// them), with a loud warning. Returns each head's measured aliased overlap
/// (lit by both; empty without flat fields), its de-aliasing figures and,
/// where a de-aliaser ran, its first period's frames before and after.
pub fn resolve_measured_overlap(
    captured: &mut Captured,
    config: &ScanConfig,
    calibration: &RigCalibration,
    warnings: &mut Vec<String>,
) -> Result<ResolvedOverlap, ScanError> {
    let Some(flat) = &captured.flat else {
        return Ok(ResolvedOverlap::default());
    };
    let params = AliasParams::default();
    let solver = match config.dealias {
        DealiasMethod::Analytic => Some(
            AnalyticDealiaser::new(
                &config.periods_px,
                captured.steps,
                config.projector_px.0,
                AnalyticParams::default(),
            )
            .map_err(ScanError::Dealias)?,
        ),
        DealiasMethod::Epipolar | DealiasMethod::Mask | DealiasMethod::Learned => None,
    };
    let mut overlaps = Vec::new();
    let mut all_stats = Vec::new();
    let mut samples = Vec::new();
    for (h, (frames, flat)) in captured.frames.iter_mut().zip(flat).enumerate() {
        let started = std::time::Instant::now();
        let steps = captured.steps;
        let aliased: Vec<Raster<f32>> = frames.iter().take(steps).cloned().collect();
        let lit = camera_lighting(flat, h, &params);
        let both = lit.lit.both();
        let mask = &lit.unusable;
        let both_count = both.iter().filter(|&&b| b).count();
        let mask_count = mask.iter().filter(|&&m| m).count();
        let mut stats = match (config.dealias, &solver, &config.learned) {
            (DealiasMethod::Epipolar, _, _) => dealias_frames(
                frames,
                flat,
                h,
                &lit,
                &EpipolarDealiaser::new(
                    calibration,
                    h,
                    &config.periods_px,
                    steps,
                    EpipolarParams::default(),
                )
                .map_err(ScanError::Epipolar)?,
                config.noise_sigma * captured.noise_factor,
                config.shot_noise_share,
            ),
            (DealiasMethod::Analytic, Some(solver), _) => dealias_frames(
                frames,
                flat,
                h,
                &lit,
                solver,
                config.noise_sigma * captured.noise_factor,
                config.shot_noise_share,
            ),
            (DealiasMethod::Learned, _, Some(network)) => {
                dealias_frames_learned(frames, flat, h, &lit, network, h as u64)
                    .map_err(ScanError::Network)?
            }
            (DealiasMethod::Learned, _, None) => return Err(ScanError::NoLearnedModel),
            _ => {
                let warning = format!(
                    "simultaneous mode: camera {} has {both_count} pixels that the flat fields show lit \
                     by both projectors (aliased fringes); they and the pixels lit by the other head's \
                     projector alone, {mask_count} in all (grown by {} px), are MASKED OUT \
                     (--dealias mask)",
                    HEAD_NAMES[h], params.grow_px
                );
                warnings.push(warning);
                mask_pixels(frames, mask);
                overlaps.push(both);
                all_stats.push(DealiasStats {
                    affected: mask_count,
                    time_ms: started.elapsed().as_millis() as u64,
                    ..DealiasStats::default()
                });
                samples.push(None);
                continue;
            }
        };
        stats.time_ms = started.elapsed().as_millis() as u64;
        tracing::info!(
            camera = HEAD_NAMES[h],
            method = config.dealias.name(),
            affected = stats.affected,
            attempted = stats.attempted,
            separated = stats.separated,
            ill_posed = stats.ill_posed,
            misfit = stats.misfit,
            unsolved = stats.unsolved,
            inconsistent = stats.inconsistent,
            bad_input = stats.bad_input,
            evaluations = stats.network.map_or(0, |n| n.evaluations),
            time_ms = stats.time_ms,
            "de-aliased the overlap"
        );
        let refused = stats.attempted - stats.separated;
        if refused * 20 > stats.attempted.max(1) {
            let warning = format!(
                "simultaneous mode: camera {}: {refused} of {} overlap pixels could not be \
                 de-aliased ({} ill-posed, {} misfit, {} unsolved, {} inconsistent with their \
                 neighbours, {} NaN or saturated input) and are masked",
                HEAD_NAMES[h],
                stats.attempted,
                stats.ill_posed,
                stats.misfit,
                stats.unsolved,
                stats.inconsistent,
                stats.bad_input
            );
            warnings.push(warning);
        }
        samples.push(Some(DealiasSample {
            aliased,
            separated: frames.iter().take(steps).cloned().collect(),
            overlap: both.clone(),
            reference: None,
        }));
        overlaps.push(both);
        all_stats.push(stats);
    }
    Ok(ResolvedOverlap {
        overlaps,
        stats: all_stats,
        samples,
    })
}

/// What [`resolve_measured_overlap`] found, per head.
#[derive(Debug, Default)]
pub struct ResolvedOverlap {
    /// Pixels the flat fields show lit by both projectors.
    pub overlaps: Vec<Vec<bool>>,
    /// De-aliasing figures.
    pub stats: Vec<DealiasStats>,
    /// The first period's frames before and after, where a de-aliaser ran.
    pub samples: Vec<Option<DealiasSample>>,
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::demultiplex::phase_shift_rad;

    #[test]
    fn demultiplexed_frames_decode_to_each_heads_own_phase() {
        let demux = HeadBins::design_default();
        let (phi_a, phi_b) = (0.7f64, -2.1f64);
        let taken: Vec<Raster<f32>> = (0..8)
            .map(|k| {
                let v = 0.4
                    + 0.2 * (phi_a + phase_shift_rad(1, k, 8)).cos()
                    + 0.1 * (phi_b + phase_shift_rad(2, k, 8)).cos();
                Raster::filled(2, 1, v as f32)
            })
            .collect();
        for (head, want) in [(0, phi_a), (1, phi_b)] {
            let f = demultiplexed_frames(&demux, &taken, head).unwrap();
            assert_eq!(f.len(), 4);
            let s: Vec<f64> = f.iter().map(|r| r.data[0] as f64).collect();
            // 4-step decode: atan2(-(I1 - I3), I0 - I2).
            let got = (-(s[1] - s[3])).atan2(s[0] - s[2]);
            assert!((got - want).abs() < 1e-5, "head {head}: {got} vs {want}");
        }
    }

    fn take(values: &[[f32; 2]]) -> Vec<Raster<f32>> {
        values
            .iter()
            .map(|v| Raster::from_vec(2, 1, v.to_vec()).unwrap())
            .collect()
    }

    #[test]
    fn averaged_takes_are_the_mean_unless_a_take_saturated() {
        let takes = vec![
            take(&[[0.2, 0.9], [0.4, 0.1]]),
            take(&[[0.4, 1.0], [0.6, 0.3]]),
            take(&[[0.3, 0.95], [0.5, 0.2]]),
        ];
        let mean = average_takes(0, takes, 0.995).unwrap();
        assert_eq!(mean.len(), 2);
        let close = |a: f32, b: f32| (a - b).abs() < 1e-6;
        assert!(close(mean[0].data[0], 0.3), "{:?}", mean[0].data);
        // One clipped sample: the pixel keeps it, so the mask sees it.
        assert!(close(mean[0].data[1], 1.0), "{:?}", mean[0].data);
        assert!(close(mean[1].data[0], 0.5) && close(mean[1].data[1], 0.2));
        // One take passes through untouched.
        let one = average_takes(0, vec![take(&[[0.7, 0.1]])], 0.995).unwrap();
        assert_eq!(one[0].data, vec![0.7, 0.1]);
    }

    #[test]
    fn takes_of_another_count_or_size_are_refused() {
        let short = vec![take(&[[0.2, 0.9], [0.4, 0.1]]), take(&[[0.4, 1.0]])];
        assert!(matches!(
            average_takes(1, short, 0.995),
            Err(ScanError::TakesDiffer {
                head: 1,
                take: 1,
                frames: 1,
                expected: 2
            })
        ));
        let wide = vec![
            take(&[[0.2, 0.9]]),
            vec![Raster::from_vec(1, 2, vec![0.1, 0.2]).unwrap()],
        ];
        assert!(matches!(
            average_takes(0, wide, 0.995),
            Err(ScanError::TakesDiffer { take: 1, .. })
        ));
    }
}
