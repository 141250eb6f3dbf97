//! High-speed scan (seed 001): one head; per camera frame the DMD shows the 24
//! binary patterns of a [`PatternSet`] (8 directions x R, G, B LEDs, 200 us
//! each) inside one 4.8 ms colour exposure, and the host decodes 24 depth maps,
//! each at its own pattern's instant on the board clock: 24 3D frames per
//! camera frame (208 Hz camera -> 5 kHz 3D).
//!
//! ```text
//! dark + LED flats (R, G, B alone, one frame each) ──crosstalk_from_flats──> 3x3 mixing
//! 24 binary patterns ──load_coloured_sequence──> DMD table
//! protocol's multiplexed_24_at_5khz(frames) ──Board::run_plan──> board clock
//! ──Camera::take_colour_frames──> one colour exposure per frame
//! ──highspeed::Decoder──> 24 x (absolute phase, depth) per frame
//! ```
//!
//! Truth, when the caller has one (the twin), is asked for at each pattern's
//! instant, so a moving surface is measured where it was when that pattern lit it.

use std::path::PathBuf;
use std::time::Instant;

use nalgebra::{Isometry3, Matrix3, Point3};

use super::truth::{CameraTruth, TrueSphere};
use super::{Progress, ScanError};
use crate::calibration::RigCalibration;
use crate::fit::fit_sphere;
use crate::highspeed::{
    crosstalk_from_flats, Decoder, DecoderConfig, FddNet, LearnedStage, PatternSet, SetPattern,
    ZocrNet,
};
use crate::point_cloud::PointCloud;
use crate::raster::{neighbours4, Raster};
use crate::reconstruct::{ReconstructConfig, Reconstructor};
use crate::rig::{require_clean, Board, Camera, Led, Projector, WHITE};
use protocol::plan::examples::{multiplexed_24_at_5khz, FAST_FRAME_NS};
use protocol::{HeadSet, PatternSlot, ScanPlan};

/// What a high-speed scan needs besides the rig and its calibration.
#[derive(Clone, Debug)]
pub struct HighSpeedConfig {
    /// What is scanned, for the report.
    pub scene: String,
    /// Camera frames (each gives 24 instants).
    pub frames: u32,
    /// How each exposure is decoded.
    pub decoder: DecoderConfig,
    /// ZOCR-Net (seed 001's first network) in place of the analytic
    /// zero-order and crosstalk removal; checked against the rig's set
    /// before any capture.
    pub zocr: Option<ZocrNet>,
    /// FDD-Net (seed 001's third network, compact) correcting every
    /// pattern's demodulated phase; checked against the rig's set before
    /// any capture.
    pub fdd: Option<FddNet>,
}

impl HighSpeedConfig {
    /// Three camera frames, the default (analytic) decoder.
    pub fn new(scene: &str) -> Self {
        Self {
            scene: scene.to_string(),
            frames: 3,
            decoder: DecoderConfig::default(),
            zocr: None,
            fdd: None,
        }
    }
}

/// The truth at an instant (seconds on the board clock), if the caller has
/// one: the camera's per-pixel truth and the spheres where they were then.
pub type TruthAt<'a> = &'a dyn Fn(f64) -> Option<(CameraTruth, Vec<TrueSphere>)>;

/// One pattern's instant of one camera frame.
#[derive(Clone, Debug)]
pub struct InstantResult {
    /// Camera frame index.
    pub frame: usize,
    /// The pattern.
    pub pattern: SetPattern,
    /// Board-clock time of the middle of the pattern, seconds.
    pub time_s: f64,
    /// Depth (camera z), metres, NaN where not decoded.
    pub depth_m: Raster<f32>,
    /// The points, camera frame (= head A's frame).
    pub cloud: PointCloud,
    /// Figures against the truth at this instant.
    pub truth: Option<InstantTruth>,
}

/// One instant against the truth at that instant.
#[derive(Clone, Debug, PartialEq)]
pub struct InstantTruth {
    /// Object pixels (lit, not the wall) with a decoded depth, share of all.
    pub coverage: f64,
    /// Depth RMSE over decoded object pixels, metres.
    pub depth_rmse_m: f64,
    /// Median absolute depth error, metres.
    pub depth_median_m: f64,
    /// Decoded object pixels more than 1 mm off.
    pub over_1mm: usize,
    /// The same figures over the object's interior only: pixels at least
    /// [`INTERIOR_MARGIN_PX`] from any other object (where the decoder's
    /// windows see one surface).
    pub interior: InteriorTruth,
    /// Each true sphere seen with at least [`MIN_SPHERE_POINTS`] decoded points, fitted.
    pub spheres: Vec<InstantSphere>,
}

/// Depth figures over an object's interior at one instant.
#[derive(Clone, Debug, PartialEq)]
pub struct InteriorTruth {
    /// Interior object pixels.
    pub pixels: usize,
    /// Of them decoded, share.
    pub coverage: f64,
    /// Depth RMSE, metres (NaN: none decoded).
    pub depth_rmse_m: f64,
    /// Median absolute depth error, metres.
    pub depth_median_m: f64,
}

/// How far from another object (or the background) a pixel is interior: the
/// demultiplexer's windows are about this wide across a fringe (+-2 sigma).
pub const INTERIOR_MARGIN_PX: usize = 10;

/// One sphere fitted at one instant: over every decoded point the truth
/// gives it, and over its interior points only.
#[derive(Clone, Debug, PartialEq)]
pub struct InstantSphere {
    /// The sphere's name in the truth.
    pub name: String,
    /// The fit of all its decoded points.
    pub whole: SphereFit,
    /// The fit of its decoded points at least [`INTERIOR_MARGIN_PX`] from
    /// any other object, where the demultiplexer's windows see the sphere
    /// alone (`None` under [`MIN_SPHERE_POINTS`]): it tells the wrong fringe
    /// orders at the rims from the shape error inside them.
    pub interior: Option<SphereFit>,
}

/// A sphere fitted to some of its decoded points, against the truth.
#[derive(Clone, Debug, PartialEq)]
pub struct SphereFit {
    /// Points fitted.
    pub points: usize,
    /// RMS of the radial residuals, metres.
    pub fit_rmse_m: f64,
    /// Fitted minus true radius, metres.
    pub radius_error_m: f64,
    /// Fitted centre minus the true one at this instant (length), metres.
    pub centre_error_m: f64,
    /// The fitted centre, camera frame.
    pub centre_m: [f64; 3],
}

/// One camera frame.
#[derive(Clone, Debug)]
pub struct FrameResult {
    /// The colour exposure (R, G, B, full scale 1), for the pictures.
    pub exposure: [Raster<f32>; 3],
    /// Seconds decoding it took.
    pub decode_s: f64,
    /// Saturated pixels left undecoded.
    pub saturated: usize,
    /// Its 24 instants in projection order.
    pub instants: Vec<InstantResult>,
}

/// A finished high-speed scan, in memory.
#[derive(Clone, Debug)]
pub struct HighSpeedResult {
    /// What was scanned.
    pub scene: String,
    /// The measured channel <- LED crosstalk.
    pub crosstalk: Matrix3<f64>,
    /// Patterns per second (the 3D rate).
    pub pattern_rate_hz: f64,
    /// Camera frames per second.
    pub camera_rate_hz: f64,
    /// The frames.
    pub frames: Vec<FrameResult>,
    /// Whether figures are against the twin's truth calibration.
    pub calibration_is_true: bool,
    /// The conventional capture of the same motion, when one was run
    /// ([`run_conventional`]).
    pub conventional: Option<ConventionalResult>,
    /// ZOCR-Net's file when it did the decoder's first stage (`None`: the
    /// analytic zero-order and crosstalk removal).
    pub zocr_model: Option<PathBuf>,
    /// FDD-Net's file when it corrected the demodulated phases.
    pub fdd_model: Option<PathBuf>,
    /// Demodulations after the first, each by the last one's phase
    /// ([`crate::highspeed::DemuxOptions::refinements`]).
    pub demodulation_refinements: u32,
    /// Passes of sibling cancellation after the first demodulation
    /// ([`crate::highspeed::DemuxOptions::cancellations`]).
    pub sibling_cancellations: u32,
    /// Decodes after the first on carriers predicted from the last
    /// ([`crate::highspeed::DecoderConfig::consensus_passes`]).
    pub consensus_passes: u32,
    /// Whether the consensus passes settled their holes at depth edges
    /// ([`crate::highspeed::DecoderConfig::settle_edges`]).
    pub settle_edges: bool,
}

/// Minimum points on a sphere for a fit at one instant.
pub const MIN_SPHERE_POINTS: usize = 300;

/// Runs a high-speed scan on head A of `rig`.
pub fn run_high_speed<R: Board + Projector + Camera>(
    rig: &mut R,
    config: &HighSpeedConfig,
    calibration: &RigCalibration,
    truth_at: Option<TruthAt<'_>>,
    progress: &mut dyn FnMut(Progress),
) -> Result<HighSpeedResult, ScanError> {
    if calibration.heads.len() != 1 {
        return Err(ScanError::HighSpeedNeedsOneHead {
            heads: calibration.heads.len(),
        });
    }
    let head = &calibration.heads[0];
    let dmd = rig.dmd_size_px(0)?;
    let set = PatternSet::seed001(dmd)?;
    let mut decoder = Decoder::new(set.clone(), head, config.decoder)?;
    if let Some(net) = &config.zocr {
        check_stage(net, &set, decoder.size())?;
        decoder = decoder.with_zocr(net.clone());
    }
    if let Some(net) = &config.fdd {
        check_stage(net, &set, decoder.size())?;
        decoder = decoder.with_fdd(net.clone())?;
    }
    let clock_hz = rig
        .limits()
        .map_or(170_000_000.0, |l| f64::from(l.timer_clock_hz));

    progress(Progress::Stage {
        name: "LED flats",
        total: 1,
    });
    let white = Raster::filled(dmd.0 as usize, dmd.1 as usize, 1.0f32);
    let black = Raster::filled(dmd.0 as usize, dmd.1 as usize, 0.0f32);
    let leds: [Led; 4] = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    rig.load_coloured_sequence(0, &[black, white.clone(), white.clone(), white], &leds)?;
    require_clean(&rig.run_plan(&led_flats_plan())?)?;
    let flats = rig.take_colour_frames(0)?;
    if flats.len() != 4 {
        return Err(ScanError::FlatFields {
            head: "A",
            frames: flats.len(),
        });
    }
    // Each LED's flat less the dark frame: ambient light is white and would
    // read as crosstalk.
    let lit: Vec<[Vec<f32>; 3]> = flats[1..]
        .iter()
        .map(|flat| {
            [0, 1, 2].map(|c| {
                flat[c]
                    .data
                    .iter()
                    .zip(&flats[0][c].data)
                    .map(|(v, d)| {
                        if *v >= config.decoder.saturation_level {
                            *v
                        } else {
                            v - d
                        }
                    })
                    .collect()
            })
        })
        .collect();
    let view = |l: usize| [&lit[l][0][..], &lit[l][1][..], &lit[l][2][..]];
    let crosstalk =
        crosstalk_from_flats([view(0), view(1), view(2)], config.decoder.saturation_level)?;
    progress(Progress::Done);

    // The flats' crosstalk goes into the decoder that reads the fringes.
    let decoder = decoder.with_crosstalk(crosstalk)?;

    progress(Progress::Stage {
        name: "capture",
        total: 1,
    });
    rig.load_coloured_sequence(0, &set.binary_frames(), &set.leds())?;
    let plan = multiplexed_24_at_5khz(config.frames.max(1));
    let outcome = rig.run_plan(&plan)?;
    require_clean(&outcome)?;
    let exposures = rig.take_colour_frames(0)?;
    progress(Progress::Done);
    let times = instant_times_s(&plan, outcome.start_tick as f64 / clock_hz);

    progress(Progress::Stage {
        name: "decode",
        total: exposures.len() as u64,
    });
    let mut frames = Vec::with_capacity(exposures.len());
    for (f, exposure) in exposures.into_iter().enumerate() {
        let started = Instant::now();
        let decoded = decoder.decode([&exposure[0], &exposure[1], &exposure[2]])?;
        let decode_s = started.elapsed().as_secs_f64();
        let (w, h) = decoder.size();
        let instants = decoded
            .instants
            .into_iter()
            .map(|instant| {
                let time_s = times
                    .get(f * set.patterns().len() + instant.pattern.index)
                    .copied()
                    .unwrap_or(f64::NAN);
                let depth_m = Raster {
                    width: w,
                    height: h,
                    data: instant.depth_m,
                };
                let cloud = cloud_of(&decoder, &depth_m);
                let truth = truth_at.and_then(|t| t(time_s)).map(|(truth, spheres)| {
                    measure_instant(&|i, z| decoder.point(i, z), &depth_m, &truth, &spheres)
                });
                InstantResult {
                    frame: f,
                    pattern: instant.pattern,
                    time_s,
                    depth_m,
                    cloud,
                    truth,
                }
            })
            .collect();
        frames.push(FrameResult {
            exposure,
            decode_s,
            saturated: decoded.saturated,
            instants,
        });
        progress(Progress::Step);
    }
    progress(Progress::Done);
    let slot_ns = plan
        .slots
        .first()
        .map_or(f64::NAN, |s| f64::from(s.display_ns));
    Ok(HighSpeedResult {
        scene: config.scene.clone(),
        crosstalk,
        pattern_rate_hz: 1e9 / slot_ns,
        camera_rate_hz: 1e9 / f64::from(FAST_FRAME_NS),
        frames,
        calibration_is_true: false,
        conventional: None,
        zocr_model: decoder.zocr().map(|n| n.path().to_path_buf()),
        fdd_model: decoder.fdd().map(|n| n.path().to_path_buf()),
        demodulation_refinements: config.decoder.demux.refinements,
        sibling_cancellations: config.decoder.demux.cancellations,
        consensus_passes: config.decoder.consensus_passes,
        settle_edges: config.decoder.settle_edges,
    })
}

/// A learned stage must fit the rig's pattern set; one trained at another
/// camera size runs with a warning.
fn check_stage(
    net: &impl LearnedStage,
    set: &PatternSet,
    (width, height): (usize, usize),
) -> Result<(), ScanError> {
    net.check_set(set)?;
    if let Some(warning) = net.size_warning(width, height) {
        tracing::warn!("{warning}");
    }
    Ok(())
}

/// How long the DMD shows each of the 24 patterns (the plan's shortest
/// slot), microseconds: the exposure a DMD controller's pattern table must
/// not exceed. Its LED flats (1.5 ms slots) are then lit this long too, which
/// dims them but leaves the channel ratios they measure as they are.
pub fn pattern_display_us() -> u32 {
    let plan = multiplexed_24_at_5khz(1);
    let ns = plan.slots.iter().map(|s| s.display_ns).min().unwrap_or(0);
    ns.div_ceil(1000)
}

/// Four frames of the 208 Hz camera on the high-speed wiring: a dark one
/// (pattern 0, no LED) and each LED's white flat (patterns 1, 2, 3), 1.5 ms
/// each: an LED alone then fills its channel nearly as far as the multiplexed
/// exposure's brightest pixels (all eight of its patterns on, 1.6 ms) do, and
/// its weak leak into the other channels stays well above the 8-bit step.
pub fn led_flats_plan() -> ScanPlan {
    short_exposures_plan(4)
}

/// How long [`short_exposures_plan`] shows each pattern, nanoseconds.
const SHORT_DISPLAY_NS: u32 = 1_500_000;

/// `count` frames of the 208 Hz camera on the high-speed wiring, each a
/// 1.6 ms exposure showing pattern `k` for 1.5 ms.
fn short_exposures_plan(count: u32) -> ScanPlan {
    let base = multiplexed_24_at_5khz(1);
    let mut plan = ScanPlan::new(&base.heads, 1, count * FAST_FRAME_NS, base.margin_ns)
        .expect("the high-speed wiring is valid");
    let first = base.exposures[0];
    for k in 0..count {
        let slot = PatternSlot {
            pattern_index: k as u16,
            offset_ns: first.start_ns,
            display_ns: SHORT_DISPLAY_NS,
        };
        plan.push_exposure(
            HeadSet::A,
            first.start_ns + k * FAST_FRAME_NS,
            1_600_000,
            &[slot],
        )
        .expect("short exposures fit their frames");
    }
    plan
}

/// A conventional capture of the same head at the same camera rate, for
/// comparison: 12 grey fringes (3 periods x 4 steps, white light), one per
/// 208 Hz frame, decoded into one depth map by the sequential pipeline. A
/// surface that moves during its 58 ms is smeared; on the twin it is
/// measured against the truth at the capture's middle.
#[derive(Clone, Debug)]
pub struct ConventionalResult {
    /// Camera frames (12).
    pub frames: usize,
    /// From the first pattern's start to the last one's end, seconds.
    pub duration_s: f64,
    /// Board-clock time of the middle of the capture, seconds.
    pub time_s: f64,
    /// Depth (camera z), metres, NaN where not decoded.
    pub depth_m: Raster<f32>,
    /// Figures against the truth at the middle of the capture.
    pub truth: Option<InstantTruth>,
}

/// How the conventional capture is decoded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConventionalConfig {
    /// Noise of a half-scale grey sample, full-scale units: the fringe-order
    /// check refuses what this noise could miscount, so it should be the
    /// camera's own.
    pub noise_sigma: f32,
    /// Share of its variance that is shot noise (0..=1).
    pub shot_noise_share: f32,
    /// Depths kept (camera z, metres): the high-speed decoder's working
    /// range, so both captures answer for the same volume.
    pub depth_range_m: (f64, f64),
}

/// Runs the conventional capture of [`ConventionalResult`] on head A of
/// `rig` (after or instead of a high-speed scan).
pub fn run_conventional<R: Board + Projector + Camera>(
    rig: &mut R,
    calibration: &RigCalibration,
    config: &ConventionalConfig,
    truth_at: Option<TruthAt<'_>>,
    progress: &mut dyn FnMut(Progress),
) -> Result<ConventionalResult, ScanError> {
    if calibration.heads.len() != 1 {
        return Err(ScanError::HighSpeedNeedsOneHead {
            heads: calibration.heads.len(),
        });
    }
    let head = &calibration.heads[0];
    let dmd = rig.dmd_size_px(0)?;
    let periods = super::default_periods_px(dmd.0);
    let mut rc_config = ReconstructConfig::new(periods.clone());
    rc_config.noise_sigma = config.noise_sigma;
    rc_config.shot_noise_share = config.shot_noise_share;
    let failed = |source| ScanError::Reconstruct { head: "A", source };
    let reconstructor = Reconstructor::from_head(head, rc_config.clone()).map_err(failed)?;
    let patterns = super::plan::fringe_sequence(dmd, &periods, rc_config.steps);
    let clock_hz = rig
        .limits()
        .map_or(170_000_000.0, |l| f64::from(l.timer_clock_hz));
    progress(Progress::Stage {
        name: "conventional capture",
        total: 1,
    });
    rig.load_coloured_sequence(0, &patterns, &vec![WHITE; patterns.len()])?;
    let plan = short_exposures_plan(patterns.len() as u32);
    let outcome = rig.run_plan(&plan)?;
    require_clean(&outcome)?;
    let frames = rig.take_frames(0)?;
    progress(Progress::Done);
    // The plan has one slot per pattern; a camera that sent another number
    // of frames is refused by the reconstructor's frame count.
    let start_s = outcome.start_tick as f64 / clock_hz;
    let times = instant_times_s(&plan, start_s);
    let first = times.first().copied().unwrap_or(start_s);
    let last = times.last().copied().unwrap_or(start_s);
    let display_s = f64::from(SHORT_DISPLAY_NS) * 1e-9;
    let time_s = 0.5 * (first + last);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let mut depth_m = reconstructor
        .reconstruct(&refs, None)
        .map_err(failed)?
        .depth_m();
    let (near, far) = config.depth_range_m;
    for z in &mut depth_m.data {
        if !(near..=far).contains(&f64::from(*z)) {
            *z = f32::NAN;
        }
    }
    let rays = head.camera.normalised_grid();
    let point = |i: usize, z: f32| {
        let r = rays[i];
        [r[0] as f32 * z, r[1] as f32 * z, z]
    };
    let truth = truth_at
        .and_then(|t| t(time_s))
        .map(|(truth, spheres)| measure_instant(&point, &depth_m, &truth, &spheres));
    Ok(ConventionalResult {
        frames: frames.len(),
        duration_s: last - first + display_s,
        time_s,
        depth_m,
        truth,
    })
}

/// Board-clock time (s) of the middle of every slot, in display order over
/// all cycles, for a plan started at `start_s`.
pub fn instant_times_s(plan: &ScanPlan, start_s: f64) -> Vec<f64> {
    let period_s = f64::from(plan.repeat_period_ns) * 1e-9;
    (0..plan.repeat_count)
        .flat_map(|cycle| {
            plan.exposures().flat_map(move |e| {
                let start_ns = f64::from(e.entry.start_ns);
                e.slots.iter().map(move |s| {
                    start_s
                        + f64::from(cycle) * period_s
                        + (start_ns + f64::from(s.offset_ns) + 0.5 * f64::from(s.display_ns)) * 1e-9
                })
            })
        })
        .collect()
}

/// The decoded points of one instant, camera frame.
fn cloud_of(decoder: &Decoder, depth: &Raster<f32>) -> PointCloud {
    let points_m = depth
        .data
        .iter()
        .enumerate()
        .filter(|(_, z)| z.is_finite())
        .map(|(i, &z)| decoder.point(i, z))
        .collect();
    PointCloud {
        points_m,
        ..PointCloud::default()
    }
}

/// One instant's depth against the truth at that instant (both in the camera
/// frame: the truth's points carried by its camera pose).
fn measure_instant(
    point: &dyn Fn(usize, f32) -> [f32; 3],
    depth: &Raster<f32>,
    truth: &CameraTruth,
    spheres: &[TrueSphere],
) -> InstantTruth {
    let cam: &Isometry3<f64> = &truth.camera_from_world;
    let interior = interior_pixels(&truth.object, truth.width, INTERIOR_MARGIN_PX);
    let mut errors = Vec::new();
    let mut interior_errors = Vec::new();
    let (mut object, mut interior_object) = (0usize, 0usize);
    for (i, &z) in depth.data.iter().enumerate() {
        if !truth.own_object.get(i).copied().unwrap_or(false) {
            continue;
        }
        let inside = interior.get(i).copied().unwrap_or(false);
        object += 1;
        interior_object += usize::from(inside);
        if !z.is_finite() {
            continue;
        }
        let p = truth.point_m[i];
        let true_z = (cam * Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))).z;
        errors.push(f64::from(z) - true_z);
        if inside {
            interior_errors.push(f64::from(z) - true_z);
        }
    }
    let (rmse, median) = rmse_and_median(&errors);
    let abs: Vec<f64> = errors.iter().map(|e| e.abs()).collect();
    let (interior_rmse, interior_median) = rmse_and_median(&interior_errors);
    let spheres = spheres
        .iter()
        .filter_map(|s| {
            let fit = |keep: &dyn Fn(usize) -> bool| {
                let points: Vec<Point3<f64>> = depth
                    .data
                    .iter()
                    .enumerate()
                    .filter(|&(i, z)| {
                        z.is_finite() && truth.object.get(i) == Some(&s.object) && keep(i)
                    })
                    .map(|(i, &z)| Point3::from(point(i, z).map(f64::from)))
                    .collect();
                if points.len() < MIN_SPHERE_POINTS {
                    return None;
                }
                let fit = fit_sphere(&points)?;
                let centre_true = cam * Point3::from(s.centre_m);
                Some(SphereFit {
                    points: points.len(),
                    fit_rmse_m: fit.rms_m,
                    radius_error_m: fit.radius_m - s.radius_m,
                    centre_error_m: (fit.centre_m - centre_true).norm(),
                    centre_m: fit.centre_m.coords.into(),
                })
            };
            Some(InstantSphere {
                name: s.name.clone(),
                whole: fit(&|_| true)?,
                interior: fit(&|i| interior.get(i).copied().unwrap_or(false)),
            })
        })
        .collect();
    InstantTruth {
        coverage: errors.len() as f64 / object.max(1) as f64,
        depth_rmse_m: rmse,
        depth_median_m: median,
        over_1mm: abs.iter().filter(|&&e| e > 1e-3).count(),
        interior: InteriorTruth {
            pixels: interior_object,
            coverage: interior_errors.len() as f64 / interior_object.max(1) as f64,
            depth_rmse_m: interior_rmse,
            depth_median_m: interior_median,
        },
        spheres,
    }
}

/// RMS and median absolute value of `errors` (NaN, NaN when empty).
fn rmse_and_median(errors: &[f64]) -> (f64, f64) {
    if errors.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let rmse = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    let mut abs: Vec<f64> = errors.iter().map(|e| e.abs()).collect();
    abs.sort_by(f64::total_cmp);
    (rmse, abs[abs.len() / 2])
}

/// Per pixel of a row-major `width`-wide object map: no pixel within
/// `margin` (Chebyshev distance) shows another object or lies off the image.
fn interior_pixels(object: &[u16], width: usize, margin: usize) -> Vec<bool> {
    if width == 0 {
        return Vec::new();
    }
    let height = object.len() / width;
    // A pixel is an edge when a 4-neighbour differs or it is on the border.
    let edge: Vec<bool> = (0..width * height)
        .map(|i| {
            neighbours4(i, width, height)
                .into_iter()
                .any(|n| n.is_none_or(|j| object[j] != object[i]))
        })
        .collect();
    // Grow the edges by `margin` along rows, then along columns.
    let grow = |mask: &[bool], step: usize, len: usize, lines: usize, stride: usize| {
        let mut out = vec![false; mask.len()];
        for line in 0..lines {
            let at = |k: usize| line * stride + k * step;
            let mut last_edge: Option<usize> = None;
            for k in 0..len {
                if mask[at(k)] {
                    last_edge = Some(k);
                }
                out[at(k)] |= last_edge.is_some_and(|e| k - e <= margin);
            }
            last_edge = None;
            for k in (0..len).rev() {
                if mask[at(k)] {
                    last_edge = Some(k);
                }
                out[at(k)] |= last_edge.is_some_and(|e| e - k <= margin);
            }
        }
        out
    };
    let rows = grow(&edge, 1, width, height, width);
    let near = grow(&rows, width, height, width, 1);
    near.iter().map(|&n| !n).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn instants_are_the_slots_middles_cycle_after_cycle() {
        let plan = multiplexed_24_at_5khz(2);
        let t = instant_times_s(&plan, 1.0);
        assert_eq!(t.len(), 48);
        // 2 us lead + 2 us offset + 100 us half slot.
        assert!((t[0] - (1.0 + 104e-6)).abs() < 1e-12, "{}", t[0]);
        assert!((t[1] - t[0] - 200e-6).abs() < 1e-12);
        assert!((t[24] - t[0] - f64::from(FAST_FRAME_NS) * 1e-9).abs() < 1e-12);
    }

    #[test]
    fn interior_keeps_pixels_a_margin_away_from_other_objects() {
        // 20x12, object 1 in columns 5..15 of rows 2..10, background 0.
        let (w, h) = (20, 12);
        let object: Vec<u16> = (0..w * h)
            .map(|i| u16::from((5..15).contains(&(i % w)) && (2..10).contains(&(i / w))))
            .collect();
        let inside = interior_pixels(&object, w, 2);
        let kept: Vec<(usize, usize)> = (0..w * h)
            .filter(|&i| inside[i])
            .map(|i| (i % w, i / w))
            .collect();
        // Object 1: edges at x 5, 14 and y 2, 9; 2 px inside them leaves x 8..=11, y 5..=6.
        let expected_object: Vec<(usize, usize)> = (5..=6)
            .flat_map(|y| (8..=11).map(move |x| (x, y)))
            .collect();
        let object_kept: Vec<_> = kept
            .iter()
            .copied()
            .filter(|&(x, y)| object[y * w + x] == 1)
            .collect();
        assert_eq!(object_kept, expected_object);
        // The background is a strip at most 4 px wide between the object and
        // the image border: none of it is interior.
        assert!(kept.iter().all(|&(x, y)| object[y * w + x] == 1));
    }

    #[test]
    fn the_interior_fit_leaves_out_wrong_rims() {
        // A 60x60 view (1 mm per pixel, orthographic) of a 25 mm sphere 0.5 m
        // away before a background; the outer 5 px of its disc decoded 5 mm
        // too deep, as wrong fringe orders at a rim are.
        let (w, radius) = (60usize, 0.025);
        let xy = |i: usize| {
            [
                ((i % w) as f64 - 30.0) * 1e-3,
                ((i / w) as f64 - 30.0) * 1e-3,
            ]
        };
        let on_sphere = |i: usize| xy(i)[0].hypot(xy(i)[1]) < radius;
        let true_z =
            |i: usize| 0.5 - (radius * radius - xy(i)[0].powi(2) - xy(i)[1].powi(2)).sqrt();
        let n = w * w;
        let truth = CameraTruth {
            width: w,
            height: w,
            camera_from_world: Isometry3::identity(),
            point_m: (0..n)
                .map(|i| {
                    [
                        xy(i)[0] as f32,
                        xy(i)[1] as f32,
                        if on_sphere(i) { true_z(i) } else { 0.6 } as f32,
                    ]
                })
                .collect(),
            normal: vec![[0.0, 0.0, -1.0]; n],
            object: (0..n).map(|i| if on_sphere(i) { 0 } else { 1 }).collect(),
            own_object: (0..n).map(on_sphere).collect(),
            overlap: vec![false; n],
        };
        let depth = Raster {
            width: w,
            height: w,
            data: (0..n)
                .map(|i| {
                    let r = xy(i)[0].hypot(xy(i)[1]);
                    let rim = if r > radius - 0.005 { 0.005 } else { 0.0 };
                    if on_sphere(i) {
                        (true_z(i) + rim) as f32
                    } else {
                        f32::NAN
                    }
                })
                .collect(),
        };
        let sphere = TrueSphere {
            name: "s".into(),
            object: 0,
            centre_m: [0.0, 0.0, 0.5],
            radius_m: radius,
        };
        let point = |i: usize, z: f32| [xy(i)[0] as f32, xy(i)[1] as f32, z];
        let t = measure_instant(&point, &depth, &truth, &[sphere]);
        let s = &t.spheres[0];
        let inner = s.interior.as_ref().expect("an interior fit");
        assert!(s.whole.fit_rmse_m > 5e-4, "whole {:?}", s.whole);
        assert!(inner.points < s.whole.points);
        // Only the f32 rounding of the points is left inside.
        assert!(inner.fit_rmse_m < 2e-6, "interior {inner:?}");
        assert!(inner.radius_error_m.abs() < 1e-5, "interior {inner:?}");
    }

    #[test]
    fn the_flats_plan_validates() {
        let plan = led_flats_plan();
        assert_eq!(plan.exposures.len(), 4);
        assert_eq!(plan.slots.len(), 4);
    }
}
