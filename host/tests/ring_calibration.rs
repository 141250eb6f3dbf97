//! Issue 21: calibrating a ring of four heads from rendered checkerboard views, as
//! `slscan calibrate --sim --scene ring-4` does: every head on its own board views,
//! each pair of neighbouring heads (A-B, B-C, C-D, D-A) on boards held near the part
//! facing both cameras, and each head's pose from head A chained along the ring, its
//! loop error spread over the pairs; compared with the twin's true devices. Small
//! renders (320x240 camera, 640x400 DMD, eight views per head) keep it under a minute
//! in release. Run with
//! `cargo test -p slscan --release --test ring_calibration -- --nocapture`.

use std::time::Instant;

use hil_sim::twin::scenes::Detail;
use hil_sim::twin::SensorModel;
use nalgebra::Matrix3;
use slscan::calibration::head::HeadOptions;
use slscan::calibration::rodrigues::rotation_angle_between;
use slscan::calibration::truth_error::rig_error;
use slscan::sim::calibration::twin_scene::{calibrate_scene, scene_heads};

const DETAIL: Detail = Detail {
    camera: (320, 240),
    projector: (640, 400),
};
/// Board views per head: rendering them (a white field and 24 fringe frames each)
/// is most of the test's time.
const VIEWS: usize = 8;

#[test]
fn ring_4_heads_and_their_poses_from_head_a_are_recovered() {
    let start = Instant::now();
    let heads = scene_heads("ring-4", &DETAIL, VIEWS, ["A", "B"]).expect("ring scene");
    assert_eq!(heads.names, ["A", "B", "C", "D"]);
    let cal = calibrate_scene(&heads, &SensorModel::mono12(), 1, &HeadOptions::default())
        .expect("calibrates");
    cal.rig.validate().expect("a valid rig");
    assert_eq!(cal.rig.heads.len(), 4);
    assert_eq!(cal.rig.head_poses.len(), 3);
    let errors = rig_error(&cal.rig, &heads.truth);
    for (shared, pair) in heads.pairs.iter().zip(&cal.pairs) {
        let [a, b] = shared.heads;
        println!(
            "pair {}-{}: {} of {} shared views, rms {:.3} px",
            heads.names[a],
            heads.names[b],
            pair.view_rms_a_px.len(),
            shared.world_from_board.len(),
            pair.rms_px
        );
    }
    for (e, head) in errors.heads.iter().zip(&cal.rig.heads) {
        println!(
            "head {}: camera rms {:.3} px, dfx {:+.2} px, camera->projector {:.4} deg / {:.3} mm",
            e.name,
            head.camera_rms_px().unwrap_or(f64::NAN),
            e.camera.dfx_px,
            e.camera_to_projector.rotation_deg,
            e.camera_to_projector.translation_mm
        );
    }
    for (h, e) in errors.head_poses.iter().enumerate() {
        println!(
            "pose A -> {}: {:.4} deg / {:.3} mm",
            heads.names[h + 1],
            e.rotation_deg,
            e.translation_mm
        );
    }
    let loop_error = cal.loop_error.expect("a ring closes");
    println!(
        "loop error before spreading: {:.4} deg / {:.3} mm",
        rotation_angle_between(&loop_error.rotation, &Matrix3::identity()).to_degrees(),
        loop_error.translation_m.norm() * 1e3
    );
    println!("took {:.1} s", start.elapsed().as_secs_f64());
    for (h, e) in errors.head_poses.iter().enumerate() {
        assert!(
            e.rotation_deg < 0.3 && e.translation_mm < 5.0,
            "pose A -> {}: {e:?}",
            heads.names[h + 1]
        );
    }
}
