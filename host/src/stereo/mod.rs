//! The stereo head: two calibrated cameras and an uncalibrated projector that only
//! labels the surface. Each camera's frames are decoded elsewhere into an absolute
//! projector coordinate per pixel; a left pixel and the right pixel of equal coordinate
//! on the same epipolar line see the same surface point, and the two cameras' rays give
//! its depth.
//!
//! ```text
//! StereoHead --(rectify: Bouguet rotations, common focal length)--> Rectification
//!     (set up once: each left pixel's rectified position, each rectified right
//!      pixel's original distorted right pixel)
//! right u, B --(matching::resample_row: bicubic where all 16 neighbours are valid)
//!     --> rectified right rows + monotonic runs
//! left pixel u --(matching::find: bracketing pair on the four rectified rows around
//!     the pixel's y, cubic solve along each, cubic across them)--> disparity, du/dx
//!     --(triangulate: Z = f B / d; sigma = coordinate noise / slope -> disparity -> ray)
//!     --> PixelMaps indexed by the left camera's original pixels --> cloud
//! ```
//!
//! [`StereoReconstructor::new`] does the set-up (rectification maps);
//! [`StereoReconstructor::reconstruct`] is the per-capture call: rayon over rectified
//! right rows, then over left rows. The result is a [`Reconstruction`] like a projector
//! head's, so pictures, PLY and reports take it unchanged. Its `phase_u` map holds
//! `2 pi u / period_px` of the left pixel and its `background` the smaller modulation
//! of the pair (the stereo head is given no background).

mod matching;
mod rectify;
mod triangulate;

use rayon::prelude::*;

pub use rectify::{Rectification, RectifiedGrid};

use crate::calibration::StereoHead;
use crate::raster::Raster;
use crate::reconstruct::{PixelMaps, Reconstruction, RowMut};
use crate::simd::Simd;
use crate::unwrap::PixelStatus;

use matching::{Match, RectifiedRight};
use triangulate::Triangulator;

/// Which camera of the head a value belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// The left (reference) camera.
    Left,
    /// The right camera.
    Right,
}

impl std::fmt::Display for Side {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Side::Left => "left",
            Side::Right => "right",
        })
    }
}

/// How to match and triangulate a stereo capture.
#[derive(Clone, Debug, PartialEq)]
pub struct StereoConfig {
    /// The finest fringe period, projector pixels: the result's phase map is
    /// `2 pi u / period_px`.
    pub period_px: f64,
    /// Standard deviation of a decoded projector coordinate at modulation 1, projector
    /// pixels (see [`StereoConfig::coordinate_noise_px`]); a pixel of modulation B has
    /// this over B. Predicts each point's sigma.
    pub coordinate_noise_px: f64,
    /// Pixels of either camera whose modulation is below this are not used.
    pub min_modulation: f32,
    /// Largest step of the right row's coordinate between neighbouring rectified pixels,
    /// projector pixels: a larger step is a depth edge, never bridged.
    pub max_step_px: f32,
    /// Largest difference of the match's position between the two rectified rows
    /// around a left pixel, rectified pixels: more is an edge between the rows.
    pub max_row_shift_px: f32,
    /// Depths searched, metres (nearest, farthest): bounds the disparity window.
    pub depth_range_m: (f64, f64),
    /// Compute normals for the cloud.
    pub normals: bool,
}

impl StereoConfig {
    /// The given period and coordinate noise, B >= 0.05, steps up to 8 projector px per
    /// rectified px, rows agreeing within 2 px, depths 0.05..10 m, normals on.
    pub fn new(period_px: f64, coordinate_noise_px: f64) -> Self {
        Self {
            period_px,
            coordinate_noise_px,
            min_modulation: 0.05,
            max_step_px: 8.0,
            max_row_shift_px: 2.0,
            depth_range_m: (0.05, 10.0),
            normals: true,
        }
    }

    /// The coordinate noise at modulation 1 of an N-step decode of period `period_px`
    /// with intensity noise `noise_sigma` (full-scale units): the Cramer-Rao phase noise
    /// `noise_sigma sqrt(2 / N)` carried into projector pixels by `P / 2 pi`.
    pub fn coordinate_noise_px(noise_sigma: f64, steps: usize, period_px: f64) -> f64 {
        noise_sigma * (2.0 / steps as f64).sqrt() * period_px / std::f64::consts::TAU
    }

    fn validate(&self) -> Result<(), StereoError> {
        let bad = |field: &'static str, value: f64, ok: bool| {
            if ok {
                Ok(())
            } else {
                Err(StereoError::Config { field, value })
            }
        };
        let positive = |v: f64| v.is_finite() && v > 0.0;
        bad("period_px", self.period_px, positive(self.period_px))?;
        let noise = self.coordinate_noise_px;
        bad("coordinate_noise_px", noise, positive(noise))?;
        let b = f64::from(self.min_modulation);
        bad("min_modulation", b, b.is_finite() && b >= 0.0)?;
        let step = f64::from(self.max_step_px);
        bad("max_step_px", step, positive(step))?;
        let shift = f64::from(self.max_row_shift_px);
        bad("max_row_shift_px", shift, positive(shift))?;
        let (near, far) = self.depth_range_m;
        bad("depth_range_m (nearest)", near, positive(near))?;
        bad("depth_range_m (farthest)", far, positive(far) && far > near)
    }
}

/// What can be wrong with a stereo head, its configuration or a capture.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum StereoError {
    /// A calibration value is not finite, or a size or focal length not positive.
    #[error("{camera} camera: {field} is {value}, which no camera has")]
    Calibration {
        /// The camera.
        camera: Side,
        /// The offending field.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// A pose's rotation is not a proper rotation.
    #[error("{camera} camera: the rotation is not a rotation (defect {defect:.2e})")]
    NotARotation {
        /// The camera.
        camera: Side,
        /// `max |R^T R - I| + |det R - 1|`.
        defect: f64,
    },
    /// The cameras' centres coincide (within a micrometre).
    #[error("the two cameras' centres coincide: no baseline")]
    NoBaseline,
    /// The baseline is not mostly along the cameras' x axes (one above or in front of
    /// the other): rows cannot be made epipolar lines of a side-by-side pair.
    #[error(
        "the cameras are not side by side: baseline {baseline_m:?} m in the half-rotated \
         camera frame is not mostly along x"
    )]
    NotSideBySide {
        /// Right camera centre in the (half-rotated) left camera frame, metres.
        baseline_m: [f64; 3],
    },
    /// The "right" camera is on the left (swapped cameras, or `R`, `T` inverted).
    #[error(
        "the right camera is left of the left one (baseline {baseline_m:?} m): swapped \
         cameras, or the right pose inverted"
    )]
    Swapped {
        /// Right camera centre in the (half-rotated) left camera frame, metres.
        baseline_m: [f64; 3],
    },
    /// The rectified views of the two cameras share no rows.
    #[error("the rectified images of the two cameras share no rows")]
    NoOverlap,
    /// The rectified right image would be absurdly large (cameras turned far apart).
    #[error(
        "the rectified right image would be {width} x {height} px, over 4x the camera's \
         pixels: cameras turned too far from each other"
    )]
    RectifiedTooLarge {
        /// Rectified width, pixels.
        width: usize,
        /// Rectified height, pixels.
        height: usize,
    },
    /// A map is not its camera's size.
    #[error("{map} is {got:?} but the {camera} camera is {expected:?} (width, height)")]
    MapSize {
        /// The map's name.
        map: &'static str,
        /// The camera.
        camera: Side,
        /// The camera's size.
        expected: (usize, usize),
        /// The map's size.
        got: (usize, usize),
    },
    /// A configuration value out of range.
    #[error("stereo configuration: {field} = {value} is out of range")]
    Config {
        /// The field.
        field: &'static str,
        /// Its value.
        value: f64,
    },
}

/// The stereo pipeline for one head, set up once.
#[derive(Clone, Debug)]
pub struct StereoReconstructor {
    config: StereoConfig,
    rectification: Rectification,
    triangulator: Triangulator,
    simd: Simd,
}

impl StereoReconstructor {
    /// Checks the head and the configuration and computes the rectification maps.
    pub fn new(head: &StereoHead, config: StereoConfig) -> Result<Self, StereoError> {
        config.validate()?;
        let rectification = Rectification::new(&head.left, &head.right)?;
        let triangulator = Triangulator::new(&rectification, &head.left);
        Ok(Self {
            config,
            rectification,
            triangulator,
            simd: Simd::best(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &StereoConfig {
        &self.config
    }

    /// The rectification (rotations, common focal length, maps).
    pub fn rectification(&self) -> &Rectification {
        &self.rectification
    }

    /// Matches and triangulates one capture: each camera's absolute projector column
    /// (projector pixels, NaN where not decoded) and modulation (full-scale units).
    /// The result is indexed by the left camera's pixels.
    pub fn reconstruct(
        &self,
        left_u: &Raster<f32>,
        left_modulation: &Raster<f32>,
        right_u: &Raster<f32>,
        right_modulation: &Raster<f32>,
    ) -> Result<Reconstruction, StereoError> {
        let r = &self.rectification;
        let checks = [
            ("left_u", Side::Left, left_u.size(), r.left_size()),
            (
                "left_modulation",
                Side::Left,
                left_modulation.size(),
                r.left_size(),
            ),
            ("right_u", Side::Right, right_u.size(), r.right_size()),
            (
                "right_modulation",
                Side::Right,
                right_modulation.size(),
                r.right_size(),
            ),
        ];
        for (map, camera, got, expected) in checks {
            if got != expected {
                return Err(StereoError::MapSize {
                    map,
                    camera,
                    expected,
                    got,
                });
            }
        }
        let c = &self.config;
        let right = RectifiedRight::new(r, right_u, right_modulation, c);
        let (width, height) = r.left_size();
        let mut pixels = PixelMaps::default();
        pixels.resize(width, height);
        pixels.rows_mut().into_par_iter().enumerate().for_each_init(
            || right.hints(),
            |hints, (y, row)| self.left_row(y, left_u, left_modulation, &right, hints, row),
        );
        let centre = self.triangulator.left_centre_m();
        let view = [centre.x as f32, centre.y as f32, centre.z as f32];
        Ok(Reconstruction::from_pixel_maps(
            pixels, view, c.normals, self.simd,
        ))
    }

    /// Matches and triangulates left row `y` into `out`.
    fn left_row(
        &self,
        y: usize,
        left_u: &Raster<f32>,
        left_modulation: &Raster<f32>,
        right: &RectifiedRight,
        hints: &mut [usize],
        out: RowMut<'_>,
    ) {
        let c = &self.config;
        let w = left_u.width;
        let (u_row, b_row) = (
            &left_u.data[y * w..(y + 1) * w],
            &left_modulation.data[y * w..(y + 1) * w],
        );
        let (xr_row, yr_row) = self.rectification.left_row(y);
        let phase_per_px = (std::f64::consts::TAU / c.period_px) as f32;
        let window = self.triangulator.disparity_window_px(c.depth_range_m);
        for x in 0..w {
            let (u, b) = (u_row[x], b_row[x]);
            out.modulation[x] = b;
            out.background[x] = b;
            let ok_left = u.is_finite() && b >= c.min_modulation && b.is_finite();
            let found = if ok_left {
                let (xr, yr) = (xr_row[x], yr_row[x]);
                right.find(xr, yr, u, window, c.max_row_shift_px, hints)
            } else {
                None
            };
            let hit = found.and_then(|m: Match| {
                let b_pair = b.min(m.modulation);
                self.triangulator
                    .point(xr_row[x], yr_row[x], m, b, c.coordinate_noise_px)
                    .map(|p| (p, b_pair))
            });
            out.status[x] = match (ok_left, &hit) {
                (false, _) => PixelStatus::Masked,
                (true, None) => PixelStatus::Unreliable,
                (true, Some(_)) => PixelStatus::Valid,
            };
            match hit {
                Some((p, b_pair)) => {
                    out.phase_u[x] = u * phase_per_px;
                    for k in 0..3 {
                        out.point_m[k][x] = p.point_m[k];
                    }
                    out.depth_m[x] = p.depth_m;
                    out.sigma_m[x] = p.sigma_m;
                    out.modulation[x] = b_pair;
                    out.background[x] = b_pair;
                }
                None => {
                    out.phase_u[x] = f32::NAN;
                    for k in 0..3 {
                        out.point_m[k][x] = f32::NAN;
                    }
                    out.depth_m[x] = f32::NAN;
                    out.sigma_m[x] = f32::NAN;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
