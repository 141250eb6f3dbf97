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
//! [`Reconstructor::new`] does the set-up once per head (rays, shift tables, beat tree);
//! [`Reconstructor::reconstruct`] runs all stages in one fused pass over the pixels
//! (rayon over rows), so each frame sample is read once. [`Reconstructor::reconstruct_staged`]
//! runs the same stages as separate passes and times them, for the bench's breakdown;
//! both give identical results (tested).

mod cloud;

use std::time::Instant;

use rayon::prelude::*;

use crate::calibration::{CameraModel, Head, ProjectorModel};
use crate::phase::{PhaseError, PhaseShift};
use crate::point_cloud::PointCloud;
use crate::raster::Raster;
use crate::triangulation::{ProjectorAxis, Triangulator};
use crate::unwrap::heterodyne::{Heterodyne, MAX_PERIODS};
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
    /// Intensity noise standard deviation (frame units) used to predict point noise.
    pub noise_sigma: f32,
    /// Largest heterodyne rounding residual accepted, radians.
    pub max_residual_rad: f64,
    /// Pixels whose predicted fringe-order noise (heterodyne gain x CRB phase noise at
    /// their modulation) exceeds `pi / order_sigmas` are unreliable: a miscounted order
    /// can pass the residual check, so noise too large to exclude one is refused.
    /// 5 gives about 6e-7 miscounts per pixel.
    pub order_sigmas: f64,
    /// Compute normals for the cloud.
    pub normals: bool,
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
            max_residual_rad: std::f64::consts::FRAC_PI_2,
            order_sigmas: 5.0,
            normals: true,
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
    /// Row frames given without `Directions::Both`, or missing with it.
    #[error("directions are {directions:?} but row frames were {}", if *.given { "given" } else { "not given" })]
    RowFrames {
        /// Configured directions.
        directions: Directions,
        /// Whether row frames were passed.
        given: bool,
    },
}

/// One camera pixel's result.
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

const EMPTY: PixelResult = PixelResult {
    phase_u: f32::NAN,
    status: PixelStatus::Masked,
    point_m: [f32::NAN; 3],
    depth_m: f32::NAN,
    sigma_m: f32::NAN,
    modulation: 0.0,
    background: 0.0,
};

/// The organised result, one [`PixelResult`] per camera pixel, plus the cloud.
#[derive(Clone, Debug)]
pub struct Reconstruction {
    /// Per-pixel results, row-major.
    pub pixels: Raster<PixelResult>,
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

/// One decoded row of one direction: `phase[p * width + x]` per period p.
struct RowPhases {
    phase: Vec<f32>,
    modulation: Vec<f32>,
    background: Vec<f32>,
}

/// The pipeline for one head, set up once.
#[derive(Clone, Debug)]
pub struct Reconstructor {
    config: ReconstructConfig,
    shift: PhaseShift,
    heterodyne_u: Heterodyne,
    heterodyne_v: Heterodyne,
    triangulator: Triangulator,
    /// Modulation below which the order noise is too large (see `order_sigmas`).
    min_reliable_modulation: f32,
    /// `noise_sigma * sqrt(2 / N)`: the CRB phase noise is this over B.
    noise_times_crb: f32,
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
            shift,
            heterodyne_u,
            heterodyne_v,
            triangulator: Triangulator::new(camera, projector),
            min_reliable_modulation,
            noise_times_crb: sigma_phi_times_b as f32,
        })
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

    fn check(
        &self,
        frames_u: &[&Raster<f32>],
        frames_v: Option<&[&Raster<f32>]>,
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
        let all: Vec<&Raster<f32>> = frames_u
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

    /// Decodes one direction of one row: per period, wrapped phase and modulation (row
    /// loops, vectorised), background of the finest period.
    fn decode_rows(&self, rows: &[&[f32]], width: usize) -> RowPhases {
        let n = self.config.steps;
        let k = self.config.periods_px.len();
        let mut out = RowPhases {
            phase: vec![0.0; k * width],
            modulation: vec![0.0; k * width],
            background: vec![0.0; width],
        };
        let mut scratch = vec![0.0f32; width];
        for p in 0..k {
            let bg = if p == 0 {
                &mut out.background
            } else {
                &mut scratch
            };
            self.shift.decode_row(
                &rows[p * n..(p + 1) * n],
                &mut out.phase[p * width..(p + 1) * width],
                &mut out.modulation[p * width..(p + 1) * width],
                bg,
            );
        }
        out
    }

    /// Unwraps one pixel of a decoded row: (absolute phase or status, min modulation,
    /// modulation of the finest period).
    #[inline]
    fn unwrap_at(
        &self,
        row: &RowPhases,
        heterodyne: &Heterodyne,
        width: usize,
        x: usize,
    ) -> (Result<f32, PixelStatus>, f32, f32) {
        let k = self.config.periods_px.len();
        let mut wrapped = [0.0f32; MAX_PERIODS];
        let mut min_b = f32::INFINITY;
        for (p, w) in wrapped.iter_mut().enumerate().take(k) {
            *w = row.phase[p * width + x];
            min_b = min_b.min(row.modulation[p * width + x]);
        }
        // Written so that a NaN modulation (corrupt samples) is masked too.
        let usable = min_b >= self.config.min_modulation;
        let phase = if !usable {
            Err(PixelStatus::Masked)
        } else if min_b < self.min_reliable_modulation {
            Err(PixelStatus::Unreliable)
        } else {
            heterodyne
                .unwrap_pixel(&wrapped[..k])
                .ok_or(PixelStatus::Unreliable)
        };
        (phase, min_b, row.modulation[x])
    }

    /// Triangulates pixel `i` from absolute phases; fills `out`.
    #[inline]
    fn triangulate(
        &self,
        i: usize,
        phase_u: f32,
        phase_v: Option<f32>,
        b0: f32,
        out: &mut PixelResult,
    ) {
        let p0 = self.config.periods_px[0] as f32;
        let tau = std::f32::consts::TAU;
        let u = phase_u * p0 / tau;
        let proj = self.triangulator.projector();
        let inside = |c: f32, extent: u32| c >= -0.5 && c <= extent as f32 - 0.5;
        out.phase_u = phase_u;
        out.status = PixelStatus::Unreliable;
        if !inside(u, proj.width_px) {
            return;
        }
        let hit = match phase_v {
            None => self.triangulator.intersect(i, ProjectorAxis::Column, u),
            Some(pv) => {
                let v = pv * p0 / tau;
                if !inside(v, proj.height_px) {
                    return;
                }
                self.triangulator
                    .intersect_two_rays(i, f64::from(u), f64::from(v))
                    .map(|(t, _gap)| t)
            }
        };
        let Some(t) = hit else {
            return;
        };
        // CRB phase noise of the finest period -> projector pixels -> metres along the ray.
        // With both directions this is the column-only figure: an upper bound, since the
        // two-ray solution also uses the row.
        let sigma_phi = self.noise_times_crb / b0;
        let sigma_px = sigma_phi * p0 / tau;
        out.sigma_m = self.triangulator.range_per_px(i, ProjectorAxis::Column, u) * sigma_px;
        out.point_m = [t.point_m.x, t.point_m.y, t.point_m.z];
        out.depth_m = t.depth_m;
        out.status = PixelStatus::Valid;
    }

    /// All stages in one fused pass over the pixels.
    pub fn reconstruct(
        &self,
        frames_u: &[&Raster<f32>],
        frames_v: Option<&[&Raster<f32>]>,
    ) -> Result<Reconstruction, ReconstructError> {
        let (width, height) = self.check(frames_u, frames_v)?;
        let mut pixels = vec![EMPTY; width * height];
        pixels
            .par_chunks_mut(width)
            .enumerate()
            .for_each(|(y, row)| {
                // This row of every frame, sliced once, decoded with vectorised row loops.
                let span = y * width..(y + 1) * width;
                let rows_u: Vec<&[f32]> = frames_u.iter().map(|f| &f.data[span.clone()]).collect();
                let dec_u = self.decode_rows(&rows_u, width);
                let dec_v = frames_v.map(|fv| {
                    let rows: Vec<&[f32]> = fv.iter().map(|f| &f.data[span.clone()]).collect();
                    self.decode_rows(&rows, width)
                });
                for (x, out) in row.iter_mut().enumerate() {
                    let i = y * width + x;
                    let (pu, mut b, b0) = self.unwrap_at(&dec_u, &self.heterodyne_u, width, x);
                    out.background = dec_u.background[x];
                    let pv = dec_v.as_ref().map(|dv| {
                        let (pv, bv, _) = self.unwrap_at(dv, &self.heterodyne_v, width, x);
                        b = b.min(bv);
                        pv
                    });
                    out.modulation = b;
                    let phases = match (pu, pv) {
                        (Ok(u), None) => Ok((u, None)),
                        (Ok(u), Some(Ok(v))) => Ok((u, Some(v))),
                        (Err(s), _) | (_, Some(Err(s))) => Err(s),
                    };
                    match phases {
                        Ok((u, v)) => self.triangulate(i, u, v, b0, out),
                        Err(s) => out.status = s,
                    }
                }
            });
        let pixels = Raster {
            width,
            height,
            data: pixels,
        };
        let cloud = self.cloud(&pixels);
        Ok(Reconstruction { pixels, cloud })
    }

    /// The same stages as separate passes, timed (for benches and profiling).
    pub fn reconstruct_staged(
        &self,
        frames_u: &[&Raster<f32>],
    ) -> Result<(Reconstruction, StageTimes), ReconstructError> {
        if self.config.directions != Directions::Columns {
            return Err(ReconstructError::RowFrames {
                directions: self.config.directions,
                given: false,
            });
        }
        let (width, height) = self.check(frames_u, None)?;
        let n = self.config.steps;
        let mut times = StageTimes::default();

        let t = Instant::now();
        let wrapped: Vec<crate::phase::WrappedPhase> = frames_u
            .chunks(n)
            .map(|set| self.shift.wrapped_phase(set))
            .collect::<Result<_, _>>()?;
        times.phase_s = t.elapsed().as_secs_f64();

        let t = Instant::now();
        let min_mod = self.config.min_modulation;
        let mask_data: Vec<bool> = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let b = wrapped
                    .iter()
                    .map(|w| w.modulation.data[i])
                    .fold(f32::INFINITY, f32::min);
                b >= min_mod
            })
            .collect();
        let mask = Raster {
            width,
            height,
            data: mask_data,
        };
        let phase_maps: Vec<&Raster<f32>> = wrapped.iter().map(|w| &w.phase).collect();
        let mut absolute = self.heterodyne_u.unwrap(&phase_maps, Some(&mask))?;
        for (i, s) in absolute.status.data.iter_mut().enumerate() {
            let b = wrapped
                .iter()
                .map(|w| w.modulation.data[i])
                .fold(f32::INFINITY, f32::min);
            if *s != PixelStatus::Masked && b < self.min_reliable_modulation {
                *s = PixelStatus::Unreliable;
            }
        }
        times.unwrap_s = t.elapsed().as_secs_f64();

        let t = Instant::now();
        let mut pixels = vec![EMPTY; width * height];
        pixels.par_iter_mut().enumerate().for_each(|(i, out)| {
            out.background = wrapped[0].background.data[i];
            out.modulation = wrapped
                .iter()
                .map(|w| w.modulation.data[i])
                .fold(f32::INFINITY, f32::min);
            match absolute.status.data[i] {
                PixelStatus::Valid => {
                    let b0 = wrapped[0].modulation.data[i];
                    self.triangulate(i, absolute.phase.data[i], None, b0, out)
                }
                s => out.status = s,
            }
        });
        times.triangulate_s = t.elapsed().as_secs_f64();

        let t = Instant::now();
        let pixels = Raster {
            width,
            height,
            data: pixels,
        };
        let cloud = self.cloud(&pixels);
        times.cloud_s = t.elapsed().as_secs_f64();
        Ok((Reconstruction { pixels, cloud }, times))
    }

    /// Compacts valid pixels into a cloud (see [`cloud::compact`]).
    fn cloud(&self, pixels: &Raster<PixelResult>) -> PointCloud {
        let c = self.triangulator.camera().centre_m();
        cloud::compact(
            pixels,
            self.config.normals,
            [c.x as f32, c.y as f32, c.z as f32],
        )
    }
}

impl Reconstruction {
    /// Depth map, metres (NaN where not valid).
    pub fn depth_m(&self) -> Raster<f32> {
        self.map(|p| p.depth_m)
    }

    /// Absolute phase map (NaN where not valid).
    pub fn phase_u(&self) -> Raster<f32> {
        self.map(|p| p.phase_u)
    }

    /// Status map.
    pub fn status(&self) -> Raster<PixelStatus> {
        self.map(|p| p.status)
    }

    /// Number of pixels with a status.
    pub fn count(&self, status: PixelStatus) -> usize {
        self.pixels
            .data
            .iter()
            .filter(|p| p.status == status)
            .count()
    }

    fn map<T>(&self, f: impl Fn(&PixelResult) -> T) -> Raster<T> {
        Raster {
            width: self.pixels.width,
            height: self.pixels.height,
            data: self.pixels.data.iter().map(f).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::PinholeModel;
    use crate::synth;

    fn small_rig() -> (CameraModel, ProjectorModel) {
        synth::stereo_rig(
            PinholeModel::ideal(64, 48, 160.0),
            PinholeModel::ideal(228, 285, 450.0),
            0.15,
            0.5,
        )
    }

    #[test]
    fn fused_and_staged_agree_and_errors_are_typed() {
        let (camera, projector) = small_rig();
        let scene = synth::two_spheres(0.5, 0.6);
        let truth = synth::trace(&scene, &camera, &projector);
        let light = synth::Lighting {
            ambient: 0.1,
            gain: 0.7,
            noise_sigma: 0.005,
        };
        let periods = vec![9.0, 10.0, 11.0];
        let frames = synth::render_fringe_set(&truth, &periods, 4, true, &light, 7);
        let refs: Vec<&Raster<f32>> = frames.iter().collect();
        let rec = Reconstructor::new(&camera, &projector, ReconstructConfig::new(periods)).unwrap();
        let fused = rec.reconstruct(&refs, None).unwrap();
        let (staged, _) = rec.reconstruct_staged(&refs).unwrap();
        assert!(fused.cloud.len() > 500, "{}", fused.cloud.len());
        assert_eq!(fused.cloud, staged.cloud);
        assert_eq!(fused.status(), staged.status());

        assert!(matches!(
            rec.reconstruct(&refs[..11], None),
            Err(ReconstructError::FrameCount {
                expected: 12,
                got: 11,
                ..
            })
        ));
        assert!(matches!(
            rec.reconstruct(&refs, Some(&refs)),
            Err(ReconstructError::RowFrames { .. })
        ));
        let small = Raster::filled(32, 24, 0.5f32);
        let wrong: Vec<&Raster<f32>> = vec![&small; 12];
        assert!(matches!(
            rec.reconstruct(&wrong, None),
            Err(ReconstructError::CameraSize { .. })
        ));
    }
}
