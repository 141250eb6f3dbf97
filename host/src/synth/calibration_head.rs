//! A simulated head with known truth, rendered by the formula-based renderer
//! (`synth::targets`, not the digital twin): the calibration kernel tests
//! (host/tests/calibration.rs) use it to test detection and calibration in isolation.
//! `slscan calibrate --sim` and the twin accuracy tests use `sim::calibration::twin_head`.
//! Views sweep the board through tilts of up to about 20 degrees and
//! in-plane turns, as a person would hold it, at 0.45..0.55 m.

use nalgebra::Vector3;

use super::targets::{render_checkerboard, render_phase_maps, RenderSettings};
use crate::calibration::board::Checkerboard;
use crate::calibration::head::{BoardCapture, ProjectorSpec};
use crate::calibration::rodrigues::pose_from_rodrigues;
use crate::calibration::{Distortion, Intrinsics, PinholeModel, Pose};

/// Board tilts (Rodrigues vectors) as a person holds a board: up to about 20 degrees
/// out of plane and turns in plane.
pub const TILTS: [(f64, f64, f64); 15] = [
    (0.0, 0.0, 0.0),
    (0.3, 0.0, 0.05),
    (-0.3, 0.05, -0.05),
    (0.0, 0.35, 0.1),
    (0.05, -0.35, -0.1),
    (0.25, 0.25, 0.3),
    (-0.25, -0.25, -0.3),
    (0.2, -0.3, 0.5),
    (-0.2, 0.3, -0.5),
    (0.35, 0.1, 1.2),
    (-0.1, -0.3, 1.57),
    (0.15, 0.15, -1.4),
    (0.3, -0.2, 0.2),
    (-0.35, 0.2, 0.0),
    (0.1, 0.3, -0.2),
];

/// The truth of a simulated head and the board poses it is shown.
#[derive(Debug, Clone, PartialEq)]
pub struct SimHead {
    /// Camera (pose identity: the head frame).
    pub camera: PinholeModel,
    /// Projector, pose camera -> projector.
    pub projector: PinholeModel,
    /// Fringe period of the phase maps, projector pixels.
    pub period_px: f64,
    /// Phase noise, radians.
    pub phase_noise_rad: f64,
    /// The board.
    pub board: Checkerboard,
    /// Per view: board -> camera.
    pub board_poses: Vec<Pose>,
}

/// Board -> camera pose that puts the board centre at `centre_m` (camera
/// frame) with Rodrigues rotation `rvec`.
fn pose_centred(board: &Checkerboard, rvec: Vector3<f64>, centre_m: Vector3<f64>) -> Pose {
    let mut pose = pose_from_rodrigues(&rvec, &Vector3::zeros());
    let mid = Vector3::new(
        0.5 * (board.cols - 1) as f64 * board.square_m,
        0.5 * (board.rows - 1) as f64 * board.square_m,
        0.0,
    );
    pose.translation_m = centre_m - pose.rotation * mid;
    pose
}

impl SimHead {
    /// A 640x480 camera with visible barrel distortion and a 912x1140
    /// DLP-class projector 12 cm to its left, turned 0.2 rad towards it;
    /// a 9x6 board of 25 mm squares; `views` board poses (at most 15).
    pub fn standard(views: usize) -> Self {
        let camera = PinholeModel {
            width_px: 640,
            height_px: 480,
            intrinsics: Intrinsics {
                fx: 620.0,
                fy: 615.0,
                cx: 322.5,
                cy: 241.0,
            },
            distortion: Distortion {
                k1: -0.18,
                k2: 0.07,
                p1: 0.0008,
                p2: -0.0005,
                k3: 0.0,
            },
            pose: Pose::identity(),
        };
        let projector = PinholeModel {
            width_px: 912,
            height_px: 1140,
            intrinsics: Intrinsics {
                fx: 1450.0,
                fy: 1440.0,
                cx: 452.0,
                cy: 600.0,
            },
            distortion: Distortion {
                k1: 0.03,
                k2: -0.01,
                ..Distortion::none()
            },
            pose: pose_from_rodrigues(
                &Vector3::new(0.0, 0.2, 0.0),
                &Vector3::new(-0.12, 0.0, 0.015),
            ),
        };
        let board = Checkerboard {
            cols: 9,
            rows: 6,
            square_m: 0.025,
        };
        let tilts = TILTS;
        let board_poses = tilts
            .iter()
            .take(views.min(tilts.len()))
            .enumerate()
            .map(|(k, &(a, b, c))| {
                let z = 0.45 + 0.1 * (k % 3) as f64 / 2.0;
                let shift = 0.02 * ((k % 5) as f64 - 2.0);
                pose_centred(
                    &board,
                    Vector3::new(a, b, c),
                    Vector3::new(shift, -0.5 * shift, z),
                )
            })
            .collect();
        Self {
            camera,
            projector,
            period_px: 18.0,
            phase_noise_rad: 0.01,
            board,
            board_poses,
        }
    }

    /// A second head that sees the same board poses from about 15 cm to the
    /// side, turned 0.3 rad so that the boards stay centred, with a camera
    /// and a projector of its own; returns it and the true head-0 camera ->
    /// head-1 camera pose.
    pub fn second_head(&self) -> (SimHead, Pose) {
        let to_second = pose_from_rodrigues(
            &Vector3::new(0.0, 0.3, 0.0),
            &Vector3::new(-0.15, 0.0, 0.04),
        );
        let mut second = self.clone();
        second.camera.intrinsics = Intrinsics {
            fx: 640.0,
            fy: 636.0,
            cx: 318.0,
            cy: 243.5,
        };
        second.camera.distortion = Distortion {
            k1: -0.12,
            k2: 0.04,
            p1: -0.0006,
            p2: 0.0004,
            k3: 0.0,
        };
        second.projector.intrinsics.cx = 460.0;
        second.projector.pose = pose_from_rodrigues(
            &Vector3::new(0.0, -0.2, 0.0),
            &Vector3::new(0.12, 0.0, 0.015),
        );
        second.board_poses = self
            .board_poses
            .iter()
            .map(|p| to_second.compose(p))
            .collect();
        (second, to_second)
    }

    /// The projector spec the calibration is told.
    pub fn projector_spec(&self) -> ProjectorSpec {
        ProjectorSpec {
            width_px: self.projector.width_px,
            height_px: self.projector.height_px,
            period_px: self.period_px,
        }
    }

    /// The camera as it sees view `v` (pose board -> camera).
    pub fn camera_at(&self, v: usize) -> PinholeModel {
        PinholeModel {
            pose: self.board_poses[v],
            ..self.camera
        }
    }

    /// The projector as it sees view `v` (pose board -> projector).
    pub fn projector_at(&self, v: usize) -> PinholeModel {
        PinholeModel {
            pose: self.projector.pose.compose(&self.board_poses[v]),
            ..self.projector
        }
    }

    /// Renders every view: board image and, with `with_phase`, phase maps.
    pub fn render(&self, settings: &RenderSettings, with_phase: bool) -> Vec<BoardCapture> {
        (0..self.board_poses.len())
            .map(|v| {
                let s = RenderSettings {
                    seed: settings.seed.wrapping_add(v as u64),
                    ..*settings
                };
                let camera = self.camera_at(v);
                BoardCapture {
                    name: format!("view_{v:02}"),
                    image: render_checkerboard(&camera, &self.board, &s),
                    phase: with_phase.then(|| {
                        render_phase_maps(
                            &camera,
                            &self.projector_at(v),
                            &self.board,
                            self.period_px,
                            self.phase_noise_rad,
                            s.seed ^ 0x5eed,
                        )
                    }),
                }
            })
            .collect()
    }
}
