//! A whole scan: plan -> capture -> reconstruct -> fuse -> measure.
//!
//! ```text
//! rig file (`calibrate`) or the twin's truth ──> RigCalibration (per head frame)
//! per head (sequential mode: head A alone, then head B alone):
//!   fringe set ──Projector::load_sequence──> DMD table
//!   plan (one pattern per exposure) ──Board::run_plan──> board-clock timeline
//!   ──Camera::take_frames──> one frame per trigger ──Reconstructor──> cloud
//! clouds A, B ──fusion::fuse_heads (ICP from the calibrated B->A)──> fused cloud
//! every cloud ──truth_frame (rigid fit of its frame)──metrics (twin ground truth)──> RMSE, coverage
//! ```
//!
//! [`run_sim`] does it all on the simulated rig and returns a [`ScanResult`]
//! in memory; [`output::write_scan`] writes it (every file via a temporary
//! and a rename, `scan.ply` last), so a failed scan writes no `scan.ply`.

pub mod calibration_source;
pub mod capture;
mod clouds;
mod fuse;
pub mod metrics;
pub mod output;
pub mod plan;
pub mod truth_frame;
pub mod twin_truth;

use std::sync::Arc;
use std::time::Instant;

use hil_sim::board::SimBoardConfig;
use hil_sim::twin::scenes::{built_in, Detail};
use hil_sim::twin::{SensorModel, TwinError, TwinRig};
use nalgebra::{Isometry3, Vector3};

use crate::board::ClientConfig;
use crate::fusion::{FusionError, IcpResult};
use crate::patterns::three_pitch_periods_px;
use crate::point_cloud::PointCloud;
use crate::raster::Raster;
use crate::reconstruct::{ReconstructConfig, ReconstructError, Reconstruction, Reconstructor};
use crate::rig::sim::{SimRig, SimRigConfig};
use crate::rig::RigError;
pub use calibration_source::{CalibrationSource, UsedCalibration};
use clouds::{from_fusion, points_f64, transformed};
use metrics::{PixelAccuracy, Sample};

/// How the two heads share time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Head A alone, then head B alone (seed 000's reference runs): no aliasing.
    Sequential,
    /// Both heads at once with identical sequences: the overlap is aliased
    /// and masked out (no de-aliaser yet).
    Simultaneous,
    /// Both at once, N = 8, head A's shifts at temporal frequency 1, B's at 2,
    /// separated per pixel by [`crate::demultiplex`].
    SimultaneousMultiplexed,
}

/// Everything a simulated scan needs.
#[derive(Clone, Debug)]
pub struct ScanConfig {
    /// Built-in twin scene with two heads (e.g. `large-part`).
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
    /// Seed of device jitter and sensor noise.
    pub seed: u64,
    /// Simulated board faults (for failure tests).
    pub board: SimBoardConfig,
    /// Timeouts of the board client.
    pub client: ClientConfig,
    /// The calibration to reconstruct with (default: the twin's truth).
    pub calibration: CalibrationSource,
}

impl ScanConfig {
    /// Sequential scan of `scene` at 640x480 / 1280x800 with
    /// [`default_periods_px`]. (Seed 000's 100/110/120/130 px set works
    /// too, but its coarse fringes give about 5x the depth noise here.)
    pub fn new(scene: &str) -> Self {
        ScanConfig {
            scene: scene.to_string(),
            mode: Mode::Sequential,
            camera_px: (640, 480),
            projector_px: (1280, 800),
            periods_px: default_periods_px(1280),
            steps: 4,
            seed: 1,
            board: SimBoardConfig::default(),
            client: ClientConfig {
                attempt_timeout: std::time::Duration::from_secs(2),
                attempts: 3,
            },
            calibration: CalibrationSource::TwinTruth,
        }
    }
}

/// Seed 004's three pitches over the DMD width, S = 64 fringes: about
/// 17.5 / 20 / 22.9 px on a 1280 px DMD, one beat spanning the width.
/// (On `large-part` at 320x240: S = 36 gives 1.6x the depth noise, seed
/// 000's 100/110/120/130 px set about 5x.)
pub fn default_periods_px(dmd_width_px: u32) -> Vec<f64> {
    three_pitch_periods_px(f64::from(dmd_width_px), 64).to_vec()
}

/// The simulated cameras' sensor: 12-bit mono with its exposure set so a
/// full-on pattern on a white diffuser at the reference distance fills 70 %
/// of the well over one pattern's display time.
pub fn sim_sensor() -> SensorModel {
    let mut sensor = SensorModel::mono12();
    sensor.electrons_per_unit = 0.7 * sensor.full_well_e / plan::display_s();
    sensor
}

/// The sensor's noise at half scale (shot + read, datasheet figures), in
/// frame units: what the reconstruction's noise prediction assumes.
pub fn noise_sigma(sensor: &SensorModel) -> f32 {
    let half_e = 0.5 * sensor.full_well_e;
    ((half_e + sensor.read_noise_e.powi(2)).sqrt() / sensor.full_well_e) as f32
}

/// What can stop a scan.
#[derive(Debug, thiserror::Error)]
pub enum ScanError {
    /// The scene could not be built or rendered.
    #[error("digital twin")]
    Twin(#[from] TwinError),
    /// The scene has not the two heads a dual-head scan needs.
    #[error("scene {scene} has {cameras} cameras and {projectors} projectors; a dual-head scan needs 2 of each")]
    NotDualHead {
        /// Scene name.
        scene: String,
        /// Cameras in its rig.
        cameras: usize,
        /// Projectors in its rig.
        projectors: usize,
    },
    /// Demultiplexing a camera's frames failed.
    #[error("demultiplex head {head}")]
    Demultiplex {
        /// Head name.
        head: &'static str,
        /// Why.
        source: crate::demultiplex::DemuxError,
    },
    /// The calibration file is unusable (checked before any capture).
    #[error("calibration")]
    Calibration(#[from] calibration_source::CalibrationSourceError),
    /// The plan could not be built.
    #[error("plan")]
    Plan(#[from] plan::PlanBuildError),
    /// Board, projector or camera failed (board silent, missing frame, ...).
    #[error("rig")]
    Rig(#[from] RigError),
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
}

/// Runs [`run_sim`] and, only when it succeeded, writes the result into
/// `dir` ([`output::write_scan`]): a failed scan leaves no `scan.ply`.
pub fn scan_to_dir(
    config: &ScanConfig,
    dir: &std::path::Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<crate::io::report::ScanReport, ScanError> {
    let result = run_sim(config, progress)?;
    Ok(output::write_scan(dir, &result)?)
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
    /// The first fringe frame the camera took (for pictures).
    pub first_frame: Raster<f32>,
    /// Per-pixel reconstruction, head frame.
    pub reconstruction: Reconstruction,
    /// The cloud moved into head A's frame (the fused frame).
    pub cloud_in_a: PointCloud,
    /// Per-pixel error map against the truth, metres (NaN where not valid).
    pub error_m: Raster<f32>,
    /// Per-pixel accuracy.
    pub accuracy: PixelAccuracy,
    /// Point-to-plane RMSE against the true surface, metres.
    pub plane_rmse_m: f64,
    /// Coverage of the measurable object surface.
    pub coverage: f64,
    /// How the head's calibrated frame was fitted onto the truth before measuring.
    pub frame_fit: truth_frame::FrameFit,
}

/// The fused result.
#[derive(Clone, Debug)]
pub struct FusedResult {
    /// The cloud, head A's frame.
    pub cloud: PointCloud,
    /// Registration of B onto A (`None` when the heads share no surface,
    /// as in simultaneous mode with the aliased overlap masked out).
    pub icp: Option<IcpResult>,
    /// Point-to-plane RMSE against the true surface, metres.
    pub plane_rmse_m: f64,
    /// Coverage of the measurable object surface.
    pub coverage: f64,
    /// Error of the B->A pose used (ICP-refined, or calibrated without ICP)
    /// against the twin's true B->A, both heads' frames fitted onto the
    /// truth: (degrees, metres).
    pub residual_pose_error: (f64, f64),
    /// How head A's calibrated frame (the fused frame) was fitted onto the truth.
    pub frame_fit: truth_frame::FrameFit,
}

/// A finished scan, in memory.
#[derive(Clone, Debug)]
pub struct ScanResult {
    /// The configuration it ran with.
    pub config: ScanConfig,
    /// The calibration it reconstructed with.
    pub calibration: UsedCalibration,
    /// Heads A and B.
    pub heads: Vec<HeadResult>,
    /// The fused cloud.
    pub fused: FusedResult,
    /// Samples of the measurable object surface.
    pub surface_samples: usize,
    /// Wall-clock time per stage, milliseconds, in order.
    pub timings_ms: Vec<(&'static str, f64)>,
    /// Loud caveats of this run (masked aliased pixels, ...).
    pub warnings: Vec<String>,
}

struct Clock {
    last: Instant,
    timings: Vec<(&'static str, f64)>,
}

impl Clock {
    fn lap(&mut self, name: &'static str) {
        let now = Instant::now();
        let ms = (now - self.last).as_secs_f64() * 1e3;
        tracing::info!(stage = name, ms = format_args!("{ms:.0}"), "stage done");
        self.timings.push((name, ms));
        self.last = now;
    }
}

/// Runs a dual-head scan on the simulated rig (board on a pty, twin cameras).
pub fn run_sim(
    config: &ScanConfig,
    progress: &mut dyn FnMut(Progress),
) -> Result<ScanResult, ScanError> {
    let mut clock = Clock {
        last: Instant::now(),
        timings: Vec::new(),
    };
    let detail = Detail {
        camera: config.camera_px,
        projector: config.projector_px,
    };
    let (scene, rig) = built_in(&config.scene, &detail)?;
    if rig.cameras.len() != 2 || rig.projectors.len() != 2 {
        return Err(ScanError::NotDualHead {
            scene: config.scene.clone(),
            cameras: rig.cameras.len(),
            projectors: rig.projectors.len(),
        });
    }
    // Before anything is captured: a bad rig file ends the scan here.
    let used = calibration_source::resolve(
        &config.calibration,
        &rig,
        config.camera_px,
        config.projector_px,
    )?;
    let calibration = &used.rig;
    let is_object = metrics::object_ids(&scene);
    let twin = Arc::new(TwinRig::new(scene, rig)?);
    let sensor = sim_sensor();
    let noise_sigma = noise_sigma(&sensor);
    progress(Progress::Stage {
        name: "ray-cast cameras",
        total: 2,
    });
    for cam in 0..2 {
        twin.renderer(cam)?;
        progress(Progress::Step);
    }
    progress(Progress::Done);
    let mut sim = SimRig::start(
        twin.clone(),
        SimRigConfig {
            board: config.board.clone(),
            client: config.client,
            sensor,
            noise_seed: config.seed,
        },
    )?;
    clock.lap("setup");

    let mut captured = capture::capture(&mut sim, config, progress)?;
    clock.lap("capture");
    let mut warnings = Vec::new();
    if config.mode == Mode::Simultaneous {
        capture::mask_aliased_overlap(&mut captured, &twin, &mut warnings)?;
    }

    // Reconstruct each head in its own frame.
    let mut recons = Vec::new();
    progress(Progress::Stage {
        name: "reconstruct",
        total: 2,
    });
    for (h, head_frames) in captured.frames.iter().enumerate() {
        let head_name = twin_truth::HEAD_NAMES[h];
        let mut rc_config = ReconstructConfig::new(config.periods_px.clone());
        rc_config.steps = captured.steps;
        rc_config.noise_sigma = noise_sigma * captured.noise_factor;
        let rc = Reconstructor::from_head(&calibration.heads[h], rc_config).map_err(|source| {
            ScanError::Reconstruct {
                head: head_name,
                source,
            }
        })?;
        let refs: Vec<&Raster<f32>> = head_frames.iter().collect();
        let r = rc
            .reconstruct(&refs, None)
            .map_err(|source| ScanError::Reconstruct {
                head: head_name,
                source,
            })?;
        tracing::info!(head = head_name, points = r.cloud.len(), "reconstructed");
        recons.push(r);
        progress(Progress::Step);
    }
    progress(Progress::Done);
    clock.lap("reconstruct");

    // Fuse B into A, starting from the calibrated B -> A.
    progress(Progress::Stage {
        name: "fuse",
        total: 1,
    });
    let a_from_b_calibrated: Isometry3<f64> = used.a_from_b();
    let fused = fuse::fuse(
        &recons[0].cloud,
        &recons[1].cloud,
        &a_from_b_calibrated,
        config,
        &mut warnings,
    )?;
    progress(Progress::Step);
    progress(Progress::Done);
    clock.lap("fuse");

    // Measure against the truth, everything in head A's calibrated frame,
    // each cloud's frame first fitted onto the truth (see truth_frame).
    progress(Progress::Stage {
        name: "measure",
        total: 3,
    });
    let geometries: Vec<_> = (0..2).map(|h| twin.renderer(h)).collect::<Result<_, _>>()?;
    let any_pixel = |g: &hil_sim::twin::CameraGeometry| -> Vec<bool> {
        g.point_m.iter().map(|p| p[0].is_finite()).collect()
    };
    let fused_cloud = from_fusion(&fused.cloud);
    let fused_pts = points_f64(&fused_cloud);
    let true_a_from_world = twin_truth::head_from_world(twin.rig(), 0);
    let truth_in_true_a: Vec<Sample> = geometries
        .iter()
        .flat_map(|g| metrics::samples(g.geometry(), &any_pixel(g.geometry()), &true_a_from_world))
        .collect();
    let fused_fit = truth_frame::fit_frame(
        &fused_pts,
        &truth_in_true_a,
        &true_a_from_world,
        "fused cloud",
        &mut warnings,
    );
    let a_from_world = fused_fit.frame_from_world;
    let mut surface: Vec<Sample> = Vec::new();
    let mut all_surface: Vec<Sample> = Vec::new();
    for (h, g) in geometries.iter().enumerate() {
        let g = g.geometry();
        let own = metrics::own_object_pixels(g, h, &is_object);
        surface.extend(metrics::samples(g, &own, &a_from_world));
        all_surface.extend(metrics::samples(g, &any_pixel(g), &a_from_world));
    }
    let mut heads = Vec::new();
    for (h, recon) in recons.into_iter().enumerate() {
        let g = geometries[h].geometry();
        let true_head_from_world = twin_truth::head_from_world(twin.rig(), h);
        let frame_fit = truth_frame::fit_frame(
            &points_f64(&recon.cloud),
            &metrics::samples(g, &any_pixel(g), &true_head_from_world),
            &true_head_from_world,
            &format!("head {}", twin_truth::HEAD_NAMES[h]),
            &mut warnings,
        );
        let head_from_world = frame_fit.frame_from_world;
        let accuracy = metrics::pixel_accuracy(&recon, g, &head_from_world, h, &is_object);
        let a_from_head = a_from_world * head_from_world.inverse();
        let cloud_in_a = transformed(&recon.cloud, &a_from_head);
        let pts = points_f64(&cloud_in_a);
        let error_m = error_map(&recon, g, &head_from_world);
        heads.push(HeadResult {
            name: twin_truth::HEAD_NAMES[h],
            first_frame: captured.raw[h][0].clone(),
            plane_rmse_m: metrics::point_to_plane_rmse(&pts, &all_surface)?,
            coverage: metrics::coverage(&pts, &surface)?,
            reconstruction: recon,
            cloud_in_a,
            error_m,
            accuracy,
            frame_fit,
        });
        progress(Progress::Step);
    }
    let true_a_from_b = twin_truth::b_from_a(twin.rig()).inverse();
    let used_pose = fused
        .icp
        .as_ref()
        .map_or(a_from_b_calibrated, |icp| icp.transform);
    // The pose used maps B's calibrated frame into A's; in true frames:
    let used_in_true_frames = heads[0].frame_fit.true_from_estimate
        * used_pose
        * heads[1].frame_fit.true_from_estimate.inverse();
    let diff = used_in_true_frames * true_a_from_b.inverse();
    let fused = FusedResult {
        plane_rmse_m: metrics::point_to_plane_rmse(&fused_pts, &all_surface)?,
        coverage: metrics::coverage(&fused_pts, &surface)?,
        cloud: fused_cloud,
        icp: fused.icp,
        residual_pose_error: (
            diff.rotation.angle().to_degrees(),
            diff.translation.vector.norm(),
        ),
        frame_fit: fused_fit,
    };
    progress(Progress::Step);
    progress(Progress::Done);
    clock.lap("measure");
    Ok(ScanResult {
        config: config.clone(),
        calibration: used,
        heads,
        fused,
        surface_samples: surface.len(),
        timings_ms: clock.timings,
        warnings,
    })
}

/// |reconstructed - true| per pixel, metres (NaN where either is missing).
fn error_map(
    recon: &Reconstruction,
    truth: &hil_sim::twin::CameraGeometry,
    head_from_world: &Isometry3<f64>,
) -> Raster<f32> {
    let data = recon
        .pixels
        .data
        .iter()
        .zip(&truth.point_m)
        .map(|(px, t)| {
            if !(px.point_m[0].is_finite() && t[0].is_finite()) {
                return f32::NAN;
            }
            let tt = head_from_world * nalgebra::Point3::new(t[0] as f64, t[1] as f64, t[2] as f64);
            let p = Vector3::new(
                px.point_m[0] as f64,
                px.point_m[1] as f64,
                px.point_m[2] as f64,
            );
            (p - tt.coords).norm() as f32
        })
        .collect();
    Raster {
        width: recon.pixels.width,
        height: recon.pixels.height,
        data,
    }
}
