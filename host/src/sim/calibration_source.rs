//! The calibration a simulated scan reconstructs with: a rig file written by
//! `slscan calibrate` (what a user of the real rig does), or the digital
//! twin's true devices (simulation only, labelled so in the report).

use std::path::PathBuf;

use hil_sim::twin::Rig;

use super::truth;
use crate::calibration::truth_error::{rig_error, RigTruthError};
use crate::calibration::RigCalibration;
use crate::scan::calibration_file::{read_checked, CalibrationFileError};

/// The calibration a scan reconstructs with.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum CalibrationSource {
    /// The digital twin's true device models (simulation only; NOT an estimate).
    #[default]
    TwinTruth,
    /// A rig file (`slscan calibrate ... --out FILE`).
    File(PathBuf),
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

/// The calibration of `source` for a scan of the twin `twin_rig`'s first
/// `heads` heads, with the estimate's error against the twin's truth.
pub fn resolve(
    source: &CalibrationSource,
    twin_rig: &Rig,
    heads: usize,
    camera_px: (u32, u32),
    projector_px: (u32, u32),
) -> Result<UsedCalibration, CalibrationFileError> {
    let truth = truth::twin_calibration(twin_rig, heads);
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
            let rig = read_checked(path, heads, camera_px, projector_px)?;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::write_rig;
    use hil_sim::twin::scenes::{dual_head, Detail};

    fn temp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("slscan-calsrc-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    #[test]
    fn a_truth_file_gives_the_true_pose_and_zero_error() {
        let detail = Detail::default();
        let rig = dual_head(&detail);
        let path = temp("truth.json");
        write_rig(&path, &truth::twin_calibration(&rig, 2)).unwrap();
        let used = resolve(
            &CalibrationSource::File(path.clone()),
            &rig,
            2,
            detail.camera,
            detail.projector,
        )
        .unwrap();
        let want = truth::b_from_a(&rig).inverse();
        let got = used.rig.head_to_head().unwrap().to_isometry().inverse();
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
        write_rig(&path, &truth::twin_calibration(&rig, 2)).unwrap();
        let err = read_checked(&path, 2, (320, 240), detail.projector).unwrap_err();
        assert!(matches!(
            err,
            CalibrationFileError::ImageSize {
                device: "camera",
                file_px: (640, 480),
                scan_px: (320, 240),
                ..
            }
        ));
        let err = read_checked(&path, 2, detail.camera, (912, 1140)).unwrap_err();
        assert!(err.to_string().contains("projector"), "{err}");
        write_rig(&path, &truth::twin_calibration(&rig, 1)).unwrap();
        let err = read_checked(&path, 2, detail.camera, detail.projector).unwrap_err();
        assert!(matches!(
            err,
            CalibrationFileError::HeadCount {
                heads: 1,
                expected: 2,
                ..
            }
        ));
        // The same one-head file is right for a one-head scan.
        read_checked(&path, 1, detail.camera, detail.projector).unwrap();
        std::fs::remove_file(&path).unwrap();
    }
}
