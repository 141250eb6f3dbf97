//! The options of `slscan calibrate --sim`, apart from the command so that
//! the simulated run (`calibrate_sim`, built with the `sim` feature) and the
//! command share them without importing each other.

use std::path::PathBuf;

use super::parse::parse_size;

/// Rays per pixel and axis of the twin's board renders (hil-sim's
/// `CALIBRATION_PIXEL_SAMPLES`; a test holds them equal). Written out here
/// so that the options read the same in a build without the simulator.
pub const CALIBRATION_PIXEL_SAMPLES: u32 = 4;

/// `slscan calibrate --sim` options (ignored without `--sim`).
#[derive(clap::Args)]
pub struct SimOptions {
    /// --sim: number of board poses (at most 15).
    #[arg(long, default_value_t = 12)]
    pub views: usize,
    /// --sim: sensor read noise, grey levels (0..1), photon shot noise on top; default:
    /// the twin's 12-bit sensor (6 e- of a 10 ke- full well, 0.0006).
    #[arg(long)]
    pub noise: Option<f64>,
    /// --sim: bit depth of the rendered images (8 or 16).
    #[arg(long, default_value_t = 8, value_parser = parse_bits)]
    pub bits: u8,
    /// --sim: simulate and calibrate two heads and their head-to-head pose.
    #[arg(long, requires = "sim")]
    pub two_heads: bool,
    /// --sim: rays per camera pixel and axis of the board renders (each pixel
    /// integrates over its area); 1 renders one aliased ray per pixel.
    #[arg(long, default_value_t = CALIBRATION_PIXEL_SAMPLES,
          value_parser = clap::value_parser!(u32).range(1..=16))]
    pub pixel_samples: u32,
    /// --sim --two-heads / --scene: name of the second head.
    #[arg(long, default_value = "B")]
    pub head_b: String,
    /// --sim: calibrate every head of this built-in twin scene of two to four
    /// heads and each head's pose from the first (same devices and head poses as
    /// `scan --sim --scene NAME`), e.g. `large-part`, `ring-4`; heads past the
    /// second are named C, D.
    #[arg(
        long,
        value_name = "NAME",
        requires = "sim",
        conflicts_with = "two_heads"
    )]
    pub scene: Option<String>,
    /// --sim --scene: camera image size as WIDTHxHEIGHT (must match the scan's).
    #[arg(long, value_name = "WxH", value_parser = parse_size, default_value = "640x480")]
    pub camera: (u32, u32),
    /// --sim: also write the rendered board images (PNG) and phase maps (.npy) here
    /// (one folder per head with --two-heads).
    #[arg(long, value_name = "DIR")]
    pub save_images: Option<PathBuf>,
}

fn parse_bits(s: &str) -> Result<u8, String> {
    match s.trim() {
        "8" => Ok(8),
        "16" => Ok(16),
        other => Err(format!("{other:?}: bit depth is 8 or 16")),
    }
}
