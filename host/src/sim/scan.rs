//! A whole scan on the simulated rig: the twin scene's rig with the board on
//! a pty ([`super::rig::SimRig`]), its calibration (a rig file, or the
//! twin's truth), the product's own [`crate::scan::run_on_rig`], and the
//! twin's truth to measure against.

use std::sync::Arc;

use hil_sim::board::SimBoardConfig;
use hil_sim::twin::scenes::{built_in, Detail};
use hil_sim::twin::{SensorModel, TwinError, TwinRig};

use super::calibration_source::{self, CalibrationSource};
use super::rig::{SimRig, SimRigConfig};
use super::truth::ground_truth;
use crate::io::report::ScanReport;
use crate::rig::dlpc::Controller;
use crate::rig::RigError;
use crate::scan::calibration_file::CalibrationFileError;
use crate::scan::underwater::Medium;
use crate::scan::{output, plan, run_on_rig, Clock, Progress, ScanConfig, ScanError, ScanResult};

/// A simulated scan: the product's [`ScanConfig`] plus what only the
/// simulator has.
#[derive(Clone, Debug)]
pub struct SimScanConfig {
    /// The scan itself (its `scene` names the built-in twin scene, e.g. `large-part`).
    pub scan: ScanConfig,
    /// Seed of the cameras' sensor noise.
    pub seed: u64,
    /// Simulated board: seed of device jitter, injected faults.
    pub board: SimBoardConfig,
    /// The simulated projectors' intensity response, displayed grey g ->
    /// g^gamma (1 = a DMD in pattern mode, about 2.2 through a video input).
    pub sim_projector_gamma: f64,
    /// The calibration the scan reconstructs with (default: the twin's truth).
    pub calibration: CalibrationSource,
    /// Drive the projectors through this DMD controller's driver and
    /// hil-sim's byte-level controller (default: patterns straight to the
    /// simulated DMDs).
    pub projector_driver: Option<Controller>,
    /// Trigger (and as many feedback) lines of the simulated board; `None`:
    /// the STM32G474's 4 (two heads) for a scene of one or two heads, 8 for
    /// three or four.
    pub board_lines: Option<u8>,
}

impl SimScanConfig {
    /// [`ScanConfig::new`] of `scene` with the twin sensor's noise figures
    /// ([`noise_sigma`], [`shot_noise_share`] of [`sim_sensor`]), seed 1, a
    /// fault-free board, linear projectors and the twin's true calibration.
    pub fn new(scene: &str) -> Self {
        let mut scan = ScanConfig::new(scene);
        scan.noise_sigma = noise_sigma(&sim_sensor());
        scan.shot_noise_share = shot_noise_share(&sim_sensor());
        SimScanConfig {
            scan,
            seed: 1,
            board: SimBoardConfig::default(),
            sim_projector_gamma: 1.0,
            calibration: CalibrationSource::TwinTruth,
            projector_driver: None,
            board_lines: None,
        }
    }
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

/// The share of [`noise_sigma`]'s variance that is shot noise (the rest is
/// read noise): what `ReconstructConfig::shot_noise_share` wants.
pub fn shot_noise_share(sensor: &SensorModel) -> f32 {
    let half_e = 0.5 * sensor.full_well_e;
    (half_e / (half_e + sensor.read_noise_e.powi(2))) as f32
}

/// The simulated board's lines: `lines` trigger and as many feedback
/// lines, or by default the STM32G474's 4 for one or two heads and 8 for
/// three or four.
pub fn sim_board_limits(lines: Option<u8>, heads: usize) -> protocol::BoardLimits {
    let lines = lines.unwrap_or(if heads <= 2 { 4 } else { 8 });
    protocol::BoardLimits {
        output_channels: lines,
        feedback_channels: lines,
        ..protocol::BoardLimits::STM32G474
    }
}

/// What can stop a simulated scan: the scan's own errors, or the twin's.
#[derive(Debug, thiserror::Error)]
pub enum SimScanError {
    /// The scan failed (rig, calibration, reconstruction, fusion, output).
    #[error(transparent)]
    Scan(#[from] ScanError),
    /// The scene could not be built or rendered.
    #[error("digital twin")]
    Twin(#[from] TwinError),
    /// The scene's rig is not one to four camera-projector heads.
    #[error("scene {scene} has {cameras} cameras and {projectors} projectors; a scan takes 1 to {} heads (a camera and a projector each)", protocol::limits::MAX_HEADS)]
    HeadCount {
        /// Scene name.
        scene: String,
        /// Cameras in its rig.
        cameras: usize,
        /// Projectors in its rig.
        projectors: usize,
    },
    /// The calibration file is unusable (checked before any capture).
    #[error("calibration")]
    Calibration(#[from] CalibrationFileError),
    /// A simulated water scan needs the level of the twin's water.
    #[error("a simulated water scan needs a turbidity level (--turbidity T1..T4)")]
    NoTurbidity,
    /// The simulated rig could not be started.
    #[error("simulated rig")]
    Rig(#[from] RigError),
}

/// Removes an earlier run's outputs from `dir` ([`output::remove_stale`]),
/// runs [`run_sim`] and, only when it succeeded, writes the result into
/// `dir` ([`output::write_scan`]): a failed scan leaves no `scan.ply` or
/// `report.json`, neither its own nor an older one.
pub fn scan_to_dir(
    config: &SimScanConfig,
    dir: &std::path::Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<ScanReport, SimScanError> {
    output::remove_stale(dir).map_err(ScanError::from)?;
    let result = run_sim(config, progress)?;
    Ok(output::write_scan(dir, &result, progress).map_err(ScanError::from)?)
}

/// Runs a scan of a one- or two-head twin scene on the simulated rig (board
/// on a pty, twin cameras), reconstructing with the configured calibration and measuring
/// against the twin's ground truth.
pub fn run_sim(
    config: &SimScanConfig,
    progress: &mut dyn FnMut(Progress),
) -> Result<ScanResult, SimScanError> {
    let mut clock = Clock::start();
    let scan = &config.scan;
    let detail = Detail {
        camera: scan.camera_px,
        projector: scan.projector_px,
    };
    let (scene, mut rig) = built_in(&scan.scene, &detail)?;
    for p in &mut rig.projectors {
        p.gamma = config.sim_projector_gamma;
    }
    if let Medium::Water(water) = &scan.medium {
        let level = water.turbidity.ok_or(SimScanError::NoTurbidity)?;
        super::underwater::submerge(&mut rig, level);
    }
    let heads = rig.cameras.len();
    if !(1..=protocol::limits::MAX_HEADS).contains(&heads) || rig.projectors.len() != heads {
        return Err(SimScanError::HeadCount {
            scene: scan.scene.clone(),
            cameras: rig.cameras.len(),
            projectors: rig.projectors.len(),
        });
    }
    // Before anything is captured: a bad rig file or a mode the rig cannot
    // run ends the scan here.
    let used = calibration_source::resolve(
        &config.calibration,
        &rig,
        heads,
        scan.camera_px,
        scan.projector_px,
    )?;
    crate::scan::check_before_capture(&used.rig, scan)?;
    let twin = Arc::new(TwinRig::new(scene, rig)?);
    progress(Progress::Stage {
        name: "ray-cast cameras",
        total: heads as u64,
    });
    for cam in 0..heads {
        twin.renderer(cam)?;
        progress(Progress::Step);
    }
    progress(Progress::Done);
    let mut truth = ground_truth(&twin, heads)?;
    truth.calibration_is_true = config.calibration == CalibrationSource::TwinTruth;
    let mut sim = SimRig::start(
        twin.clone(),
        SimRigConfig {
            board: config.board.clone(),
            client: scan.client,
            sensor: sim_sensor(),
            noise_seed: config.seed,
            board_limits: sim_board_limits(config.board_lines, heads),
        },
    )?;
    if let Some(controller) = config.projector_driver {
        sim.drive_projectors_through(controller, (plan::display_s() * 1e6).round() as u32);
    }
    clock.lap("setup");
    let mut result = run_on_rig(
        &mut sim,
        &used.rig,
        &used.description,
        Some(&truth),
        scan,
        progress,
    )?;
    result.calibration_vs_truth = used.vs_truth;
    // The scan's own stages are in its timings; what follows is timed apart.
    clock.restart();
    if let Some(water) = &mut result.underwater {
        // The reference the pictures put beside each head's captured and
        // decoded frame: its first fringe through clear water.
        let fringes = plan::fringe_sequence(scan.projector_px, &scan.periods_px, scan.steps);
        if let Some(first) = fringes.first() {
            for h in 0..heads {
                let frame =
                    super::underwater::clear_water_frame(twin.scene(), twin.rig(), h, first)?;
                water.references.extend(frame);
            }
        }
        clock.lap("clear-water reference");
    }
    if result.heads.iter().any(|h| h.dealias_sample.is_some()) {
        // The reference beside each camera's de-aliased frames: its first
        // period's fringes shown by its own projector alone.
        let fringes = plan::fringe_sequence(scan.projector_px, &scan.periods_px, scan.steps);
        let first: Vec<&crate::raster::Raster<f32>> = fringes.iter().take(scan.steps).collect();
        for (h, head) in result.heads.iter_mut().enumerate() {
            if let Some(sample) = &mut head.dealias_sample {
                let frames =
                    super::reference::own_projector_frames(twin.scene(), twin.rig(), h, &first)?;
                sample.reference = Some(frames);
            }
        }
        clock.lap("de-aliasing reference");
    }
    result.timings_ms.splice(0..0, clock.timings);
    Ok(result)
}
