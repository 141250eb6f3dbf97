//! Extrinsics between two calibrated devices that saw the same board views:
//! camera -> projector within a head, or camera of head 0 -> camera of
//! head 1 (head-to-head). As OpenCV's `stereoCalibrate` with
//! `CALIB_FIX_INTRINSIC`: intrinsics stay fixed, and LM refines the relative
//! pose together with every view's board pose in device A, minimising the
//! reprojection error in both devices.

use nalgebra::{DMatrix, DVector, Matrix3, Point2, Vector2, Vector3};

use super::bundle::{rms_px, view_residuals};
use super::homography::fit_homography;
use super::lm::{block_jacobian, minimise, LeastSquaresProblem, LmError, LmOptions, LmReport};
use super::rodrigues::{pose_from_rodrigues, rodrigues_from_rotation};
use super::zhang::{pose_from_homography, PlanarView};
use super::{Intrinsics, PinholeModel, Pose};

/// Result of [`calibrate_pair`].
#[derive(Debug, Clone, PartialEq)]
pub struct PairCalibration {
    /// Device A frame -> device B frame.
    pub a_to_b: Pose,
    /// Per view: board frame -> device A frame.
    pub board_to_a: Vec<Pose>,
    /// Per view: RMS reprojection error in A, pixels.
    pub view_rms_a_px: Vec<f64>,
    /// Per view: RMS reprojection error in B, pixels.
    pub view_rms_b_px: Vec<f64>,
    /// RMS over all points of both devices, pixels.
    pub rms_px: f64,
    /// What the optimiser did.
    pub report: LmReport,
}

/// Errors of [`calibrate_pair`].
#[derive(Debug, thiserror::Error)]
pub enum ExtrinsicsError {
    /// The per-device lists differ in length or are empty.
    #[error("need the same, non-zero number of views and poses: a {a_views}/{a_poses}, b {b_views}/{b_poses}")]
    CountMismatch {
        /// Views of A.
        a_views: usize,
        /// Initial poses of A.
        a_poses: usize,
        /// Views of B.
        b_views: usize,
        /// Initial poses of B.
        b_poses: usize,
    },
    /// The refinement could not run.
    #[error("refinement failed: {0}")]
    Refine(#[from] LmError),
    /// A board pose could not be found from a view (degenerate points).
    #[error("no board pose from a view of {points} points")]
    NoPose {
        /// Points in the view.
        points: usize,
    },
}

/// Board pose in a calibrated device from one view (planar PnP): the
/// homography from the board to undistorted normalised coordinates,
/// decomposed. Good to start [`calibrate_pair`], which refines it.
pub fn planar_pose(device: &PinholeModel, view: &PlanarView) -> Result<Pose, ExtrinsicsError> {
    let no_pose = ExtrinsicsError::NoPose {
        points: view.image_px.len(),
    };
    let mut from = Vec::with_capacity(view.image_px.len());
    let mut to = Vec::with_capacity(view.image_px.len());
    for (b, p) in view.board_m.iter().zip(&view.image_px) {
        if let Some((x, y)) = device.pixel_to_normalised(p.x, p.y) {
            from.push(*b);
            to.push(Point2::new(x, y));
        }
    }
    let h = fit_homography(&from, &to).map_err(|_| no_pose)?;
    let unit = Intrinsics {
        fx: 1.0,
        fy: 1.0,
        cx: 0.0,
        cy: 0.0,
    };
    pose_from_homography(&unit, &h).ok_or(ExtrinsicsError::NoPose {
        points: view.image_px.len(),
    })
}

struct PairProblem<'a> {
    a: &'a PinholeModel,
    b: &'a PinholeModel,
    views_a: &'a [PlanarView],
    views_b: &'a [PlanarView],
    /// Residual offset of each view (A then B), plus the total at the end.
    offsets: Vec<usize>,
}

fn pose_at(p: &DVector<f64>, at: usize) -> Pose {
    pose_from_rodrigues(
        &Vector3::new(p[at], p[at + 1], p[at + 2]),
        &Vector3::new(p[at + 3], p[at + 4], p[at + 5]),
    )
}

impl PairProblem<'_> {
    /// Residuals of view `v` in A and B under parameters `p`.
    fn view(&self, p: &DVector<f64>, v: usize) -> (Vec<Vector2<f64>>, Vec<Vector2<f64>>) {
        let a_to_b = pose_at(p, 0);
        let board_to_a = pose_at(p, 6 + 6 * v);
        let mut a = *self.a;
        a.pose = board_to_a;
        let mut b = *self.b;
        b.pose = a_to_b.compose(&board_to_a);
        (
            view_residuals(&a, &self.views_a[v]),
            view_residuals(&b, &self.views_b[v]),
        )
    }

    fn view_into(&self, p: &DVector<f64>, v: usize, out: &mut [f64]) {
        let (ra, rb) = self.view(p, v);
        for (k, r) in ra.iter().chain(&rb).enumerate() {
            out[2 * k] = r.x;
            out[2 * k + 1] = r.y;
        }
    }
}

impl LeastSquaresProblem for PairProblem<'_> {
    fn residual_count(&self) -> usize {
        self.offsets.last().copied().unwrap_or(0)
    }

    fn residuals(&self, p: &DVector<f64>, out: &mut DVector<f64>) {
        for v in 0..self.views_a.len() {
            let (s, e) = (self.offsets[v], self.offsets[v + 1]);
            self.view_into(p, v, &mut out.as_mut_slice()[s..e]);
        }
    }

    fn jacobian(&self, p: &DVector<f64>, jac: &mut DMatrix<f64>) {
        // Each view's residuals depend on the pair pose and its own board pose.
        block_jacobian(
            p,
            &self.offsets,
            |v| (0..6).chain(6 + 6 * v..12 + 6 * v),
            |q, v, out| self.view_into(q, v, out),
            jac,
        );
    }
}

/// Mean of the per-view relative poses `board_to_b[v] * board_to_a[v]^-1`
/// (rotation: the chordal mean, projected back onto SO(3)).
fn mean_relative_pose(board_to_a: &[Pose], board_to_b: &[Pose]) -> Pose {
    let mut r_sum = Matrix3::zeros();
    let mut t_sum = Vector3::zeros();
    for (a, b) in board_to_a.iter().zip(board_to_b) {
        let rel = b.compose(&a.inverse());
        r_sum += rel.rotation;
        t_sum += rel.translation_m;
    }
    let n = board_to_a.len().max(1) as f64;
    let svd = r_sum.svd(true, true);
    let rotation = match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => {
            let r = u * vt;
            if r.determinant() < 0.0 {
                let mut u = u;
                u.column_mut(2).neg_mut();
                u * vt
            } else {
                r
            }
        }
        _ => Matrix3::identity(),
    };
    Pose {
        rotation,
        translation_m: t_sum / n,
    }
}

/// Relative pose of two calibrated devices from shared board views.
///
/// `a` and `b` carry the (fixed) intrinsics and distortion; their poses are
/// ignored. `views_a[v]` and `views_b[v]` are the same board pose seen by
/// each; `board_to_a` / `board_to_b` are each device's own estimate of those
/// poses (from its calibration), used to start.
pub fn calibrate_pair(
    a: &PinholeModel,
    b: &PinholeModel,
    views_a: &[PlanarView],
    views_b: &[PlanarView],
    board_to_a: &[Pose],
    board_to_b: &[Pose],
    options: &LmOptions,
) -> Result<PairCalibration, ExtrinsicsError> {
    let n = views_a.len();
    if n == 0 || views_b.len() != n || board_to_a.len() != n || board_to_b.len() != n {
        return Err(ExtrinsicsError::CountMismatch {
            a_views: n,
            a_poses: board_to_a.len(),
            b_views: views_b.len(),
            b_poses: board_to_b.len(),
        });
    }
    let start_rel = mean_relative_pose(board_to_a, board_to_b);
    let mut start = Vec::with_capacity(6 + 6 * n);
    for pose in std::iter::once(&start_rel).chain(board_to_a) {
        start.extend(rodrigues_from_rotation(&pose.rotation).iter());
        start.extend(pose.translation_m.iter());
    }
    let mut offsets = vec![0];
    for (va, vb) in views_a.iter().zip(views_b) {
        let last = offsets.last().copied().unwrap_or(0);
        offsets.push(last + 2 * (va.board_m.len() + vb.board_m.len()));
    }
    let problem = PairProblem {
        a,
        b,
        views_a,
        views_b,
        offsets,
    };
    let (p, report) = minimise(&problem, DVector::from_vec(start), options)?;
    let mut view_rms_a_px = Vec::with_capacity(n);
    let mut view_rms_b_px = Vec::with_capacity(n);
    let mut all = Vec::new();
    for v in 0..n {
        let (ra, rb) = problem.view(&p, v);
        view_rms_a_px.push(rms_px(&ra));
        view_rms_b_px.push(rms_px(&rb));
        all.extend(ra);
        all.extend(rb);
    }
    Ok(PairCalibration {
        a_to_b: pose_at(&p, 0),
        board_to_a: (0..n).map(|v| pose_at(&p, 6 + 6 * v)).collect(),
        view_rms_a_px,
        view_rms_b_px,
        rms_px: rms_px(&all),
        report,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::rodrigues::rotation_angle_between;
    use nalgebra::Point3;

    fn observe(dev: &PinholeModel, pose: Pose, board: &[Point2<f64>]) -> PlanarView {
        let mut d = *dev;
        d.pose = pose;
        PlanarView {
            board_m: board.to_vec(),
            image_px: board
                .iter()
                .map(|p| Point2::from(d.project(&Point3::new(p.x, p.y, 0.0)).unwrap()))
                .collect(),
        }
    }

    #[test]
    fn recovers_relative_pose_from_perturbed_start() {
        let a = PinholeModel::ideal(640, 480, 700.0);
        let b = PinholeModel::ideal(912, 1140, 1500.0);
        let truth = pose_from_rodrigues(
            &Vector3::new(0.02, -0.25, 0.01),
            &Vector3::new(-0.12, 0.01, 0.02),
        );
        let board: Vec<Point2<f64>> = (0..5)
            .flat_map(|j| (0..7).map(move |i| Point2::new(i as f64 * 0.03, j as f64 * 0.03)))
            .collect();
        let poses: Vec<Pose> = [(0.2, 0.1, 0.0), (-0.2, 0.15, 0.3), (0.1, -0.25, -0.2)]
            .iter()
            .map(|&(x, y, z)| {
                pose_from_rodrigues(&Vector3::new(x, y, z), &Vector3::new(-0.09, -0.06, 0.5))
            })
            .collect();
        let va: Vec<_> = poses.iter().map(|p| observe(&a, *p, &board)).collect();
        let vb: Vec<_> = poses
            .iter()
            .map(|p| observe(&b, truth.compose(p), &board))
            .collect();
        // Start from poses a little off, as separate calibrations would give.
        let nudge = pose_from_rodrigues(
            &Vector3::new(0.01, -0.01, 0.005),
            &Vector3::new(0.002, 0.0, -0.003),
        );
        let pa: Vec<Pose> = poses.iter().map(|p| nudge.compose(p)).collect();
        let pb: Vec<Pose> = poses.iter().map(|p| truth.compose(p)).collect();
        let cal = calibrate_pair(&a, &b, &va, &vb, &pa, &pb, &LmOptions::default()).unwrap();
        let pnp = planar_pose(&b, &vb[1]).unwrap();
        assert!(rotation_angle_between(&pnp.rotation, &pb[1].rotation) < 1e-9);
        assert!(rotation_angle_between(&cal.a_to_b.rotation, &truth.rotation) < 1e-9);
        assert!((cal.a_to_b.translation_m - truth.translation_m).norm() < 1e-9);
        assert!(cal.rms_px < 1e-6, "{}", cal.rms_px);
    }

    #[test]
    fn count_mismatch_is_an_error() {
        let a = PinholeModel::ideal(64, 48, 50.0);
        assert!(matches!(
            calibrate_pair(&a, &a, &[], &[], &[], &[], &LmOptions::default()),
            Err(ExtrinsicsError::CountMismatch { .. })
        ));
    }
}
