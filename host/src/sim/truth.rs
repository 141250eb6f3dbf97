//! The digital twin's truth for a scan: its true device models as a rig
//! calibration (in each head's camera frame; the twin's truth, NOT an
//! estimated calibration, and reports say so), and its per-pixel surface
//! truth as the plain [`GroundTruth`] that `scan::measure` takes.

use hil_sim::twin::scene::Motion;
use hil_sim::twin::{CameraGeometry, Illum, Object, Rig, Scene, Shape, TwinError, TwinRig};
use nalgebra::Isometry3;

use super::calibration::from_twin::{head_from_twin, pose_from_twin};
use crate::calibration::RigCalibration;
use crate::scan::truth::TrueSphere;
use crate::scan::{CameraTruth, GroundTruth, HEAD_NAMES};

/// The twin's per-pixel truth of its first `heads` cameras (head `h` is
/// camera `h` with projector `h`) as plain data, for a scan reconstructed
/// with an estimated calibration (its frames fitted onto the truth; set
/// `calibration_is_true` when it uses the twin's own devices). Every scene
/// object but the one named `wall` is "the object".
pub fn ground_truth(twin: &TwinRig, heads: usize) -> Result<GroundTruth, TwinError> {
    let is_object = object_ids(twin.scene());
    let cameras = (0..heads)
        .map(|h| {
            let renderer = twin.renderer(h)?;
            Ok(camera_truth(
                renderer.geometry(),
                h,
                &is_object,
                head_from_world(twin.rig(), h),
            ))
        })
        .collect::<Result<_, TwinError>>()?;
    Ok(GroundTruth {
        cameras,
        spheres: static_spheres(twin.scene()),
        calibration_is_true: false,
    })
}

/// The scene's spheres that stay where they are (a moving one has no one
/// true centre for a whole scan).
pub fn static_spheres(scene: &Scene) -> Vec<TrueSphere> {
    spheres_where(scene, 0.0, |o| matches!(o.motion, Motion::Static))
}

/// Every sphere of the scene with its centre at time `time_s` (board
/// clock, seconds; a moving sphere where its motion has taken it), for
/// measuring one instant of a high-speed scan.
pub fn spheres_at(scene: &Scene, time_s: f64) -> Vec<TrueSphere> {
    spheres_where(scene, time_s, |_| true)
}

fn spheres_where(scene: &Scene, time_s: f64, keep: impl Fn(&Object) -> bool) -> Vec<TrueSphere> {
    scene
        .objects
        .iter()
        .enumerate()
        .filter(|(_, o)| keep(o))
        .filter_map(|(k, o)| match &o.shape {
            Shape::Sphere { radius_m } => Some(TrueSphere {
                name: o.name.clone(),
                object: u16::try_from(k).ok()?,
                centre_m: o.pose_at(time_s).translation.vector.into(),
                radius_m: *radius_m,
            }),
            _ => None,
        })
        .collect()
}

/// The per-pixel truth of camera `head` (with projector `head`, in the
/// frame and conventions of [`ground_truth`]) with the scene posed at
/// `time_s` (board clock, seconds): what one instant of a high-speed scan
/// is measured against. A static scene reuses the twin's cached geometry;
/// a moving one is ray-cast at that instant.
pub fn camera_truth_at(twin: &TwinRig, head: usize, time_s: f64) -> Result<CameraTruth, TwinError> {
    let count = twin.rig().cameras.len();
    if head >= count {
        return Err(TwinError::NoSuchCamera { index: head, count });
    }
    let is_object = object_ids(twin.scene());
    let camera_from_world = head_from_world(twin.rig(), head);
    if !twin.scene().is_dynamic() {
        let renderer = twin.renderer(head)?;
        return Ok(camera_truth(
            renderer.geometry(),
            head,
            &is_object,
            camera_from_world,
        ));
    }
    let g = CameraGeometry::new(&twin.scene().at(time_s), twin.rig(), head)?;
    Ok(camera_truth(&g, head, &is_object, camera_from_world))
}

/// Which scene objects are "the object": all but those named `wall`.
pub fn object_ids(scene: &Scene) -> Vec<bool> {
    scene.objects.iter().map(|o| o.name != "wall").collect()
}

fn camera_truth(
    g: &CameraGeometry,
    projector: usize,
    is_object: &[bool],
    camera_from_world: Isometry3<f64>,
) -> CameraTruth {
    let own_object = match g.projectors.get(projector) {
        Some(view) => g
            .object
            .iter()
            .zip(&view.illum)
            .map(|(&o, &il)| {
                il == Illum::Lit && is_object.get(o as usize).copied().unwrap_or(false)
            })
            .collect(),
        None => vec![false; g.object.len()],
    };
    CameraTruth {
        width: g.width as usize,
        height: g.height as usize,
        camera_from_world,
        point_m: g.point_m.clone(),
        normal: g.normal.clone(),
        object: g.object.clone(),
        own_object,
        overlap: g.overlap.clone(),
    }
}

/// Head `h`'s frame (its camera frame) from the twin's world frame.
pub fn head_from_world(rig: &Rig, h: usize) -> Isometry3<f64> {
    rig.cameras[h].model.world_from_device.inverse()
}

/// The rig calibration of the twin's first `heads` camera/projector pairs:
/// each head in its camera's frame, `head_poses[i - 1]` = head A's frame -> head i's.
pub fn twin_calibration(rig: &Rig, heads: usize) -> RigCalibration {
    let heads_out = (0..heads)
        .map(|h| {
            head_from_twin(rig, h, h, HEAD_NAMES[h])
                .unwrap_or_else(|| panic!("the twin rig has no camera/projector pair {h}"))
        })
        .collect();
    // pose_from_twin inverts a twin (device -> world) pose, so hand it
    // head i -> A to get the A -> head i pose the calibration stores.
    let head_poses = (1..heads)
        .map(|h| pose_from_twin(&head_from_first(rig, h).inverse()))
        .collect();
    RigCalibration {
        heads: heads_out,
        head_poses,
        stereo_heads: vec![],
    }
}

/// The true rig calibration of built-in scene `scene` at `detail`'s sizes
/// (every head of the scene), for writing as a rig file.
pub fn scene_calibration(
    scene: &str,
    detail: &hil_sim::twin::scenes::Detail,
) -> Result<RigCalibration, TwinError> {
    let (_, rig) = hil_sim::twin::scenes::built_in(scene, detail)?;
    let heads = rig
        .cameras
        .len()
        .min(rig.projectors.len())
        .min(protocol::limits::MAX_HEADS);
    Ok(twin_calibration(&rig, heads))
}

/// Head A's frame -> head B's frame.
pub fn b_from_a(rig: &Rig) -> Isometry3<f64> {
    head_from_first(rig, 1)
}

/// Head `h`'s frame from head A's (the twin's true pose).
pub fn head_from_first(rig: &Rig, h: usize) -> Isometry3<f64> {
    head_from_world(rig, h) * head_from_world(rig, 0).inverse()
}

#[cfg(test)]
mod tests {
    use super::*;
    use hil_sim::twin::scenes::{dual_head, Detail};
    use nalgebra::Point3;

    #[test]
    fn projector_pixel_of_a_world_point_matches_the_twin() {
        let rig = dual_head(&Detail {
            camera: (64, 48),
            projector: (128, 80),
        });
        let cal = twin_calibration(&rig, 2);
        cal.validate().expect("valid rig");
        let world = Point3::new(0.05, 0.01, 0.5);
        for h in 0..2 {
            let in_head = head_from_world(&rig, h) * world;
            let ours = cal.heads[h].projector.project(&in_head).unwrap();
            let twin = rig.projectors[h].model.project(&world.coords).unwrap();
            assert!((ours.x - twin[0]).abs() < 1e-9 && (ours.y - twin[1]).abs() < 1e-9);
            let cam = cal.heads[h].camera.project(&in_head).unwrap();
            let twin_cam = rig.cameras[h].model.project(&world.coords).unwrap();
            assert!((cam.x - twin_cam[0]).abs() < 1e-9);
        }
    }
}

#[cfg(test)]
mod ground_truth_tests {
    use super::*;
    use hil_sim::twin::scenes::{built_in, Detail};
    use std::sync::Arc;

    #[test]
    fn plain_truth_matches_the_twin_geometry() {
        let detail = Detail {
            camera: (64, 48),
            projector: (128, 80),
        };
        let (scene, rig) = built_in("large-part", &detail).unwrap();
        let twin = Arc::new(TwinRig::new(scene, rig).unwrap());
        let truth = ground_truth(&twin, 2).unwrap();
        truth.validate().unwrap();
        for h in 0..2 {
            let g = twin.renderer(h).unwrap();
            let g = g.geometry();
            let c = &truth.cameras[h];
            assert_eq!((c.width, c.height), (64, 48));
            assert_eq!(c.point_m, g.point_m);
            // Own-object pixels are lit by the head's projector and see no wall.
            let own = c.own_object.iter().filter(|&&o| o).count();
            assert!(own > 0 && own < c.point_m.len(), "{own}");
            for (i, &o) in c.own_object.iter().enumerate() {
                if o {
                    assert_eq!(g.projectors[h].illum[i], Illum::Lit);
                    assert_ne!(twin.scene().objects[g.object[i] as usize].name, "wall");
                }
            }
        }
        let want = b_from_a(twin.rig());
        let got = truth.b_from_a(0, 1);
        assert!((want.translation.vector - got.translation.vector).norm() < 1e-12);
    }
}

#[cfg(test)]
mod instant_tests {
    use super::*;
    use hil_sim::twin::scenes::{built_in, Detail};
    use std::sync::Arc;

    #[test]
    fn a_falling_ball_moves_in_the_truth_and_the_wall_does_not() {
        let detail = Detail {
            camera: (96, 72),
            projector: (128, 80),
        };
        let (scene, rig) = built_in("falling", &detail).unwrap();
        let twin = Arc::new(TwinRig::new(scene, rig).unwrap());
        let (t0, t1) = (0.0, 0.02);
        let a = camera_truth_at(&twin, 0, t0).unwrap();
        let b = camera_truth_at(&twin, 0, t1).unwrap();
        // At t = 0 the truth is ground_truth's.
        assert_eq!(
            a.point_m,
            ground_truth(&twin, 1).unwrap().cameras[0].point_m
        );
        let wall = twin
            .scene()
            .objects
            .iter()
            .position(|o| o.name == "wall")
            .unwrap() as u16;
        let (mut moved, mut walls) = (0, 0);
        for i in 0..a.point_m.len() {
            if a.object[i] == wall && b.object[i] == wall {
                assert_eq!(a.point_m[i], b.point_m[i], "pixel {i}");
                assert!(!a.own_object[i] && !b.own_object[i]);
                walls += 1;
            } else if a.point_m[i] != b.point_m[i] {
                moved += 1;
            }
        }
        // 12 mm of fall, about 3 px here, of a ball about 16 px across.
        assert!(moved > 50 && walls > a.point_m.len() / 2, "{moved} {walls}");
        // The sphere truth follows the ball: 0.5 m/s and g for 20 ms.
        let (s0, s1) = (spheres_at(twin.scene(), t0), spheres_at(twin.scene(), t1));
        assert_eq!((s0.len(), s1.len()), (1, 1));
        assert!(static_spheres(twin.scene()).is_empty());
        let fall = 0.5 * t1 + 0.5 * 9.81 * t1 * t1;
        assert!((s1[0].centre_m[1] - s0[0].centre_m[1] - fall).abs() < 1e-12);
        assert_eq!((s1[0].centre_m[0], s1[0].centre_m[2]), (0.0, 0.48));
        assert_eq!(s1[0].radius_m, 0.03);
        // Pixels of the ball at t1 lie on the sphere centred where it fell to.
        let c = nalgebra::Vector3::from(s1[0].centre_m);
        let ball = s1[0].object;
        let on_ball: Vec<usize> = (0..b.object.len())
            .filter(|&i| b.object[i] == ball)
            .collect();
        assert!(on_ball.len() > 50);
        for i in on_ball {
            let p = b.point_m[i];
            let r = (nalgebra::Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64) - c).norm();
            assert!((r - 0.03).abs() < 1e-5, "pixel {i}: {r}");
        }
        assert!(matches!(
            camera_truth_at(&twin, 1, t0),
            Err(TwinError::NoSuchCamera { index: 1, count: 1 })
        ));
    }

    #[test]
    fn a_static_scene_has_one_truth_at_every_instant() {
        let detail = Detail {
            camera: (48, 36),
            projector: (64, 40),
        };
        let (scene, rig) = built_in("spheres", &detail).unwrap();
        let twin = TwinRig::new(scene, rig).unwrap();
        let a = camera_truth_at(&twin, 0, 0.0).unwrap();
        let b = camera_truth_at(&twin, 0, 1.5).unwrap();
        assert_eq!(a.point_m, b.point_m);
        assert_eq!(spheres_at(twin.scene(), 1.5), static_spheres(twin.scene()));
        assert_eq!(spheres_at(twin.scene(), 0.0).len(), 2);
    }
}
