//! How far an estimated rig calibration is from a known truth (the digital twin's
//! devices): intrinsics differences and pose errors, per head and head to head.
//!
//! Pure comparison of two [`RigCalibration`]s in the same conventions (each head in
//! its camera frame, `head_to_head` = head 0 -> head 1); `calibrate --sim` prints it
//! and a simulated scan reports it.

use serde::Serialize;

use super::rodrigues::rotation_angle_between;
use super::{PinholeModel, Pose, RigCalibration};

/// Recovered minus true intrinsics of one device, pixels.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct IntrinsicsError {
    /// fx recovered - true.
    pub dfx_px: f64,
    /// fy recovered - true.
    pub dfy_px: f64,
    /// cx recovered - true.
    pub dcx_px: f64,
    /// cy recovered - true.
    pub dcy_px: f64,
}

/// Distance between a recovered and a true pose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PoseError {
    /// Angle of the relative rotation, degrees.
    pub rotation_deg: f64,
    /// Distance between the translations, millimetres.
    pub translation_mm: f64,
}

/// One head's errors.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HeadTruthError {
    /// The head's name in the estimate.
    pub name: String,
    /// Camera intrinsics.
    pub camera: IntrinsicsError,
    /// Projector intrinsics.
    pub projector: IntrinsicsError,
    /// Camera -> projector pose.
    pub camera_to_projector: PoseError,
}

/// A whole rig's errors.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RigTruthError {
    /// Per head, in the estimate's order.
    pub heads: Vec<HeadTruthError>,
    /// Head 0 -> head 1 pose, when both rigs have two heads.
    pub head_to_head: Option<PoseError>,
    /// Head 0 -> head i pose for i = 1..K, as far as both rigs have heads.
    pub head_poses: Vec<PoseError>,
}

/// Recovered minus true intrinsics.
pub fn intrinsics_error(got: &PinholeModel, truth: &PinholeModel) -> IntrinsicsError {
    let (g, t) = (got.intrinsics, truth.intrinsics);
    IntrinsicsError {
        dfx_px: g.fx - t.fx,
        dfy_px: g.fy - t.fy,
        dcx_px: g.cx - t.cx,
        dcy_px: g.cy - t.cy,
    }
}

/// Rotation angle and translation distance between two poses.
pub fn pose_error(got: &Pose, truth: &Pose) -> PoseError {
    PoseError {
        rotation_deg: rotation_angle_between(&got.rotation, &truth.rotation).to_degrees(),
        translation_mm: (got.translation_m - truth.translation_m).norm() * 1e3,
    }
}

/// Compares `estimate` with `truth` head by head (pairing them by order; the
/// comparison stops at the shorter list).
pub fn rig_error(estimate: &RigCalibration, truth: &RigCalibration) -> RigTruthError {
    let heads = estimate
        .heads
        .iter()
        .zip(&truth.heads)
        .map(|(e, t)| HeadTruthError {
            name: e.name.clone(),
            camera: intrinsics_error(&e.camera, &t.camera),
            projector: intrinsics_error(&e.projector, &t.projector),
            // Both heads sit in their camera frame, so the projector pose is camera -> projector.
            camera_to_projector: pose_error(
                &e.projector.pose.compose(&e.camera.pose.inverse()),
                &t.projector.pose.compose(&t.camera.pose.inverse()),
            ),
        })
        .collect();
    let head_poses: Vec<PoseError> = estimate
        .head_poses
        .iter()
        .zip(&truth.head_poses)
        .map(|(e, t)| pose_error(e, t))
        .collect();
    RigTruthError {
        heads,
        head_to_head: head_poses
            .first()
            .copied()
            .filter(|_| head_poses.len() == 1),
        head_poses,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::Head;
    use nalgebra::{Rotation3, Vector3};

    fn head(fx: f64, turn_rad: f64) -> Head {
        let mut projector = PinholeModel::ideal(1280, 800, 1200.0);
        projector.pose = Pose {
            rotation: *Rotation3::from_euler_angles(0.0, turn_rad, 0.0).matrix(),
            translation_m: Vector3::new(-0.1, 0.0, 0.0),
        };
        Head {
            name: "A".into(),
            camera: PinholeModel::ideal(640, 480, fx),
            projector,
            view_errors: Vec::new(),
            port: None,
        }
    }

    #[test]
    fn differences_are_recovered_minus_true_and_angles_in_degrees() {
        let truth = RigCalibration::single(head(800.0, 0.2));
        let estimate = RigCalibration::single(head(803.0, 0.2 + 1f64.to_radians()));
        let e = rig_error(&estimate, &truth);
        assert!((e.heads[0].camera.dfx_px - 3.0).abs() < 1e-12);
        assert_eq!(e.heads[0].projector.dfx_px, 0.0);
        let p = e.heads[0].camera_to_projector;
        assert!((p.rotation_deg - 1.0).abs() < 1e-9, "{p:?}");
        assert!(p.translation_mm.abs() < 1e-9);
        assert!(e.head_to_head.is_none());
    }

    #[test]
    fn head_to_head_translation_is_in_millimetres() {
        let mut truth = RigCalibration::single(head(800.0, 0.2));
        truth.heads.push(head(800.0, 0.2));
        truth.head_poses = vec![Pose::identity()];
        let mut estimate = truth.clone();
        estimate.head_poses = vec![Pose {
            rotation: nalgebra::Matrix3::identity(),
            translation_m: Vector3::new(0.0, 0.002, 0.0),
        }];
        let e = rig_error(&estimate, &truth);
        let h = e.head_to_head.expect("two heads");
        assert!((h.translation_mm - 2.0).abs() < 1e-9 && h.rotation_deg.abs() < 1e-9);
    }
}
