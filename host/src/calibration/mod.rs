//! Calibration of the rig: the device models every other stage uses, and the rig file.
//!
//! ```text
//! checkerboard captures --(zhang, projector: calibration)--> RigCalibration --(rig_file)--> rig.json
//! rig.json --(rig_file::read)--> RigCalibration --> triangulation / reconstruct
//! ```
//!
//! A rig has one or two *heads*; each head is a camera and a projector whose poses are
//! given in the head's own world frame (usually the camera frame, so the camera pose is
//! the identity). With two heads, [`RigCalibration::head_to_head`] maps head 0's frame
//! into head 1's. A rig may also hold stereo heads (two cameras and an uncalibrated
//! projector, [`StereoHead`]), and then needs no projector-camera head at all.
//! [`opencv`] reads and writes OpenCV's calibration files.

pub mod board;
pub mod bundle;
pub mod detect;
pub mod extrinsics;
pub mod head;
pub mod homography;
pub mod lm;
pub mod opencv;
pub mod phase_file;
mod pinhole;
pub mod projector;
pub mod rig_file;
pub mod rodrigues;
pub mod truth_error;
pub mod zhang;

pub use pinhole::{CameraModel, Distortion, Intrinsics, PinholeModel, Pose, ProjectorModel, Ray};
pub use rig_file::{read_rig, write_rig, RigFileError};

/// Reprojection error of one calibration view (one board pose), pixels RMS.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewError {
    /// Name of the view (file name or index), as the calibration saw it.
    pub view: String,
    /// Camera reprojection error, pixels RMS.
    pub camera_rms_px: f64,
    /// Projector reprojection error, pixels RMS, when the projector was calibrated.
    pub projector_rms_px: Option<f64>,
}

/// One projector-camera head.
#[derive(Clone, Debug, PartialEq)]
pub struct Head {
    /// Name of the head ("A", "B", ...), as the scan plan calls it.
    pub name: String,
    /// The camera, pose world -> camera.
    pub camera: CameraModel,
    /// The projector, pose world -> projector.
    pub projector: ProjectorModel,
    /// Per-view reprojection errors of the calibration that produced this head.
    pub view_errors: Vec<ViewError>,
}

/// A stereo head: two calibrated cameras and an uncalibrated projector that only
/// labels the surface (each point's absolute phase matches a left pixel to a right
/// one); depth comes from the two cameras. Poses map the head's world frame (usually
/// the left camera's) into each camera, as OpenCV's `R`/`T` do.
#[derive(Clone, Debug, PartialEq)]
pub struct StereoHead {
    /// Name of the head, as the rig file calls it.
    pub name: String,
    /// The left (reference) camera, pose world -> camera.
    pub left: CameraModel,
    /// The right camera, pose world -> camera.
    pub right: CameraModel,
}

/// A calibrated rig of one or two projector-camera heads, and any stereo heads.
#[derive(Clone, Debug, PartialEq)]
pub struct RigCalibration {
    /// One or two projector-camera heads (none when there is a stereo head).
    pub heads: Vec<Head>,
    /// With two heads: head 0's world frame -> head 1's world frame. `None` with one head.
    pub head_to_head: Option<Pose>,
    /// Stereo heads (two cameras each), each in its own world frame.
    pub stereo_heads: Vec<StereoHead>,
}

impl Head {
    /// RMS over views of the camera reprojection error, pixels; `None` without views.
    pub fn camera_rms_px(&self) -> Option<f64> {
        rms(self.view_errors.iter().map(|v| v.camera_rms_px))
    }

    /// RMS over views of the projector reprojection error, pixels; `None` without any.
    pub fn projector_rms_px(&self) -> Option<f64> {
        rms(self.view_errors.iter().filter_map(|v| v.projector_rms_px))
    }
}

impl RigCalibration {
    /// A one-head rig.
    pub fn single(head: Head) -> Self {
        Self {
            heads: vec![head],
            head_to_head: None,
            stereo_heads: vec![],
        }
    }

    /// The head with this name.
    pub fn head(&self, name: &str) -> Option<&Head> {
        self.heads.iter().find(|h| h.name == name)
    }

    /// The stereo head with this name.
    pub fn stereo_head(&self, name: &str) -> Option<&StereoHead> {
        self.stereo_heads.iter().find(|h| h.name == name)
    }

    /// Checks everything a reader of the rig relies on (see [`RigFileError`] for the list).
    pub fn validate(&self) -> Result<(), RigFileError> {
        rig_file::validate(self)
    }
}

fn rms(values: impl Iterator<Item = f64>) -> Option<f64> {
    let (n, sum) = values.fold((0usize, 0.0), |(n, s), v| (n + 1, s + v * v));
    (n > 0).then(|| (sum / n as f64).sqrt())
}
