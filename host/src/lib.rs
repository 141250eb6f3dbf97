//! The scanner's host library: from patterns and images to metric point clouds.
//!
//! ```text
//! patterns (encode) --> projector ... camera --> io::images
//!   --> phase (wrapped phase, modulation) --> unwrap (absolute phase)
//!   --> triangulation (with calibration::RigCalibration) --> io::ply
//! ```
//!
//! (Being written.)
#![warn(missing_docs)]

pub mod board;
pub mod calibration;
pub mod demultiplex;
pub mod fit;
pub mod fusion;
pub mod io;
pub mod patterns;
pub mod phase;
pub mod point_cloud;
pub mod raster;
pub mod reconstruct;
pub mod rig;
pub mod scan;
pub mod synth;
pub mod triangulation;
pub mod unwrap;
