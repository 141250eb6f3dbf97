//! The digital twin's truth for a scan: its true device models as a rig
//! calibration (in each head's camera frame; the twin's truth, NOT an
//! estimated calibration, and reports say so), and its per-pixel surface
//! truth as the plain [`GroundTruth`] that `scan::measure` takes.

use hil_sim::twin::scene::Motion;
use hil_sim::twin::{CameraGeometry, Illum, Rig, Scene, Shape, TwinError, TwinRig};
use nalgebra::Isometry3;

use super::calibration::from_twin::{head_from_twin, pose_from_twin};
use crate::calibration::RigCalibration;
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
pub fn static_spheres(scene: &Scene) -> Vec<crate::scan::truth::TrueSphere> {
    scene
        .objects
        .iter()
        .enumerate()
        .filter_map(|(k, o)| match (&o.shape, &o.motion) {
            (Shape::Sphere { radius_m }, Motion::Static) => Some(crate::scan::truth::TrueSphere {
                name: o.name.clone(),
                object: u16::try_from(k).ok()?,
                centre_m: o.pose.translation.vector.into(),
                radius_m: *radius_m,
            }),
            _ => None,
        })
        .collect()
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
