//! One file per `slscan` subcommand.

pub mod board;
pub mod calibrate;
pub mod patterns;
pub mod reconstruct;
pub mod scan;
