//! A whole scan: plan -> capture -> reconstruct -> fuse -> measure.
//!
//! ```text
//! RigCalibration (a rig file from `calibrate`; sim default: the twin's truth)
//! per head (sequential mode: head A alone, then head B alone, ...):
//!   fringe set ──Projector::load_sequence──> DMD table
//!   plan (one pattern per exposure) ──Board::run_plan──> board-clock timeline
//!   ──Camera::take_frames──> one frame per trigger ──Reconstructor──> cloud
//! clouds A, B ──fusion::fuse_heads (ICP from the calibrated B->A)──> fused cloud
//! clouds A..D (3-4 heads) ──fusion::register_views (every pose at once,
//!   from the calibrated ones)──merge_views──> fused cloud
//! every cloud ──truth_frame (rigid fit of its frame)──metrics (twin ground truth,
//!   when there is one)──> RMSE, coverage
//! ```
//!
//! [`run_on_rig`] does it on any rig ([`crate::rig`]'s traits) with a given
//! calibration and an optional ground truth (plain data, [`GroundTruth`]);
//! `crate::sim::scan::run_sim` builds the simulated rig and the twin's truth
//! around it; on hardware the caller builds a
//! [`crate::rig::hardware::HardwareRig`] and passes no truth (the report's
//! truth figures are then null). Either returns a [`ScanResult`] in memory;
//! [`output::write_scan`] writes it (every file via a temporary and a
//! rename, `scan.ply` last), so a failed scan writes no `scan.ply`.

mod adaptive_capture;
pub mod aliasing;
pub mod calibration_file;
pub mod capture;
pub mod clouds;
pub mod dealias_picture;
pub mod exposure;
mod fuse;
mod fuse_views;
pub mod high_speed;
pub mod high_speed_output;
pub mod measure;
pub mod metrics;
pub mod output;
pub mod plan;
mod reconstruct_head;
pub mod self_check;
pub mod spheres;
pub mod truth;
pub mod truth_frame;
pub mod underwater;

use std::time::Instant;

use crate::board::ClientConfig;
use crate::calibration::RigCalibration;
use crate::fusion::{FusionError, IcpResult};
use crate::patterns::three_pitch_periods_px;
use crate::point_cloud::PointCloud;
use crate::raster::Raster;
use crate::reconstruct::{ReconstructError, Reconstruction};
use crate::rig::{Board, Camera, Projector, RigError};
use clouds::transformed;
pub use exposure::{AutoExposure, ExposureFigures, Exposures};
use metrics::PixelAccuracy;
pub(crate) use reconstruct_head::head_reconstructor;
use reconstruct_head::reconstruct_head;
pub use truth::{CameraTruth, GroundTruth};

/// Head names in plan order, one per head a plan may have
/// (`protocol::limits::MAX_HEADS`).
pub const HEAD_NAMES: [&str; protocol::limits::MAX_HEADS] = ["A", "B", "C", "D"];

/// How the heads share time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Head A alone, then head B alone, and so on (seed 000's reference
    /// runs): no aliasing.
    Sequential,
    /// Both heads at once with identical sequences: the overlap is aliased,
    /// de-aliased per pixel or masked ([`ScanConfig::dealias`]).
    Simultaneous,
    /// All heads at once, each head's shifts on its own temporal frequency
    /// (two heads: N = 8, A on 1, B on 2; three or four: the fewest steps
    /// whose bins are safe against gamma's 2nd and 3rd harmonics),
    /// separated per pixel by [`crate::demultiplex`].
    SimultaneousMultiplexed,
}

/// Everything a scan needs besides the rig and its calibration.
#[derive(Clone, Debug)]
pub struct ScanConfig {
    /// What is scanned, for the report: a twin scene's name, or "hardware".
    pub scene: String,
    /// Time sharing of the heads.
    pub mode: Mode,
    /// Camera image size (width, height), pixels.
    pub camera_px: (u32, u32),
    /// Projector DMD size (width, height), pixels.
    pub projector_px: (u32, u32),
    /// Fringe periods, projector pixels, finest first.
    pub periods_px: Vec<f64>,
    /// Phase steps per period.
    pub steps: usize,
    /// Camera noise at half scale, frame units (what the reconstruction's
    /// noise prediction and order checks assume).
    pub noise_sigma: f32,
    /// Share of that noise's variance that is shot noise (see
    /// [`crate::reconstruct::ReconstructConfig::shot_noise_share`]): each point's predicted
    /// sigma then follows its pixel's own level.
    pub shot_noise_share: f32,
    /// Timeouts of the board client.
    pub client: ClientConfig,
    /// Projector response the patterns are pre-compensated for (each grey
    /// level g sent as g^(1/gamma)); `None` sends linear patterns.
    pub precompensate_gamma: Option<f64>,
    /// Simultaneous mode: how pixels the other projector lights are treated.
    pub dealias: crate::dealias::DealiasMethod,
    /// The network of [`crate::dealias::DealiasMethod::Learned`], loaded
    /// and checked before the scan (`None` otherwise).
    pub learned: Option<std::sync::Arc<crate::dealias::learned::LearnedDealiaser>>,
    /// How each head's fringes are exposed (sequential mode): once, at
    /// several exposures, or adapted per projector pixel.
    pub exposures: Exposures,
    /// Frames taken of every fringe pattern and averaged before decoding
    /// (sequential mode, single, multi or auto exposure; 1: no averaging). N
    /// frames cut the camera noise by sqrt(N) where one exposure cannot be
    /// made longer: what a turbid-water scan at the plan's longest exposure
    /// needs.
    pub frames_per_pattern: usize,
    /// Frame value at and above which a sample counts as saturated; a pixel
    /// with one in its fringe set is masked.
    pub saturation_level: f32,
    /// What the heads look through: air, or water behind flat ports (each
    /// set restored, every pixel triangulated through the ports).
    pub medium: underwater::Medium,
}

impl ScanConfig {
    /// Sequential scan of `scene` at 640x480 / 1280x800 with
    /// [`default_periods_px`], camera noise 0.01 at half scale, all of it
    /// taken as read noise (the hardware CLI's defaults; a simulated scan
    /// sets its twin sensor's figures). (Seed 000's 100/110/120/130 px set
    /// works too, but its coarse fringes give about 5x the depth noise here.)
    pub fn new(scene: &str) -> Self {
        ScanConfig {
            scene: scene.to_string(),
            mode: Mode::Sequential,
            camera_px: (640, 480),
            projector_px: (1280, 800),
            periods_px: default_periods_px(1280),
            steps: 4,
            noise_sigma: 0.01,
            shot_noise_share: 0.0,
            client: ClientConfig {
                attempt_timeout: std::time::Duration::from_secs(2),
                attempts: 3,
            },
            precompensate_gamma: None,
            dealias: crate::dealias::DealiasMethod::default(),
            learned: None,
            exposures: Exposures::Single,
            frames_per_pattern: 1,
            saturation_level: DEFAULT_SATURATION_LEVEL,
            medium: underwater::Medium::Air,
        }
    }
}

/// Most frames a scan averages per pattern (16 cut the noise by 4x; more
/// would hold a sequential head for seconds per set).
pub const MAX_FRAMES_PER_PATTERN: usize = 16;

/// Frame averaging runs in the sequential mode's fixed or auto exposures,
/// 1 to [`MAX_FRAMES_PER_PATTERN`] frames.
fn check_frames_per_pattern(config: &ScanConfig) -> Result<(), ScanError> {
    let frames = config.frames_per_pattern;
    let why = if !(1..=MAX_FRAMES_PER_PATTERN).contains(&frames) {
        "give 1 to 16"
    } else if frames > 1
        && (config.mode != Mode::Sequential
            || !matches!(
                config.exposures,
                Exposures::Single | Exposures::Multi(_) | Exposures::Auto(_)
            ))
    {
        "averaging runs in the sequential mode with single, multi or auto exposure"
    } else {
        return Ok(());
    };
    Err(ScanError::FramesPerPattern { frames, why })
}

/// Samples at or above 99.5 % of full scale count as saturated: a sensor
/// that clips reads full scale there, and noise alone does not reach it
/// from a level that would decode.
pub const DEFAULT_SATURATION_LEVEL: f32 = 0.995;

/// Seed 004's three pitches over the DMD width, S = 64 fringes: about
/// 17.5 / 20 / 22.9 px on a 1280 px DMD, one beat spanning the width.
/// (On `large-part` at 320x240: S = 36 gives 1.6x the depth noise, seed
/// 000's 100/110/120/130 px set about 5x.)
pub fn default_periods_px(dmd_width_px: u32) -> Vec<f64> {
    three_pitch_periods_px(f64::from(dmd_width_px), 64).to_vec()
}

/// The simultaneous mode's default with analytic de-aliasing: four periods
/// of 73, 64, 56 and 50 fringes over the DMD width (17.5 / 20 / 22.9 /
/// 25.6 px on 1280 px). Three periods give 6 real numbers per pixel for the
/// 4 unknowns and leave many pixels with several solutions; these four
/// beat down to one fringe over the width (differences 9, 8, 6; then 1, 2;
/// then 1), so heterodyne unwraps each projector's phases.
pub fn dealias_periods_px(dmd_width_px: u32) -> Vec<f64> {
    [73.0, 64.0, 56.0, 50.0]
        .iter()
        .map(|fringes| f64::from(dmd_width_px) / fringes)
        .collect()
}

/// What can stop a scan.
#[derive(Debug, thiserror::Error)]
pub enum ScanError {
    /// A scan needs a calibration of one head, or of as many as the sync
    /// board has trigger lines for.
    #[error("the calibration has {heads} head(s); the sync board drives 1 to {} (two trigger lines each, protocol::limits::MAX_HEADS)", protocol::limits::MAX_HEADS)]
    HeadCount {
        /// Heads in the calibration.
        heads: usize,
    },
    /// The rig has more heads than the connected sync board has lines for.
    #[error("the rig has {heads} heads; the sync board has {output_channels} trigger lines and {feedback_channels} feedback lines (two of each per head): {max_heads} heads")]
    TooManyHeadsForBoard {
        /// Heads in the calibration.
        heads: usize,
        /// The board's trigger outputs.
        output_channels: u8,
        /// The board's feedback inputs.
        feedback_channels: u8,
        /// Heads those lines drive.
        max_heads: usize,
    },
    /// Simultaneous mode with identical sequences de-aliases two
    /// projectors, not more.
    #[error("mode simultaneous (identical sequences, de-aliased per pixel) separates two projectors; a rig of {heads} heads scans sequential or simultaneous-multiplexed")]
    SimultaneousNeedsTwo {
        /// Heads in the calibration.
        heads: usize,
    },
    /// The de-aliasing network failed to run.
    #[error("learned de-aliasing")]
    Network(#[source] crate::infer::ModelError),
    /// `--dealias learned` without a loaded network.
    #[error("learned de-aliasing needs a model (--dealias-model)")]
    NoLearnedModel,
    /// Every head after the first needs its pose from head A.
    #[error("the calibration has {heads} heads but {poses} head pose(s) from head A (need {})", heads - 1)]
    NoHeadPoses {
        /// Heads in the calibration.
        heads: usize,
        /// Poses it has.
        poses: usize,
    },
    /// Simultaneous modes share the time of two or more heads.
    #[error("mode {mode:?} runs two or more heads at once; a one-head rig scans sequentially")]
    ModeNeedsTwoHeads {
        /// The mode asked for.
        mode: Mode,
    },
    /// A camera delivered another number of flat-field frames than the
    /// plan's three.
    #[error("head {head}: {frames} flat-field frames, not as many as the plan exposed")]
    FlatFields {
        /// Head name.
        head: &'static str,
        /// Frames found after the fringes.
        frames: usize,
    },
    /// Demultiplexing a camera's frames failed.
    #[error("demultiplex head {head}")]
    Demultiplex {
        /// Head name.
        head: &'static str,
        /// Why.
        source: crate::demultiplex::DemuxError,
    },
    /// A fringe period that cannot be projected (or none at all).
    #[error("fringe period {period} px: give one or more periods of at least 2 projector pixels (--periods)")]
    BadPeriod {
        /// The offending period (NaN when none was given).
        period: f64,
    },
    /// A pre-compensation gamma that is not a positive finite number.
    #[error("pre-compensation gamma {gamma} is not a positive finite number")]
    BadGamma {
        /// The value given.
        gamma: f64,
    },
    /// The plan could not be built.
    #[error("plan")]
    Plan(#[from] plan::PlanBuildError),
    /// Several exposures and adaptive projection take one head at a time.
    #[error("{exposures} exposure needs the sequential mode, not {mode:?}")]
    ExposuresNeedSequential {
        /// The mode asked for.
        mode: Mode,
        /// The exposure kind asked for.
        exposures: &'static str,
    },
    /// A multi-exposure scan without exposures.
    #[error("a multi-exposure scan needs at least one exposure scale")]
    NoExposures,
    /// The takes of an averaged capture differ in frame count or size.
    #[error("head {head}: take {take} of the averaged frames has {frames} frames or another size than the first ({expected} frames)")]
    TakesDiffer {
        /// Head index.
        head: usize,
        /// The take that differs.
        take: usize,
        /// Its frame count.
        frames: usize,
        /// The first take's frame count.
        expected: usize,
    },
    /// Frame averaging out of range, or asked of a capture that does not
    /// average.
    #[error("{frames} frames per pattern: {why}")]
    FramesPerPattern {
        /// The count asked for.
        frames: usize,
        /// What is wrong with it.
        why: &'static str,
    },
    /// Auto exposure's settings are out of range.
    #[error("{0}")]
    AutoExposure(String),
    /// Adaptive projection could not adapt (bad preliminaries or parameters).
    #[error("adaptive projection")]
    Adaptive(#[from] crate::adaptive::AdaptiveError),
    /// A saturation level outside (0, 1].
    #[error("saturation level {0} must be in (0, 1] (frame units)")]
    SaturationLevel(f32),
    /// Board, projector or camera failed (board silent, missing frame, ...).
    #[error("rig")]
    Rig(#[from] RigError),
    /// Epipolar or analytic de-aliasing needs more periods than the scan has.
    #[error("de-aliasing needs at least {} fringe periods (2 reals each; with three, many pixels have several solutions), the scan has {periods}; give more --periods or --dealias mask", crate::dealias::analytic::MIN_PERIODS)]
    DealiasPeriods {
        /// Periods of the scan.
        periods: usize,
    },
    /// The de-aliaser could not be set up for the period set.
    #[error("de-aliaser")]
    Dealias(#[source] crate::unwrap::UnwrapError),
    /// The epipolar de-aliaser cannot work with this rig or period set.
    #[error("epipolar de-aliasing (give --dealias analytic or mask to scan without it)")]
    Epipolar(#[source] crate::dealias::EpipolarError),
    /// A head's reconstruction failed.
    #[error("reconstruct head {head}")]
    Reconstruct {
        /// Head name.
        head: &'static str,
        /// Why.
        source: ReconstructError,
    },
    /// Registration or merging failed.
    #[error("fusion")]
    Fusion(#[from] FusionError),
    /// Writing the results failed (nothing half-written is left behind).
    #[error("writing the scan")]
    Output(#[from] output::OutputError),
    /// The ground truth has fewer cameras than the scan has heads.
    #[error("the ground truth has {truths} camera(s) for {heads} heads")]
    TruthHeads {
        /// Heads scanned.
        heads: usize,
        /// Cameras in the truth.
        truths: usize,
    },
    /// The ground truth's per-pixel arrays do not fit its images.
    #[error(transparent)]
    TruthSize(#[from] truth::TruthSizeError),
    /// The high-speed mode runs one head (seed 001's rig).
    #[error(
        "mode high-speed runs one head (one colour camera, one DMD); the calibration has {heads}"
    )]
    HighSpeedNeedsOneHead {
        /// Heads in the calibration.
        heads: usize,
    },
    /// A water scan needs every head's flat port in the calibration.
    #[error("a water scan triangulates through each head's flat port, and head {head} has none in the calibration (add \"port\" to the rig file's head)")]
    NoPort {
        /// Head name.
        head: &'static str,
    },
    /// A water scan takes one head at a time.
    #[error("a water scan runs the sequential mode, not {mode:?}")]
    WaterNeedsSequential {
        /// The mode asked for.
        mode: Mode,
    },
    /// Restoring the underwater frames failed (or its parameters are bad).
    #[error("underwater restoration")]
    Restore(#[source] crate::underwater::RestoreError),
    /// The learned underwater restorer failed to run.
    #[error("learned underwater restoration")]
    RestoreNetwork(#[source] crate::infer::ModelError),
    /// Triangulating through the flat ports failed.
    #[error("triangulation through the flat ports")]
    Port(#[source] crate::triangulation::flat_port::FlatPortError),
    /// Setting up or decoding the high-speed exposures failed.
    #[error("high-speed decoding")]
    HighSpeed(#[from] crate::highspeed::HighSpeedError),
}

/// A step of progress, for bars and logs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Progress {
    /// A stage starts with this many steps.
    Stage {
        /// Stage name.
        name: &'static str,
        /// Steps it will take.
        total: u64,
    },
    /// One step of the current stage done.
    Step,
    /// The current stage is done.
    Done,
}

/// One head's result.
#[derive(Clone, Debug)]
pub struct HeadResult {
    /// "A" or "B".
    pub name: &'static str,
    /// The mean of the camera's frames and its saturated pixels (pictures).
    pub frames: crate::pictures::FrameSummary,
    /// Per-pixel reconstruction, head frame.
    pub reconstruction: Reconstruction,
    /// The cloud moved into head A's frame (the fused frame) by the B->A
    /// pose fusion used, so it lines up with the fused cloud.
    pub cloud_in_a: PointCloud,
    /// RMS of the predicted per-point sigma, metres (needs no truth).
    pub predicted_rms_m: f64,
    /// Simultaneous mode: what de-aliasing (or masking) the overlap did.
    pub dealias: Option<crate::dealias::DealiasStats>,
    /// Simultaneous mode with a de-aliaser: its first period's frames
    /// before and after (and the simulator's clean reference), for the
    /// picture and the error figure.
    pub dealias_sample: Option<dealias_picture::DealiasSample>,
    /// What the exposure left (saturated, below the modulation floor) and,
    /// adaptive, what it chose.
    pub exposure: ExposureFigures,
    /// Adaptive: the floods, the DMD level map and the adapted patterns, for
    /// the outputs.
    pub adaptive: Option<capture::AdaptiveRecord>,
    /// Figures against the ground truth (`None` on hardware).
    pub truth: Option<HeadTruth>,
}

/// One head's figures against the ground truth.
#[derive(Clone, Debug)]
pub struct HeadTruth {
    /// Per-pixel error map against the truth, metres (NaN where not valid).
    pub error_m: Raster<f32>,
    /// Per-pixel accuracy.
    pub accuracy: PixelAccuracy,
    /// Per-pixel accuracy on the overlap: pixels whose surface point both
    /// projectors light (the twin's truth), where the modes differ.
    pub overlap: metrics::MaskedAccuracy,
    /// Simultaneous mode: the overlap the flat fields measured against the
    /// twin's true overlap (`None` in the other modes).
    pub aliased_mask: Option<aliasing::MaskAgreement>,
    /// Point-to-plane RMSE against the true surface, metres (the head's
    /// cloud moved into head A's frame by the TRUE pose: the head alone).
    pub plane_rmse_m: f64,
    /// Coverage of the measurable object surface.
    pub coverage: f64,
    /// How the head's calibrated frame was fitted onto the truth before measuring.
    pub frame_fit: truth_frame::FrameFit,
    /// Each sphere of known size this head saw, fitted (frame fitted onto the truth).
    pub spheres: Vec<spheres::SphereFigures>,
    /// Error of the pose fusion used for this head (head A's frame <- this
    /// head's, registered or calibrated) against the twin's, both frames
    /// fitted onto the truth: (degrees, metres); `None` for head A.
    pub residual_pose_error: Option<(f64, f64)>,
}

/// The fused result.
#[derive(Clone, Debug)]
pub struct FusedResult {
    /// The cloud, head A's frame.
    pub cloud: PointCloud,
    /// Registration of B onto A (`None` with one head, and when the heads
    /// share no surface, as in simultaneous mode with the aliased overlap
    /// masked out).
    pub icp: Option<IcpResult>,
    /// Three or four heads: every head's pose registered at once (per head
    /// the correction and fitness, per overlapping pair the overlap RMSE).
    pub views: Option<crate::fusion::MultiViewResult>,
    /// Figures against the ground truth (`None` on hardware).
    pub truth: Option<FusedTruth>,
    /// The calibration's checks that need no truth (two heads with ICP).
    pub self_check: Option<self_check::SelfCheck>,
    /// The same for three or four heads (with a registration).
    pub views_check: Option<self_check::ViewsCheck>,
    /// Why the heads could not be fused (then the cloud is empty and only
    /// the per-head clouds and the report are written).
    pub failure: Option<String>,
}

/// The fused cloud's figures against the ground truth.
#[derive(Clone, Debug)]
pub struct FusedTruth {
    /// Point-to-plane RMSE against the true surface, metres.
    pub plane_rmse_m: f64,
    /// Coverage of the measurable object surface.
    pub coverage: f64,
    /// Error of the B->A pose used (ICP-refined, or calibrated without ICP)
    /// against the twin's true B->A, both heads' frames fitted onto the
    /// truth: (degrees, metres); `None` with one head.
    pub residual_pose_error: Option<(f64, f64)>,
    /// How head A's calibrated frame (the fused frame) was fitted onto the truth.
    pub frame_fit: truth_frame::FrameFit,
}

/// A finished scan, in memory.
#[derive(Clone, Debug)]
pub struct ScanResult {
    /// The configuration it ran with.
    pub config: ScanConfig,
    /// Where the calibration came from (for the report).
    pub calibration_source: String,
    /// An estimated calibration's error against the twin's truth (`None`
    /// with the truth itself, and on hardware).
    pub calibration_vs_truth: Option<crate::calibration::truth_error::RigTruthError>,
    /// The heads, A (and B).
    pub heads: Vec<HeadResult>,
    /// The fused cloud (one head: its cloud).
    pub fused: FusedResult,
    /// Samples of the measurable object surface (`None` without a truth).
    pub surface_samples: Option<usize>,
    /// Wall-clock time per stage, milliseconds, in order.
    pub timings_ms: Vec<(&'static str, f64)>,
    /// Loud caveats of this run (masked aliased pixels, ...).
    pub warnings: Vec<String>,
    /// A water scan: what the restoration did and what the ports left out.
    pub underwater: Option<underwater::RestoreFigures>,
}

/// What a scan refuses before touching the rig: a bad pre-compensation
/// gamma, a calibration of no head or of more heads than the rig has names
/// for, two heads without their head-to-head pose, and a mode that needs
/// two heads on one.
pub fn check_before_capture(
    calibration: &RigCalibration,
    config: &ScanConfig,
) -> Result<(), ScanError> {
    if let Some(gamma) = config
        .precompensate_gamma
        .filter(|g| !(g.is_finite() && *g > 0.0))
    {
        return Err(ScanError::BadGamma { gamma });
    }
    if config.periods_px.is_empty() {
        return Err(ScanError::BadPeriod { period: f64::NAN });
    }
    if let Some(&period) = config
        .periods_px
        .iter()
        .find(|p| !(p.is_finite() && **p >= 2.0))
    {
        return Err(ScanError::BadPeriod { period });
    }
    let heads = calibration.heads.len();
    if heads == 0 || heads > protocol::limits::MAX_HEADS {
        return Err(ScanError::HeadCount { heads });
    }
    if calibration.head_poses.len() != heads - 1 {
        return Err(ScanError::NoHeadPoses {
            heads,
            poses: calibration.head_poses.len(),
        });
    }
    if heads == 1 && config.mode != Mode::Sequential {
        return Err(ScanError::ModeNeedsTwoHeads { mode: config.mode });
    }
    if heads > 2 && config.mode == Mode::Simultaneous {
        return Err(ScanError::SimultaneousNeedsTwo { heads });
    }
    if !(config.saturation_level > 0.0 && config.saturation_level <= 1.0) {
        return Err(ScanError::SaturationLevel(config.saturation_level));
    }
    underwater::check_before_capture(calibration, config)?;
    check_frames_per_pattern(config)?;
    match &config.exposures {
        Exposures::Single => {}
        _ if config.mode != Mode::Sequential => {
            return Err(ScanError::ExposuresNeedSequential {
                mode: config.mode,
                exposures: config.exposures.name(),
            })
        }
        Exposures::Multi(scales) if scales.is_empty() => return Err(ScanError::NoExposures),
        Exposures::Multi(scales) => {
            for &scale in scales {
                plan::one_pattern_per_scaled_exposure(protocol::HeadSet::A, 1, scale)?;
            }
        }
        Exposures::AdaptiveHdr(params) => params.validate()?,
        Exposures::AdaptiveColour(params) => params.validate()?,
        Exposures::Auto(rule) => rule.validate().map_err(ScanError::AutoExposure)?,
    }
    let periods = config.periods_px.len();
    if config.mode == Mode::Simultaneous
        && matches!(
            config.dealias,
            crate::dealias::DealiasMethod::Analytic | crate::dealias::DealiasMethod::Epipolar
        )
        && periods < crate::dealias::analytic::MIN_PERIODS
    {
        return Err(ScanError::DealiasPeriods { periods });
    }
    if config.mode == Mode::Simultaneous
        && config.dealias == crate::dealias::DealiasMethod::Epipolar
    {
        crate::dealias::EpipolarDealiaser::new(
            calibration,
            0,
            &config.periods_px,
            config.steps,
            crate::dealias::EpipolarParams::default(),
        )
        .map_err(ScanError::Epipolar)?;
    }
    if config.mode == Mode::Simultaneous
        && config.dealias == crate::dealias::DealiasMethod::Learned
        && config.learned.is_none()
    {
        return Err(ScanError::NoLearnedModel);
    }
    Ok(())
}

/// Refuses, before any capture, a rig of more heads than the connected
/// board reported lines for (a board that has not said is left to refuse
/// the plan itself).
fn check_board_heads(board: &impl Board, heads: usize) -> Result<(), ScanError> {
    match board.limits() {
        Some(limits) if heads > limits.max_heads() => Err(ScanError::TooManyHeadsForBoard {
            heads,
            output_channels: limits.output_channels,
            feedback_channels: limits.feedback_channels,
            max_heads: limits.max_heads(),
        }),
        _ => Ok(()),
    }
}

/// Wall-clock time per stage, logged as each ends.
pub(crate) struct Clock {
    last: Instant,
    pub(crate) timings: Vec<(&'static str, f64)>,
}

impl Clock {
    pub(crate) fn start() -> Self {
        Clock {
            last: Instant::now(),
            timings: Vec::new(),
        }
    }

    /// Starts the next lap now: the time since the last lap was spent in
    /// stages another clock timed (the simulator's after its scan).
    #[cfg(feature = "sim")]
    pub(crate) fn restart(&mut self) {
        self.last = Instant::now();
    }

    pub(crate) fn lap(&mut self, name: &'static str) {
        let now = Instant::now();
        let ms = (now - self.last).as_secs_f64() * 1e3;
        tracing::info!(stage = name, ms = format_args!("{ms:.0}"), "stage done");
        self.timings.push((name, ms));
        self.last = now;
    }
}

/// Runs a scan on any rig of one or two heads: capture -> reconstruct (with
/// `calibration`, described for the report by `calibration_source`) ->
/// fuse (two heads: ICP of B onto A; one head: its cloud is the scan), and,
/// when a ground `truth` exists (the twin), measure against it. Without one
/// (hardware) the report's truth figures are null. Simultaneous mode
/// measures its aliased overlap from flat fields, so it runs on hardware too.
pub fn run_on_rig<R: Board + Projector + Camera>(
    rig: &mut R,
    calibration: &RigCalibration,
    calibration_source: &str,
    truth: Option<&GroundTruth>,
    config: &ScanConfig,
    progress: &mut dyn FnMut(Progress),
) -> Result<ScanResult, ScanError> {
    let mut clock = Clock::start();
    check_before_capture(calibration, config)?;
    let heads = calibration.heads.len();
    check_board_heads(rig, heads)?;
    let mut captured = capture::capture(rig, config, calibration, progress)?;
    clock.lap("capture");
    let mut restored = match &config.medium {
        underwater::Medium::Water(water) => {
            let figures = underwater::restore_captured(&mut captured, water, progress)?;
            clock.lap("restore");
            Some(figures)
        }
        underwater::Medium::Air => None,
    };
    let mut warnings = Vec::new();
    let capture::ResolvedOverlap {
        overlaps: aliased_masks,
        stats: dealias_stats,
        samples: mut dealias_samples,
    } = capture::resolve_measured_overlap(&mut captured, config, calibration, &mut warnings)?;
    if captured.flat.is_some() {
        clock.lap("de-alias");
    }

    // Reconstruct each head in its own frame.
    let mut recons = Vec::new();
    progress(Progress::Stage {
        name: "reconstruct",
        total: heads as u64,
    });
    let mut exposures = Vec::new();
    let mut adaptive = std::mem::take(&mut captured.adaptive).into_iter();
    for (h, head) in HEAD_NAMES
        .into_iter()
        .enumerate()
        .take(captured.frames.len())
    {
        let record = if config.exposures.is_adaptive() {
            adaptive.next()
        } else {
            None
        };
        let (r, figures, left_out) = reconstruct_head(
            calibration,
            config,
            &mut captured,
            h,
            record.as_ref(),
            &mut warnings,
        )?;
        if let Some(restored) = &mut restored {
            restored.port_misses.push(left_out.port_misses);
            restored.blur_edge_px.push(left_out.blur_edges);
        }
        tracing::info!(head, points = r.cloud.len(), "reconstructed");
        exposures.push((figures, record));
        recons.push(r);
        progress(Progress::Step);
    }
    progress(Progress::Done);
    clock.lap("reconstruct");

    // Two heads: fuse B into A, starting from the calibrated B -> A. One
    // head: nothing to register, its cloud is the scan.
    progress(Progress::Stage {
        name: "fuse",
        total: 1,
    });
    let fuse::HeadsFused {
        cloud: fused_cloud,
        icp,
        views,
        a_from_head,
        self_check,
        views_check,
        failure: fusion_failure,
    } = fuse::fuse_heads(&recons, calibration, config, &mut warnings)?;
    progress(Progress::Step);
    progress(Progress::Done);
    clock.lap("fuse");

    let measured = match truth {
        Some(truth) => {
            progress(Progress::Stage {
                name: "measure",
                total: 1,
            });
            // Without a fused cloud the heads are still measured; the
            // fused figures (of head A alone then) are dropped below.
            let measured_fused = if fusion_failure.is_some() {
                &recons[0].cloud
            } else {
                &fused_cloud
            };
            let m = measure::measure(
                truth,
                &recons,
                measured_fused,
                &a_from_head,
                &aliased_masks,
                &mut warnings,
            )?;
            progress(Progress::Step);
            progress(Progress::Done);
            clock.lap("measure");
            Some(m)
        }
        None => None,
    };
    let (mut head_truths, fused_truth, surface_samples) = match measured {
        Some(m) => (
            m.heads.into_iter().map(Some).collect(),
            Some(m.fused).filter(|_| fusion_failure.is_none()),
            Some(m.surface_samples),
        ),
        None => ((0..heads).map(|_| None).collect::<Vec<_>>(), None, None),
    };
    let heads = recons
        .into_iter()
        .zip(exposures)
        .enumerate()
        .map(|(h, (recon, (exposure, adaptive)))| HeadResult {
            name: HEAD_NAMES[h],
            frames: crate::pictures::summarise_frames(&captured.raw[h]),
            cloud_in_a: transformed(&recon.cloud, &a_from_head[h]),
            predicted_rms_m: measure::predicted_rms_m(&recon),
            reconstruction: recon,
            dealias: dealias_stats.get(h).copied(),
            dealias_sample: dealias_samples.get_mut(h).and_then(Option::take),
            exposure,
            adaptive,
            truth: head_truths[h].take(),
        })
        .collect();
    Ok(ScanResult {
        config: config.clone(),
        calibration_source: calibration_source.to_string(),
        calibration_vs_truth: None,
        heads,
        fused: FusedResult {
            cloud: fused_cloud,
            icp,
            views,
            truth: fused_truth,
            self_check,
            views_check,
            failure: fusion_failure,
        },
        surface_samples,
        timings_ms: clock.timings,
        warnings,
        underwater: restored,
    })
}

#[cfg(test)]
mod tests;
