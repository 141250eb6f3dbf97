//! One file per `slscan` subcommand.

pub mod board;
pub mod calibrate;
#[cfg(feature = "sim")]
pub mod calibrate_scene;
#[cfg(feature = "sim")]
pub mod calibrate_sim;
pub mod calibrate_sim_options;
pub mod calibration_io;
pub mod calibration_print;
pub mod devices;
pub mod fuse;
pub mod parse;
pub mod patterns;
pub mod reconstruct;
pub mod reconstruct_stereo;
pub mod register;
pub mod scan;
pub mod scan_high_speed;
pub mod transcript;

/// The error of a `--sim` option in a build without the simulator.
#[cfg(not(feature = "sim"))]
pub fn no_simulator(what: &str) -> anyhow::Error {
    anyhow::anyhow!(
        "{what}: this slscan was built without the simulator (cargo feature `sim`); \
         rebuild with default features, or use the hardware options"
    )
}
