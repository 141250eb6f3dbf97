//! The digital twin's devices as slscan calibration models.
//!
//! These are the twin's TRUE devices written as a calibration, not an estimated one:
//! accuracy tests reconstruct twin renders with them, and `calibrate --sim` compares
//! its estimate against them.
//!
//! Pose conventions differ: the twin stores `world_from_device` (device -> world),
//! slscan stores world -> device (`X_d = R X_w + t`), so poses are inverted here.
//! Both use OpenCV's pinhole + Brown-Conrady model with pixel centres at integers,
//! so intrinsics and distortion carry over unchanged.

use hil_sim::twin::{Medium, Pinhole, Rig};

use crate::calibration::{Distortion, Head, Intrinsics, PinholeModel, Pose, StereoHead};
use crate::triangulation::flat_port::FlatPort;

/// A twin pose (`world_from_device`, an isometry) as slscan's world -> device [`Pose`].
pub fn pose_from_twin(world_from_device: &hil_sim::twin::Pose) -> Pose {
    let device_from_world = world_from_device.inverse();
    Pose {
        rotation: *device_from_world.rotation.to_rotation_matrix().matrix(),
        translation_m: device_from_world.translation.vector,
    }
}

/// A twin device as a [`PinholeModel`] posed in the twin's world frame.
pub fn pinhole_from_twin(device: &Pinhole) -> PinholeModel {
    let k = &device.intrinsics;
    let d = &device.distortion;
    PinholeModel {
        width_px: k.width,
        height_px: k.height,
        intrinsics: Intrinsics {
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
        },
        distortion: Distortion {
            k1: d.k1,
            k2: d.k2,
            p1: d.p1,
            p2: d.p2,
            k3: d.k3,
        },
        pose: pose_from_twin(&device.world_from_device),
    }
}

/// The twin's flat ports as a [`FlatPort`]: thin, square to each device's axis, water
/// beyond. `None` in air (and for twin water whose index our port refuses, below 1).
pub fn port_from_twin(medium: &Medium) -> Option<FlatPort> {
    match medium {
        Medium::Air => None,
        Medium::Water(w) => FlatPort::thin(w.port_distance_m, w.refractive_index).ok(),
    }
}

/// Twin camera `camera` and projector `projector` of `rig` as one head in slscan's
/// convention: the head frame is the camera frame (camera pose identity, projector pose
/// camera -> projector). Returns `None` when either index is out of range.
///
/// Twin world points map into this head frame with [`Head::camera`]'s twin pose, i.e.
/// `pose_from_twin(&rig.cameras[camera].model.world_from_device)`.
pub fn head_from_twin(rig: &Rig, camera: usize, projector: usize, name: &str) -> Option<Head> {
    let cam = &rig.cameras.get(camera)?.model;
    let proj = &rig.projectors.get(projector)?.model;
    let world_to_camera = pose_from_twin(&cam.world_from_device);
    let world_to_projector = pose_from_twin(&proj.world_from_device);
    Some(Head {
        name: name.to_string(),
        camera: PinholeModel {
            pose: Pose::identity(),
            ..pinhole_from_twin(cam)
        },
        projector: PinholeModel {
            pose: world_to_projector.compose(&world_to_camera.inverse()),
            ..pinhole_from_twin(proj)
        },
        view_errors: Vec::new(),
        port: port_from_twin(&rig.medium),
    })
}

/// Twin cameras `left` and `right` of `rig` as a stereo head in slscan's convention:
/// the head frame is the left camera's (its pose the identity, the right pose left ->
/// right, as OpenCV's `R`, `T`). The rig's projectors play no part: they only label
/// the surface. Returns `None` when either index is out of range.
///
/// Twin world points map into this head frame with the left camera's twin pose,
/// `pose_from_twin(&rig.cameras[left].model.world_from_device)`.
pub fn stereo_head_from_twin(
    rig: &Rig,
    left: usize,
    right: usize,
    name: &str,
) -> Option<StereoHead> {
    let l = &rig.cameras.get(left)?.model;
    let r = &rig.cameras.get(right)?.model;
    let world_to_left = pose_from_twin(&l.world_from_device);
    let world_to_right = pose_from_twin(&r.world_from_device);
    Some(StereoHead {
        name: name.to_string(),
        left: PinholeModel {
            pose: Pose::identity(),
            ..pinhole_from_twin(l)
        },
        right: PinholeModel {
            pose: world_to_right.compose(&world_to_left.inverse()),
            ..pinhole_from_twin(r)
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use hil_sim::twin::scenes::{dual_head, stereo_head, Detail};
    use hil_sim::twin::V3;
    use nalgebra::Point3;

    #[test]
    fn converted_devices_project_world_points_like_the_twin() {
        let rig = dual_head(&Detail {
            camera: (64, 48),
            projector: (80, 50),
        });
        for (c, p) in [(0, 0), (1, 1)] {
            let head = head_from_twin(&rig, c, p, "A").unwrap();
            let cam = &rig.cameras[c].model;
            let proj = &rig.projectors[p].model;
            let to_head = pose_from_twin(&cam.world_from_device);
            for w in [V3::new(-0.1, 0.02, 0.5), V3::new(0.05, -0.03, 0.55)] {
                let x = to_head.apply(&Point3::from(w));
                let want_c = cam.project(&w).unwrap();
                let got_c = head.camera.project(&x).unwrap();
                let want_p = proj.project(&w).unwrap();
                let got_p = head.projector.project(&x).unwrap();
                for (g, t) in [(got_c, want_c), (got_p, want_p)] {
                    assert!((g.x - t[0]).abs() < 1e-9 && (g.y - t[1]).abs() < 1e-9);
                }
            }
        }
        assert!(head_from_twin(&rig, 2, 0, "A").is_none());
    }

    #[test]
    fn a_stereo_head_projects_world_points_like_the_twin_cameras() {
        let rig = stereo_head(&Detail {
            camera: (64, 48),
            projector: (80, 50),
        });
        let head = stereo_head_from_twin(&rig, 0, 1, "S").unwrap();
        let to_head = pose_from_twin(&rig.cameras[0].model.world_from_device);
        for w in [V3::new(-0.03, 0.02, 0.5), V3::new(0.05, -0.03, 0.55)] {
            let x = to_head.apply(&Point3::from(w));
            for (cam, twin) in [(&head.left, 0), (&head.right, 1)] {
                let want = rig.cameras[twin].model.project(&w).unwrap();
                let got = cam.project(&x).unwrap();
                assert!((got.x - want[0]).abs() < 1e-9 && (got.y - want[1]).abs() < 1e-9);
            }
        }
        // The right camera sits 170 mm away, on the left camera's right.
        let c = head.right.centre_m();
        assert!((c.coords.norm() - 0.17).abs() < 1e-9 && c.x > 0.16, "{c}");
        assert!(stereo_head_from_twin(&rig, 0, 2, "S").is_none());
    }
}
