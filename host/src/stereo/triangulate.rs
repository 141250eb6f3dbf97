//! Points from rectified disparities, and their predicted noise.
//!
//! In the rectified frame (left camera centre at the origin, right at `(B, 0, 0)`) a
//! left pixel at rectified `(x, y)` matched at right `x - d` lies at depth `Z = f B / d`
//! on the left pixel's ray. The match moves with the noise of both coordinates: the left
//! value `u` and the right row's samples, each `noise / B` projector pixels at
//! modulation `B`; the right row's slope `g` carries them to disparity,
//! `sigma_d = noise sqrt(1 / B_L^2 + 1 / B_R^2) / |g|`, and `dZ / dd = -Z / d` to depth,
//! along the left ray.
//!
//! The prediction counts one right pixel's noise at the match; the interpolations
//! (bicubic resampling, then cubic along the row and across rows) average neighbouring
//! right pixels, so the measured noise lies below it, down to about `sqrt(1 / 2)` of it
//! where both cameras are equally noisy (the twin's spheres: 0.81 to 0.85).

use nalgebra::{Matrix3, Point3, Vector3};

use super::matching::Match;
use super::rectify::Rectification;
use crate::calibration::CameraModel;

/// One triangulated pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct StereoPoint {
    /// Point in the head's world frame, metres.
    pub point_m: [f32; 3],
    /// Depth along the left camera's axis, metres.
    pub depth_m: f32,
    /// Predicted standard deviation along the left ray, metres.
    pub sigma_m: f32,
}

/// Rectified disparity -> world point, for one head.
#[derive(Clone, Debug)]
pub(super) struct Triangulator {
    focal_px: f64,
    baseline_m: f64,
    /// Grid offsets: rectified pixel = grid + offset.
    x0: f64,
    y0: f64,
    /// Rectified frame -> world rotation, and the left centre in the world.
    to_world: Matrix3<f64>,
    left_centre_m: Point3<f64>,
    /// Rectified frame -> left camera frame's z (the left camera's axis).
    depth_row: Vector3<f64>,
}

impl Triangulator {
    pub fn new(r: &Rectification, left: &CameraModel) -> Self {
        let rect_to_left = r.left_rotation().transpose();
        let grid = r.grid();
        Self {
            focal_px: r.focal_px(),
            baseline_m: r.baseline_m(),
            x0: grid.x0,
            y0: grid.y0,
            to_world: left.pose.rotation.transpose() * rect_to_left,
            left_centre_m: left.centre_m(),
            depth_row: rect_to_left.row(2).transpose(),
        }
    }

    /// The left camera's centre, world frame, metres.
    pub fn left_centre_m(&self) -> Point3<f64> {
        self.left_centre_m
    }

    /// Disparities (grid pixels) of depths `nearest..farthest` metres: (smallest, largest).
    pub fn disparity_window_px(&self, (nearest, farthest): (f64, f64)) -> (f32, f32) {
        let fb = self.focal_px * self.baseline_m;
        ((fb / farthest) as f32, (fb / nearest) as f32)
    }

    /// The point of a left pixel at rectified grid `(x, y)` of modulation `b_left`
    /// matched at `m`, with coordinate noise `noise_px` at modulation 1; `None` for a
    /// disparity that is not positive.
    pub fn point(
        &self,
        x: f32,
        y: f32,
        m: Match,
        b_left: f32,
        noise_px: f64,
    ) -> Option<StereoPoint> {
        let d = f64::from(x) - f64::from(m.x);
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        let f = self.focal_px;
        let z = f * self.baseline_m / d;
        let (xn, yn) = ((f64::from(x) + self.x0) / f, (f64::from(y) + self.y0) / f);
        let rect = Vector3::new(xn * z, yn * z, z);
        let world = self.left_centre_m + self.to_world * rect;
        let (bl, br) = (f64::from(b_left), f64::from(m.modulation));
        let sigma_d =
            noise_px * (1.0 / (bl * bl) + 1.0 / (br * br)).sqrt() / f64::from(m.slope).abs();
        let sigma_ray = z / d * sigma_d * (xn * xn + yn * yn + 1.0).sqrt();
        Some(StereoPoint {
            point_m: [world.x as f32, world.y as f32, world.z as f32],
            depth_m: self.depth_row.dot(&rect) as f32,
            sigma_m: sigma_ray as f32,
        })
    }
}
