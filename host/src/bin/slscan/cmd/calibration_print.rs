//! What `slscan calibrate` prints: devices, per-view errors, and (in
//! simulation) recovered against true values.

use super::transcript::say;
use slscan::calibration::head::{CameraStage, HeadCalibration};
use slscan::calibration::rodrigues::rotation_angle_between;
use slscan::calibration::PinholeModel;

pub(super) fn print_device(what: &str, d: &PinholeModel) {
    let (k, dist) = (d.intrinsics, d.distortion);
    say!(
        "{what} {}x{}: fx {:.3} fy {:.3} cx {:.3} cy {:.3} | k1 {:.5} k2 {:.5} p1 {:.6} p2 {:.6} k3 {:.5}",
        d.width_px, d.height_px, k.fx, k.fy, k.cx, k.cy, dist.k1, dist.k2, dist.p1, dist.p2, dist.k3
    );
}

pub(super) fn print_camera_stage(stage: &CameraStage) {
    print_device("camera", &stage.camera);
    say!("view            camera_rms_px");
    for (name, rms) in stage.names.iter().zip(&stage.calibration.view_rms_px) {
        say!("{name:<15} {rms:.4}");
    }
    for (name, err) in &stage.skipped {
        say!("{name:<15} skipped: {err}");
    }
    say!("camera reprojection RMS {:.4} px", stage.calibration.rms_px);
}

pub(super) fn print_head(cal: &HeadCalibration) {
    print_device("camera", &cal.head.camera);
    print_device("projector", &cal.head.projector);
    let t = cal.head.projector.pose.translation_m * 1e3;
    say!(
        "camera->projector: rotation {:.3} deg, translation ({:.2}, {:.2}, {:.2}) mm",
        rotation_angle_between(
            &nalgebra::Matrix3::identity(),
            &cal.head.projector.pose.rotation
        )
        .to_degrees(),
        t.x,
        t.y,
        t.z
    );
    say!("view            camera_rms_px  projector_rms_px");
    for e in &cal.head.view_errors {
        say!(
            "{:<15} {:<14.4} {:.4}",
            e.view,
            e.camera_rms_px,
            e.projector_rms_px.unwrap_or(f64::NAN)
        );
    }
    for (name, err) in &cal.camera.skipped {
        say!("{name:<15} skipped: {err}");
    }
    say!(
        "reprojection RMS: camera {:.4} px, projector {:.4} px (joint {:.4} px)",
        cal.head.camera_rms_px().unwrap_or(f64::NAN),
        cal.head.projector_rms_px().unwrap_or(f64::NAN),
        cal.pair.rms_px
    );
}

/// Recovered against the digital twin's true head (simulation only).
#[cfg(feature = "sim")]
pub(super) fn print_truth_comparison(truth: &slscan::calibration::Head, cal: &HeadCalibration) {
    let pairs = [
        ("camera", &cal.head.camera, &truth.camera),
        ("projector", &cal.head.projector, &truth.projector),
    ];
    say!("recovered - true (digital twin):");
    for (what, got, truth) in pairs {
        let (g, t) = (got.intrinsics, truth.intrinsics);
        say!(
            "  {what}: dfx {:+.3} dfy {:+.3} dcx {:+.3} dcy {:+.3} px | dk1 {:+.5} dk2 {:+.5} dp1 {:+.6} dp2 {:+.6}",
            g.fx - t.fx,
            g.fy - t.fy,
            g.cx - t.cx,
            g.cy - t.cy,
            got.distortion.k1 - truth.distortion.k1,
            got.distortion.k2 - truth.distortion.k2,
            got.distortion.p1 - truth.distortion.p1,
            got.distortion.p2 - truth.distortion.p2,
        );
    }
    let angle = rotation_angle_between(
        &cal.head.projector.pose.rotation,
        &truth.projector.pose.rotation,
    );
    let dt = (cal.head.projector.pose.translation_m - truth.projector.pose.translation_m).norm();
    say!(
        "  camera->projector: rotation {:.4} deg, translation {:.3} mm",
        angle.to_degrees(),
        dt * 1e3
    );
}
