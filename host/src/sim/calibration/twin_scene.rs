//! Calibration of a built-in dual-head twin scene's two heads from rendered
//! checkerboard views, as a user of the real rig would do before scanning.
//!
//! ```text
//! scene rig (same devices and head poses as `scan --sim --scene NAME`)
//!   per head: TwinHead (that head's camera + projector), board held at 12 poses
//!             relative to its camera (twin_head's poses) --calibrate_head--> head
//!   both:     board held in the overlap, seen by both cameras
//!             --calibrate_head_to_head--> head 0 camera -> head 1 camera
//! ```
//!
//! Only the checkerboard views are rendered: the scene's own objects (e.g. the panel of
//! `large-part`) are not in the calibration scenes, as a user calibrates before placing
//! the part. The truth returned beside the estimate is the twin's device set.

use hil_sim::twin::scenes::{built_in, single_head, Detail, CHECKERBOARD};
use hil_sim::twin::{Rig, SensorModel, TwinError, V3};

use super::from_twin::{head_from_twin, pose_from_twin};
use super::twin_head::{self, TwinHead};
use crate::calibration::board::Target;
use crate::calibration::extrinsics::PairCalibration;
use crate::calibration::head::{
    calibrate_head, calibrate_head_to_head, HeadCalibration, HeadError, HeadOptions,
};
use crate::calibration::{Head, Pose, RigCalibration};

/// Shared-view board poses tried in the overlap (centre x, y, z in metres; Rodrigues
/// tilt): the board held where both cameras see it whole. Poses that either camera
/// would not see whole are dropped by [`scene_heads`].
const SHARED_POSES: [([f64; 3], [f64; 3]); 6] = [
    ([0.0, 0.0, 0.55], [0.0, 0.0, 0.0]),
    ([0.0, 0.03, 0.56], [0.25, 0.0, 0.05]),
    ([0.0, -0.03, 0.54], [-0.25, 0.05, -0.05]),
    ([0.01, 0.0, 0.58], [0.05, 0.2, 0.3]),
    ([-0.01, 0.01, 0.57], [0.1, -0.2, -0.3]),
    ([0.0, -0.01, 0.6], [-0.15, 0.1, 0.6]),
];

/// Fraction of the image width a shared view's outer inner corners keep from the border.
const SHARED_MARGIN: f64 = 0.04;

/// What can stop a scene calibration.
#[derive(Debug, thiserror::Error)]
pub enum SceneCalibrationError {
    /// The scene could not be built or rendered.
    #[error("digital twin: {0}")]
    Twin(#[from] TwinError),
    /// The scene has not two heads.
    #[error("scene {scene} has {cameras} cameras and {projectors} projectors; a dual-head calibration needs 2 of each")]
    NotDualHead {
        /// Scene name.
        scene: String,
        /// Cameras in its rig.
        cameras: usize,
        /// Projectors in its rig.
        projectors: usize,
    },
    /// No board pose of the overlap is seen whole by both cameras.
    #[error("scene {scene}: no shared board pose is seen whole by both cameras")]
    NoSharedView {
        /// Scene name.
        scene: String,
    },
    /// A head's calibration failed.
    #[error("head {head}: {source}")]
    Head {
        /// Head name.
        head: String,
        /// Why.
        source: HeadError,
    },
    /// The head-to-head pose failed.
    #[error("head-to-head: {0}")]
    HeadToHead(#[source] HeadError),
}

/// A dual-head scene set up for calibration.
#[derive(Debug, Clone)]
pub struct SceneHeads {
    /// Scene name.
    pub scene: String,
    /// One twin head per scene head (its camera and projector), with its board views.
    pub heads: Vec<TwinHead>,
    /// Head names, in order.
    pub names: [String; 2],
    /// Board poses (twin world) both cameras see whole.
    pub shared: Vec<hil_sim::twin::Pose>,
    /// The scene's true devices as a rig calibration.
    pub truth: RigCalibration,
}

/// A calibrated scene and the stages that produced it.
#[derive(Debug)]
pub struct SceneCalibration {
    /// The estimated rig, ready for the rig file.
    pub rig: RigCalibration,
    /// Each head's calibration stages.
    pub heads: Vec<HeadCalibration>,
    /// The head-to-head refinement over the shared views.
    pub head_to_head: PairCalibration,
}

/// Sets up the two heads of built-in scene `scene` at `detail`, each shown `views`
/// board poses (at most 15), and the shared views for the head-to-head pose.
pub fn scene_heads(
    scene: &str,
    detail: &Detail,
    views: usize,
    names: [&str; 2],
) -> Result<SceneHeads, SceneCalibrationError> {
    let (_, rig) = built_in(scene, detail)?;
    if rig.cameras.len() != 2 || rig.projectors.len() != 2 {
        return Err(SceneCalibrationError::NotDualHead {
            scene: scene.to_string(),
            cameras: rig.cameras.len(),
            projectors: rig.projectors.len(),
        });
    }
    // twin_head's board poses are laid out for the single head's camera; carry them
    // into each scene camera's frame so each head sees the same spread of views.
    let standard = TwinHead::standard(views, detail);
    let single_from_world = single_head(detail).cameras[0]
        .model
        .world_from_device
        .inverse();
    let heads = (0..2)
        .map(|h| {
            let sub = head_rig(&rig, h);
            let world_from_camera = sub.cameras[0].model.world_from_device;
            let world_from_board = standard
                .world_from_board
                .iter()
                .map(|b| world_from_camera * single_from_world * b)
                .collect();
            TwinHead {
                truth: head_from_twin(&sub, 0, 0, names[h]).expect("one camera, one projector"),
                rig: sub,
                world_from_board,
                pixel_samples: standard.pixel_samples,
            }
        })
        .collect();
    let shared: Vec<hil_sim::twin::Pose> = SHARED_POSES
        .iter()
        .map(|(t, r)| hil_sim::twin::Pose::new(V3::from(*t), V3::from(*r)))
        .filter(|pose| (0..2).all(|h| seen_whole(&rig, h, pose)))
        .collect();
    if shared.is_empty() {
        return Err(SceneCalibrationError::NoSharedView {
            scene: scene.to_string(),
        });
    }
    Ok(SceneHeads {
        scene: scene.to_string(),
        heads,
        names: names.map(String::from),
        shared,
        truth: truth(&rig, names).expect("checked above: two cameras, two projectors"),
    })
}

/// Renders every view of `scene` with `sensor` and calibrates both heads and the
/// head-to-head pose.
pub fn calibrate_scene(
    scene: &SceneHeads,
    sensor: &SensorModel,
    seed: u64,
    options: &HeadOptions,
) -> Result<SceneCalibration, SceneCalibrationError> {
    let target = Target::Checkerboard(twin_head::board());
    let mut heads = Vec::with_capacity(2);
    let mut shared_images = Vec::with_capacity(2);
    for (h, twin) in scene.heads.iter().enumerate() {
        let name = &scene.names[h];
        let head_seed = seed.wrapping_add(h as u64 * 0x9e37);
        let start = std::time::Instant::now();
        let captures = twin.render(sensor, head_seed, true)?;
        let rendered = start.elapsed();
        let cal = calibrate_head(name, &target, &captures, &twin.projector_spec(), options)
            .map_err(|source| SceneCalibrationError::Head {
                head: name.clone(),
                source,
            })?;
        tracing::info!(
            head = %name,
            views = captures.len(),
            render_ms = rendered.as_millis() as u64,
            calibrate_ms = (start.elapsed() - rendered).as_millis() as u64,
            "head calibrated"
        );
        heads.push(cal);
        let shared = TwinHead {
            world_from_board: scene.shared.clone(),
            ..twin.clone()
        };
        let images: Vec<_> = shared
            .render(sensor, head_seed.wrapping_add(0x51ed), false)?
            .into_iter()
            .map(|c| c.image)
            .collect();
        shared_images.push(images);
    }
    let pairs: Vec<_> = shared_images[0]
        .iter()
        .cloned()
        .zip(shared_images[1].iter().cloned())
        .collect();
    let head_to_head = calibrate_head_to_head(
        &heads[0].head.camera,
        &heads[1].head.camera,
        &target,
        &pairs,
        options,
    )
    .map_err(SceneCalibrationError::HeadToHead)?;
    let rig = RigCalibration {
        heads: heads.iter().map(|c| c.head.clone()).collect(),
        head_poses: vec![head_to_head.a_to_b],
        stereo_heads: vec![],
    };
    Ok(SceneCalibration {
        rig,
        heads,
        head_to_head,
    })
}

/// The scene rig's camera `h` and projector `h` as a one-head rig.
fn head_rig(rig: &Rig, h: usize) -> Rig {
    Rig {
        cameras: vec![rig.cameras[h].clone()],
        projectors: vec![rig.projectors[h].clone()],
        medium: rig.medium,
    }
}

/// Whether camera `h` sees every inner corner of the board at `pose`, away from the
/// border by [`SHARED_MARGIN`] of the image width.
fn seen_whole(rig: &Rig, h: usize, pose: &hil_sim::twin::Pose) -> bool {
    let cam = &rig.cameras[h].model;
    let (w, ht) = (
        f64::from(cam.intrinsics.width),
        f64::from(cam.intrinsics.height),
    );
    let m = SHARED_MARGIN * w;
    CHECKERBOARD
        .corners_px(pose, cam)
        .iter()
        .all(|c| c.is_some_and(|[x, y]| x >= m && y >= m && x <= w - 1.0 - m && y <= ht - 1.0 - m))
}

/// The twin's true devices of a dual-head rig: each head in its camera frame,
/// head-to-head = camera 0 -> camera 1; `None` unless the rig has two cameras
/// and two projectors.
pub fn truth(rig: &Rig, names: [&str; 2]) -> Option<RigCalibration> {
    let heads = (0..2)
        .map(|h| head_from_twin(rig, h, h, names[h]))
        .collect::<Option<Vec<Head>>>()?;
    let world_to_0 = pose_from_twin(&rig.cameras[0].model.world_from_device);
    let world_to_1 = pose_from_twin(&rig.cameras[1].model.world_from_device);
    let head_to_head: Pose = world_to_1.compose(&world_to_0.inverse());
    Some(RigCalibration {
        heads,
        head_poses: vec![head_to_head],
        stereo_heads: vec![],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_part_heads_keep_their_scene_devices_and_share_views() {
        let detail = Detail {
            camera: (160, 120),
            projector: (320, 200),
        };
        let s = scene_heads("large-part", &detail, 4, ["A", "B"]).expect("dual-head scene");
        let (_, rig) = built_in("large-part", &detail).unwrap();
        assert_eq!(truth(&rig, ["A", "B"]).as_ref(), Some(&s.truth));
        s.truth.validate().expect("valid truth");
        assert!(!s.shared.is_empty());
        for h in 0..2 {
            assert_eq!(s.heads[h].truth.camera, s.truth.heads[h].camera);
            assert_eq!(s.heads[h].truth.projector, s.truth.heads[h].projector);
            assert_eq!(s.heads[h].world_from_board.len(), 4);
            // Every board view is seen whole by its own camera.
            for pose in &s.heads[h].world_from_board {
                assert!(seen_whole(&s.heads[h].rig, 0, pose));
            }
        }
    }

    #[test]
    fn a_single_head_scene_is_refused() {
        let err = scene_heads("plane", &Detail::default(), 4, ["A", "B"]).unwrap_err();
        assert!(matches!(
            err,
            SceneCalibrationError::NotDualHead { cameras: 1, .. }
        ));
    }
}
