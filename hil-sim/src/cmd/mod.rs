//! One file per `hil-sim` subcommand.

pub mod dataset;
pub mod render;
pub mod scenes;
pub mod serve;
pub mod soak;
