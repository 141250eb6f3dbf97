//! The scanner's host library: from patterns and images to fused point clouds.
//!
//! (Being written.)
#![warn(missing_docs)]

pub mod demultiplex;
pub mod fusion;
