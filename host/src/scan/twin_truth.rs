//! The calibration a simulated scan reconstructs with: the digital twin's
//! true device models, in each head's camera frame. This is the twin's
//! truth, NOT an estimated calibration; reports say so.

use hil_sim::twin::Rig;
use nalgebra::Isometry3;

use crate::calibration::from_twin::{head_from_twin, pose_from_twin};
use crate::calibration::RigCalibration;

/// Head names in plan order.
pub const HEAD_NAMES: [&str; 2] = ["A", "B"];

/// Head `h`'s frame (its camera frame) from the twin's world frame.
pub fn head_from_world(rig: &Rig, h: usize) -> Isometry3<f64> {
    rig.cameras[h].model.world_from_device.inverse()
}

/// The rig calibration of the twin's first `heads` camera/projector pairs:
/// each head in its camera's frame, `head_to_head` = head A's frame -> head B's.
pub fn twin_calibration(rig: &Rig, heads: usize) -> RigCalibration {
    let heads_out = (0..heads)
        .map(|h| {
            head_from_twin(rig, h, h, HEAD_NAMES[h])
                .unwrap_or_else(|| panic!("the twin rig has no camera/projector pair {h}"))
        })
        .collect();
    // pose_from_twin inverts a twin (device -> world) pose, so hand it B -> A
    // to get the A -> B pose the calibration stores.
    let head_to_head = (heads == 2).then(|| pose_from_twin(&b_from_a(rig).inverse()));
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
