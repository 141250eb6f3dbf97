//! Where a scan's calibration comes from: a rig file written by
//! `slscan calibrate` (what a user of the real rig does), or, in simulation
//! only, the digital twin's true devices. The file is read and checked
//! against the scan (two heads, each device's image size) before anything
//! is captured.

use std::path::{Path, PathBuf};

use hil_sim::twin::Rig;
use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion};

use super::twin_truth;
use crate::calibration::truth_error::{rig_error, RigTruthError};
use crate::calibration::{read_rig, PinholeModel, Pose, RigCalibration, RigFileError};

/// The calibration a scan reconstructs with.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum CalibrationSource {
    /// The digital twin's true device models (simulation only; NOT an estimate).
    #[default]
    TwinTruth,
    /// A rig file (`slscan calibrate ... --out FILE`).
    File(PathBuf),
}

/// What can be wrong with the calibration a scan is given.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationSourceError {
    /// The rig file is missing, unreadable or invalid (missing field, NaN, ...).
    #[error(transparent)]
    File(#[from] RigFileError),
    /// A dual-head scan needs a rig file with two heads.
    #[error("rig file {path}: {heads} head(s); a dual-head scan needs 2")]
    HeadCount {
        /// The file.
        path: PathBuf,
        /// Heads in it.
        heads: usize,
    },
    /// A device in the file was calibrated at another image size than the scan uses.
    #[error("rig file {path}: head {head} {device} is {file_px:?} px, the scan's {device} is {scan_px:?} px")]
    ImageSize {
        /// The file.
        path: PathBuf,
        /// Head name in the file.
        head: String,
        /// "camera" or "projector".
        device: &'static str,
        /// (width, height) in the file.
        file_px: (u32, u32),
        /// (width, height) the scan uses.
        scan_px: (u32, u32),
    },
}

/// The calibration in use, where it came from, and (in simulation) its error
/// against the twin's truth.
#[derive(Clone, Debug)]
pub struct UsedCalibration {
    /// The rig: head 0 = A, head 1 = B, each in its camera frame.
    pub rig: RigCalibration,
    /// For people: the file path, or that it is the twin's truth.
    pub description: String,
    /// Recovered - true, when the calibration is an estimate and the truth is known.
    pub vs_truth: Option<RigTruthError>,
}

impl UsedCalibration {
    /// Head B's frame -> head A's frame, the ICP's initial guess.
    pub fn a_from_b(&self) -> Isometry3<f64> {
        let b_from_a = self
            .rig
            .head_to_head
            .as_ref()
            .expect("a checked dual-head rig has head_to_head");
        isometry_from_pose(b_from_a).inverse()
    }
}

/// Reads the rig file at `path` and checks it fits a dual-head scan with these
/// camera and projector sizes.
pub fn read_checked(
    path: &Path,
    camera_px: (u32, u32),
    projector_px: (u32, u32),
) -> Result<RigCalibration, CalibrationSourceError> {
    let rig = read_rig(path)?;
    if rig.heads.len() != 2 {
        return Err(CalibrationSourceError::HeadCount {
            path: path.to_owned(),
            heads: rig.heads.len(),
        });
    }
    for head in &rig.heads {
        let devices: [(&'static str, &PinholeModel, (u32, u32)); 2] = [
            ("camera", &head.camera, camera_px),
            ("projector", &head.projector, projector_px),
        ];
        for (device, model, scan_px) in devices {
            let file_px = (model.width_px, model.height_px);
            if file_px != scan_px {
                return Err(CalibrationSourceError::ImageSize {
                    path: path.to_owned(),
                    head: head.name.clone(),
                    device,
                    file_px,
                    scan_px,
                });
            }
        }
    }
    Ok(rig)
}

/// The calibration of `source` for a scan of the twin `twin_rig`, with the
/// estimate's error against the twin's truth.
pub fn resolve(
    source: &CalibrationSource,
    twin_rig: &Rig,
    camera_px: (u32, u32),
    projector_px: (u32, u32),
) -> Result<UsedCalibration, CalibrationSourceError> {
    let truth = twin_truth::twin_calibration(twin_rig, 2);
    Ok(match source {
        CalibrationSource::TwinTruth => {
            tracing::warn!(
                "calibration: the digital twin's TRUE device models, not an estimated calibration"
            );
            UsedCalibration {
                rig: truth,
                description: "twin truth: the digital twin's TRUE device models (not an estimated calibration)".into(),
                vs_truth: None,
            }
        }
        CalibrationSource::File(path) => {
            let rig = read_checked(path, camera_px, projector_px)?;
            let vs_truth = rig_error(&rig, &truth);
            tracing::info!(file = %path.display(), "calibration: estimated, from the rig file");
            UsedCalibration {
                rig,
                description: format!("rig file {}", path.display()),
                vs_truth: Some(vs_truth),
            }
        }
    })
}

/// A calibration [`Pose`] (`x_to = R x_from + t`) as an isometry (the
/// rotation re-orthonormalised through a quaternion).
pub fn isometry_from_pose(p: &Pose) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(p.translation_m),
        UnitQuaternion::from_matrix(&p.rotation),
    )
}

/// An isometry as a calibration [`Pose`].
pub fn pose_from_isometry(t: &Isometry3<f64>) -> Pose {
    let rotation: Matrix3<f64> = *t.rotation.to_rotation_matrix().matrix();
    Pose {
        rotation,
        translation_m: t.translation.vector,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::write_rig;
    use hil_sim::twin::scenes::{dual_head, Detail};
    use nalgebra::{Point3, Vector3};

    fn temp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("slscan-calsrc-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    #[test]
    fn pose_and_isometry_agree_on_points() {
        let t = Isometry3::new(Vector3::new(0.1, -0.2, 0.3), Vector3::new(0.2, 0.1, -0.3));
        let p = pose_from_isometry(&t);
        let x = Point3::new(0.3, 0.4, 0.5);
        assert!((p.apply(&x) - t * x).norm() < 1e-12);
        assert!((isometry_from_pose(&p) * x - t * x).norm() < 1e-12);
    }

    #[test]
    fn a_truth_file_gives_the_true_pose_and_zero_error() {
        let detail = Detail::default();
        let rig = dual_head(&detail);
        let path = temp("truth.json");
        write_rig(&path, &twin_truth::twin_calibration(&rig, 2)).unwrap();
        let used = resolve(
            &CalibrationSource::File(path.clone()),
            &rig,
            detail.camera,
            detail.projector,
        )
        .unwrap();
        let want = twin_truth::b_from_a(&rig).inverse();
        let got = used.a_from_b();
        assert!((got.translation.vector - want.translation.vector).norm() < 1e-12);
        assert!(got.rotation.angle_to(&want.rotation) < 1e-9);
        let e = used.vs_truth.expect("estimate compared");
        assert!(e.head_to_head.unwrap().translation_mm < 1e-9);
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn wrong_sizes_and_one_head_are_refused_by_name() {
        let detail = Detail::default();
        let rig = dual_head(&detail);
        let path = temp("sizes.json");
        write_rig(&path, &twin_truth::twin_calibration(&rig, 2)).unwrap();
        let err = read_checked(&path, (320, 240), detail.projector).unwrap_err();
        assert!(matches!(
            err,
            CalibrationSourceError::ImageSize {
                device: "camera",
                file_px: (640, 480),
                scan_px: (320, 240),
                ..
            }
        ));
        let err = read_checked(&path, detail.camera, (912, 1140)).unwrap_err();
        assert!(err.to_string().contains("projector"), "{err}");
        write_rig(&path, &twin_truth::twin_calibration(&rig, 1)).unwrap();
        let err = read_checked(&path, detail.camera, detail.projector).unwrap_err();
        assert!(matches!(
            err,
            CalibrationSourceError::HeadCount { heads: 1, .. }
        ));
        std::fs::remove_file(&path).unwrap();
    }
}
