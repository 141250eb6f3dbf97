//! A high-speed scan on the simulated rig: the twin scene's head A (a colour
//! camera, a DMD with R, G, B LEDs) with the board on a pty, the product's own
//! [`run_high_speed`], and the twin's truth asked for at each pattern's instant.

use std::sync::Arc;

use hil_sim::board::SimBoardConfig;
use hil_sim::twin::scenes::{built_in, Detail};
use hil_sim::twin::{SensorModel, TwinRig};

use super::rig::{SimRig, SimRigConfig};
use super::scan::{noise_sigma, shot_noise_share, sim_board_limits, SimScanError};
use super::truth::{camera_truth_at, spheres_at, twin_calibration};
use crate::board::ClientConfig;
use crate::rig::dlpc::Controller;
use crate::scan::high_speed::{
    pattern_display_us, run_conventional, run_high_speed, ConventionalConfig, HighSpeedConfig,
    HighSpeedResult,
};
use crate::scan::Progress;

/// A simulated high-speed scan.
#[derive(Clone, Debug)]
pub struct SimHighSpeedConfig {
    /// The scan (its `scene` names the built-in twin scene).
    pub scan: HighSpeedConfig,
    /// Camera image size, pixels.
    pub camera_px: (u32, u32),
    /// DMD size, pixels.
    pub projector_px: (u32, u32),
    /// Seed of the camera's noise.
    pub seed: u64,
    /// Simulated board.
    pub board: SimBoardConfig,
    /// Timeouts of the board client.
    pub client: ClientConfig,
    /// The DLPC driver the patterns go through to hil-sim's byte-level
    /// controller (its pattern table at [`pattern_display_us`]); `None`:
    /// straight to the simulated DMD.
    pub projector_driver: Option<Controller>,
    /// Also run the conventional 12-frame capture of the same motion
    /// ([`run_conventional`]) after the high-speed one.
    pub conventional: bool,
}

impl SimHighSpeedConfig {
    /// `scene` at 640x480 / 1280x800, seed 1.
    pub fn new(scene: &str) -> Self {
        Self {
            scan: HighSpeedConfig::new(scene),
            camera_px: (640, 480),
            projector_px: (1280, 800),
            seed: 1,
            board: SimBoardConfig::default(),
            client: ClientConfig {
                attempt_timeout: std::time::Duration::from_secs(2),
                attempts: 3,
            },
            projector_driver: None,
            conventional: false,
        }
    }
}

/// The high-speed camera: 8-bit colour, its gain set so a white diffuser at
/// the reference distance lit full-on for 1.6 ms fills 80 % of the well: one
/// LED's eight patterns light a pixel for 0.8 ms on average and 1.6 ms where
/// all eight are on, so only brighter-than-white or nearer surfaces clip.
pub fn high_speed_sensor() -> SensorModel {
    let mut sensor = SensorModel::colour8();
    sensor.electrons_per_unit = 0.8 * sensor.full_well_e / 1.6e-3;
    sensor
}

/// The conventional capture's decoding with the noise of
/// [`high_speed_sensor`]'s frames read as grey (the mean of three channels
/// with independent noise) and the decoder's default depth range.
pub fn conventional_config() -> ConventionalConfig {
    let sensor = high_speed_sensor();
    ConventionalConfig {
        noise_sigma: noise_sigma(&sensor) / 3f32.sqrt(),
        shot_noise_share: shot_noise_share(&sensor),
        depth_range_m: crate::highspeed::DecoderConfig::default().depth_range_m,
    }
}

/// Runs a high-speed scan of `config.scan.scene`'s head A on the simulated
/// rig with the twin's true calibration.
pub fn run_sim_high_speed(
    config: &SimHighSpeedConfig,
    progress: &mut dyn FnMut(Progress),
) -> Result<HighSpeedResult, SimScanError> {
    let detail = Detail {
        camera: config.camera_px,
        projector: config.projector_px,
    };
    let (scene, rig) = built_in(&config.scan.scene, &detail)?;
    if rig.cameras.is_empty() || rig.projectors.is_empty() {
        return Err(SimScanError::HeadCount {
            scene: config.scan.scene.clone(),
            cameras: rig.cameras.len(),
            projectors: rig.projectors.len(),
        });
    }
    let calibration = twin_calibration(&rig, 1);
    let heads = rig.cameras.len().min(rig.projectors.len());
    let twin = Arc::new(TwinRig::new(scene, rig)?);
    progress(Progress::Stage {
        name: "ray-cast camera",
        total: 1,
    });
    twin.renderer(0)?;
    progress(Progress::Done);
    let mut sim = SimRig::start(
        twin.clone(),
        SimRigConfig {
            board: config.board.clone(),
            client: config.client,
            sensor: high_speed_sensor(),
            noise_seed: config.seed,
            board_limits: sim_board_limits(None, heads),
        },
    )?;
    if let Some(controller) = config.projector_driver {
        sim.drive_projectors_through(controller, pattern_display_us());
    }
    let truth_at = |t: f64| {
        let truth = camera_truth_at(&twin, 0, t).ok()?;
        Some((truth, spheres_at(twin.scene(), t)))
    };
    let mut result = run_high_speed(
        &mut sim,
        &config.scan,
        &calibration,
        Some(&truth_at),
        progress,
    )?;
    if config.conventional {
        let conventional = run_conventional(
            &mut sim,
            &calibration,
            &ConventionalConfig {
                depth_range_m: config.scan.decoder.depth_range_m,
                ..conventional_config()
            },
            Some(&truth_at),
            progress,
        )?;
        result.conventional = Some(conventional);
    }
    result.calibration_is_true = true;
    Ok(result)
}
