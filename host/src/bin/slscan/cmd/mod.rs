//! One file per `slscan` subcommand.

pub mod board;
pub mod calibrate;
pub mod calibrate_scene;
pub mod patterns;
pub mod reconstruct;
pub mod scan;
