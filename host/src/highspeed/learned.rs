//! What the high-speed decoder's learned stages (ZOCR-Net, FDD-Net) share:
//! loading a one-step network of a given channel layout, and
//! [`LearnedStage`]: the check that it was trained for the set's patterns,
//! the warning for another camera size and the tiling.

use std::path::Path;

use super::set::PatternSet;
use super::HighSpeedError;
use crate::infer::Model;

/// Loads `onnx` (and its metadata) as the one-step network `name` of
/// `inputs` -> `outputs` channels trained for `set`'s patterns.
pub(super) fn load_stage(
    onnx: &Path,
    set: &PatternSet,
    name: &str,
    inputs: usize,
    outputs: usize,
) -> Result<Model, HighSpeedError> {
    let model = Model::load(onnx)?;
    let m = &model.meta;
    if model.is_diffusion() || m.cond_channels != inputs || m.frame_channels != outputs {
        return Err(HighSpeedError::BadConfig {
            why: format!(
                "model {} is a {} network with {} -> {} channels; {name} is one-step, {inputs} -> {outputs}",
                onnx.display(),
                m.kind,
                m.cond_channels,
                m.frame_channels
            ),
        });
    }
    check_set(&model, set)?;
    Ok(model)
}

/// What a loaded learned stage answers: the checks before a capture and
/// its cost, the same for every stage.
pub trait LearnedStage {
    /// The network's name in messages.
    const NAME: &'static str;
    /// Tiles overlap by this much (about what the network sees).
    const TILE_OVERLAP_PX: usize;

    /// The loaded network.
    fn model(&self) -> &Model;

    /// Whether the network was trained for `set`'s patterns (their DMD
    /// periods, in projection order).
    fn check_set(&self, set: &PatternSet) -> Result<(), HighSpeedError> {
        check_set(self.model(), set)
    }

    /// A warning when the network was trained on frames of another size
    /// than `width` x `height`: its fringes' periods in camera pixels, all it
    /// knows, then differ from what it saw in training.
    fn size_warning(&self, width: usize, height: usize) -> Option<String> {
        let model = self.model();
        let trained = model.meta.data.as_ref()?.size;
        (trained != [width, height]).then(|| {
            format!(
                "{} {} was trained on {}x{} twin frames; this camera's are {width}x{height}, \
                 so its fringe periods in pixels may lie outside what the network saw",
                Self::NAME,
                model.path.display(),
                trained[0],
                trained[1]
            )
        })
    }

    /// The network's file.
    fn path(&self) -> &Path {
        &self.model().path
    }

    /// Tiles of `width` x `height` the network runs per exposure.
    fn tiles_per_exposure(&self, width: usize, height: usize) -> usize {
        let t = self.model().meta.tile;
        let along = |n| crate::infer::tiles::axis_origins(n, t, Self::TILE_OVERLAP_PX).len();
        along(width) * along(height)
    }
}

/// Whether `model` was trained for `set`'s patterns.
fn check_set(model: &Model, set: &PatternSet) -> Result<(), HighSpeedError> {
    let periods = set_periods(set);
    if model.trained_for(&periods, 1) {
        return Ok(());
    }
    Err(HighSpeedError::BadPatternSet {
        why: format!(
            "model {} was trained for pattern periods {:?} DMD px, this set has {:?}",
            model.path.display(),
            model.meta.periods_px,
            periods
        ),
    })
}

/// The set's patterns' periods on the DMD, pixels, in projection order
/// (what a learned stage's metadata records it was trained for).
pub fn set_periods(set: &PatternSet) -> Vec<f64> {
    set.patterns()
        .iter()
        .map(|p| 1.0 / p.frequency[0].hypot(p.frequency[1]))
        .collect()
}
