//! `slscan scan`: plan, capture, reconstruct and (with two heads) fuse a scan, on
//! the simulated rig (`--sim`) or on hardware (`--port`, `--frames-from`,
//! `--calibration`).

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use slscan::adaptive::colour::{ColourChoice, ColourParams};
use slscan::adaptive::hdr::HdrParams;
use slscan::board::ClientConfig;
use slscan::calibration::{read_rig, RigCalibration};
use slscan::dealias::DealiasMethod;
use slscan::io::report::{figure, ScanReport};
use slscan::rig::camera_source::FrameSource;
use slscan::rig::folder_camera::{FolderCamera, FolderCameraConfig, FolderHead};
use slscan::rig::folder_projector::{FolderProjector, FolderProjectorHead, PatternDelivery};
use slscan::rig::hardware::HardwareRig;
use slscan::rig::serial_board::SerialBoard;
use slscan::scan::underwater::{water_periods_px, Medium, Restorer, Turbidity, WaterScan};
use slscan::scan::{
    self, dealias_periods_px, default_periods_px, Exposures, Mode, Progress, ScanConfig,
};
use slscan::underwater::learned::PhysicsCorrection;

/// Options of `slscan scan`.
#[derive(clap::Args)]
#[command(after_long_help = HARDWARE_HELP)]
pub struct Args {
    /// Scan the simulated rig (board on a pty, digital-twin cameras).
    #[arg(long, conflicts_with_all = ["port", "frames_from", "cameras"])]
    sim: bool,
    /// Built-in twin scene of one to four heads (--sim; `hil-sim scenes`
    /// lists them; `ring-3` and `ring-4` have three and four).
    #[arg(long, default_value = "large-part")]
    scene: String,
    /// How the heads share time.
    #[arg(long, value_enum, default_value_t = ModeArg::Sequential)]
    mode: ModeArg,
    /// Output folder (scan.ply, head_a.ply, head_b.ply, ..., report.json, PNGs).
    #[arg(long)]
    out: PathBuf,
    /// Camera width, pixels (--sim; on hardware the calibration's).
    #[arg(long, default_value_t = 640, value_parser = clap::value_parser!(u32).range(16..=16384))]
    width: u32,
    /// Camera height, pixels (--sim; on hardware the calibration's).
    #[arg(long, default_value_t = 480, value_parser = clap::value_parser!(u32).range(16..=16384))]
    height: u32,
    /// Seed of device jitter and sensor noise (--sim).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// --mode high-speed: camera frames (each gives 24 depth maps).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=16))]
    frames: u32,
    /// Fringe periods, projector pixels, finest first (4 steps each);
    /// default: three pitches of S + sqrt(S) + 1, S and S - sqrt(S) fringes
    /// over the DMD width (S = 64: 73 / 64 / 56), and for the simultaneous
    /// mode's de-aliasing four periods of 73 / 64 / 56 / 50 fringes.
    #[arg(long, value_delimiter = ',')]
    periods: Option<Vec<f64>>,
    /// Hardware: the sync board's serial port, e.g. /dev/ttyACM0.
    #[arg(long)]
    port: Option<PathBuf>,
    /// Hardware: the folder the camera vendor's software saves frames into,
    /// one subfolder per head named as in the calibration (A/, B/).
    #[arg(long)]
    frames_from: Option<PathBuf>,
    /// Hardware: take head N's frames from a GenICam camera (GigE Vision,
    /// USB3 Vision) through Aravis instead of --frames-from, one per head in
    /// head order: genicam:ID (`slscan devices list` shows the ids; needs a
    /// build with `--features genicam`).
    #[arg(
        long = "camera",
        value_name = "genicam:ID",
        conflicts_with = "frames_from"
    )]
    cameras: Vec<String>,
    /// Hardware, --camera: pixel format (Mono8, Mono10, Mono12, Mono14, Mono16).
    #[arg(long, default_value = "Mono8")]
    camera_pixel_format: String,
    /// Hardware, --camera: exposure time in us (default: the camera's);
    /// auto exposure and auto gain are switched off either way.
    #[arg(long)]
    camera_exposure_us: Option<f64>,
    /// Hardware, --camera: gain in the camera's unit (default: the camera's).
    #[arg(long)]
    camera_gain: Option<f64>,
    /// Hardware, --camera: the TriggerSource the sync board's line enters by.
    #[arg(long, default_value = "Line0")]
    camera_trigger_source: String,
    /// The rig calibration file (slscan-rig JSON, one to four heads): required on
    /// hardware; with --sim, reconstruct with it and seed the ICP from it
    /// (`slscan calibrate --sim --scene NAME --out FILE`) instead of the
    /// digital twin's TRUE devices (the default, labelled so in the report).
    #[arg(long)]
    calibration: Option<PathBuf>,
    /// Hardware: where the DMD pattern sets are written (or, with
    /// --patterns-preloaded, checked): PATTERNS/<head>/pattern_NNN.png.
    /// Default: OUT/dmd_patterns.
    #[arg(long)]
    patterns_dir: Option<PathBuf>,
    /// Hardware: the DMDs already hold the pattern sets, loaded from
    /// --patterns-dir; check the folder matches instead of writing it.
    #[arg(long)]
    patterns_preloaded: bool,
    /// Hardware: drive head N's DMD controller over USB HID instead of
    /// writing PNGs, one per head in head order: dlpc350 or dlpc900,
    /// optionally :SERIAL (needs a build with `--features hid`).
    #[arg(long = "projector", value_name = "dlpc350|dlpc900[:SERIAL]")]
    projectors: Vec<String>,
    /// Hardware: bits per sample the cameras deliver (e.g. 12 in 16-bit
    /// files); default: the files' own depth (8 or 16).
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=16))]
    bit_depth: Option<u8>,
    /// Hardware: seconds to wait for a head's frames after the board ran.
    #[arg(long, default_value_t = 10.0)]
    frame_timeout_s: f64,
    /// Hardware: milliseconds between looks at the frames folder.
    #[arg(long, default_value_t = 50)]
    frame_poll_ms: u64,
    /// Hardware: milliseconds a head's full frame count must hold before the
    /// frames are read (catches a late extra frame; longer than the camera
    /// software's gap between two saves).
    #[arg(long, default_value_t = 500)]
    frame_settle_ms: u64,
    /// Hardware: camera noise at half scale, in [0, 1] frame units (feeds
    /// the reconstruction's noise prediction and fringe-order checks).
    #[arg(long, default_value_t = 0.01)]
    noise_sigma: f32,
    /// Hardware: share of that noise's variance that is shot noise, 0..1
    /// (then each point's predicted sigma follows its pixel's level; a camera
    /// with full well W and read noise r electrons has (W/2) / (W/2 + r^2)).
    /// 0 gives every pixel the half-scale noise.
    #[arg(long, default_value_t = 0.0)]
    shot_noise_share: f32,
    /// The simulated projectors' response: intensity = grey^gamma
    /// (1 = DMD pattern mode; about 2.2 through a video input).
    #[arg(long, default_value_t = 1.0)]
    sim_projector_gamma: f64,
    /// --mode high-speed: after it, a conventional capture of the same
    /// motion at the same camera rate (12 grey fringes, one per frame),
    /// measured against the truth at its middle (--sim; not with
    /// --projector-driver: a DLPC's pattern table at the fringes' 200 us
    /// cannot show 8-bit grey fringes).
    #[arg(long, requires = "sim", conflicts_with = "projector_driver")]
    compare_conventional: bool,
    /// --mode high-speed: seed 001's ZOCR-Net (an ONNX file from
    /// training/highspeed, such as models/highspeed_zocr.onnx) removes the
    /// zero order and the colour crosstalk instead of the analytic stage;
    /// checked against the pattern set before any capture.
    #[arg(long, value_name = "ONNX")]
    zocr_model: Option<PathBuf>,
    /// --mode high-speed: seed 001's FDD-Net (an ONNX file from
    /// training/highspeed, such as models/highspeed_fdd.onnx) corrects every
    /// pattern's demodulated phase before unwrapping; checked against the
    /// pattern set before any capture.
    #[arg(long, value_name = "ONNX")]
    fdd_model: Option<PathBuf>,
    /// --mode high-speed: demodulate each pattern this many more times, each
    /// time by the phase the pass before found: small curved parts keep their
    /// shape (the window flattens less of them) at the cost of more noise
    /// (README, high-speed section). Not with --fdd-model, which learnt the
    /// single pass's errors.
    #[arg(
        long,
        value_name = "N",
        default_value_t = 0,
        conflicts_with = "fdd_model"
    )]
    demod_refinements: u32,
    /// --mode high-speed: passes of sibling cancellation after the first
    /// demodulation (seed 001's second stage, spatial-frequency
    /// decomposition, done by formula): each pattern demodulated again, with
    /// a wider window, from its LED's fringes minus the seven other
    /// directions' as the pass before found them: lower typical error,
    /// heavier tails, 1.3-1.4x the decode time (README, high-speed
    /// section). Not with --fdd-model, which learnt the single pass's errors.
    #[arg(
        long,
        value_name = "N",
        default_value_t = 0,
        conflicts_with = "fdd_model"
    )]
    sibling_cancellations: u32,
    /// --mode high-speed: decodes after the first on predicted carriers:
    /// every pattern demodulated again against the phase it has at the depth
    /// the pass before's 24 depths agree on, so the windows no longer
    /// flatten small curved parts (held-out twin scenes: phase MAE 0.117 ->
    /// 0.085 rad); about twice the decode time (README, high-speed section).
    /// Not with --fdd-model, which learnt the single pass's errors.
    #[arg(
        long,
        value_name = "N",
        default_value_t = 0,
        conflicts_with = "fdd_model"
    )]
    consensus_passes: u32,
    /// --mode high-speed, with --consensus-passes: settle the consensus's
    /// holes at depth edges on the surface around them that best explains
    /// the fringes there instead of filling them smoothly (held-out twin
    /// scenes: phase MAE 0.085 -> 0.0785 rad; the spheres' outlines get
    /// worse: README, high-speed section).
    #[arg(long)]
    settle_edges: bool,
    /// Drive the simulated projectors through this DMD controller's USB HID
    /// driver and hil-sim's byte-level controller (--sim; default: patterns
    /// go straight to the simulated DMDs).
    #[arg(long, value_enum, requires = "sim")]
    projector_driver: Option<ProjectorDriverArg>,
    /// Trigger lines (and as many feedback lines) of the simulated sync
    /// board, two per head (--sim; default: the STM32G474's 4 for a scene
    /// of one or two heads, 8 for three or four).
    #[arg(long, requires = "sim", value_parser = clap::value_parser!(u8).range(2..=8))]
    sim_board_lines: Option<u8>,
    /// Pre-compensate the patterns for a projector response of this gamma
    /// (send grey^(1/gamma)).
    #[arg(long)]
    precompensate_gamma: Option<f64>,
    /// Simultaneous mode: separate the two projectors' fringes per pixel
    /// where both light it (epipolar: along the pixel's ray through the
    /// calibrated rig; analytic: with free columns; learned: a network), or
    /// mask every pixel the other projector lights (mask).
    #[arg(long, value_enum, default_value_t = DealiasArg::Epipolar)]
    dealias: DealiasArg,
    /// --dealias learned: the ONNX network (its .json metadata beside it);
    /// default: the shipped one-step network, models/dealias_onestep.onnx.
    #[arg(long)]
    dealias_model: Option<PathBuf>,
    /// --dealias learned or --restorer learned with a diffusion model: DDIM
    /// sampler steps (network evaluations per tile; seed 000's DDPM used
    /// 4000, seed 002's 1000).
    #[arg(long, default_value_t = 8)]
    sampler_steps: usize,
    /// Adapt the projection to the surface (sequential mode): `hdr` takes 7
    /// grey floods and one full-intensity fringe set, then projects fringes
    /// whose level is chosen per projector pixel (lower where the surface
    /// saturates) at an exposure chosen for the view (longer for dark parts).
    #[arg(long, value_enum, conflicts_with = "exposures")]
    adaptive: Option<AdaptiveArg>,
    /// Multi-exposure scan (sequential mode): the fringe set at each of these
    /// exposures, in standard exposures (e.g. 2.5,1,0.25), each pixel taken
    /// from its best unsaturated one.
    #[arg(long, value_delimiter = ',')]
    exposures: Option<Vec<f64>>,
    /// Auto exposure (sequential mode): one white flood per head at the
    /// standard exposure, then that head's fringes at the exposure that
    /// brings the 99.5th percentile of its lit pixels to 0.85 of full scale
    /// (1/32 to 8 standard exposures), so a dim or steep view reaches the
    /// fringe-order noise floor and a bright one is not clipped.
    #[arg(long, conflicts_with_all = ["exposures", "adaptive"])]
    auto_exposure: bool,
    /// Frames taken of every fringe pattern and averaged before decoding
    /// (sequential mode; 1 to 16): N frames cut the camera noise by sqrt(N)
    /// where the exposure cannot be made longer (turbid water at the plan's
    /// longest exposure).
    #[arg(long, default_value_t = 1)]
    average_frames: usize,
    /// Frame value (0..1 of full scale) at and above which a sample counts
    /// as saturated; pixels with one are masked.
    #[arg(long, default_value_t = scan::DEFAULT_SATURATION_LEVEL)]
    saturation_level: f32,
    /// What the heads look through: water puts every device behind a flat
    /// port (the rig file's "port" on each head; the twin's are 30 mm in
    /// front of each device), restores each fringe set (--restorer) and
    /// triangulates through the ports; default periods 21 / 16 / 12 fringes
    /// over the DMD (61 / 80 / 107 px on 1280, as coarse as seed 002's);
    /// --sim: exposure lengthened for the water's attenuation.
    #[arg(long, value_enum, default_value_t = MediumArg::Air)]
    medium: MediumArg,
    /// --medium water: the turbidity (--sim: the twin's water of that
    /// level; hardware: the report's label).
    #[arg(long, value_enum, ignore_case = true)]
    turbidity: Option<TurbidityArg>,
    /// --medium water: how each fringe set is restored before decoding.
    #[arg(long, value_enum, default_value_t = RestorerArg::Classical)]
    restorer: RestorerArg,
    /// --medium water, --restorer learned: the ONNX network (its .json
    /// metadata beside it); default: models/underwater_onestep.onnx.
    #[arg(long)]
    restorer_model: Option<PathBuf>,
    /// --medium water, classical restorer: forward-scatter PSF sigma, camera
    /// pixels (--sim default: the level's rate over a nominal 0.47 m
    /// camera-side water path; required on hardware).
    #[arg(long)]
    water_psf_sigma_px: Option<f64>,
    /// --medium water, --restorer learned with a diffusion model: seed
    /// 002's physics-gradient correction after every sampler step at this
    /// strength (the seed's is 0.01), with the forward-scatter PSF as the
    /// classical restorer takes it.
    #[arg(long)]
    physics_correction: Option<f32>,
    /// --medium water: decoded pixels within this many forward-scatter PSF
    /// sigmas of a silhouette are left out (the blur mixes the other side's
    /// fringe into them; 0 keeps them). Default 2.
    #[arg(long)]
    water_edge_margin: Option<f64>,
}

/// `--medium` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum MediumArg {
    /// In air: pinhole triangulation.
    Air,
    /// Under water, behind each head's flat port.
    Water,
}

/// `--turbidity` values (seed 002's levels).
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum TurbidityArg {
    /// Relatively clear water.
    T1,
    /// Mildly turbid nearshore water.
    T2,
    /// Highly turbid, sediment-rich water.
    T3,
    /// Extremely turbid water, strong backscatter.
    T4,
}

impl From<TurbidityArg> for Turbidity {
    fn from(t: TurbidityArg) -> Self {
        match t {
            TurbidityArg::T1 => Turbidity::T1,
            TurbidityArg::T2 => Turbidity::T2,
            TurbidityArg::T3 => Turbidity::T3,
            TurbidityArg::T4 => Turbidity::T4,
        }
    }
}

/// `--restorer` values.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum RestorerArg {
    /// The frames as taken.
    None,
    /// Wiener deconvolution with the forward-scatter Gaussian, then the
    /// set's backscatter veil floor subtracted.
    Classical,
    /// A network trained on twin data (--restorer-model; diffusion models
    /// take --sampler-steps).
    Learned,
}

/// `--medium`, `--turbidity`, `--restorer`, `--water-psf-sigma-px`; the PSF
/// defaults to `default_psf_sigma_px` of the level (the simulator's), and
/// without one a classical restorer needs `--water-psf-sigma-px`; a
/// learned restorer is loaded and checked against `periods_px` here, before
/// any capture.
fn medium_for(
    args: &Args,
    periods_px: &[f64],
    default_psf_sigma_px: impl Fn(Turbidity) -> Option<f64>,
) -> anyhow::Result<Medium> {
    let turbidity = args.turbidity.map(Turbidity::from);
    if args.medium == MediumArg::Air {
        if turbidity.is_some()
            || args.water_psf_sigma_px.is_some()
            || args.physics_correction.is_some()
            || args.water_edge_margin.is_some()
        {
            anyhow::bail!(
                "--turbidity, --water-psf-sigma-px, --water-edge-margin and --physics-correction describe water: add --medium water"
            );
        }
        return Ok(Medium::Air);
    }
    let psf = args
        .water_psf_sigma_px
        .or_else(|| turbidity.and_then(&default_psf_sigma_px));
    if args.physics_correction.is_some() && !matches!(args.restorer, RestorerArg::Learned) {
        anyhow::bail!("--physics-correction corrects a learned restorer's sampler: add --restorer learned with a diffusion --restorer-model");
    }
    let restorer = match args.restorer {
        RestorerArg::None => Restorer::None,
        RestorerArg::Classical => Restorer::Classical,
        RestorerArg::Learned => {
            let path = shipped_model(args.restorer_model.as_deref(), DEFAULT_RESTORER_MODEL);
            let net = slscan::underwater::learned::LearnedRestorer::load(
                &path,
                periods_px,
                4,
                args.sampler_steps,
            )?;
            let physics = match (args.physics_correction, psf) {
                (None, _) => None,
                (Some(_), _) if !net.model().is_diffusion() => anyhow::bail!(
                    "--physics-correction: {} is a one-step network, it has no sampler to correct; give a diffusion --restorer-model",
                    path.display()
                ),
                (Some(strength), Some(psf_sigma_px)) => Some(PhysicsCorrection {
                    strength,
                    ..PhysicsCorrection::seed(psf_sigma_px)
                }),
                (Some(_), None) => anyhow::bail!(
                    "--physics-correction needs the forward-scatter PSF: give --water-psf-sigma-px (camera pixels)"
                ),
            };
            tracing::warn!(
                model = %path.display(),
                "learned underwater restoration: decodes where classical cannot (T4 from one \
                 frame), but where classical decodes it is less accurate (sphere radii off by \
                 80-330 um, README); --restorer classical stays the choice for measurement"
            );
            Restorer::Learned(std::sync::Arc::new(net.with_physics(physics)))
        }
    };
    let psf_sigma_px = match (&restorer, psf) {
        (_, Some(sigma)) => sigma,
        (Restorer::None | Restorer::Learned(_), None) => 0.0,
        (Restorer::Classical, None) => anyhow::bail!(
            "--restorer classical under water needs the forward-scatter PSF: give \
             --water-psf-sigma-px (camera pixels), or --restorer none"
        ),
    };
    Ok(Medium::Water(WaterScan {
        turbidity,
        restorer,
        psf_sigma_px,
        edge_margin_sigmas: args
            .water_edge_margin
            .unwrap_or(slscan::scan::underwater::EDGE_MARGIN_SIGMAS),
    }))
}

/// `--adaptive` values.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum AdaptiveArg {
    /// Per-projector-pixel fringe level from 7 grey floods, and the one
    /// exposure at which the most pixels decode: 31 images per head.
    Hdr,
    /// The same at the standard exposure, as seed 003 publishes it (it only
    /// lowers the projector where the surface saturates; dark parts stay
    /// as starved as in a plain scan).
    HdrFixedExposure,
    /// Seed 004 for coloured and reflective parts: 5 floods (grey 0 and
    /// 100, red, green, blue), Gray-code + pixel-shift matching (68
    /// images), then 3-step fringes in each surface's own colour at a level
    /// chosen per projector pixel and one exposure; each image is three
    /// sub-frames, one per LED.
    Colour,
    /// The same with white at the chosen level instead of the surface's
    /// colour (on a mono camera, the most modulation a level can give).
    ColourWhite,
}

/// `--adaptive` / `--exposures`: how each head's fringes are exposed.
fn exposures_for(args: &Args) -> Exposures {
    if args.auto_exposure {
        return Exposures::Auto(scan::AutoExposure::default());
    }
    match (&args.adaptive, &args.exposures) {
        (Some(AdaptiveArg::Hdr), _) => Exposures::AdaptiveHdr(HdrParams::default()),
        (Some(AdaptiveArg::Colour), _) => Exposures::AdaptiveColour(ColourParams::default()),
        (Some(AdaptiveArg::ColourWhite), _) => Exposures::AdaptiveColour(ColourParams {
            choice: ColourChoice::White,
            ..ColourParams::default()
        }),
        (Some(AdaptiveArg::HdrFixedExposure), _) => {
            let mut params = HdrParams::default();
            params.rule.range = (1.0, 1.0);
            Exposures::AdaptiveHdr(params)
        }
        (None, Some(scales)) => Exposures::Multi(scales.clone()),
        (None, None) => Exposures::Single,
    }
}

/// `--dealias` values.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum DealiasArg {
    /// Per-pixel phasor separation along the pixel's ray: the calibrated rig
    /// ties both projector columns to one range (three unknowns).
    Epipolar,
    /// Per-pixel phasor separation from the four unknowns (two columns, two
    /// modulations), without the calibration.
    Analytic,
    /// Mask every pixel the other projector lights.
    Mask,
    /// A network trained on twin data (--dealias-model); measured weaker
    /// than analytic, see models/README.md.
    Learned,
}

impl From<DealiasArg> for DealiasMethod {
    fn from(d: DealiasArg) -> Self {
        match d {
            DealiasArg::Epipolar => DealiasMethod::Epipolar,
            DealiasArg::Analytic => DealiasMethod::Analytic,
            DealiasArg::Mask => DealiasMethod::Mask,
            DealiasArg::Learned => DealiasMethod::Learned,
        }
    }
}

const HARDWARE_HELP: &str = "\
Hardware scan: slscan scan --port /dev/ttyACM0 --frames-from FRAMES --calibration rig.json --mode sequential --out DIR

Cameras: the camera vendor's software (hardware-trigger mode, trigger from the sync board) saves one
8- or 16-bit PNG/TIFF per trigger into FRAMES/<head>/ (FRAMES/A/, FRAMES/B/). Trigger order is file-name
order with numbers compared as numbers (img_9 before img_10). Files already there when a run starts are
ignored (the folder need not be emptied); hidden files and other extensions are ignored, so a tool that
writes a temporary and renames is read once renamed; otherwise a file counts once its size stays the same
over one poll interval. Each head must deliver exactly its trigger count within --frame-timeout-s, and
the count must hold for --frame-settle-ms: fewer or more ends the scan with an error and no scan.ply.

Projectors: with --projector dlpc350[:SERIAL] or dlpc900[:SERIAL] (once per head, a build with --features hid)
slscan uploads each head's set to its TI DLPC controller over USB HID and starts it in external-trigger mode
(never run on a real device yet). Otherwise each head's pattern set is written as PATTERNS/<head>/pattern_NNN.png
for the DMD vendor's GUI to load (one pattern per trigger, in file order); with --patterns-preloaded the set is
not written but checked against what the scan needs.

No ground truth on hardware: report.json's rmse and coverage figures are null. Simultaneous mode measures
which pixels both projectors light from three flat-field exposures it adds after the fringes (both dark,
A alone full on, B alone full on), then separates the two fringes there (--dealias analytic,
four periods by default) or masks them (--dealias mask).";

/// `--projector-driver` values.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum ProjectorDriverArg {
    /// TI DLPC350 (LightCrafter 4500).
    Dlpc350,
    /// TI DLPC900 (LightCrafter 6500 / 9000).
    Dlpc900,
}

impl From<ProjectorDriverArg> for slscan::rig::dlpc::Controller {
    fn from(a: ProjectorDriverArg) -> Self {
        match a {
            ProjectorDriverArg::Dlpc350 => Self::Dlpc350,
            ProjectorDriverArg::Dlpc900 => Self::Dlpc900,
        }
    }
}

/// `--mode` values.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum ModeArg {
    /// Head A alone, then head B alone.
    Sequential,
    /// Both heads at once, identical sequences; the overlap de-aliased per pixel (--dealias), the rest the other projector lights masked.
    Simultaneous,
    /// Both at once, N = 8, head A on temporal bin 1, head B on bin 2, demultiplexed per pixel.
    SimultaneousMultiplexed,
    /// Head A only, seed 001: 24 binary patterns (8 directions x R, G, B) in one colour exposure per camera frame, 24 depth maps per frame, each at its pattern's instant.
    HighSpeed,
}

/// Runs `slscan scan`.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.zocr_model.is_none() || matches!(args.mode, ModeArg::HighSpeed),
        "--zocr-model is seed 001's network for --mode high-speed only"
    );
    anyhow::ensure!(
        args.fdd_model.is_none() || matches!(args.mode, ModeArg::HighSpeed),
        "--fdd-model is seed 001's network for --mode high-speed only"
    );
    anyhow::ensure!(
        args.demod_refinements == 0 || matches!(args.mode, ModeArg::HighSpeed),
        "--demod-refinements is for --mode high-speed only"
    );
    anyhow::ensure!(
        args.sibling_cancellations == 0 || matches!(args.mode, ModeArg::HighSpeed),
        "--sibling-cancellations is for --mode high-speed only"
    );
    anyhow::ensure!(
        args.consensus_passes == 0 || matches!(args.mode, ModeArg::HighSpeed),
        "--consensus-passes is for --mode high-speed only"
    );
    anyhow::ensure!(
        !args.settle_edges || args.consensus_passes > 0,
        "--settle-edges settles the consensus passes' holes: give --consensus-passes 1 or more"
    );
    let mode = match args.mode {
        ModeArg::Sequential => Mode::Sequential,
        ModeArg::Simultaneous => Mode::Simultaneous,
        ModeArg::SimultaneousMultiplexed => Mode::SimultaneousMultiplexed,
        ModeArg::HighSpeed if args.sim => {
            return super::scan_high_speed::run(&super::scan_high_speed::Options {
                scene: &args.scene,
                out: &args.out,
                camera_px: (args.width, args.height),
                seed: args.seed,
                frames: args.frames,
                projector_driver: args.projector_driver.map(Into::into),
                conventional: args.compare_conventional,
                zocr_model: args.zocr_model.as_deref(),
                fdd_model: args.fdd_model.as_deref(),
                demod_refinements: args.demod_refinements,
                sibling_cancellations: args.sibling_cancellations,
                consensus_passes: args.consensus_passes,
                settle_edges: args.settle_edges,
            })
        }
        ModeArg::HighSpeed => return high_speed_hardware(&args),
    };
    let mut bars = Bars::new();
    let mut on_progress = |p: Progress| bars.on(p);
    let failed = || {
        format!(
            "scan into {} failed; no scan.ply written",
            args.out.display()
        )
    };
    let report = if args.sim {
        scan_sim(&args, mode, &mut on_progress).with_context(failed)?
    } else {
        let missing = missing_hardware_args(&args);
        let (Some(port), Some(calibration), true) =
            (&args.port, &args.calibration, missing.is_empty())
        else {
            anyhow::bail!(
                "no rig given: pass --sim for the simulated rig, or --port, --calibration and \
                 --frames-from or --camera for hardware (missing: {})",
                missing.join(", ")
            );
        };
        scan_hardware(&args, mode, port, calibration, &mut on_progress).with_context(failed)?
    };
    print_summary(&report);
    if report.fused.failure.is_some() {
        anyhow::bail!(
            "scan into {} failed: the heads could not be fused (see the warning above), so no \
             scan.ply; the per-head clouds, pictures and report are written",
            args.out.display()
        );
    }
    println!("wrote {}", args.out.join("scan.ply").display());
    Ok(())
}

/// `--mode high-speed` on hardware: head A's board, DMD (a DLPC controller,
/// or patterns for the vendor's GUI) and colour camera, from the rig file.
fn high_speed_hardware(args: &Args) -> anyhow::Result<()> {
    use slscan::scan::high_speed::{run_high_speed, HighSpeedConfig};
    use slscan::scan::high_speed_output::{remove_stale, write_high_speed};
    let missing = missing_hardware_args(args);
    let (Some(port), Some(calibration_path), true) =
        (&args.port, &args.calibration, missing.is_empty())
    else {
        anyhow::bail!(
            "no rig given: pass --sim for the simulated rig, or --port, --calibration and \
             --frames-from or --camera for hardware (missing: {})",
            missing.join(", ")
        );
    };
    if !args.cameras.is_empty() {
        let settings = genicam_settings(args)?;
        anyhow::ensure!(
            settings.pixel_format.is_colour(),
            "--mode high-speed needs colour frames: --camera-pixel-format {} is monochrome \
             (RGB8, BGR8 or a Bayer format such as BayerRG8)",
            settings.pixel_format.name()
        );
    }
    let calibration = read_rig(calibration_path)
        .with_context(|| format!("reading the calibration {}", calibration_path.display()))?;
    let mut config = HighSpeedConfig::new(&format!("rig file {}", calibration_path.display()));
    config.frames = args.frames;
    config.decoder.demux.refinements = args.demod_refinements;
    config.decoder.demux.cancellations = args.sibling_cancellations;
    config.decoder.consensus_passes = args.consensus_passes;
    config.decoder.settle_edges = args.settle_edges;
    let failed = || {
        format!(
            "high-speed scan into {} failed; nothing written",
            args.out.display()
        )
    };
    // Before any device is touched: a failed scan leaves no earlier outputs.
    remove_stale(&args.out).with_context(failed)?;
    if let Some(head) = calibration.heads.first() {
        let dmd = (head.projector.width_px, head.projector.height_px);
        config.zocr = super::scan_high_speed::load_zocr(args.zocr_model.as_deref(), dmd)
            .with_context(failed)?;
        config.fdd = super::scan_high_speed::load_fdd(args.fdd_model.as_deref(), dmd)
            .with_context(failed)?;
    }
    let board = SerialBoard::open(port, ClientConfig::default())
        .with_context(|| format!("connecting to the sync board on {}", port.display()))?;
    let cameras = frame_source(args, &calibration)?;
    let heads = calibration.heads.len();
    let mut bars = Bars::new();
    let mut progress = |p| bars.on(p);
    let result = if args.projectors.is_empty() {
        let projector = folder_projector(args, &calibration);
        let mut rig = HardwareRig::new(board, projector, cameras, heads);
        run_high_speed(&mut rig, &config, &calibration, None, &mut progress)
    } else {
        // The pattern table at the fringes' 200 us: the flats' longer
        // slots then show them that long (see `pattern_display_us`).
        let display_us = slscan::scan::high_speed::pattern_display_us();
        let projector = dlpc_projectors(&args.projectors, heads, display_us)?;
        let mut rig = HardwareRig::new(board, projector, cameras, heads);
        run_high_speed(&mut rig, &config, &calibration, None, &mut progress)
    }
    .with_context(failed)?;
    let report =
        write_high_speed(&args.out, &result, config.decoder.depth_range_m).with_context(failed)?;
    super::scan_high_speed::print_summary(&report, &args.out);
    Ok(())
}

/// `--sim`: the simulated rig of `--scene`.
#[cfg(feature = "sim")]
fn scan_sim(
    args: &Args,
    mode: Mode,
    progress: &mut dyn FnMut(Progress),
) -> anyhow::Result<ScanReport> {
    use slscan::sim::calibration_source::CalibrationSource;
    use slscan::sim::scan::{scan_to_dir, SimScanConfig};
    let mut config = SimScanConfig::new(&args.scene);
    if let Some(path) = &args.calibration {
        config.calibration = CalibrationSource::File(path.clone());
    }
    config.seed = args.seed;
    config.sim_projector_gamma = args.sim_projector_gamma;
    config.projector_driver = args.projector_driver.map(Into::into);
    config.board_lines = args.sim_board_lines;
    let scan = &mut config.scan;
    scan.mode = mode;
    scan.camera_px = (args.width, args.height);
    scan.precompensate_gamma = args.precompensate_gamma;
    scan.dealias = args.dealias.into();
    scan.periods_px = periods_for(args, mode, scan.projector_px.0);
    scan.learned = load_network(args, mode, &scan.periods_px, scan.steps)?;
    scan.exposures = exposures_for(args);
    scan.frames_per_pattern = args.average_frames;
    scan.saturation_level = args.saturation_level;
    scan.medium = medium_for(args, &scan.periods_px, |level| {
        Some(slscan::sim::underwater::nominal_psf_sigma_px(level))
    })?;
    if let (Medium::Water(water), Exposures::Single) = (&scan.medium, &scan.exposures) {
        if let Some(level) = water.turbidity {
            let scale = slscan::sim::underwater::exposure_scale(level);
            scan.exposures = Exposures::Multi(vec![scale]);
        }
    }
    Ok(scan_to_dir(&config, &args.out, progress)?)
}

#[cfg(not(feature = "sim"))]
fn scan_sim(_: &Args, _: Mode, _: &mut dyn FnMut(Progress)) -> anyhow::Result<ScanReport> {
    Err(super::no_simulator("scan --sim"))
}

/// `--periods`, or the default: 21 / 16 / 12 fringes under water,
/// four periods for the simultaneous mode's analytic de-aliasing, seed
/// 004's three pitches otherwise.
fn periods_for(args: &Args, mode: Mode, dmd_width_px: u32) -> Vec<f64> {
    match (&args.periods, mode, DealiasMethod::from(args.dealias)) {
        (Some(p), ..) => p.clone(),
        (None, ..) if args.medium == MediumArg::Water => water_periods_px(dmd_width_px),
        (
            None,
            Mode::Simultaneous,
            DealiasMethod::Epipolar | DealiasMethod::Analytic | DealiasMethod::Learned,
        ) => dealias_periods_px(dmd_width_px),
        (None, ..) => default_periods_px(dmd_width_px),
    }
}

/// The DMD vendor's GUI as the projector: patterns written to
/// `--patterns-dir` (default `OUT/dmd_patterns`), or already loaded there.
fn folder_projector(args: &Args, calibration: &RigCalibration) -> FolderProjector {
    FolderProjector::new(
        args.patterns_dir
            .clone()
            .unwrap_or_else(|| args.out.join("dmd_patterns")),
        FolderProjectorHead::of_rig(calibration),
        if args.patterns_preloaded {
            PatternDelivery::Preloaded
        } else {
            PatternDelivery::Write
        },
    )
}

fn missing_hardware_args(args: &Args) -> Vec<&'static str> {
    [
        ("--port", args.port.is_none()),
        (
            "--frames-from or --camera",
            args.frames_from.is_none() && args.cameras.is_empty(),
        ),
        ("--calibration", args.calibration.is_none()),
    ]
    .into_iter()
    .filter_map(|(name, missing)| missing.then_some(name))
    .collect()
}

/// The hardware rig from the options and the calibration, then the scan.
fn scan_hardware(
    args: &Args,
    mode: Mode,
    port: &Path,
    calibration_path: &Path,
    progress: &mut dyn FnMut(Progress),
) -> anyhow::Result<ScanReport> {
    let calibration = read_rig(calibration_path)
        .with_context(|| format!("reading the calibration {}", calibration_path.display()))?;
    let config = hardware_config(args, mode, &calibration)?;
    slscan::scan::check_before_capture(&calibration, &config)?;
    // Before any device is touched: a failed scan must not leave an
    // earlier run's scan.ply or report.json to be read as its result.
    scan::output::remove_stale(&args.out)?;
    let board = SerialBoard::open(port, ClientConfig::default())
        .with_context(|| format!("connecting to the sync board on {}", port.display()))?;
    let cameras = frame_source(args, &calibration)?;
    let source = format!("rig file {}", calibration_path.display());
    let heads = calibration.heads.len();
    let result = if args.projectors.is_empty() {
        let projector = folder_projector(args, &calibration);
        let mut rig = HardwareRig::new(board, projector, cameras, heads);
        scan::run_on_rig(&mut rig, &calibration, &source, None, &config, progress)?
    } else {
        let exposure_us = (slscan::scan::plan::display_s() * 1e6).round() as u32;
        let projector = dlpc_projectors(&args.projectors, heads, exposure_us)?;
        let mut rig = HardwareRig::new(board, projector, cameras, heads);
        scan::run_on_rig(&mut rig, &calibration, &source, None, &config, progress)?
    };
    Ok(scan::output::write_scan(&args.out, &result, progress)?)
}

/// The heads' cameras: GenICam devices (`--camera`) or the folder the
/// vendor's software fills (`--frames-from`).
fn frame_source(args: &Args, calibration: &RigCalibration) -> anyhow::Result<Box<dyn FrameSource>> {
    if !args.cameras.is_empty() {
        return genicam_cameras(args, calibration);
    }
    let frames = args
        .frames_from
        .as_ref()
        .context("--frames-from or --camera is needed on hardware")?;
    Ok(Box::new(FolderCamera::new(FolderCameraConfig {
        root: frames.to_owned(),
        heads: FolderHead::of_rig(calibration),
        bit_depth: args.bit_depth,
        timeout: Duration::from_secs_f64(args.frame_timeout_s.max(0.0)),
        poll_interval: Duration::from_millis(args.frame_poll_ms.max(1)),
        settle: Duration::from_millis(args.frame_settle_ms),
    })?))
}

/// `--camera genicam:ID`: the camera id.
fn parse_camera(spec: &str) -> anyhow::Result<&str> {
    match spec.split_once(':') {
        Some(("genicam", id)) if !id.is_empty() => Ok(id),
        _ => anyhow::bail!(
            "--camera {spec}: expected genicam:ID (`slscan devices list` shows the ids)"
        ),
    }
}

/// The camera settings from the `--camera-*` options.
fn genicam_settings(args: &Args) -> anyhow::Result<slscan::rig::genicam::GenicamSettings> {
    use slscan::rig::genicam::{GenicamSettings, PixelFormat};
    let name = &args.camera_pixel_format;
    let pixel_format = PixelFormat::from_name(name).with_context(|| {
        let names: Vec<_> = PixelFormat::ALL.iter().map(|f| f.name()).collect();
        format!(
            "--camera-pixel-format {name}: expected one of {}",
            names.join(", ")
        )
    })?;
    Ok(GenicamSettings {
        pixel_format,
        exposure_us: args.camera_exposure_us,
        gain: args.camera_gain,
        trigger_source: args.camera_trigger_source.clone(),
        frame_timeout: Duration::from_secs_f64(args.frame_timeout_s.max(0.0)),
        ..GenicamSettings::default()
    })
}

/// Each head's GenICam camera, opened and checked against the calibrated
/// image size.
#[cfg(feature = "genicam")]
fn genicam_cameras(
    args: &Args,
    calibration: &RigCalibration,
) -> anyhow::Result<Box<dyn FrameSource>> {
    use slscan::rig::genicam::aravis_camera::{GenicamCamera, GenicamCameras};
    let heads = calibration.heads.len();
    anyhow::ensure!(
        args.cameras.len() == heads,
        "{} --camera given for a rig of {heads} heads (one per head, in head order)",
        args.cameras.len()
    );
    let settings = genicam_settings(args)?;
    let mut cameras = Vec::with_capacity(heads);
    for (spec, head) in args.cameras.iter().zip(&calibration.heads) {
        let id = parse_camera(spec)?;
        let camera = GenicamCamera::open(id, &settings)
            .with_context(|| format!("opening camera {id} of head {}", head.name))?;
        let calibrated = (head.camera.width_px, head.camera.height_px);
        anyhow::ensure!(
            camera.image_size_px() == calibrated,
            "camera {id} of head {} gives {:?} images, calibrated for {calibrated:?} (width, height)",
            head.name,
            camera.image_size_px()
        );
        cameras.push(camera);
    }
    Ok(Box::new(GenicamCameras::new(cameras)))
}

#[cfg(not(feature = "genicam"))]
fn genicam_cameras(
    args: &Args,
    _calibration: &RigCalibration,
) -> anyhow::Result<Box<dyn FrameSource>> {
    for spec in &args.cameras {
        parse_camera(spec)?;
    }
    genicam_settings(args)?;
    Err(slscan::rig::genicam::GenicamError::NotBuilt.into())
}

/// `--projector KIND[:SERIAL]`, one per head.
fn parse_projector(spec: &str) -> anyhow::Result<(slscan::rig::dlpc::Controller, Option<&str>)> {
    use slscan::rig::dlpc::Controller;
    let (kind, serial) = match spec.split_once(':') {
        Some((k, s)) => (k, Some(s)),
        None => (spec, None),
    };
    let controller = match kind {
        "dlpc350" => Controller::Dlpc350,
        "dlpc900" => Controller::Dlpc900,
        other => {
            anyhow::bail!("--projector {other}: expected dlpc350 or dlpc900 (optionally :SERIAL)")
        }
    };
    Ok((controller, serial))
}

/// The heads' DLPC controllers opened over USB HID, each pattern table at
/// `exposure_us`.
#[cfg(feature = "hid")]
fn dlpc_projectors(
    specs: &[String],
    heads: usize,
    exposure_us: u32,
) -> anyhow::Result<slscan::rig::dlpc::DlpcProjector<slscan::rig::dlpc::hid::HidapiLink>> {
    use slscan::rig::dlpc::{hid::HidapiLink, DlpcHead, DlpcProjector, DriverConfig};
    anyhow::ensure!(
        specs.len() == heads,
        "{} --projector given for a rig of {heads} heads (one per head, in head order)",
        specs.len()
    );
    let mut out = Vec::with_capacity(heads);
    for spec in specs {
        let (controller, serial) = parse_projector(spec)?;
        let link = HidapiLink::open(controller, serial)
            .with_context(|| format!("opening the {} ({spec}) over USB HID", controller.name()))?;
        out.push(DlpcHead::new(
            link,
            controller,
            DriverConfig::new(exposure_us),
        ));
    }
    Ok(DlpcProjector::new(out))
}

#[cfg(not(feature = "hid"))]
fn dlpc_projectors(
    specs: &[String],
    _heads: usize,
    _exposure_us: u32,
) -> anyhow::Result<FolderProjector> {
    for spec in specs {
        parse_projector(spec)?;
    }
    anyhow::bail!(
        "--projector needs USB HID: this slscan was built without the `hid` feature \
         (cargo build --release -p slscan --features hid)"
    )
}

/// Sizes from the calibration (both heads' DMDs must match: one pattern
/// set serves both), the rest from the options.
fn hardware_config(
    args: &Args,
    mode: Mode,
    calibration: &RigCalibration,
) -> anyhow::Result<ScanConfig> {
    let Some(a) = calibration.heads.first() else {
        anyhow::bail!("the calibration has no head");
    };
    let dmd = (a.projector.width_px, a.projector.height_px);
    if let Some(other) = calibration
        .heads
        .iter()
        .find(|h| (h.projector.width_px, h.projector.height_px) != dmd)
    {
        anyhow::bail!(
            "head {}'s DMD is {}x{} but head {}'s is {}x{}: one pattern set serves both heads",
            other.name,
            other.projector.width_px,
            other.projector.height_px,
            a.name,
            dmd.0,
            dmd.1
        );
    }
    let mut config = ScanConfig::new("hardware");
    config.mode = mode;
    config.camera_px = (a.camera.width_px, a.camera.height_px);
    config.projector_px = dmd;
    config.periods_px = periods_for(args, mode, dmd.0);
    config.noise_sigma = args.noise_sigma;
    config.shot_noise_share = args.shot_noise_share;
    config.precompensate_gamma = args.precompensate_gamma;
    config.dealias = args.dealias.into();
    config.learned = load_network(args, mode, &config.periods_px, config.steps)?;
    config.exposures = exposures_for(args);
    config.frames_per_pattern = args.average_frames;
    config.saturation_level = args.saturation_level;
    config.medium = medium_for(args, &config.periods_px, |_| None)?;
    Ok(config)
}

/// The shipped one-step de-aliaser.
const DEFAULT_MODEL: &str = "models/dealias_onestep.onnx";

/// The shipped underwater restorer.
const DEFAULT_RESTORER_MODEL: &str = "models/underwater_onestep.onnx";

/// `given`, or the shipped model `default` (a path from the repository
/// root), found beside the sources when the working directory is elsewhere.
fn shipped_model(given: Option<&Path>, default: &str) -> PathBuf {
    match given {
        Some(p) => p.to_path_buf(),
        None if Path::new(default).exists() => PathBuf::from(default),
        None => Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("..")
            .join(default),
    }
}

/// `--dealias learned` in the simultaneous mode: the network, loaded and
/// checked against the scan's fringes before anything is captured.
fn load_network(
    args: &Args,
    mode: Mode,
    periods_px: &[f64],
    steps: usize,
) -> anyhow::Result<Option<std::sync::Arc<slscan::dealias::learned::LearnedDealiaser>>> {
    if mode != Mode::Simultaneous || DealiasMethod::from(args.dealias) != DealiasMethod::Learned {
        return Ok(None);
    }
    let path = shipped_model(args.dealias_model.as_deref(), DEFAULT_MODEL);
    let network = slscan::dealias::learned::LearnedDealiaser::load(
        &path,
        periods_px,
        steps,
        args.sampler_steps,
    )?;
    tracing::warn!(
        model = %path.display(),
        "learned de-aliasing: the shipped networks recover the overlap worse than --dealias \
         analytic (models/README.md)"
    );
    Ok(Some(std::sync::Arc::new(network)))
}

fn print_summary(report: &ScanReport) {
    let f1 = |v: Option<f64>| figure(v, 1, "um");
    let f3 = |v: Option<f64>| figure(v, 3, "");
    for h in &report.heads {
        println!(
            "head {}: {} points, RMSE {} (predicted {}; median {}, {} over 1 mm), coverage {}",
            h.name,
            h.points,
            f1(h.rmse_um),
            f1(Some(h.predicted_rms_um)),
            f1(h.median_error_um),
            h.outliers_over_1mm
                .map_or("n/a".to_string(), |n| n.to_string()),
            f3(h.coverage)
        );
        let e = &h.exposure;
        let pct = |f: f64| format!("{:.2} %", 100.0 * f);
        match &e.adaptive {
            Some(a) => println!(
                "head {} exposure: {}, {} images, adapted fringes at {:.3} x the standard exposure ({}); saturated {} -> {}, below the modulation floor {} -> {}; {} pixels lowered ({} placed by homography, {} unplaced)",
                h.name,
                e.kind,
                e.images,
                a.exposure_scale,
                a.exposure_limited_by,
                pct(a.saturated_fraction_before),
                pct(e.saturated_fraction),
                pct(a.below_modulation_floor_fraction_before),
                pct(e.below_modulation_floor_fraction),
                a.lowered_pixels,
                a.mapped_by_homography_pixels,
                a.unmapped_pixels
            ),
            None => println!(
                "head {} exposure: {}, {} images at {:?} x the standard exposure, {} averaged per pattern; saturated {}, below the modulation floor {}",
                h.name,
                e.kind,
                e.images,
                e.exposure_scales,
                e.frames_per_pattern,
                pct(e.saturated_fraction),
                pct(e.below_modulation_floor_fraction)
            ),
        }
        if let (Some(points), Some(pixels @ 1..)) = (h.overlap_points, h.overlap_pixels) {
            println!(
                "head {} overlap (pixels lit by both projectors): {points} of {pixels} pixels reconstructed, RMSE {}",
                h.name,
                f1(h.overlap_rmse_um)
            );
        }
        for s in &h.spheres {
            println!(
                "head {} sphere {}: {} points, radius {:.4} mm (true {:.4}, error {:+.1} um), centre error {:.1} um, fit RMSE {:.1} um (noise limit {:.1} um)",
                h.name,
                s.name,
                s.points,
                s.radius_mm,
                s.true_radius_mm,
                s.radius_error_um,
                s.centre_error_um,
                s.fit_rmse_um,
                s.noise_limit_um
            );
        }
        if let Some(e) = h.sphere_centre_distance_error_um {
            println!("head {} sphere centre distance error {e:+.1} um", h.name);
        }
        if let Some(d) = &h.dealias {
            println!(
                "head {} de-aliasing ({}): {} pixels lit by the other projector, {} also by its own; {} separated, {} ill-posed, {} misfit, {} unsolved, {} inconsistent",
                h.name,
                d.method,
                d.affected_pixels,
                d.attempted_pixels,
                d.separated_pixels,
                d.ill_posed_pixels,
                d.misfit_pixels,
                d.unsolved_pixels,
                d.inconsistent_pixels
            );
            if let Some(n) = &d.network {
                println!(
                    "head {} network {} ({}): {} tiles, {} evaluations ({} per tile), {} NaN/saturated pixels masked, {} ms",
                    h.name, n.model, n.kind, n.tiles, n.evaluations, n.sampler_steps, d.bad_input_pixels, d.time_ms
                );
            }
        }
        if let Some(m) = &h.aliased_mask {
            println!(
                "head {} overlap measured by flat fields: {} px lit by both projectors, true overlap {} px, IoU {:.4}, recall {:.4}",
                h.name, m.measured_overlap_pixels, m.true_overlap_pixels, m.iou, m.recall
            );
        }
    }
    let f = &report.fused;
    println!(
        "fused: {} points, RMSE {} (point-to-plane), coverage {}",
        f.points,
        f1(f.rmse_um),
        f3(f.coverage)
    );
    match &f.icp {
        Some(icp) => println!(
            "ICP correction of the calibrated pose: {:.4} deg / {:.1} um, overlap RMSE {:.1} um",
            icp.rotation_deg, icp.translation_um, icp.overlap_rmse_um
        ),
        None if report.heads.len() == 1 => {
            println!("one head: its cloud is the scan (nothing to register)")
        }
        None if f.registration.is_some() => print_registration(report),
        None if f.failure.is_some() => {
            println!("no fused cloud: the heads could not be registered")
        }
        None => println!("no ICP: the heads share no usable surface; calibrated pose used"),
    }
    println!("calibration: {}", report.calibration);
    print_calibration_vs_truth(report);
    if report.surface_samples.is_none() {
        println!("no ground truth: RMSE and coverage are not measured (null in report.json)");
    }
    for w in &report.warnings {
        eprintln!("slscan: WARNING: {w}");
    }
}

/// Three or four heads: what joint registration did, per head and per pair.
fn print_registration(report: &ScanReport) {
    let Some(r) = &report.fused.registration else {
        return;
    };
    println!(
        "multi-view registration: {} in {} iterations; self-check: {}",
        if r.converged {
            "converged"
        } else {
            "did NOT converge"
        },
        r.iterations,
        r.verdict
    );
    for h in &report.heads {
        if let Some(g) = &h.registration {
            println!(
                "  head {}: correction of the calibrated pose {:.4} deg / {:.1} um, fitness {:.3}, pose vs truth {} / {}",
                h.name,
                g.rotation_deg,
                g.translation_um,
                g.fitness,
                figure(h.pose_error_vs_truth_deg, 4, "deg"),
                figure(h.pose_error_vs_truth_um, 1, "um")
            );
        }
    }
    for p in &r.pairs {
        println!(
            "  heads {}: overlap RMSE {:.1} um over {} point pairs (noise predicts {}), shape disagreement {}",
            p.heads,
            p.overlap_rmse_um,
            p.inliers,
            figure(p.predicted_overlap_um, 1, "um"),
            figure(p.shape_disagreement_um, 1, "um")
        );
    }
}

/// In simulation: an estimated calibration's error against the twin's
/// truth, and the frame fits applied before measuring.
fn print_calibration_vs_truth(report: &ScanReport) {
    if let Some(e) = &report.calibration_vs_truth {
        for h in &e.heads {
            println!(
                "  head {} vs twin truth: camera dfx {:+.2} dcx {:+.2} dcy {:+.2} px, projector dfx {:+.2} dcy {:+.2} px, camera->projector {:.3} deg / {:.2} mm",
                h.name,
                h.camera.dfx_px,
                h.camera.dcx_px,
                h.camera.dcy_px,
                h.projector.dfx_px,
                h.projector.dcy_px,
                h.camera_to_projector.rotation_deg,
                h.camera_to_projector.translation_mm
            );
        }
        if let Some(p) = &e.head_to_head {
            println!(
                "  head-to-head vs twin truth: {:.3} deg / {:.2} mm (the ICP's start)",
                p.rotation_deg, p.translation_mm
            );
        }
    }
    // With the twin's own devices the frames are the true ones, not fitted.
    if let (Some(fit), Some(_)) = (&report.truth_frame_fit, &report.calibration_vs_truth) {
        let heads: Vec<String> = fit
            .heads
            .iter()
            .map(|o| format!("{:.3} deg / {:.0} um", o.rotation_deg, o.translation_um))
            .collect();
        println!(
            "frames fitted onto the truth before measuring: heads {}, fused {:.3} deg / {:.0} um",
            heads.join(", "),
            fit.fused.rotation_deg,
            fit.fused.translation_um
        );
    }
    if let (Some(deg), Some(um)) = (
        report.fused.pose_error_vs_truth_deg,
        report.fused.pose_error_vs_truth_um,
    ) {
        println!("B->A pose used vs truth (frames fitted): {deg:.4} deg / {um:.1} um");
    }
}

/// One progress bar per stage.
pub(super) struct Bars {
    style: ProgressStyle,
    bar: Option<ProgressBar>,
}

impl Bars {
    pub(super) fn new() -> Self {
        let style = ProgressStyle::with_template("{prefix:>18} [{bar:30}] {pos}/{len} {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> ");
        Bars { style, bar: None }
    }

    pub(super) fn on(&mut self, p: Progress) {
        match p {
            Progress::Stage { name, total } => {
                self.bar = Some(
                    ProgressBar::new(total)
                        .with_style(self.style.clone())
                        .with_prefix(name),
                );
            }
            Progress::Step => {
                if let Some(b) = &self.bar {
                    b.inc(1);
                }
            }
            Progress::Done => {
                if let Some(b) = self.bar.take() {
                    b.finish();
                }
            }
        }
    }
}
