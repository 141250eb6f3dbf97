//! Inference of the shipped networks (`models/`) on tract-onnx.
//!
//! ```text
//! model.onnx + model.json (metadata written by training/)
//!   -> load: parse, check the metadata, fix the tile shapes, check the
//!      weights are finite, optimise once            -> Model
//!   -> tiles::infer_tiled: any image size, overlapping tiles blended,
//!      tiles in parallel on all cores, evaluations counted
//! ```
//!
//! A missing, truncated, malformed or mismatched file is a [`ModelError`]
//! naming the file, raised at load (before any capture).

pub mod ddim;
pub mod tiles;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use tract_onnx::prelude::*;
use tract_onnx::tract_core::ops::konst::Const;

/// The metadata `training/` writes beside each ONNX file.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
pub struct ModelMeta {
    /// Network name (file stem).
    pub network: String,
    /// "onestep" or "diffusion".
    pub kind: String,
    /// Input names in order (cond, or cond, x_t, t).
    pub inputs: Vec<String>,
    /// Square tile side, pixels.
    pub tile: usize,
    /// Channels of the condition input.
    pub cond_channels: usize,
    /// Channels of the output (and of x_t).
    pub frame_channels: usize,
    /// Normalisation of the inputs.
    pub normalisation: Normalisation,
    /// Noise schedule (diffusion only).
    pub schedule: Option<Schedule>,
    /// Fringe periods the network was trained on, DMD pixels.
    pub periods_px: Vec<f64>,
    /// Phase steps per period.
    pub steps_per_period: usize,
    /// Training profile ("cpu" or "gpu").
    pub profile: String,
    /// Optimiser steps taken.
    pub train_steps: u64,
    /// Training wall time, seconds.
    pub train_seconds: f64,
    /// Trainable parameters.
    pub parameters: u64,
    /// What it was trained on, where the metadata says.
    #[serde(default)]
    pub data: Option<TrainingData>,
}

/// The training data a network's metadata records.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
pub struct TrainingData {
    /// Camera image size of the samples, pixels (width, height).
    pub size: [usize; 2],
}

/// Input normalisation of the de-aliasing networks.
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
pub struct Normalisation {
    /// Least per-pixel light scale, full-scale units.
    pub s_min: f32,
}

/// A diffusion noise schedule.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
pub struct Schedule {
    /// "cosine" is the only kind.
    pub kind: String,
    /// Offset s of the cosine schedule.
    pub s: f64,
}

/// Why a model cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The ONNX file or its metadata cannot be read.
    #[error("model file {path}: cannot read")]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The metadata is not the JSON `training/` writes.
    #[error("model metadata {path}: {source}")]
    Meta {
        /// The file.
        path: PathBuf,
        /// The parse error.
        #[source]
        source: serde_json::Error,
    },
    /// The metadata is inconsistent or not what this program runs.
    #[error("model {path}: {why}")]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        why: String,
    },
    /// tract cannot parse, type or optimise the ONNX graph (truncated,
    /// malformed, or shapes unlike the metadata's).
    #[error("model file {path}: not a usable ONNX network: {source}")]
    Onnx {
        /// The file.
        path: PathBuf,
        /// tract's error.
        #[source]
        source: TractError,
    },
    /// A weight is NaN or infinite.
    #[error("model file {path}: {count} non-finite weights")]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// How many.
        count: usize,
    },
    /// Running the network failed.
    #[error("model {network}: inference failed: {source}")]
    Run {
        /// Network name.
        network: String,
        /// tract's error.
        #[source]
        source: TractError,
    },
}

/// A loaded, validated and optimised network; cheap to clone, safe to run
/// from many threads at once.
#[derive(Clone, Debug)]
pub struct Model {
    /// Its metadata.
    pub meta: ModelMeta,
    /// The ONNX file.
    pub path: PathBuf,
    plan: Arc<TypedSimplePlan>,
}

impl Model {
    /// Whether the network was trained for these fringes: the same periods
    /// (to 1 ppm) in the same order, and the same steps per period.
    pub fn trained_for(&self, periods_px: &[f64], steps: usize) -> bool {
        let m = &self.meta;
        m.steps_per_period == steps
            && m.periods_px.len() == periods_px.len()
            && m.periods_px
                .iter()
                .zip(periods_px)
                .all(|(a, b)| (a - b).abs() <= 1e-6 * b.abs())
    }

    /// Whether this is a conditional diffusion model (sampled in steps)
    /// rather than a one-step network.
    pub fn is_diffusion(&self) -> bool {
        self.meta.kind == "diffusion"
    }

    /// Network evaluations per tile: `sampler_steps` for a diffusion
    /// model, 1 for a one-step network.
    pub fn evaluations_per_tile(&self, sampler_steps: usize) -> usize {
        if self.is_diffusion() {
            sampler_steps
        } else {
            1
        }
    }

    /// Tile `k`'s output from its condition `cond`: one run of a one-step
    /// network, or a diffusion model's DDIM sample in `sampler_steps` steps
    /// ([`ddim::sample_tile`]) seeded by `seed` and `k`, so every tile draws
    /// its own noise and a run is reproducible.
    pub fn predict_tile(
        &self,
        cond: &[f32],
        k: usize,
        sampler_steps: usize,
        seed: u64,
    ) -> Result<Vec<f32>, ModelError> {
        if self.is_diffusion() {
            ddim::sample_tile(self, cond, sampler_steps, tile_seed(seed, k))
        } else {
            self.run(&[cond])
        }
    }
}

/// Tile `k`'s sampler seed in a run seeded `seed`.
pub fn tile_seed(seed: u64, k: usize) -> u64 {
    seed ^ (k as u64).wrapping_mul(0x9E37_79B9)
}

/// The metadata file beside `onnx` (`x.onnx` -> `x.json`).
pub fn meta_path(onnx: &Path) -> PathBuf {
    onnx.with_extension("json")
}

/// Reads and checks the metadata beside `onnx`.
pub fn read_meta(onnx: &Path) -> Result<ModelMeta, ModelError> {
    let path = meta_path(onnx);
    let text = std::fs::read(&path).map_err(|source| ModelError::Read {
        path: path.clone(),
        source,
    })?;
    let meta: ModelMeta = serde_json::from_slice(&text).map_err(|source| ModelError::Meta {
        path: path.clone(),
        source,
    })?;
    check_meta(&meta).map_err(|why| ModelError::Unsupported { path, why })?;
    Ok(meta)
}

/// The metadata's own consistency: the input list the kind needs, sizes
/// in range, a schedule exactly when diffusing.
pub fn check_meta(meta: &ModelMeta) -> Result<(), String> {
    let want: &[&str] = match meta.kind.as_str() {
        "onestep" => &["cond"],
        "diffusion" => &["cond", "x_t", "t"],
        other => return Err(format!("unknown network kind {other:?}")),
    };
    if meta.inputs != want {
        return Err(format!(
            "a {} network takes inputs {want:?}, the metadata lists {:?}",
            meta.kind, meta.inputs
        ));
    }
    if !(8..=1024).contains(&meta.tile) || !meta.tile.is_multiple_of(4) {
        return Err(format!(
            "tile {} px is not a multiple of 4 in 8..=1024",
            meta.tile
        ));
    }
    if meta.cond_channels == 0 || meta.frame_channels == 0 || meta.cond_channels > 256 {
        return Err("channel counts out of range".into());
    }
    if (meta.kind == "diffusion") != meta.schedule.is_some() {
        return Err("a schedule is given exactly for diffusion networks".into());
    }
    if let Some(s) = &meta.schedule {
        if s.kind != "cosine" || !(0.0..1.0).contains(&s.s) {
            return Err(format!(
                "schedule {:?} (s = {}) is not a cosine schedule",
                s.kind, s.s
            ));
        }
    }
    let n = meta.normalisation.s_min;
    if !(n.is_finite() && n > 0.0) {
        return Err(format!("normalisation s_min {n} must be > 0"));
    }
    Ok(())
}

impl Model {
    /// Loads `onnx` and its metadata, fixes the inputs to one tile, checks
    /// every weight is finite and optimises the graph.
    pub fn load(onnx: &Path) -> Result<Model, ModelError> {
        let meta = read_meta(onnx)?;
        let bytes = std::fs::read(onnx).map_err(|source| ModelError::Read {
            path: onnx.to_path_buf(),
            source,
        })?;
        Self::from_bytes(&bytes, meta, onnx)
    }

    /// As [`Self::load`], from the ONNX file's bytes and its checked
    /// metadata; `onnx` names the file in errors. A panic inside tract on a
    /// malformed graph is caught and reported as [`ModelError::Onnx`].
    pub fn from_bytes(bytes: &[u8], meta: ModelMeta, onnx: &Path) -> Result<Model, ModelError> {
        let built = std::panic::catch_unwind(|| Self::build(bytes, &meta, onnx));
        match built {
            Ok(plan) => Ok(Model {
                meta,
                path: onnx.to_path_buf(),
                plan: plan?,
            }),
            Err(_) => Err(ModelError::Onnx {
                path: onnx.to_path_buf(),
                source: anyhow::anyhow!("tract panicked on the graph"),
            }),
        }
    }

    /// Parses, types, checks and optimises the graph.
    fn build(
        bytes: &[u8],
        meta: &ModelMeta,
        onnx: &Path,
    ) -> Result<Arc<TypedSimplePlan>, ModelError> {
        let onnx_err = |source| ModelError::Onnx {
            path: onnx.to_path_buf(),
            source,
        };
        let mut model = tract_onnx::onnx()
            .model_for_read(&mut &bytes[..])
            .map_err(onnx_err)?;
        for (i, shape) in input_shapes(meta).iter().enumerate() {
            model = model
                .with_input_fact(i, f32::fact(shape).into())
                .map_err(onnx_err)?;
        }
        let typed = model.into_typed().map_err(onnx_err)?;
        let count = non_finite_weights(&typed).map_err(onnx_err)?;
        if count > 0 {
            return Err(ModelError::NonFinite {
                path: onnx.to_path_buf(),
                count,
            });
        }
        check_output(&typed, meta).map_err(|why| ModelError::Unsupported {
            path: onnx.to_path_buf(),
            why,
        })?;
        typed
            .into_optimized()
            .and_then(|m| m.into_runnable())
            .map_err(onnx_err)
    }

    /// Runs one tile: `inputs` in the metadata's order and shapes
    /// ([`input_shapes`]); returns the output, `frame_channels x tile x tile`.
    pub fn run(&self, inputs: &[&[f32]]) -> Result<Vec<f32>, ModelError> {
        let run_err = |source| ModelError::Run {
            network: self.meta.network.clone(),
            source,
        };
        let shapes = input_shapes(&self.meta);
        let mut values = TVec::new();
        for (data, shape) in inputs.iter().zip(&shapes) {
            values.push(
                Tensor::from_shape(shape, data)
                    .map_err(run_err)?
                    .into_tvalue(),
            );
        }
        if values.len() != shapes.len() {
            return Err(run_err(anyhow::anyhow!(
                "{} inputs given, {} needed",
                values.len(),
                shapes.len()
            )));
        }
        let out = self.plan.run(values).map_err(run_err)?;
        let view = out[0].try_as_plain_ram().map_err(run_err)?;
        Ok(view.as_slice::<f32>().map_err(run_err)?.to_vec())
    }
}

/// The shape of each input for one tile.
pub fn input_shapes(meta: &ModelMeta) -> Vec<Vec<usize>> {
    let t = meta.tile;
    let mut shapes = vec![vec![1, meta.cond_channels, t, t]];
    if meta.kind == "diffusion" {
        shapes.push(vec![1, meta.frame_channels, t, t]);
        shapes.push(vec![1]);
    }
    shapes
}

/// Counts NaN or infinite values among the f32 constants (the weights).
fn non_finite_weights(model: &TypedModel) -> TractResult<usize> {
    let mut count = 0;
    for node in model.nodes() {
        if let Some(c) = node.op_as::<Const>() {
            let t = c.val();
            if t.datum_type() == f32::datum_type() {
                let view = t.try_as_plain_ram()?;
                count += view
                    .as_slice::<f32>()?
                    .iter()
                    .filter(|v| !v.is_finite())
                    .count();
            }
        }
    }
    Ok(count)
}

/// The single output must be `1 x frame_channels x tile x tile`.
fn check_output(model: &TypedModel, meta: &ModelMeta) -> Result<(), String> {
    let outputs = model.output_outlets().map_err(|e| e.to_string())?;
    if outputs.len() != 1 {
        return Err(format!("{} outputs, expected 1", outputs.len()));
    }
    let fact = model.outlet_fact(outputs[0]).map_err(|e| e.to_string())?;
    let want = [1, meta.frame_channels, meta.tile, meta.tile];
    let got: Option<Vec<usize>> = fact.shape.as_concrete().map(|s| s.to_vec());
    if got.as_deref() != Some(&want[..]) {
        return Err(format!(
            "output shape {:?}, the metadata says {want:?}",
            fact.shape
        ));
    }
    Ok(())
}
