//! The scanner's host library: from patterns and images to metric point clouds.
//!
//! ```text
//! patterns (encode) --> projector ... camera --> io::images (8/16-bit -> f32 [0, 1])
//!   --> phase (N-step / FTP: wrapped phase, modulation, background)
//!   --> unwrap (heterodyne | pdm | gray_code | quality_guided: absolute phase + status)
//!   --> triangulation (calibration::RigCalibration: ray/plane or ray/ray)
//!   --> point_cloud --> io::ply (x y z, normals, colour, quality)
//! ```
//!
//! [`reconstruct::Reconstructor`] runs phase -> heterodyne -> triangulation in one fused
//! pass for one head; [`stereo::StereoReconstructor`] matches two cameras' projector
//! coordinates and triangulates them (a stereo head). `sim` (cargo feature `sim`, on by default) is the only module that
//! knows the simulator (hil-sim): the simulated rig, the twin's truth and calibration views;
//! `--no-default-features` builds the hardware path and the CLI without it. [`synth`] is a formula-based renderer for tests and benches (not the
//! digital twin); [`fit`] fits planes and spheres for accuracy reports.
//! [`underwater`] restores fringes seen through water (forward scatter, backscatter veil)
//! before `phase` (issue 18).
#![warn(missing_docs)]

pub mod adaptive;
pub mod board;
pub mod calibration;
pub mod capture;
pub mod dealias;
pub mod demultiplex;
pub mod fft2;
pub mod fit;
pub mod fusion;
pub mod highspeed;
pub mod huge_pages;
pub mod infer;
pub mod io;
pub mod patterns;
pub mod phase;
pub mod pictures;
pub mod point_cloud;
pub mod raster;
pub mod reconstruct;
pub mod rig;
pub mod scan;
#[cfg(feature = "sim")]
pub mod sim;
pub mod simd;
pub mod stereo;
pub mod synth;
pub mod triangulation;
pub mod underwater;
pub mod unwrap;
