//! Calibration of a built-in twin scene's heads (two to four) from rendered
//! checkerboard views, as a user of the real rig would do before scanning.
//!
//! ```text
//! scene rig (same devices and head poses as `scan --sim --scene NAME`)
//!   per head:  TwinHead (that head's camera + projector), board held at twin_head's
//!              poses relative to its camera --calibrate_head--> head
//!   per pair:  neighbouring heads (A, B), (B, C), ...: board held where both cameras
//!              see it whole --calibrate_head_to_head--> camera h -> camera h+1
//!   chain:     A -> B -> C ... --> head A's frame -> each head's (the rig's head_poses)
//! ```
//!
//! Only the checkerboard views are rendered: the scene's own objects (e.g. the panel of
//! `large-part`, the blade of `ring-4`) are not in the calibration scenes, as a user
//! calibrates before placing the part. The truth returned beside the estimate is the
//! twin's device set.
//!
//! Each view is rendered in a *room*: twin_head's scene, a dim wall at z = 0.65 m of
//! the room's frame behind the board. The two-head scenes' heads all look along +z, so
//! their room is the scene's world (the figures the README quotes). A ring's heads face
//! one another across the part, and a wall fixed in the world would stand between some
//! of them and their boards: there each head's own views are rendered in its camera's
//! frame (as the single head's) and each pair's shared views in a frame whose wall
//! stands behind the board, facing both cameras.

use hil_sim::twin::scenes::{built_in, single_head, Detail, CHECKERBOARD};
use hil_sim::twin::{look_at, Rig, SensorModel, TwinError, V3};

use super::from_twin::{head_from_twin, pose_from_twin};
use super::twin_head::{self, TwinHead};
use crate::calibration::board::{GrayImage, Target};
use crate::calibration::detect::detect_target;
use crate::calibration::extrinsics::PairCalibration;
use crate::calibration::head::{
    calibrate_head, calibrate_head_to_head, HeadCalibration, HeadError, HeadOptions,
};
use crate::calibration::rodrigues::{pose_from_rodrigues, rodrigues_from_rotation};
use crate::calibration::{Head, Pose, RigCalibration};

type TwinPose = hil_sim::twin::Pose;

/// Shared-view board poses of the two-head scenes (centre x, y, z in metres;
/// Rodrigues tilt): the board held where both cameras see it whole. Poses that either
/// camera would not see whole are dropped by [`scene_heads`].
const SHARED_POSES: [([f64; 3], [f64; 3]); 6] = [
    ([0.0, 0.0, 0.55], [0.0, 0.0, 0.0]),
    ([0.0, 0.03, 0.56], [0.25, 0.0, 0.05]),
    ([0.0, -0.03, 0.54], [-0.25, 0.05, -0.05]),
    ([0.01, 0.0, 0.58], [0.05, 0.2, 0.3]),
    ([-0.01, 0.01, 0.57], [0.1, -0.2, -0.3]),
    ([0.0, -0.01, 0.6], [-0.15, 0.1, 0.6]),
];

/// Shared-view board poses of a ring's pair of heads, relative to where the two
/// cameras' axes meet (the part's place): how far beyond it along the bisector of the
/// two viewing directions, metres, and the Rodrigues tilt of a board squarely facing
/// that bisector. Beyond the crossing both cameras see the board less obliquely
/// (45 deg at the crossing for heads 90 deg apart); tilts about the board's own x axis
/// and in its plane leave the two cameras' obliquities balanced, those about its y axis
/// (towards one camera) stay small. Poses either camera would not see whole are dropped.
const RING_SHARED_POSES: [(f64, [f64; 3]); 6] = [
    (0.06, [0.0, 0.0, 0.0]),
    (0.08, [0.2, 0.0, 0.05]),
    (0.04, [-0.2, 0.05, -0.05]),
    (0.10, [0.05, 0.1, 0.3]),
    (0.06, [0.1, -0.1, -0.3]),
    (0.02, [-0.15, 0.05, 0.5]),
];

/// Where twin_head's scene stands its wall: z of the room's frame, metres.
const ROOM_WALL_M: f64 = 0.65;
/// How far behind a ring pair's farthest shared board its room's wall stands, metres.
const RING_WALL_GAP_M: f64 = 0.15;

/// Fraction of the image width a shared view's outer inner corners keep from the border.
const SHARED_MARGIN: f64 = 0.04;

/// What can stop a scene calibration.
#[derive(Debug, thiserror::Error)]
pub enum SceneCalibrationError {
    /// The scene could not be built or rendered.
    #[error("digital twin: {0}")]
    Twin(#[from] TwinError),
    /// The scene has not 2 to `MAX_HEADS` heads, each a camera and a projector.
    #[error("scene {scene} has {cameras} cameras and {projectors} projectors; a scene calibration needs 2 to {} heads of one camera and one projector each", protocol::limits::MAX_HEADS)]
    HeadCount {
        /// Scene name.
        scene: String,
        /// Cameras in its rig.
        cameras: usize,
        /// Projectors in its rig.
        projectors: usize,
    },
    /// No shared board pose of a pair of heads is seen whole by both cameras.
    #[error("scene {scene}: no shared board pose is seen whole by the cameras of both heads {a} and {b}")]
    NoSharedView {
        /// Scene name.
        scene: String,
        /// The pair's first head.
        a: String,
        /// The pair's second head.
        b: String,
    },
    /// A head's calibration failed.
    #[error("head {head}: {source}")]
    Head {
        /// Head name.
        head: String,
        /// Why.
        source: HeadError,
    },
    /// A head-to-head pose failed.
    #[error("head-to-head {a} -> {b}: {source}")]
    HeadToHead {
        /// The pair's first head.
        a: String,
        /// The pair's second head.
        b: String,
        /// Why (boxed: a head error is large).
        source: Box<HeadError>,
    },
}

/// The board views two neighbouring heads share.
#[derive(Debug, Clone)]
pub struct SharedViews {
    /// The pair's heads (indices into [`SceneHeads::heads`]); the pose calibrated is
    /// camera `heads[0]` -> camera `heads[1]`.
    pub heads: [usize; 2],
    /// Board poses (twin world) both cameras see whole.
    pub world_from_board: Vec<TwinPose>,
    /// The room the views are rendered in (see the module doc).
    pub world_from_room: TwinPose,
}

/// A scene set up for calibration.
#[derive(Debug, Clone)]
pub struct SceneHeads {
    /// Scene name.
    pub scene: String,
    /// The scene's rig, twin world frame.
    pub rig: Rig,
    /// One twin head per scene head (its camera and projector, in its room), with its
    /// board views.
    pub heads: Vec<TwinHead>,
    /// Head names, in order.
    pub names: Vec<String>,
    /// Shared views of each pair of neighbouring heads: (A, B), (B, C), ..., and for a
    /// ring of three or more the closing pair (last, A).
    pub pairs: Vec<SharedViews>,
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
    /// The head-to-head refinement of each pair of [`SceneHeads::pairs`], in order.
    pub pairs: Vec<PairCalibration>,
    /// A ring's loop error before it was spread: head A -> A around the ring
    /// (`None` for two heads).
    pub loop_error: Option<Pose>,
}

/// Sets up the heads of built-in scene `scene` at `detail`, each shown `views` board
/// poses (at most 15), and the shared views of each pair of neighbouring heads. Head
/// `h` is named `names[h]`, or its letter (`C`, `D`) past the names given.
pub fn scene_heads<'n>(
    scene: &str,
    detail: &Detail,
    views: usize,
    names: impl AsRef<[&'n str]>,
) -> Result<SceneHeads, SceneCalibrationError> {
    let (_, rig) = built_in(scene, detail)?;
    let k = rig.cameras.len();
    if rig.projectors.len() != k || !(2..=protocol::limits::MAX_HEADS).contains(&k) {
        return Err(SceneCalibrationError::HeadCount {
            scene: scene.to_string(),
            cameras: k,
            projectors: rig.projectors.len(),
        });
    }
    let names = head_names(names.as_ref(), k);
    let ring = k > 2;
    // twin_head's board poses are laid out for the single head's camera; carry them
    // into each scene camera's frame so each head sees the same spread of views.
    let standard = TwinHead::standard(views, detail);
    let single_from_world = single_head(detail).cameras[0]
        .model
        .world_from_device
        .inverse();
    let heads = (0..k)
        .map(|h| {
            let sub = head_rig(&rig, h);
            let world_from_camera = sub.cameras[0].model.world_from_device;
            let world_from_room = if ring {
                world_from_camera
            } else {
                TwinPose::identity()
            };
            let room_from_camera = world_from_room.inverse() * world_from_camera;
            let world_from_board = standard
                .world_from_board
                .iter()
                .map(|b| room_from_camera * single_from_world * b)
                .collect();
            TwinHead {
                truth: head_from_twin(&sub, 0, 0, &names[h]).expect("one camera, one projector"),
                rig: in_room(&sub, &world_from_room),
                world_from_board,
                pixel_samples: standard.pixel_samples,
            }
        })
        .collect();
    // A ring is closed by the pair (last, A): its loop error is spread over the chain.
    let closing = if ring { k } else { k - 1 };
    let pairs = (0..closing)
        .map(|h| {
            let pair = [h, (h + 1) % k];
            let shared = if ring {
                ring_shared_views(&rig, pair)
            } else {
                fixed_shared_views(&rig, pair)
            };
            if shared.world_from_board.is_empty() {
                return Err(SceneCalibrationError::NoSharedView {
                    scene: scene.to_string(),
                    a: names[pair[0]].clone(),
                    b: names[pair[1]].clone(),
                });
            }
            Ok(shared)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let name_refs: Vec<&str> = names.iter().map(String::as_str).collect();
    Ok(SceneHeads {
        scene: scene.to_string(),
        truth: truth(&rig, &name_refs).expect("checked above: one projector per camera"),
        rig,
        heads,
        names,
        pairs,
    })
}

/// Renders every view of `scene` with `sensor` and calibrates every head, every pair's
/// head-to-head pose, and chains the pairs into each head's pose from head A.
pub fn calibrate_scene(
    scene: &SceneHeads,
    sensor: &SensorModel,
    seed: u64,
    options: &HeadOptions,
) -> Result<SceneCalibration, SceneCalibrationError> {
    let target = Target::Checkerboard(twin_head::board());
    let head_seed = |h: usize| seed.wrapping_add(h as u64 * 0x9e37);
    let mut heads = Vec::with_capacity(scene.heads.len());
    for (h, twin) in scene.heads.iter().enumerate() {
        let name = &scene.names[h];
        let start = std::time::Instant::now();
        let captures = twin.render(sensor, head_seed(h), true)?;
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
    }
    let mut pairs = Vec::with_capacity(scene.pairs.len());
    for (p, shared) in scene.pairs.iter().enumerate() {
        let [a, b] = shared.heads;
        let room_from_world = shared.world_from_room.inverse();
        let mut images = Vec::with_capacity(2);
        for h in [a, b] {
            let twin = TwinHead {
                rig: in_room(&head_rig(&scene.rig, h), &shared.world_from_room),
                world_from_board: shared
                    .world_from_board
                    .iter()
                    .map(|w| room_from_world * w)
                    .collect(),
                ..scene.heads[h].clone()
            };
            // Pair 0 keeps the two-head scenes' seeds (their figures stay as measured).
            let pair_seed = head_seed(h).wrapping_add(0x51ed + 0x1000 * p as u64);
            let rendered: Vec<_> = twin
                .render(sensor, pair_seed, false)?
                .into_iter()
                .map(|c| c.image)
                .collect();
            images.push(rendered);
        }
        // A shared board one camera does not find is dropped, as calibrate_head drops a
        // head's own views: a user would hold it again.
        let mut views = Vec::with_capacity(images[0].len());
        for (v, (img_a, img_b)) in images[0].iter().zip(&images[1]).enumerate() {
            let found = |img: &GrayImage| detect_target(img, &target, &options.detect).is_ok();
            match [found(img_a), found(img_b)] {
                [true, true] => views.push((img_a.clone(), img_b.clone())),
                [a_found, _] => tracing::warn!(
                    head = %scene.names[if a_found { b } else { a }],
                    pair = %format!("{}-{}", scene.names[a], scene.names[b]),
                    view = v,
                    "shared board not found; view skipped"
                ),
            }
        }
        let pair = calibrate_head_to_head(
            &heads[a].head.camera,
            &heads[b].head.camera,
            &target,
            &views,
            options,
        )
        .map_err(|source| SceneCalibrationError::HeadToHead {
            a: scene.names[a].clone(),
            b: scene.names[b].clone(),
            source: Box::new(source),
        })?;
        tracing::info!(
            a = %scene.names[a],
            b = %scene.names[b],
            views = views.len(),
            rms_px = pair.rms_px,
            "head-to-head calibrated"
        );
        pairs.push(pair);
    }
    let k = scene.heads.len();
    let pair_poses: Vec<Pose> = pairs.iter().map(|p| p.a_to_b).collect();
    let open = chain(&pair_poses[..k - 1]);
    let (head_poses, loop_error) = match pair_poses.get(k - 1) {
        Some(last_to_a) => {
            let loop_error = last_to_a.compose(&open[k - 2]);
            (close_loop(&open, &loop_error), Some(loop_error))
        }
        None => (open, None),
    };
    let rig = RigCalibration {
        heads: heads.iter().map(|c| c.head.clone()).collect(),
        head_poses,
        stereo_heads: vec![],
    };
    Ok(SceneCalibration {
        rig,
        heads,
        pairs,
        loop_error,
    })
}

/// Spreads a ring's loop error over its chain: `loop_error` = head A -> A around the
/// ring (the closing pair's pose after the chain), the identity if every pair were
/// exact. Each of the K pairs takes an equal share: head h's pose is corrected by
/// `loop_error^(-h/K)` in head A's frame (rotation by its angle, translation
/// linearly: the errors are small), so the closing pair is left 1/K of it.
fn close_loop(open: &[Pose], loop_error: &Pose) -> Vec<Pose> {
    let k = open.len() + 1;
    let rvec = rodrigues_from_rotation(&loop_error.rotation);
    open.iter()
        .enumerate()
        .map(|(i, a_to_h)| {
            let share = -((i + 1) as f64) / k as f64;
            let correction =
                pose_from_rodrigues(&(share * rvec), &(share * loop_error.translation_m));
            a_to_h.compose(&correction)
        })
        .collect()
}

/// Head A's frame -> head h's for h = 1..K from the neighbouring pairs' poses:
/// A -> C = (B -> C) after (A -> B), and so on along the chain.
fn chain(pair_poses: &[Pose]) -> Vec<Pose> {
    pair_poses
        .iter()
        .scan(Pose::identity(), |a_to_h, h_to_next| {
            *a_to_h = h_to_next.compose(a_to_h);
            Some(*a_to_h)
        })
        .collect()
}

/// `given[h]`, or head `h`'s letter past those given.
fn head_names(given: &[&str], k: usize) -> Vec<String> {
    (0..k)
        .map(|h| match given.get(h) {
            Some(name) => name.to_string(),
            None => char::from(b'A' + h as u8).to_string(),
        })
        .collect()
}

/// The scene rig's camera `h` and projector `h` as a one-head rig.
fn head_rig(rig: &Rig, h: usize) -> Rig {
    Rig {
        cameras: vec![rig.cameras[h].clone()],
        projectors: vec![rig.projectors[h].clone()],
        medium: rig.medium,
    }
}

/// `rig` with its devices given in the room's frame rather than the world's.
fn in_room(rig: &Rig, world_from_room: &TwinPose) -> Rig {
    let room_from_world = world_from_room.inverse();
    let mut rig = rig.clone();
    for c in &mut rig.cameras {
        c.model.world_from_device = room_from_world * c.model.world_from_device;
    }
    for p in &mut rig.projectors {
        p.model.world_from_device = room_from_world * p.model.world_from_device;
    }
    rig
}

/// A two-head scene's shared views: those of [`SHARED_POSES`] both cameras see whole,
/// in the scene's world.
fn fixed_shared_views(rig: &Rig, heads: [usize; 2]) -> SharedViews {
    SharedViews {
        heads,
        world_from_board: SHARED_POSES
            .iter()
            .map(|(t, r)| TwinPose::new(V3::from(*t), V3::from(*r)))
            .filter(|pose| heads.iter().all(|&h| seen_whole(rig, h, pose)))
            .collect(),
        world_from_room: TwinPose::identity(),
    }
}

/// A ring pair's shared views: [`RING_SHARED_POSES`] about where the two cameras' axes
/// meet, those both cameras see whole, in a room whose wall stands behind them.
fn ring_shared_views(rig: &Rig, heads: [usize; 2]) -> SharedViews {
    let axis = |h: usize| {
        let w = rig.cameras[h].model.world_from_device;
        (w.translation.vector, w.rotation * V3::z())
    };
    let ((oa, da), (ob, db)) = (axis(heads[0]), axis(heads[1]));
    let bisector = (da + db).normalize();
    let crossing = axes_crossing(oa, da, ob, db).unwrap_or(0.5 * (oa + ob) + 0.5 * bisector);
    let down = V3::new(0.0, -1.0, 0.0);
    let world_from_board = RING_SHARED_POSES
        .iter()
        .map(|&(beyond_m, tilt)| {
            let centre = crossing + beyond_m * bisector;
            // A board squarely facing the bisector, as the single head's boards face
            // its camera (board z along the view, y down), then tilted.
            look_at(centre, centre + bisector, down) * TwinPose::new(V3::zeros(), V3::from(tilt))
        })
        .filter(|pose| heads.iter().all(|&h| seen_whole(rig, h, pose)))
        .collect();
    let farthest_m = RING_SHARED_POSES
        .iter()
        .map(|&(beyond_m, _)| beyond_m)
        .fold(0.0, f64::max);
    let wall = crossing + (farthest_m + RING_WALL_GAP_M) * bisector;
    let origin = wall - ROOM_WALL_M * bisector;
    SharedViews {
        heads,
        world_from_board,
        world_from_room: look_at(origin, wall, down),
    }
}

/// Midpoint of the shortest segment between the lines `oa + t da` and `ob + u db`
/// (unit directions); `None` when they are near parallel.
fn axes_crossing(oa: V3, da: V3, ob: V3, db: V3) -> Option<V3> {
    let w0 = oa - ob;
    let (b, d, e) = (da.dot(&db), da.dot(&w0), db.dot(&w0));
    let denom = 1.0 - b * b;
    if denom < 1e-6 {
        return None;
    }
    let t = (b * e - d) / denom;
    let u = (e - b * d) / denom;
    Some(0.5 * ((oa + t * da) + (ob + u * db)))
}

/// Whether camera `h` sees every inner corner of the board at `pose`, away from the
/// border by [`SHARED_MARGIN`] of the image width.
fn seen_whole(rig: &Rig, h: usize, pose: &TwinPose) -> bool {
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

/// The twin's true devices of a rig of K heads (camera k and projector k form head
/// k): each head in its camera frame, `head_poses[h - 1]` = camera 0 -> camera h;
/// head `h` named `names[h]` or its letter past those given. `None` unless the rig has
/// one projector per camera and at least one of each.
pub fn truth(rig: &Rig, names: &[&str]) -> Option<RigCalibration> {
    let k = rig.cameras.len();
    if k == 0 || rig.projectors.len() != k {
        return None;
    }
    let names = head_names(names, k);
    let heads = (0..k)
        .map(|h| head_from_twin(rig, h, h, &names[h]))
        .collect::<Option<Vec<Head>>>()?;
    let world_to = |h: usize| pose_from_twin(&rig.cameras[h].model.world_from_device);
    let from_0 = world_to(0).inverse();
    let head_poses = (1..k).map(|h| world_to(h).compose(&from_0)).collect();
    Some(RigCalibration {
        heads,
        head_poses,
        stereo_heads: vec![],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::rodrigues::rotation_angle_between;

    const SMALL: Detail = Detail {
        camera: (160, 120),
        projector: (320, 200),
    };

    #[test]
    fn large_part_heads_keep_their_scene_devices_and_share_views() {
        let s = scene_heads("large-part", &SMALL, 4, ["A", "B"]).expect("dual-head scene");
        let (_, rig) = built_in("large-part", &SMALL).unwrap();
        assert_eq!(truth(&rig, &["A", "B"]).as_ref(), Some(&s.truth));
        s.truth.validate().expect("valid truth");
        assert_eq!(s.pairs.len(), 1);
        assert_eq!(s.pairs[0].heads, [0, 1]);
        assert!(!s.pairs[0].world_from_board.is_empty());
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
    fn ring_heads_share_views_with_their_neighbours_in_front_of_the_wall() {
        let s = scene_heads("ring-4", &SMALL, 3, ["A"]).expect("ring scene");
        assert_eq!(s.names, ["A", "B", "C", "D"]);
        assert_eq!(s.truth.head_poses.len(), 3);
        s.truth.validate().expect("valid truth");
        let heads: Vec<[usize; 2]> = s.pairs.iter().map(|p| p.heads).collect();
        assert_eq!(heads, [[0, 1], [1, 2], [2, 3], [3, 0]]);
        for h in 0..4 {
            // Rendered in its camera's frame: boards between the camera and the wall.
            let cam = s.heads[h].rig.cameras[0].model.world_from_device;
            assert!(cam.translation.vector.norm() < 1e-12);
            for pose in &s.heads[h].world_from_board {
                assert!(seen_whole(&s.heads[h].rig, 0, pose));
                assert!(pose.translation.z < ROOM_WALL_M - 0.05);
            }
        }
        for pair in &s.pairs {
            assert!(pair.world_from_board.len() >= 3, "{:?}", pair.heads);
            // In the pair's room both cameras look at each board from the side away
            // from the wall, and the wall stands behind it.
            let room_from_world = pair.world_from_room.inverse();
            for b in &pair.world_from_board {
                let b = room_from_world * b;
                assert!(b.translation.z + 0.1 < ROOM_WALL_M, "{}", b.translation.z);
                for &h in &pair.heads {
                    let cam = room_from_world * s.rig.cameras[h].model.world_from_device;
                    assert!(cam.translation.z + 0.2 < b.translation.z, "camera {h}");
                }
            }
        }
    }

    #[test]
    fn chaining_pairs_gives_each_heads_pose_from_the_first() {
        let (_, rig) = built_in("ring-4", &SMALL).unwrap();
        let t = truth(&rig, &[]).unwrap();
        let pair = |a: usize, b: usize| {
            let to = |h: usize| t.pose_from_first(h).unwrap();
            to(b).compose(&to(a).inverse())
        };
        let pairs: Vec<Pose> = (0..3).map(|h| pair(h, h + 1)).collect();
        for (got, want) in chain(&pairs).iter().zip(&t.head_poses) {
            assert!((got.translation_m - want.translation_m).norm() < 1e-12);
            assert!((got.rotation - want.rotation).norm() < 1e-12);
        }
    }

    #[test]
    fn a_loop_error_is_spread_so_the_ring_closes() {
        let (_, rig) = built_in("ring-4", &SMALL).unwrap();
        let t = truth(&rig, &[]).unwrap();
        // The pairs' poses off by a small rotation and shift each: the loop misses.
        let off = pose_from_rodrigues(&V3::new(1e-3, -2e-3, 5e-4), &V3::new(1e-3, 0.0, -2e-3));
        let to = |h: usize| t.pose_from_first(h % 4).unwrap();
        let pairs: Vec<Pose> = (0..4)
            .map(|h| off.compose(&to(h + 1).compose(&to(h).inverse())))
            .collect();
        let open = chain(&pairs[..3]);
        let loop_error = pairs[3].compose(&open[2]);
        let closed = close_loop(&open, &loop_error);
        let around = |poses: &[Pose]| pairs[3].compose(&poses[2]);
        let angle = |p: &Pose| rotation_angle_between(&p.rotation, &nalgebra::Matrix3::identity());
        // The closing pair keeps a quarter of the loop's error.
        let left = around(&closed);
        assert!(angle(&loop_error) > 1e-3);
        assert!((angle(&left) - 0.25 * angle(&loop_error)).abs() < 1e-9);
        assert!((left.translation_m.norm() - 0.25 * loop_error.translation_m.norm()).abs() < 2e-4);
    }

    #[test]
    fn a_single_head_scene_is_refused() {
        let err = scene_heads("plane", &Detail::default(), 4, ["A", "B"]).unwrap_err();
        assert!(matches!(
            err,
            SceneCalibrationError::HeadCount { cameras: 1, .. }
        ));
    }
}
