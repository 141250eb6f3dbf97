//! The calibration a simulated scan reconstructs with: the digital twin's
//! true device models, in each head's camera frame. This is the twin's
//! truth, NOT an estimated calibration; reports say so.

use hil_sim::twin::{Pinhole, Rig};
use nalgebra::{Isometry3, Matrix3, Vector3};

use crate::calibration::{Distortion, Head, Intrinsics, PinholeModel, Pose, RigCalibration};

/// Head names in plan order.
pub const HEAD_NAMES: [&str; 2] = ["A", "B"];

/// The host's model of a twin device, with `world_to_device` as its pose.
fn model(device: &Pinhole, world_to_device: &Isometry3<f64>) -> PinholeModel {
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
        pose: pose(world_to_device),
    }
}

/// An isometry as the calibration's rotation + translation.
pub fn pose(iso: &Isometry3<f64>) -> Pose {
    let r: Matrix3<f64> = *iso.rotation.to_rotation_matrix().matrix();
    Pose {
        rotation: r,
        translation_m: Vector3::from(iso.translation.vector),
    }
}

/// Head `h`'s frame (its camera frame) from the twin's world frame.
pub fn head_from_world(rig: &Rig, h: usize) -> Isometry3<f64> {
    rig.cameras[h].model.world_from_device.inverse()
}

/// The rig calibration of the twin's first `heads` camera/projector pairs:
/// each head in its camera's frame, `head_to_head` = head A's frame -> head B's.
pub fn twin_calibration(rig: &Rig, heads: usize) -> RigCalibration {
    let heads_out: Vec<Head> = (0..heads)
        .map(|h| {
            let cam_from_world = head_from_world(rig, h);
            let proj = &rig.projectors[h].model;
            // Projector pose in the head frame: device <- world <- camera.
            let proj_from_cam = proj.world_from_device.inverse() * cam_from_world.inverse();
            Head {
                name: HEAD_NAMES[h].to_string(),
                camera: model(&rig.cameras[h].model, &Isometry3::identity()),
                projector: model(proj, &proj_from_cam),
                view_errors: Vec::new(),
            }
        })
        .collect();
    let head_to_head = (heads == 2).then(|| pose(&b_from_a(rig)));
    RigCalibration {
        heads: heads_out,
        head_to_head,
    }
}

/// Head A's frame -> head B's frame.
pub fn b_from_a(rig: &Rig) -> Isometry3<f64> {
    head_from_world(rig, 1) * head_from_world(rig, 0).inverse()
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
