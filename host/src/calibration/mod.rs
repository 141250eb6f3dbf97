//! Calibration of the rig: the device models every other stage uses, and the rig file.
//!
//! ```text
//! checkerboard captures --(zhang, projector: calibration)--> RigCalibration --(rig_file)--> rig.json
//! rig.json --(rig_file::read)--> RigCalibration --> triangulation / reconstruct
//! ```
//!
//! A rig has one to four *heads*; each head is a camera and a projector whose poses are
//! given in the head's own world frame (usually the camera frame, so the camera pose is
//! the identity). [`RigCalibration::head_poses`] maps head 0's frame into each other
//! head's ([`RigCalibration::head_to_head`] is head 1's, for a two-head rig). A rig may also hold stereo heads (two cameras and an uncalibrated
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

use crate::triangulation::flat_port::FlatPort;
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
    /// The flat port both devices look through under water, each along its own optical
    /// axis (`None`: the head works in air). See [`crate::triangulation::flat_port`].
    pub port: Option<FlatPort>,
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
    /// One to `protocol::limits::MAX_HEADS` projector-camera heads (none
    /// when there is a stereo head).
    pub heads: Vec<Head>,
    /// Head 0's world frame -> head i's world frame, for i = 1..K (empty
    /// with one head).
    pub head_poses: Vec<Pose>,
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
            head_poses: Vec::new(),
            stereo_heads: vec![],
        }
    }

    /// A two-head rig's head 0 -> head 1 pose (`None` with any other
    /// number of heads).
    pub fn head_to_head(&self) -> Option<Pose> {
        match self.head_poses[..] {
            [a_to_b] if self.heads.len() == 2 => Some(a_to_b),
            _ => None,
        }
    }

    /// Head 0's world frame -> head `h`'s (the identity for head 0; `None`
    /// past the last head or without its pose).
    pub fn pose_from_first(&self, h: usize) -> Option<Pose> {
        match h {
            0 if !self.heads.is_empty() => Some(Pose::identity()),
            _ if h < self.heads.len() => self.head_poses.get(h - 1).copied(),
            _ => None,
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
