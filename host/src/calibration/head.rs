//! Whole-head calibration: board images (and phase maps) in, a [`Head`] out.
//!
//! ```text
//! per view: image --detect--> corners ; phase_x, phase_y --local homography--> projector corners
//! all views: corners --Zhang+LM--> camera ; projector corners --Zhang+LM--> projector
//!            both --pair LM (intrinsics fixed)--> camera -> projector pose
//! shared views of two heads --pair LM--> head 0 camera -> head 1 camera
//! ```
//!
//! A head's world frame is its camera's frame: the camera pose is the identity
//! and the projector pose is camera -> projector, as `rig_file` expects.
//! Views where the board is not found are skipped (and listed), as OpenCV's
//! tools do, so one bad capture does not spoil a session.

use nalgebra::Point2;

use super::board::{GrayImage, Target};
use super::bundle::{
    calibrate_camera, CalibrateError, CameraCalibration, CameraCalibrationOptions,
};
use super::detect::{detect_target, DetectError, DetectOptions};
use super::extrinsics::{calibrate_pair, planar_pose, ExtrinsicsError, PairCalibration};
use super::lm::LmOptions;
use super::projector::{calibrate_projector, PhaseMaps, ProjectorError};
use super::zhang::PlanarView;
use super::{Head, PinholeModel, Pose, ViewError};

/// One board pose as a head captured it.
#[derive(Debug, Clone)]
pub struct BoardCapture {
    /// Name of the view (file stem or index).
    pub name: String,
    /// The camera's image of the board, grey [0, 1].
    pub image: GrayImage,
    /// Absolute phase maps `(x, y)` of the same pose, radians, NaN = none.
    pub phase: Option<(GrayImage, GrayImage)>,
}

/// Knobs of head calibration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadOptions {
    /// Checkerboard detection.
    pub detect: DetectOptions,
    /// Camera Zhang + LM.
    pub camera: CameraCalibrationOptions,
    /// Projector Zhang + LM.
    pub projector: CameraCalibrationOptions,
    /// Half-size of the local-homography window for phase at corners, pixels.
    pub phase_window_px: usize,
    /// Pair refinement.
    pub extrinsics: LmOptions,
}

impl Default for HeadOptions {
    fn default() -> Self {
        Self {
            detect: DetectOptions::default(),
            camera: CameraCalibrationOptions::default(),
            projector: CameraCalibrationOptions::default(),
            phase_window_px: 5,
            extrinsics: LmOptions::default(),
        }
    }
}

/// The projector a head has: DMD size and the period of its fringes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProjectorSpec {
    /// DMD width, pixels.
    pub width_px: u32,
    /// DMD height, pixels.
    pub height_px: u32,
    /// Fringe period in the phase maps, projector pixels.
    pub period_px: f64,
}

/// Errors of head calibration.
#[derive(Debug, thiserror::Error)]
pub enum HeadError {
    /// Views differ in image size.
    #[error(
        "view {view} is {width}x{height}, the first view is {expected_width}x{expected_height}"
    )]
    SizeMismatch {
        /// The view.
        view: String,
        /// Its width.
        width: u32,
        /// Its height.
        height: u32,
        /// Width of the first view.
        expected_width: u32,
        /// Height of the first view.
        expected_height: u32,
    },
    /// Too few views had a detectable board.
    #[error("only {usable} of {total} views show the board (need >= {needed}); first failure: {first_failure}")]
    TooFewViews {
        /// Views with a board.
        usable: usize,
        /// Views given.
        total: usize,
        /// Views needed.
        needed: usize,
        /// The first view's detection error, as text.
        first_failure: String,
    },
    /// A view lacks phase maps while others have them.
    #[error("view {view} has no phase maps (projector calibration needs them in every view)")]
    MissingPhase {
        /// The view.
        view: String,
    },
    /// Camera calibration failed.
    #[error("camera: {0}")]
    Camera(#[source] CalibrateError),
    /// Projector calibration failed.
    #[error("projector: {0}")]
    Projector(#[from] ProjectorError),
    /// Extrinsics failed.
    #[error("extrinsics: {0}")]
    Extrinsics(#[from] ExtrinsicsError),
    /// A shared view for head-to-head was not detected.
    #[error("shared view, head {head}: {source}")]
    SharedView {
        /// Which head (0 or 1).
        head: usize,
        /// Why.
        source: DetectError,
    },
}

/// The camera stage: detected views and the calibrated camera.
#[derive(Debug)]
pub struct CameraStage {
    /// Names of the views used (board found), in order.
    pub names: Vec<String>,
    /// Views skipped, with the reason.
    pub skipped: Vec<(String, DetectError)>,
    /// Corners per used view, board order, pixels.
    pub corners_px: Vec<Vec<Point2<f64>>>,
    /// The calibration.
    pub calibration: CameraCalibration,
    /// The camera model (pose identity).
    pub camera: PinholeModel,
}

/// A calibrated head and the stages that produced it.
#[derive(Debug)]
pub struct HeadCalibration {
    /// The head, ready for the rig file.
    pub head: Head,
    /// The camera stage.
    pub camera: CameraStage,
    /// The projector's own Zhang + LM.
    pub projector: CameraCalibration,
    /// The camera -> projector refinement.
    pub pair: PairCalibration,
}

/// Minimum views for a calibration with distortion.
pub const MIN_VIEWS: usize = 3;

/// Detects the target in every capture and calibrates the camera.
pub fn calibrate_camera_stage(
    target: &Target,
    captures: &[BoardCapture],
    options: &HeadOptions,
) -> Result<CameraStage, HeadError> {
    let Some(first) = captures.first() else {
        return Err(HeadError::TooFewViews {
            usable: 0,
            total: 0,
            needed: MIN_VIEWS,
            first_failure: "no views given".into(),
        });
    };
    let size = first.image.dimensions();
    let mut names = Vec::new();
    let mut skipped = Vec::new();
    let mut corners_px = Vec::new();
    for c in captures {
        let (w, h) = c.image.dimensions();
        if (w, h) != size {
            return Err(HeadError::SizeMismatch {
                view: c.name.clone(),
                width: w,
                height: h,
                expected_width: size.0,
                expected_height: size.1,
            });
        }
        match detect_target(&c.image, target, &options.detect) {
            Ok(corners) => {
                names.push(c.name.clone());
                corners_px.push(corners);
            }
            Err(e) => {
                tracing::warn!(view = %c.name, error = %e, "board not found; view skipped");
                skipped.push((c.name.clone(), e));
            }
        }
    }
    if corners_px.len() < MIN_VIEWS {
        return Err(HeadError::TooFewViews {
            usable: corners_px.len(),
            total: captures.len(),
            needed: MIN_VIEWS,
            first_failure: skipped
                .first()
                .map_or_else(|| "none".into(), |(n, e)| format!("{n}: {e}")),
        });
    }
    let board_m = target.points_m();
    let views: Vec<PlanarView> = corners_px
        .iter()
        .map(|c| PlanarView {
            board_m: board_m.clone(),
            image_px: c.clone(),
        })
        .collect();
    let calibration = calibrate_camera(&views, size, &options.camera).map_err(HeadError::Camera)?;
    let camera = PinholeModel {
        width_px: size.0,
        height_px: size.1,
        intrinsics: calibration.intrinsics,
        distortion: calibration.distortion,
        pose: Pose::identity(),
    };
    Ok(CameraStage {
        names,
        skipped,
        corners_px,
        calibration,
        camera,
    })
}

/// Calibrates a head: camera, projector (from the phase maps of every view)
/// and the camera -> projector pose.
pub fn calibrate_head(
    name: &str,
    target: &Target,
    captures: &[BoardCapture],
    projector: &ProjectorSpec,
    options: &HeadOptions,
) -> Result<HeadCalibration, HeadError> {
    let stage = calibrate_camera_stage(target, captures, options)?;
    let mut maps = Vec::with_capacity(stage.names.len());
    for view in &stage.names {
        let capture = captures.iter().find(|c| &c.name == view);
        let Some((px, py)) = capture.and_then(|c| c.phase.as_ref()) else {
            return Err(HeadError::MissingPhase { view: view.clone() });
        };
        maps.push(PhaseMaps {
            phase_x: px,
            phase_y: py,
            period_px: projector.period_px,
        });
    }
    let board_m = target.points_m();
    let (proj_cal, proj_views) = calibrate_projector(
        &board_m,
        &stage.corners_px,
        &maps,
        (projector.width_px, projector.height_px),
        options.phase_window_px,
        &options.projector,
    )?;
    let projector_model = PinholeModel {
        width_px: projector.width_px,
        height_px: projector.height_px,
        intrinsics: proj_cal.intrinsics,
        distortion: proj_cal.distortion,
        pose: Pose::identity(),
    };
    let cam_views: Vec<PlanarView> = stage
        .corners_px
        .iter()
        .map(|c| PlanarView {
            board_m: board_m.clone(),
            image_px: c.clone(),
        })
        .collect();
    let pair = calibrate_pair(
        &stage.camera,
        &projector_model,
        &cam_views,
        &proj_views,
        &stage.calibration.board_poses,
        &proj_cal.board_poses,
        &options.extrinsics,
    )?;
    let view_errors = stage
        .names
        .iter()
        .enumerate()
        .map(|(v, n)| ViewError {
            view: n.clone(),
            camera_rms_px: pair.view_rms_a_px[v],
            projector_rms_px: Some(pair.view_rms_b_px[v]),
        })
        .collect();
    let head = Head {
        name: name.to_owned(),
        camera: stage.camera,
        projector: PinholeModel {
            pose: pair.a_to_b,
            ..projector_model
        },
        view_errors,
        port: None,
    };
    Ok(HeadCalibration {
        head,
        camera: stage,
        projector: proj_cal,
        pair,
    })
}

/// Head 0's camera frame -> head 1's camera frame from views of one board
/// pose (or several) that both cameras saw: `shared[k] = (image in head 0,
/// image in head 1)`. Intrinsics come from each head's own calibration.
pub fn calibrate_head_to_head(
    camera0: &PinholeModel,
    camera1: &PinholeModel,
    target: &Target,
    shared: &[(GrayImage, GrayImage)],
    options: &HeadOptions,
) -> Result<PairCalibration, HeadError> {
    let board_m = target.points_m();
    let mut views = [Vec::new(), Vec::new()];
    let mut poses = [Vec::new(), Vec::new()];
    for (img0, img1) in shared {
        for (head, (img, cam)) in [(img0, camera0), (img1, camera1)].into_iter().enumerate() {
            let corners = detect_target(img, target, &options.detect)
                .map_err(|source| HeadError::SharedView { head, source })?;
            let view = PlanarView {
                board_m: board_m.clone(),
                image_px: corners,
            };
            poses[head].push(planar_pose(cam, &view)?);
            views[head].push(view);
        }
    }
    Ok(calibrate_pair(
        camera0,
        camera1,
        &views[0],
        &views[1],
        &poses[0],
        &poses[1],
        &options.extrinsics,
    )?)
}
