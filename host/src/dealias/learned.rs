//! Learned de-aliasing (seed 000): a network trained on twin data
//! (`training/dealias/`) maps one camera's K x N aliased frames and its
//! flat fields to its own projector's clean K x N frames, tile by tile over
//! the overlap. A one-step network runs once per tile; a diffusion network
//! runs a few-step DDIM sampler (`training/dealias/sampling.py`, the same
//! schedule here).
//!
//! Normalisation, as `training/dealias/data.py` documents it: per pixel
//! `s = max(own - dark, 0) + max(other - dark, 0)` (at least `s_min`);
//! condition = the frames and the own and other flat fields, less dark,
//! over s; the output x0 gives `clean = dark + s (x0 + (own - dark) / s) / 2`.

use std::path::Path;

use crate::infer::tiles::{infer_tiled, Planes};
use crate::infer::{Model, ModelError};
use crate::raster::Raster;
use crate::scan::aliasing::FlatFields;

/// Tiles overlap by this many pixels (a quarter of a 64 px tile): enough
/// for the ramp to hide the tile edges, where the network sees zero padding.
const TILE_OVERLAP_PX: usize = 16;

/// A trained de-aliasing network, checked against the scan it serves.
#[derive(Clone, Debug)]
pub struct LearnedDealiaser {
    model: Model,
    sampler_steps: usize,
}

/// What one camera's learned de-aliasing ran.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LearnedRun {
    /// Tiles run.
    pub tiles: usize,
    /// Network evaluations (tiles x sampler steps).
    pub evaluations: usize,
}

/// Why a model does not fit the scan.
#[derive(Debug, thiserror::Error)]
pub enum LearnedError {
    /// The model cannot be loaded.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// Trained for other fringes than the scan shows.
    #[error("model {path}: trained on periods {trained:?} px x {trained_steps} steps, the scan uses {scan:?} px x {scan_steps} steps")]
    Patterns {
        /// The model file.
        path: String,
        /// Its periods.
        trained: Vec<f64>,
        /// Its steps.
        trained_steps: usize,
        /// The scan's periods.
        scan: Vec<f64>,
        /// The scan's steps.
        scan_steps: usize,
    },
    /// The channel counts are not K x N frames + 2 flat fields in, K x N out.
    #[error("model {path}: {cond} condition / {frames} frame channels, the scan needs {want_cond} / {want_frames}")]
    Channels {
        /// The model file.
        path: String,
        /// Its condition channels.
        cond: usize,
        /// Its frame channels.
        frames: usize,
        /// Needed condition channels.
        want_cond: usize,
        /// Needed frame channels.
        want_frames: usize,
    },
    /// A diffusion model needs at least one sampler step.
    #[error("a diffusion model needs at least one sampler step")]
    NoSteps,
}

impl LearnedDealiaser {
    /// Loads `onnx` and checks it was trained for `periods_px` x `steps`;
    /// `sampler_steps` is used by diffusion models only.
    pub fn load(
        onnx: &Path,
        periods_px: &[f64],
        steps: usize,
        sampler_steps: usize,
    ) -> Result<Self, LearnedError> {
        let model = Model::load(onnx)?;
        let m = &model.meta;
        let path = onnx.display().to_string();
        if !model.trained_for(periods_px, steps) {
            return Err(LearnedError::Patterns {
                path,
                trained: m.periods_px.clone(),
                trained_steps: m.steps_per_period,
                scan: periods_px.to_vec(),
                scan_steps: steps,
            });
        }
        let frames = periods_px.len() * steps;
        if m.frame_channels != frames || m.cond_channels != frames + 2 {
            return Err(LearnedError::Channels {
                path,
                cond: m.cond_channels,
                frames: m.frame_channels,
                want_cond: frames + 2,
                want_frames: frames,
            });
        }
        if model.is_diffusion() && sampler_steps == 0 {
            return Err(LearnedError::NoSteps);
        }
        Ok(LearnedDealiaser {
            model,
            sampler_steps,
        })
    }

    /// The network's name.
    pub fn network(&self) -> &str {
        &self.model.meta.network
    }

    /// The loaded model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Network evaluations per tile: the sampler's steps, or 1.
    pub fn evaluations_per_tile(&self) -> usize {
        self.model.evaluations_per_tile(self.sampler_steps)
    }

    /// The own projector's clean frames (`K N x H x W`, NaN where not run)
    /// of the pixels `needed`, from the condition planes ([`condition`]).
    /// `seed` makes a diffusion sample reproducible.
    pub fn predict(
        &self,
        cond: &Planes,
        needed: &[bool],
        seed: u64,
    ) -> Result<(Vec<f32>, LearnedRun), ModelError> {
        let meta = &self.model.meta;
        let tiled = infer_tiled(
            cond,
            needed,
            meta.tile,
            TILE_OVERLAP_PX,
            meta.frame_channels,
            |k, tile| self.model.predict_tile(tile, k, self.sampler_steps, seed),
        )?;
        let run = LearnedRun {
            tiles: tiled.tiles,
            evaluations: tiled.tiles * self.evaluations_per_tile(),
        };
        Ok((tiled.data, run))
    }
}

/// The network's condition planes for head `own`'s camera (`K N + 2` x H
/// x W) and each pixel's light scale s.
pub fn condition(
    frames: &[Raster<f32>],
    flat: &FlatFields,
    own: usize,
    s_min: f32,
) -> (Vec<f32>, Vec<f32>) {
    let (own_flat, other_flat) = flat.own_other(own);
    let dark = &flat.dark.data;
    let scale: Vec<f32> = dark
        .iter()
        .zip(&own_flat.data)
        .zip(&other_flat.data)
        .map(|((&d, &o), &t)| ((o - d).max(0.0) + (t - d).max(0.0)).max(s_min))
        .collect();
    let plane = dark.len();
    let mut cond = Vec::with_capacity((frames.len() + 2) * plane);
    for f in frames
        .iter()
        .map(|f| &f.data)
        .chain([&own_flat.data, &other_flat.data])
    {
        cond.extend(
            f.iter()
                .zip(dark)
                .zip(&scale)
                .map(|((&v, &d), &s)| (v - d) / s),
        );
    }
    (cond, scale)
}

/// Clean frame `k` of pixel `i` from the network output x0.
pub fn clean_frame(x0: f32, own_flat: f32, dark: f32, scale: f32) -> f32 {
    dark + 0.5 * (scale * x0 + (own_flat - dark))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn condition_and_clean_frame_invert_each_other() {
        let r = |v: f32| Raster::from_fn(2, 1, |x, _| v + 0.01 * x as f32);
        let flat = FlatFields {
            dark: r(0.05),
            lit_a: r(0.45),
            lit_b: r(0.25),
        };
        let frames = vec![r(0.3), r(0.2)];
        let (cond, s) = condition(&frames, &flat, 0, 0.02);
        assert_eq!(cond.len(), 4 * 2);
        assert!((s[0] - 0.6).abs() < 1e-6);
        // Own flat over s, then the frame back from a target that is the own fringe.
        assert!((cond[2 * 2] - 0.4 / 0.6).abs() < 1e-6);
        let x0 = 2.0 * (0.3 - 0.05) / s[0] - 0.4 / s[0];
        assert!((clean_frame(x0, 0.45, 0.05, s[0]) - 0.3).abs() < 1e-6);
    }
}
