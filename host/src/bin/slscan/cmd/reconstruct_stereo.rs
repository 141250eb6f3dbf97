//! `slscan reconstruct --stereo`: a stereo head's two frame folders (left, right) ->
//! each camera's projector columns through the capture's description -> matched and
//! triangulated by `slscan::stereo`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use slscan::calibration::StereoHead;
use slscan::capture::decode::{decode, AxisCoordinates};
use slscan::capture::{CaptureSpec, Frames, ProjectorAxis};
use slscan::io::images::{list_images, load_set, ExposureLimits};
use slscan::raster::Raster;
use slscan::reconstruct::Reconstruction;
use slscan::stereo::{StereoConfig, StereoReconstructor};

use super::reconstruct::lap;

/// What the stereo path gives back: the result (left camera's pixels), the left frames
/// (for the pictures) and the left camera's decoded axes (for the page).
pub type StereoResult = (Reconstruction, Vec<Raster<f32>>, Vec<AxisCoordinates>);

/// The inputs of one stereo reconstruction.
pub struct StereoInputs<'a> {
    /// The head.
    pub head: &'a StereoHead,
    /// How the frames (the same sequence in both folders) are to be decoded.
    pub spec: &'a CaptureSpec,
    /// The left camera's frames.
    pub left: &'a Path,
    /// The right camera's frames.
    pub right: &'a Path,
    /// The projector's size (it is not calibrated; its size bounds the coordinates).
    pub projector: (u32, u32),
    /// Intensity noise at half scale, full-scale units.
    pub noise_sigma: f32,
}

/// Decodes both cameras, then matches and triangulates; stage times into `timings`.
pub fn reconstruct_stereo(
    inputs: &StereoInputs,
    timings: &mut Vec<(String, f64)>,
) -> anyhow::Result<StereoResult> {
    let spec = inputs.spec;
    let steps = finest_steps(spec).context(
        "a stereo head matches fringe phases; this capture has no column fringes \
         (Gray codes alone give whole projector pixels, too coarse to match)",
    )?;
    let paths: Vec<Vec<PathBuf>> = [inputs.left, inputs.right]
        .iter()
        .map(|dir| {
            let paths = list_images(dir)?;
            spec.check_frame_count(paths.len())
                .with_context(|| format!("frames in {}", dir.display()))?;
            Ok(paths)
        })
        .collect::<anyhow::Result<_>>()?;
    let limits = ExposureLimits {
        max_saturated_percent: 100.0,
        min_range: 0.0,
        ..ExposureLimits::default()
    };
    let mut decoded = Vec::with_capacity(2);
    let mut left_frames = Vec::new();
    for (side, paths) in ["left", "right"].into_iter().zip(&paths) {
        let clock = Instant::now();
        let frames = load_set(paths, &limits)?;
        lap(timings, &format!("load {side}"), clock);
        let clock = Instant::now();
        let refs: Vec<&Raster<f32>> = frames.iter().collect();
        let axes = decode(spec, &refs, inputs.projector, inputs.noise_sigma)
            .with_context(|| format!("decoding the {side} camera"))?;
        lap(timings, &format!("decode {side}"), clock);
        if side == "left" {
            left_frames = frames;
        }
        decoded.push(axes);
    }
    let columns = |axes: &[AxisCoordinates]| -> anyhow::Result<usize> {
        axes.iter()
            .position(|a| a.axis == ProjectorAxis::Column)
            .context("a stereo head matches projector columns; the capture has none")
    };
    let (l, r) = (columns(&decoded[0])?, columns(&decoded[1])?);
    let (left, right) = (&decoded[0][l], &decoded[1][r]);
    let period = left.reference_period_px;
    let mut config = StereoConfig::new(
        period,
        StereoConfig::coordinate_noise_px(f64::from(inputs.noise_sigma), steps, period),
    );
    config.min_modulation = spec.thresholds.min_modulation;
    let clock = Instant::now();
    let rec = StereoReconstructor::new(inputs.head, config)?;
    lap(timings, "rectify", clock);
    let clock = Instant::now();
    let out = rec.reconstruct(
        &left.coord_px,
        &left.modulation,
        &right.coord_px,
        &right.modulation,
    )?;
    lap(timings, "match and triangulate", clock);
    let left_axes = decoded.swap_remove(0);
    Ok((out, left_frames, left_axes))
}

/// Steps of the finest column fringe set.
fn finest_steps(spec: &CaptureSpec) -> Option<usize> {
    spec.sequence
        .iter()
        .filter_map(|e| match e {
            Frames::Fringes(f) if f.axis == ProjectorAxis::Column => f
                .periods_px
                .iter()
                .copied()
                .reduce(f64::min)
                .map(|p| (p, f.steps)),
            _ => None,
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, steps)| steps)
}
