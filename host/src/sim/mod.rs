//! Everything of the host that knows the simulator (cargo feature `sim`, on
//! by default): the one door from the product into `hil-sim`. The product
//! modules (`calibration`, `scan`, `board`, `rig`, ...) speak only of
//! devices, frames and rig files; what measures a result against a truth
//! takes the truth as plain data (`scan::GroundTruth`), which [`truth`]
//! builds from the twin.
//!
//! ```text
//! twin scene (hil-sim) --rig::SimRig (board on a pty, twin cameras)--> scan::run_on_rig
//!                      --truth::ground_truth--> scan::GroundTruth --> scan::measure
//!                      --truth::twin_calibration / calibration_source--> RigCalibration
//!                      --calibration::{twin_head, twin_scene}--> rendered board views
//! rig::dlpc driver --dlpc::SimHidLink (HID reports)--> hil-sim's DLPC350 / DLPC900
//!                  --what the controller shows--> rig::SimRig's DMDs
//! ```

pub mod aliased;
pub mod board;
pub mod calibration;
pub mod calibration_source;
pub mod dlpc;
pub mod high_speed;
pub mod high_speed_samples;
pub mod reference;
pub mod rig;
pub mod scan;
pub mod truth;
pub mod underwater;

/// The twin's types a caller of this module needs (scene detail, sensor
/// model, render settings), so that no file outside `sim/` names `hil_sim`.
pub mod twin {
    pub use hil_sim::twin::scenes::Detail;
    pub use hil_sim::twin::{SensorModel, CALIBRATION_PIXEL_SAMPLES};
}
