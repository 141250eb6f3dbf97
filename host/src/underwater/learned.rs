//! Learned underwater restoration (seed 002): a network trained on twin data
//! (`training/underwater/`) maps one 4-step phase-shift set seen through
//! turbid water to the same set's clean fringe, tile by tile over the whole
//! frame. A one-step network runs once per tile; a diffusion network runs
//! the few-step DDIM sampler of [`crate::infer::ddim`].
//!
//! Normalisation, as `training/underwater/data.py` documents it: per pixel
//! `s = max(mean_k W_k, s_min)`; condition = `W_k / s - 1` for the four
//! frames and `s / (s + LEVEL_HALF)`; the output x0 (the clean fringe's AC
//! over its DC) gives the restored frame `s (1 + x0_k)`: the clean fringe's
//! shape at the underwater frame's light level.

use std::path::Path;

use crate::calibration::detect::filter::{gaussian_blur, Plane};
use crate::infer::ddim::sample_tile_corrected;
use crate::infer::tiles::{infer_tiled, Planes};
use crate::infer::{tile_seed, Model, ModelError};
use crate::raster::Raster;

/// `training/underwater/data.py`'s `LEVEL_HALF`: the light level at which
/// the level channel is one half.
pub const LEVEL_HALF: f32 = 0.05;

/// Frames per set the networks take (4 steps of one period).
pub const SET_FRAMES: usize = 4;

/// Tiles overlap by a quarter of a 64 px tile, as the de-aliaser's.
const TILE_OVERLAP_PX: usize = 16;

/// A trained restorer, checked against the scan it serves.
#[derive(Clone, Debug)]
pub struct LearnedRestorer {
    model: Model,
    sampler_steps: usize,
    physics: Option<PhysicsCorrection>,
}

/// Seed 002's periodic physics-gradient correction (its Eq. 13): every
/// `every` sampler steps the state X moves by `-strength * grad_X
/// ||y - G(X)||_2`, where y is the observed set (the condition's four
/// frames) and G the simplified degradation in the networks' normalised
/// units: the forward-scatter blur, then one contrast factor per tile for
/// attenuation and backscatter (least squares against y, in [0, 1]).
/// The seed: strength 0.01, every 50 of its 1000 steps; each of our few
/// DDIM steps spans more than 50 of those, so every step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhysicsCorrection {
    /// The forward-scatter PSF's standard deviation, camera pixels.
    pub psf_sigma_px: f64,
    /// Sampler steps between corrections (1: after every step).
    pub every: usize,
    /// The step along the residual norm's gradient (alpha in the seed).
    pub strength: f32,
}

impl PhysicsCorrection {
    /// The seed's setting for a PSF of `psf_sigma_px`.
    pub fn seed(psf_sigma_px: f64) -> Self {
        Self {
            psf_sigma_px,
            every: 1,
            strength: 0.01,
        }
    }

    /// Corrects the state `x` (four `tile` x `tile` planes) towards the
    /// observed planes `y` (the same layout).
    pub fn correct(&self, x: &mut [f32], y: &[f32], tile: usize) {
        let plane = tile * tile;
        let blur = |data: &[f32]| {
            gaussian_blur(
                &Plane {
                    width: tile,
                    height: tile,
                    data: data.to_vec(),
                },
                self.psf_sigma_px,
            )
            .data
        };
        let hx: Vec<f32> = x.chunks(plane).flat_map(blur).collect();
        let (dot, norm) = hx.iter().zip(y).fold((0.0f64, 0.0f64), |(d, n), (&h, &o)| {
            (d + f64::from(h) * f64::from(o), n + f64::from(h).powi(2))
        });
        let contrast = if norm > 0.0 {
            (dot / norm).clamp(0.0, 1.0) as f32
        } else {
            0.0
        };
        let residual: Vec<f32> = hx.iter().zip(y).map(|(&h, &o)| o - contrast * h).collect();
        let length = residual
            .iter()
            .map(|&r| f64::from(r).powi(2))
            .sum::<f64>()
            .sqrt();
        if !(length > 0.0 && length.is_finite()) || contrast == 0.0 {
            return;
        }
        // grad_X ||y - c h*X|| = -c h*(y - c h*X) / ||.||; the Gaussian is symmetric.
        let gain = self.strength * contrast / length as f32;
        for (xk, rk) in x.chunks_mut(plane).zip(residual.chunks(plane)) {
            for (xi, gi) in xk.iter_mut().zip(blur(rk)) {
                *xi += gain * gi;
            }
        }
    }
}

/// Why a model does not fit the scan.
#[derive(Debug, thiserror::Error)]
pub enum LearnedRestoreError {
    /// The model cannot be loaded.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// Trained for other fringes than the scan shows.
    #[error("restorer model {path}: trained on periods {trained:?} px x {trained_steps} steps, the scan uses {scan:?} px x {scan_steps} steps")]
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
    /// Not 5 condition channels in and 4 frames out.
    #[error("restorer model {path}: {cond} condition / {frames} frame channels, a 4-step set needs 5 / 4")]
    Channels {
        /// The model file.
        path: String,
        /// Its condition channels.
        cond: usize,
        /// Its frame channels.
        frames: usize,
    },
    /// A diffusion model needs at least one sampler step.
    #[error("a diffusion restorer needs at least one sampler step")]
    NoSteps,
}

/// What restoring one set ran.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RestoreRun {
    /// Tiles run.
    pub tiles: usize,
    /// Network evaluations (tiles x sampler steps).
    pub evaluations: usize,
}

impl LearnedRestorer {
    /// Loads `onnx` and checks it restores 4-step sets of `periods_px` x
    /// `steps`; `sampler_steps` is used by diffusion models only.
    pub fn load(
        onnx: &Path,
        periods_px: &[f64],
        steps: usize,
        sampler_steps: usize,
    ) -> Result<Self, LearnedRestoreError> {
        let model = Model::load(onnx)?;
        let m = &model.meta;
        let path = onnx.display().to_string();
        if !model.trained_for(periods_px, steps) {
            return Err(LearnedRestoreError::Patterns {
                path,
                trained: m.periods_px.clone(),
                trained_steps: m.steps_per_period,
                scan: periods_px.to_vec(),
                scan_steps: steps,
            });
        }
        if m.cond_channels != SET_FRAMES + 1 || m.frame_channels != SET_FRAMES {
            return Err(LearnedRestoreError::Channels {
                path,
                cond: m.cond_channels,
                frames: m.frame_channels,
            });
        }
        if model.is_diffusion() && sampler_steps == 0 {
            return Err(LearnedRestoreError::NoSteps);
        }
        Ok(Self {
            model,
            sampler_steps,
            physics: None,
        })
    }

    /// The same restorer with seed 002's physics correction in its sampler
    /// (diffusion models only; a one-step network has no sampler, and runs
    /// as before).
    pub fn with_physics(mut self, physics: Option<PhysicsCorrection>) -> Self {
        self.physics = physics;
        self
    }

    /// The sampler's physics correction, if any.
    pub fn physics(&self) -> Option<PhysicsCorrection> {
        self.physics
    }

    /// The loaded model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Network evaluations per tile: the sampler's steps, or 1.
    pub fn evaluations_per_tile(&self) -> usize {
        self.model.evaluations_per_tile(self.sampler_steps)
    }

    /// Restores one 4-step set (all frames one size); `seed` makes a
    /// diffusion sample reproducible. Non-finite input pixels come out NaN.
    pub fn restore_set(
        &self,
        frames: &[&Raster<f32>],
        seed: u64,
    ) -> Result<(Vec<Raster<f32>>, RestoreRun), ModelError> {
        let (w, h) = (frames[0].width, frames[0].height);
        let s_min = self.model.meta.normalisation.s_min;
        let (cond, scale) = condition(frames, s_min);
        let needed = vec![true; w * h];
        let planes = Planes {
            data: &cond,
            channels: SET_FRAMES + 1,
            width: w,
            height: h,
        };
        let meta = &self.model.meta;
        let tiled = infer_tiled(
            &planes,
            &needed,
            meta.tile,
            TILE_OVERLAP_PX,
            SET_FRAMES,
            |k, tile| match self.physics {
                Some(p) if self.model.is_diffusion() => sample_tile_corrected(
                    &self.model,
                    tile,
                    self.sampler_steps,
                    tile_seed(seed, k),
                    p.every,
                    |x| p.correct(x, &tile[..SET_FRAMES * meta.tile * meta.tile], meta.tile),
                ),
                _ => self.model.predict_tile(tile, k, self.sampler_steps, seed),
            },
        )?;
        let plane = w * h;
        let restored = (0..frames.len().min(SET_FRAMES))
            .map(|k| {
                let data = (0..plane)
                    .map(|i| {
                        let finite = frames.iter().all(|f| f.data[i].is_finite());
                        if finite {
                            restored_frame(tiled.data[k * plane + i], scale[i])
                        } else {
                            f32::NAN
                        }
                    })
                    .collect();
                Raster {
                    width: w,
                    height: h,
                    data,
                }
            })
            .collect();
        let run = RestoreRun {
            tiles: tiled.tiles,
            evaluations: tiled.tiles * self.evaluations_per_tile(),
        };
        Ok((restored, run))
    }
}

/// The condition planes (5 x H x W) of a 4-step set and each pixel's light
/// level s; non-finite samples count as 0.
pub fn condition(frames: &[&Raster<f32>], s_min: f32) -> (Vec<f32>, Vec<f32>) {
    let plane = frames[0].data.len();
    let value = |f: &Raster<f32>, i: usize| {
        let v = f.data[i];
        if v.is_finite() {
            v
        } else {
            0.0
        }
    };
    let scale: Vec<f32> = (0..plane)
        .map(|i| {
            let mean = frames.iter().map(|f| value(f, i)).sum::<f32>() / frames.len() as f32;
            mean.max(s_min)
        })
        .collect();
    let mut cond = Vec::with_capacity((SET_FRAMES + 1) * plane);
    for f in frames.iter().take(SET_FRAMES) {
        cond.extend((0..plane).map(|i| value(f, i) / scale[i] - 1.0));
    }
    cond.extend(scale.iter().map(|&s| s / (s + LEVEL_HALF)));
    (cond, scale)
}

/// A restored frame's value from the network's x0 and the pixel's level.
pub fn restored_frame(x0: f32, scale: f32) -> f32 {
    scale * (1.0 + x0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A state that is the clean tile, observed blurred and at half
    /// contrast, is already consistent: the correction leaves it; a state
    /// off the observation moves towards it, by `strength` in norm.
    #[test]
    fn the_physics_correction_moves_the_state_towards_the_observation() {
        let tile = 16;
        let clean: Vec<f32> = (0..4 * tile * tile)
            .map(|i| ((i % tile) as f32 * 0.7 + (i / (tile * tile)) as f32).sin())
            .collect();
        let p = PhysicsCorrection {
            psf_sigma_px: 1.0,
            every: 1,
            strength: 0.5,
        };
        let blur = |d: &[f32]| {
            gaussian_blur(
                &Plane {
                    width: tile,
                    height: tile,
                    data: d.to_vec(),
                },
                1.0,
            )
            .data
        };
        let y: Vec<f32> = clean
            .chunks(tile * tile)
            .flat_map(blur)
            .map(|v| 0.5 * v)
            .collect();
        let mut x = clean.clone();
        p.correct(&mut x, &y, tile);
        let moved: f32 = x.iter().zip(&clean).map(|(a, b)| (a - b).abs()).sum();
        assert!(moved < 1e-3, "{moved}");
        // Off by a constant: the residual norm falls.
        let residual = |x: &[f32]| {
            let hx: Vec<f32> = x.chunks(tile * tile).flat_map(blur).collect();
            let dot: f32 = hx.iter().zip(&y).map(|(a, b)| a * b).sum();
            let c = (dot / hx.iter().map(|a| a * a).sum::<f32>()).clamp(0.0, 1.0);
            hx.iter()
                .zip(&y)
                .map(|(a, b)| (b - c * a).powi(2))
                .sum::<f32>()
                .sqrt()
        };
        let mut x: Vec<f32> = clean.iter().map(|v| v + 0.3 * (v * 3.0).cos()).collect();
        let before = residual(&x);
        let start = x.clone();
        p.correct(&mut x, &y, tile);
        assert!(residual(&x) < before, "{} -> {before}", residual(&x));
        let step: f32 = x
            .iter()
            .zip(&start)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f32>()
            .sqrt();
        assert!(step > 0.0 && step <= 0.5 + 1e-4, "{step}");
    }

    #[test]
    fn the_condition_is_each_frame_over_the_sets_mean_and_the_level() {
        let r = |v: f32| Raster::from_fn(2, 1, |x, _| v + 0.1 * x as f32);
        let frames = [r(0.1), r(0.3), r(0.5), r(0.3)];
        let refs: Vec<&Raster<f32>> = frames.iter().collect();
        let (cond, s) = condition(&refs, 0.005);
        assert_eq!(cond.len(), 5 * 2);
        assert!((s[0] - 0.3).abs() < 1e-6 && (s[1] - 0.4).abs() < 1e-6);
        assert!((cond[0] - (0.1 / 0.3 - 1.0)).abs() < 1e-6);
        assert!((cond[8] - 0.3 / 0.35).abs() < 1e-6);
        // The frames come back from their own AC over DC.
        for (k, f) in frames.iter().enumerate() {
            let x0 = cond[k * 2 + 1];
            assert!((restored_frame(x0, s[1]) - f.data[1]).abs() < 1e-6);
        }
        // Dark pixels take the floor, not a division by zero.
        let dark = [r(0.0), r(0.0), r(0.0), r(0.0)];
        let refs: Vec<&Raster<f32>> = dark.iter().collect();
        let (cond, s) = condition(&refs, 0.005);
        assert_eq!(s[0], 0.005);
        assert!(cond.iter().all(|v| v.is_finite()));
    }
}
