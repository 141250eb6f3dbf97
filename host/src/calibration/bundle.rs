//! Camera calibration by Zhang's method: closed-form start, then
//! Levenberg-Marquardt over intrinsics, distortion and every view's pose.
//!
//! Parameters: `fx fy cx cy k1 k2 p1 p2 [k3]`, then per view a Rodrigues
//! vector and a translation (board -> camera). Residuals: reprojection error
//! in pixels, x and y per board point. The Jacobian is numeric but
//! block-sparse: a view's pose moves only that view's residuals.

use nalgebra::{DMatrix, DVector, Point2, Point3, Vector2, Vector3};

use super::lm::{block_jacobian, minimise, LeastSquaresProblem, LmError, LmOptions, LmReport};
use super::rodrigues::{pose_from_rodrigues, rodrigues_from_rotation};
use super::zhang::{closed_form, PlanarView, ZhangError};
use super::{Distortion, Intrinsics, PinholeModel, Pose};

/// Options of [`calibrate_camera`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraCalibrationOptions {
    /// Keep `k3` at zero (OpenCV's `CALIB_FIX_K3`): advised with few views or
    /// a lens with little distortion, where `k3` only fits noise.
    pub fix_k3: bool,
    /// Stopping rules of the refinement.
    pub lm: LmOptions,
}

impl Default for CameraCalibrationOptions {
    fn default() -> Self {
        Self {
            fix_k3: true,
            lm: LmOptions::default(),
        }
    }
}

/// A calibrated camera (or projector) and the board poses it saw.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraCalibration {
    /// Focal lengths and principal point, pixels.
    pub intrinsics: Intrinsics,
    /// Lens distortion (OpenCV's five coefficients).
    pub distortion: Distortion,
    /// Per view: board frame -> device frame.
    pub board_poses: Vec<Pose>,
    /// Per view: RMS reprojection error `sqrt(mean |p_proj - p_obs|^2)`, pixels.
    pub view_rms_px: Vec<f64>,
    /// The same over all points of all views, pixels (OpenCV's `rms`).
    pub rms_px: f64,
    /// What the optimiser did.
    pub report: LmReport,
}

/// Errors of [`calibrate_camera`].
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    /// The closed-form start failed.
    #[error("closed-form initialisation failed: {0}")]
    Zhang(#[from] ZhangError),
    /// The refinement could not run.
    #[error("refinement failed: {0}")]
    Refine(#[from] LmError),
    /// A view has too few points or its lists differ in length.
    #[error("view {view} has {board} board points and {image} image points (>= 4 matched needed)")]
    BadView {
        /// Index of the view.
        view: usize,
        /// Board points.
        board: usize,
        /// Image points.
        image: usize,
    },
    /// A point is NaN or infinite.
    #[error("view {view} point {point} is not finite")]
    NonFinitePoint {
        /// Index of the view.
        view: usize,
        /// Index of the point in the view.
        point: usize,
    },
    /// The refined camera is not physical (non-positive focal length ...).
    #[error("refinement diverged to fx = {fx}, fy = {fy}")]
    Diverged {
        /// Refined fx, pixels.
        fx: f64,
        /// Refined fy, pixels.
        fy: f64,
    },
}

/// Reprojection residuals of one view, `(projected - observed)` per point.
pub fn view_residuals(camera: &PinholeModel, view: &PlanarView) -> Vec<Vector2<f64>> {
    view.board_m
        .iter()
        .zip(&view.image_px)
        .map(|(b, obs)| corner_residual(camera, b, obs))
        .collect()
}

/// [`view_residuals`] as `x, y` pairs into `out` (two per corner): what
/// the refinement evaluates ~30 times per view and iteration, so without
/// a vector per call.
fn view_residuals_into(camera: &PinholeModel, view: &PlanarView, out: &mut [f64]) {
    for ((b, obs), r) in view
        .board_m
        .iter()
        .zip(&view.image_px)
        .zip(out.chunks_exact_mut(2))
    {
        let d = corner_residual(camera, b, obs);
        (r[0], r[1]) = (d.x, d.y);
    }
}

/// Board corner `board` projected by `camera`, less where it was seen.
fn corner_residual(camera: &PinholeModel, board: &Point2<f64>, seen: &Point2<f64>) -> Vector2<f64> {
    match camera.project(&Point3::new(board.x, board.y, 0.0)) {
        Some(p) => p - seen.coords,
        // Behind the camera: a large, finite penalty keeps LM well defined.
        None => Vector2::new(1e6, 1e6),
    }
}

/// `sqrt(mean |r|^2)` of residual vectors; 0 for none.
pub fn rms_px(residuals: &[Vector2<f64>]) -> f64 {
    if residuals.is_empty() {
        return 0.0;
    }
    (residuals.iter().map(|r| r.norm_squared()).sum::<f64>() / residuals.len() as f64).sqrt()
}

/// The refinement problem over intrinsics, distortion and view poses.
struct ZhangProblem<'a> {
    views: &'a [PlanarView],
    offsets: Vec<usize>,
    residual_count: usize,
    intrinsic_count: usize,
    image_size: (u32, u32),
}

impl ZhangProblem<'_> {
    fn camera(&self, p: &DVector<f64>, view: usize) -> PinholeModel {
        let i = self.intrinsic_count;
        let base = i + 6 * view;
        PinholeModel {
            width_px: self.image_size.0,
            height_px: self.image_size.1,
            intrinsics: Intrinsics {
                fx: p[0],
                fy: p[1],
                cx: p[2],
                cy: p[3],
            },
            distortion: Distortion {
                k1: p[4],
                k2: p[5],
                p1: p[6],
                p2: p[7],
                k3: if i > 8 { p[8] } else { 0.0 },
            },
            pose: pose_from_rodrigues(
                &Vector3::new(p[base], p[base + 1], p[base + 2]),
                &Vector3::new(p[base + 3], p[base + 4], p[base + 5]),
            ),
        }
    }

    fn view_into(&self, p: &DVector<f64>, view: usize, out: &mut [f64]) {
        view_residuals_into(&self.camera(p, view), &self.views[view], out);
    }
}

impl LeastSquaresProblem for ZhangProblem<'_> {
    fn residual_count(&self) -> usize {
        self.residual_count
    }

    fn residuals(&self, p: &DVector<f64>, out: &mut DVector<f64>) {
        for v in 0..self.views.len() {
            let (a, b) = (self.offsets[v], self.offsets[v + 1]);
            self.view_into(p, v, &mut out.as_mut_slice()[a..b]);
        }
    }

    fn jacobian(&self, p: &DVector<f64>, jac: &mut DMatrix<f64>) {
        // Each view's residuals depend on the intrinsics and its own 6 pose parameters.
        let n = self.intrinsic_count;
        block_jacobian(
            p,
            &self.offsets,
            |v| (0..n).chain(n + 6 * v..n + 6 * v + 6),
            |q, v, out| self.view_into(q, v, out),
            jac,
        );
    }
}

fn check_views(views: &[PlanarView]) -> Result<(), CalibrateError> {
    for (view, v) in views.iter().enumerate() {
        if v.board_m.len() != v.image_px.len() || v.board_m.len() < 4 {
            return Err(CalibrateError::BadView {
                view,
                board: v.board_m.len(),
                image: v.image_px.len(),
            });
        }
        let finite = |p: &Point2<f64>| p.x.is_finite() && p.y.is_finite();
        if let Some(point) = v
            .board_m
            .iter()
            .zip(&v.image_px)
            .position(|(b, i)| !finite(b) || !finite(i))
        {
            return Err(CalibrateError::NonFinitePoint { view, point });
        }
    }
    Ok(())
}

/// Calibrates one camera (or a projector seen as an inverse camera) from
/// views of a planar board: Zhang's closed form, then LM refinement.
pub fn calibrate_camera(
    views: &[PlanarView],
    image_size: (u32, u32),
    options: &CameraCalibrationOptions,
) -> Result<CameraCalibration, CalibrateError> {
    check_views(views)?;
    let (k, poses) = closed_form(views, image_size)?;
    let intrinsic_count = if options.fix_k3 { 8 } else { 9 };
    let mut start = vec![k.fx, k.fy, k.cx, k.cy, 0.0, 0.0, 0.0, 0.0];
    if !options.fix_k3 {
        start.push(0.0);
    }
    for pose in &poses {
        start.extend(rodrigues_from_rotation(&pose.rotation).iter());
        start.extend(pose.translation_m.iter());
    }
    let mut offsets = vec![0];
    for v in views {
        offsets.push(offsets.last().copied().unwrap_or(0) + 2 * v.board_m.len());
    }
    let problem = ZhangProblem {
        views,
        residual_count: offsets.last().copied().unwrap_or(0),
        offsets,
        intrinsic_count,
        image_size,
    };
    let (p, report) = minimise(&problem, DVector::from_vec(start), &options.lm)?;
    let first = problem.camera(&p, 0);
    if !(first.intrinsics.fx > 0.0 && first.intrinsics.fy > 0.0) {
        return Err(CalibrateError::Diverged {
            fx: first.intrinsics.fx,
            fy: first.intrinsics.fy,
        });
    }
    let mut board_poses = Vec::with_capacity(views.len());
    let mut view_rms_px = Vec::with_capacity(views.len());
    let mut all = Vec::new();
    for (v, view) in views.iter().enumerate() {
        let camera = problem.camera(&p, v);
        let residuals = view_residuals(&camera, view);
        view_rms_px.push(rms_px(&residuals));
        all.extend(residuals);
        board_poses.push(camera.pose);
    }
    Ok(CameraCalibration {
        intrinsics: first.intrinsics,
        distortion: first.distortion,
        board_poses,
        view_rms_px,
        rms_px: rms_px(&all),
        report,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::rodrigues::{pose_from_rodrigues, rotation_angle_between};

    fn truth() -> PinholeModel {
        let mut cam = PinholeModel::ideal(640, 480, 700.0);
        cam.intrinsics = Intrinsics {
            fx: 705.0,
            fy: 698.0,
            cx: 326.0,
            cy: 236.5,
        };
        cam.distortion = Distortion {
            k1: -0.21,
            k2: 0.09,
            p1: 0.0012,
            p2: -0.0008,
            k3: 0.0,
        };
        cam
    }

    fn views(cam: &PinholeModel) -> (Vec<PlanarView>, Vec<Pose>) {
        let board: Vec<Point2<f64>> = (0..6)
            .flat_map(|j| (0..9).map(move |i| Point2::new(i as f64 * 0.025, j as f64 * 0.025)))
            .collect();
        let mut out = Vec::new();
        let mut poses = Vec::new();
        for (k, &(a, b, c)) in [
            (0.3, -0.2, 0.05),
            (-0.3, 0.25, -0.1),
            (0.15, 0.35, 0.2),
            (-0.35, -0.25, 0.0),
            (0.05, 0.05, 1.2),
            (0.4, 0.1, -0.3),
        ]
        .iter()
        .enumerate()
        {
            let pose = pose_from_rodrigues(
                &Vector3::new(a, b, c),
                &Vector3::new(-0.1 + 0.01 * k as f64, -0.06, 0.42 + 0.02 * k as f64),
            );
            let mut c = *cam;
            c.pose = pose;
            let image_px = board
                .iter()
                .map(|p| Point2::from(c.project(&Point3::new(p.x, p.y, 0.0)).unwrap()))
                .collect();
            out.push(PlanarView {
                board_m: board.clone(),
                image_px,
            });
            poses.push(pose);
        }
        (out, poses)
    }

    #[test]
    fn recovers_exact_camera_with_distortion() {
        let cam = truth();
        let (views, poses) = views(&cam);
        let cal = calibrate_camera(&views, (640, 480), &CameraCalibrationOptions::default())
            .expect("calibrates");
        let (k, d) = (cal.intrinsics, cal.distortion);
        assert!(
            (k.fx - 705.0).abs() < 1e-4 && (k.fy - 698.0).abs() < 1e-4,
            "{k:?}"
        );
        assert!(
            (k.cx - 326.0).abs() < 1e-4 && (k.cy - 236.5).abs() < 1e-4,
            "{k:?}"
        );
        assert!(
            (d.k1 + 0.21).abs() < 1e-6 && (d.k2 - 0.09).abs() < 1e-6,
            "{d:?}"
        );
        assert!(
            (d.p1 - 0.0012).abs() < 1e-7 && (d.p2 + 0.0008).abs() < 1e-7,
            "{d:?}"
        );
        assert!(cal.rms_px < 1e-6, "{}", cal.rms_px);
        for (est, t) in cal.board_poses.iter().zip(&poses) {
            assert!(rotation_angle_between(&est.rotation, &t.rotation) < 1e-8);
            assert!((est.translation_m - t.translation_m).norm() < 1e-8);
        }
    }

    #[test]
    fn rejects_nan_and_short_views() {
        let (mut views, _) = views(&truth());
        views[1].image_px[3].x = f64::NAN;
        assert!(matches!(
            calibrate_camera(&views, (640, 480), &Default::default()),
            Err(CalibrateError::NonFinitePoint { view: 1, point: 3 })
        ));
        views[1].image_px.truncate(3);
        assert!(matches!(
            calibrate_camera(&views, (640, 480), &Default::default()),
            Err(CalibrateError::BadView { view: 1, .. })
        ));
    }
}
