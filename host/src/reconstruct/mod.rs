//! The reconstruction pipeline: fringe frames + calibrated head -> absolute phase ->
//! point cloud.
//!
//! ```text
//! K periods x N steps of frames --(phase: N-step per period)--> wrapped phase, B, A
//!   --(unwrap: heterodyne)--> absolute phase of the finest period, status per pixel
//!   --(triangulation: ray/plane, or ray/ray with both directions)--> points, depth
//!   --(sigma: CRB phase noise -> projector px -> metres along the ray)--> quality
//! ```
//!
//! [`Reconstructor::new`] does the set-up once per head (undistorted pixel coordinates,
//! shift tables, beat tree); [`Reconstructor::reconstruct`] runs all stages in one fused
//! pass (rayon over rows; per row decode -> heterodyne -> triangulation as whole-row loops
//! that vectorise, see `rows.rs`), so each frame sample is read once. Frames may be
//! `u8`/`u16` as cameras deliver them, or `f32` ([`crate::phase::Sample`]).
//! [`Reconstructor::reconstruct_into`] reuses a previous result's buffers.
//! [`Reconstructor::reconstruct_staged`] runs the same row functions as separate passes
//! and times them, for the bench's breakdown; both give identical results (tested).

mod cloud;
mod maps;
mod rows;
mod staged;

use rayon::prelude::*;

pub use maps::PixelMaps;
pub(crate) use maps::RowMut;

use crate::calibration::{CameraModel, Head, ProjectorModel};
use crate::phase::{PhaseError, PhaseShift, Sample};
use crate::point_cloud::PointCloud;
use crate::raster::Raster;
use crate::simd::Simd;
use crate::triangulation::Triangulator;
use crate::unwrap::heterodyne::Heterodyne;
use crate::unwrap::temporal::TemporalDecoder;
use crate::unwrap::{PixelStatus, UnwrapError};

/// Which projector coordinates the frames encode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Directions {
    /// Columns only: ray / plane triangulation.
    Columns,
    /// Columns and rows: ray / ray least squares.
    Both,
}

/// How to decode a capture.
#[derive(Clone, Debug, PartialEq)]
pub struct ReconstructConfig {
    /// Phase steps N per period.
    pub steps: usize,
    /// Fringe periods, projector pixels, finest first (heterodyne order).
    pub periods_px: Vec<f64>,
    /// Columns only, or columns then rows.
    pub directions: Directions,
    /// Pixels whose modulation (any period) is below this are masked.
    pub min_modulation: f32,
    /// Intensity noise standard deviation at half scale (frame units), used to predict
    /// point noise and to refuse pixels too noisy to count fringe orders.
    pub noise_sigma: f32,
    /// Share of the half-scale noise variance that is shot noise (0..=1), which grows
    /// with the light: a pixel with background A (full-scale units) then has noise
    /// `noise_sigma * sqrt(1 - s + 2 s A)`, and its point's predicted sigma follows its
    /// own level. 0: every pixel has `noise_sigma`. A camera with full well `W` and
    /// read noise `r` electrons has `s = (W / 2) / (W / 2 + r^2)` (0.993 for 10 000 e-
    /// and 6 e-). The fringe-order check keeps the half-scale figure.
    pub shot_noise_share: f32,
    /// Largest heterodyne rounding residual accepted, radians.
    pub max_residual_rad: f64,
    /// Pixels whose predicted fringe-order noise (heterodyne gain x CRB phase noise at
    /// their modulation) exceeds `pi / order_sigmas` are unreliable: a miscounted order
    /// can pass the residual check, so noise too large to exclude one is refused.
    /// 5 gives about 6e-7 miscounts per pixel.
    pub order_sigmas: f64,
    /// Compute normals for the cloud.
    pub normals: bool,
    /// Frame value of full white. `None`: the sample type's ([`Sample::FULL_SCALE`]:
    /// 1 for `f32`, 255 for `u8`, 65535 for `u16`); 12-bit data in `u16` give 4095.
    /// Modulation, background and the thresholds above are in units of full scale.
    pub full_scale: Option<f32>,
}

impl ReconstructConfig {
    /// 4-step, the given periods, columns only, B >= 0.05, sigma 0.01, residual pi/2.
    pub fn new(periods_px: Vec<f64>) -> Self {
        Self {
            steps: 4,
            periods_px,
            directions: Directions::Columns,
            min_modulation: 0.05,
            noise_sigma: 0.01,
            shot_noise_share: 0.0,
            max_residual_rad: std::f64::consts::FRAC_PI_2,
            order_sigmas: 5.0,
            normals: true,
            full_scale: None,
        }
    }

    /// Frames per direction (`periods x steps`).
    pub fn frames_per_direction(&self) -> usize {
        self.periods_px.len() * self.steps
    }
}

/// What can go wrong in the pipeline.
#[derive(Debug, thiserror::Error)]
pub enum ReconstructError {
    /// Bad shift set or frame sizes.
    #[error(transparent)]
    Phase(#[from] PhaseError),
    /// Bad period set.
    #[error(transparent)]
    Unwrap(#[from] UnwrapError),
    /// Not as many frames as the configuration needs.
    #[error(
        "{direction}: expected {expected} frames ({periods} periods x {steps} steps), got {got}"
    )]
    FrameCount {
        /// "columns" or "rows".
        direction: &'static str,
        /// Frames needed.
        expected: usize,
        /// Frames given.
        got: usize,
        /// Periods configured.
        periods: usize,
        /// Steps configured.
        steps: usize,
    },
    /// Frames are not the calibrated camera's size.
    #[error("frames are {got:?} but the calibrated camera is {expected:?} (width, height)")]
    CameraSize {
        /// Calibrated size.
        expected: (usize, usize),
        /// Frame size.
        got: (usize, usize),
    },
    /// A shot-noise share outside 0..=1 (or NaN).
    #[error("shot-noise share {0} must be in [0, 1]")]
    ShotNoiseShare(f32),
    /// Row frames given without `Directions::Both`, or missing with it.
    #[error("directions are {directions:?} but row frames were {}", if *.given { "given" } else { "not given" })]
    RowFrames {
        /// Configured directions.
        directions: Directions,
        /// Whether row frames were passed.
        given: bool,
    },
}

/// One camera pixel's result (gathered from the maps by [`PixelMaps::get`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelResult {
    /// Absolute phase of the finest column period (NaN unless valid).
    pub phase_u: f32,
    /// Status after unwrapping and triangulation.
    pub status: PixelStatus,
    /// Point, metres (NaN unless valid).
    pub point_m: [f32; 3],
    /// Depth along the camera axis, metres (NaN unless valid).
    pub depth_m: f32,
    /// Predicted standard deviation along the ray, metres (NaN unless valid).
    pub sigma_m: f32,
    /// Smallest modulation over the periods (and directions).
    pub modulation: f32,
    /// Background A of the finest column period.
    pub background: f32,
}

/// The organised result, one value per camera pixel in each map, plus the cloud.
#[derive(Clone, Debug, Default)]
pub struct Reconstruction {
    /// Per-pixel results, row-major.
    pub pixels: PixelMaps,
    /// The valid points with colour (grey background), quality and optional normals.
    pub cloud: PointCloud,
}

/// Seconds spent per stage by [`Reconstructor::reconstruct_staged`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageTimes {
    /// Wrapped phase, modulation, background of every period.
    pub phase_s: f64,
    /// Heterodyne unwrapping.
    pub unwrap_s: f64,
    /// Triangulation and noise prediction.
    pub triangulate_s: f64,
    /// Compaction into the cloud (and normals).
    pub cloud_s: f64,
}

/// The pipeline for one head, set up once.
#[derive(Clone, Debug)]
pub struct Reconstructor {
    config: ReconstructConfig,
    /// Phase shifting + heterodyne of the column frames (and of the row frames).
    decoder_u: TemporalDecoder,
    decoder_v: TemporalDecoder,
    triangulator: Triangulator,
    /// Modulation below which the order noise is too large (see `order_sigmas`).
    min_reliable_modulation: f32,
    /// `noise_sigma * sqrt(2 / N)`: the CRB phase noise at half scale is this over B.
    noise_times_crb: f32,
    /// `(1 - s, 2 s)` of the shot-noise share: a pixel's noise is the half-scale
    /// figure times `sqrt(.0 + .1 * A)` ([`Reconstructor::noise_scale`]).
    noise_level_terms: (f32, f32),
    /// Which build of the row loops runs (the widest the CPU has, unless set).
    simd: Simd,
}

impl Reconstructor {
    /// Sets up for a head's camera and projector.
    pub fn from_head(head: &Head, config: ReconstructConfig) -> Result<Self, ReconstructError> {
        Self::new(&head.camera, &head.projector, config)
    }

    /// Sets up for a camera and projector (rays, shift table, beat tree).
    pub fn new(
        camera: &CameraModel,
        projector: &ProjectorModel,
        config: ReconstructConfig,
    ) -> Result<Self, ReconstructError> {
        let share = config.shot_noise_share;
        if !(0.0..=1.0).contains(&share) {
            return Err(ReconstructError::ShotNoiseShare(share));
        }
        let shift = PhaseShift::new(config.steps)?;
        let residual = config.max_residual_rad;
        let heterodyne_u =
            Heterodyne::new(&config.periods_px, f64::from(projector.width_px), residual)?;
        // Rows use the same periods; check they also cover the projector's height.
        let heterodyne_v = match config.directions {
            Directions::Both => {
                Heterodyne::new(&config.periods_px, f64::from(projector.height_px), residual)?
            }
            Directions::Columns => heterodyne_u.clone(),
        };
        let gain = heterodyne_u
            .order_noise_gain()
            .max(heterodyne_v.order_noise_gain());
        let sigma_phi_times_b = f64::from(config.noise_sigma) * (2.0 / config.steps as f64).sqrt();
        let min_reliable_modulation =
            (gain * sigma_phi_times_b * config.order_sigmas / std::f64::consts::PI) as f32;
        Ok(Self {
            config,
            decoder_u: TemporalDecoder::new(shift.clone(), heterodyne_u),
            decoder_v: TemporalDecoder::new(shift, heterodyne_v),
            triangulator: Triangulator::new(camera, projector),
            min_reliable_modulation,
            noise_times_crb: sigma_phi_times_b as f32,
            noise_level_terms: (1.0 - share, 2.0 * share),
            simd: Simd::best(),
        })
    }

    /// The same pipeline with its row loops built for `simd` (the bench compares the
    /// builds; results are identical).
    pub fn with_simd(mut self, simd: Simd) -> Self {
        self.simd = simd;
        self
    }

    /// The configuration.
    pub fn config(&self) -> &ReconstructConfig {
        &self.config
    }

    /// Modulation below which pixels are unreliable for this period set and noise.
    pub fn min_reliable_modulation(&self) -> f32 {
        self.min_reliable_modulation
    }

    /// The triangulator (precomputed rays).
    pub fn triangulator(&self) -> &Triangulator {
        &self.triangulator
    }

    fn check<T>(
        &self,
        frames_u: &[&Raster<T>],
        frames_v: Option<&[&Raster<T>]>,
    ) -> Result<(usize, usize), ReconstructError> {
        let c = &self.config;
        let expected = c.frames_per_direction();
        let both = c.directions == Directions::Both;
        if both != frames_v.is_some() {
            return Err(ReconstructError::RowFrames {
                directions: c.directions,
                given: frames_v.is_some(),
            });
        }
        for (direction, frames) in [("columns", Some(frames_u)), ("rows", frames_v)] {
            if let Some(frames) = frames {
                if frames.len() != expected {
                    return Err(ReconstructError::FrameCount {
                        direction,
                        expected,
                        got: frames.len(),
                        periods: c.periods_px.len(),
                        steps: c.steps,
                    });
                }
            }
        }
        let all: Vec<&Raster<T>> = frames_u
            .iter()
            .chain(frames_v.unwrap_or(&[]))
            .copied()
            .collect();
        let size = crate::phase::check_sizes(&all)?;
        if size != self.triangulator.size() {
            return Err(ReconstructError::CameraSize {
                expected: self.triangulator.size(),
                got: size,
            });
        }
        Ok(size)
    }

    /// A pixel's intensity noise over the half-scale figure, from its background level
    /// `a` (full-scale units; see [`ReconstructConfig::shot_noise_share`]). Exactly 1
    /// without shot noise.
    #[inline(always)]
    fn noise_scale(&self, a: f32) -> f32 {
        let (constant, per_level) = self.noise_level_terms;
        (constant + per_level * a.max(0.0)).sqrt()
    }

    /// `1 / full scale` for frames of sample type `T`.
    fn sample_scale<T: Sample>(&self) -> f32 {
        1.0 / self.config.full_scale.unwrap_or(T::FULL_SCALE)
    }

    /// All stages in one fused pass over the pixels: rayon over rows, each row decoded,
    /// unwrapped and triangulated while it is in cache. Frames may be `f32`, `u16` or
    /// `u8` (see [`ReconstructConfig::full_scale`]).
    pub fn reconstruct<T: Sample>(
        &self,
        frames_u: &[&Raster<T>],
        frames_v: Option<&[&Raster<T>]>,
    ) -> Result<Reconstruction, ReconstructError> {
        let mut out = Reconstruction::default();
        self.reconstruct_into(frames_u, frames_v, &mut out)?;
        Ok(out)
    }

    /// [`Reconstructor::reconstruct`] into an existing result, reusing its buffers: a
    /// scanner decoding scan after scan saves the fresh-memory page faults (about a
    /// third of the time at 6 MP). `out` is overwritten; on error it is left as it was.
    pub fn reconstruct_into<T: Sample>(
        &self,
        frames_u: &[&Raster<T>],
        frames_v: Option<&[&Raster<T>]>,
        out: &mut Reconstruction,
    ) -> Result<(), ReconstructError> {
        let (width, height) = self.check(frames_u, frames_v)?;
        let scale = self.sample_scale::<T>();
        // Every element is overwritten below; memory is only allocated when it grows.
        out.pixels.resize(width, height);
        let counts: Vec<usize> = out
            .pixels
            .rows_mut()
            .into_par_iter()
            .enumerate()
            .map_init(rows::Scratch::default, |scratch, (y, row)| {
                self.fused_row(y, frames_u, frames_v, scale, scratch, row)
            })
            .collect();
        self.cloud_into(&out.pixels, &counts, &mut out.cloud);
        Ok(())
    }

    /// The result of per-pixel maps assembled outside the row pass (a
    /// multi-exposure scan's pixels, each taken from its best exposure):
    /// the cloud is compacted from the maps' valid pixels as the row pass's
    /// would be.
    pub fn from_maps(&self, pixels: PixelMaps) -> Reconstruction {
        let c = self.triangulator.camera().centre_m();
        let view = [c.x as f32, c.y as f32, c.z as f32];
        Reconstruction::from_pixel_maps(pixels, view, self.config.normals, self.simd)
    }

    /// Compacts valid pixels into a cloud (see [`cloud::compact_into`]).
    fn cloud_into(&self, pixels: &PixelMaps, valid_per_row: &[usize], cloud: &mut PointCloud) {
        let c = self.triangulator.camera().centre_m();
        let view = [c.x as f32, c.y as f32, c.z as f32];
        let normals = self.config.normals;
        cloud::compact_into(pixels, valid_per_row, normals, view, self.simd, cloud);
    }
}

impl Reconstruction {
    /// The result of per-pixel maps made outside the pipeline (another decoder, a
    /// stereo head): the cloud is compacted from the maps' valid pixels as the row
    /// pass's would be, normals (when asked for) turned towards `view_m`, the point
    /// the pixels were seen from.
    pub fn from_pixel_maps(pixels: PixelMaps, view_m: [f32; 3], normals: bool, simd: Simd) -> Self {
        let counts: Vec<usize> = pixels
            .status
            .chunks(pixels.width.max(1))
            .map(|row| row.iter().filter(|&&s| s == PixelStatus::Valid).count())
            .collect();
        let mut out = Reconstruction {
            pixels,
            cloud: PointCloud::default(),
        };
        cloud::compact_into(&out.pixels, &counts, normals, view_m, simd, &mut out.cloud);
        out
    }

    /// Depth map, metres (NaN where not valid).
    pub fn depth_m(&self) -> Raster<f32> {
        self.pixels.raster(&self.pixels.depth_m)
    }

    /// Absolute phase map (NaN where not valid).
    pub fn phase_u(&self) -> Raster<f32> {
        self.pixels.raster(&self.pixels.phase_u)
    }

    /// Smallest-modulation map.
    pub fn modulation(&self) -> Raster<f32> {
        self.pixels.raster(&self.pixels.modulation)
    }

    /// Status map.
    pub fn status(&self) -> Raster<PixelStatus> {
        self.pixels.raster(&self.pixels.status)
    }

    /// Number of pixels with a status.
    pub fn count(&self, status: PixelStatus) -> usize {
        self.pixels.status.iter().filter(|&&s| s == status).count()
    }
}

#[cfg(test)]
mod tests;
