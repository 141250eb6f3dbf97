//! Triangulation: camera rays against projector planes (one phase direction) or
//! projector rays (both directions), with per-point predicted noise.
//!
//! [`Triangulator::new`] does the expensive part once per camera: it undistorts every
//! camera pixel (stored as normalised coordinates, 8 bytes a pixel, so the per-frame pass
//! reads little). Per frame, a projector column `u` then costs a handful of multiply-adds
//! ([`Triangulator::intersect_columns`] does a whole row, vectorised, in the camera frame):
//!
//! ```text
//! camera ray  X(s) = C + s d                    (world, |d| = 1)
//! projector   X_p(s) = q + s e,  q = R_p C + t_p, e = R_p d
//! column u -> x_n = (u - cx)/fx (undistorted);  plane X_p.x = x_n X_p.z
//! s = (x_n q.z - q.x) / (e.x - x_n e.z)
//! ```
//!
//! With projector distortion the column is no plane. The row path
//! ([`Triangulator::intersect_columns`]) starts from a first-order inverse of the distortion
//! and takes two Newton steps on the depth along the camera ray (analytic derivative, vectorised);
//! the single-pixel [`Triangulator::intersect`] refines by fixed-point iteration on the
//! undistorted `x_n` given the current `y_n`. Two directions (`u`, `v`) use the least-squares closest point of the
//! camera ray and the projector ray.
//!
//! The set-up and the per-pixel geometry live here; the whole-row vectorised passes of
//! the pipeline in `rows.rs`, the single-pixel reference paths they are tested against
//! in `pixel.rs`. [`flat_port`] triangulates through the flat ports of underwater housings.

pub mod flat_port;
mod pixel;
mod rows;
#[cfg(test)]
mod tests;

use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;

use crate::calibration::{CameraModel, ProjectorModel};
pub use pixel::closest_points;

/// Which projector coordinate a phase map measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProjectorAxis {
    /// Column `u` (phase grows along projector x).
    Column,
    /// Row `v` (phase grows along projector y).
    Row,
}

/// Newton steps on the depth in [`Triangulator::intersect_columns`] for a distorted
/// projector, after a first-order start (the convergence is quadratic; the test
/// `distorted_rows_match_an_f64_reference` shows two reach the f32 limit for k1 = 0.1).
const DISTORTED_NEWTON_STEPS: usize = 2;

/// Newton steps undistorting a projector pixel in [`Triangulator::intersect_two_rays_row`],
/// after a first-order start (the test `two_ray_rows_match_the_f64_path` covers k1 = 0.1).
const TWO_RAY_UNDISTORT_STEPS: usize = 3;

/// Precomputed per-pixel geometry of one camera-projector pair.
#[derive(Clone, Debug)]
pub struct Triangulator {
    camera: CameraModel,
    projector: ProjectorModel,
    width: usize,
    height: usize,
    /// Undistorted normalised camera coordinates `(x, y)` per pixel (the ray is
    /// `m = (x, y, 1)` in the camera frame); NaN where undistortion failed. 8 bytes per
    /// pixel: the per-frame passes read this, so it is kept small.
    normalised: Vec<[f32; 2]>,
    /// Camera frame -> world rotation (`R_c^T`), rows.
    cam_to_world: [[f32; 3]; 3],
    /// Camera frame -> projector frame rotation (`R_p R_c^T`), rows.
    cam_to_proj: [[f32; 3]; 3],
    centre: [f32; 3],
    q: [f32; 3],
    /// Projector frame -> world rotation (`R_p^T`), rows.
    proj_to_world: [[f32; 3]; 3],
    /// Projector centre, world.
    proj_centre: [f32; 3],
    projector_distorted: bool,
}

/// Per-pixel outputs of [`Triangulator::intersect_columns`], one entry per pixel of a run
/// (NaN where there is no point). Reused between runs to avoid allocation.
#[derive(Clone, Debug, Default)]
pub struct ColumnHits {
    /// World x, y, z, metres.
    pub point_m: [Vec<f32>; 3],
    /// Depth along the camera axis, metres.
    pub depth_m: Vec<f32>,
    /// `|d range / d u|`, metres per projector pixel (see [`Triangulator::range_per_px`]).
    pub range_per_px: Vec<f32>,
    /// Scratch of [`Triangulator::intersect_two_rays_row`]: undistorted normalised
    /// projector coordinates.
    projector_xy: [Vec<f32>; 2],
}

impl ColumnHits {
    /// Sizes every output for a run of `len` pixels.
    pub fn resize(&mut self, len: usize) {
        for v in self
            .point_m
            .iter_mut()
            .chain([&mut self.depth_m, &mut self.range_per_px])
        {
            v.resize(len, f32::NAN);
        }
    }
}

/// One triangulated point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangulated {
    /// Position, metres, world frame.
    pub point_m: Point3<f32>,
    /// Distance along the camera ray, metres.
    pub range_m: f32,
    /// Depth along the camera's optical axis, metres.
    pub depth_m: f32,
}

impl Triangulator {
    /// Undistorts every camera pixel once (parallel; the costly step).
    pub fn new(camera: &CameraModel, projector: &ProjectorModel) -> Self {
        let (width, height) = (camera.width_px as usize, camera.height_px as usize);
        let centre = camera.centre_m();
        let q = projector.pose.apply(&centre);
        let normalised: Vec<[f32; 2]> = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let (u, v) = ((i % width) as f64, (i / width) as f64);
                match camera.pixel_to_normalised(u, v) {
                    Some((x, y)) => [x as f32, y as f32],
                    None => [f32::NAN; 2],
                }
            })
            .collect();
        let rows = |m: &Matrix3<f64>| {
            let mut r = [[0.0f32; 3]; 3];
            for (i, row) in r.iter_mut().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    *v = m[(i, j)] as f32;
                }
            }
            r
        };
        let cam_to_world = camera.pose.rotation.transpose();
        Self {
            camera: *camera,
            projector: *projector,
            width,
            height,
            normalised,
            cam_to_world: rows(&cam_to_world),
            cam_to_proj: rows(&(projector.pose.rotation * cam_to_world)),
            centre: to_f32(&centre.coords),
            q: to_f32(&q.coords),
            proj_to_world: rows(&projector.pose.rotation.transpose()),
            proj_centre: to_f32(&projector.centre_m().coords),
            projector_distorted: !projector.distortion.is_zero(),
        }
    }

    /// Pixel `index`'s unit world ray `d`, the same ray in the projector frame `e`, and
    /// the camera depth per metre along it (`1 / |m|`).
    #[inline]
    fn ray(&self, index: usize) -> ([f32; 3], [f32; 3], f32) {
        let [x, y] = self.normalised[index];
        let inv_norm = 1.0 / (x * x + y * y + 1.0).sqrt();
        let rotate = |r: &[[f32; 3]; 3]| {
            let mut out = [0.0f32; 3];
            for (o, row) in out.iter_mut().zip(r) {
                *o = (row[0] * x + row[1] * y + row[2]) * inv_norm;
            }
            out
        };
        (
            rotate(&self.cam_to_world),
            rotate(&self.cam_to_proj),
            inv_norm,
        )
    }

    /// Camera image size `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The camera this was built for.
    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    /// The projector this was built for.
    pub fn projector(&self) -> &ProjectorModel {
        &self.projector
    }
}

/// The point at depth `z` on camera ray `m = (x, y, 1)`: `C + z R_c^T m` (`rw` = `R_c^T`
/// rows), NaN for a NaN `z`. One pixel of the row loops; inlined so they vectorise.
#[inline(always)]
fn point_on_ray(c: [f32; 3], rw: &[[f32; 3]; 3], x: f32, y: f32, z: f32) -> [f32; 3] {
    // Written out, not `[0, 1, 2].map(..)`: the closure form stopped the loops vectorising.
    [
        c[0] + z * (rw[0][0] * x + rw[0][1] * y + rw[0][2]),
        c[1] + z * (rw[1][0] * x + rw[1][1] * y + rw[1][2]),
        c[2] + z * (rw[2][0] * x + rw[2][1] * y + rw[2][2]),
    ]
}

/// `|d range / d u|` (metres along camera ray `m` per projector column) at the column
/// plane `x_n`, with `norm = |m|`, `a`, `b` = `(R_pc m).x`, `(R_pc m).z` and
/// `den = a - x_n b`: `|m| dZ/du`, `dZ/dx_n = (q.z a - q.x b) / den^2`.
#[inline(always)]
fn metres_per_column(q: [f32; 3], norm: f32, a: f32, b: f32, den: f32, inv_fx: f32) -> f32 {
    norm * ((q[2] * a - q[0] * b) / (den * den) * inv_fx).abs()
}

fn to_f32(v: &Vector3<f64>) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}
