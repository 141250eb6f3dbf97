//! The small formula-rendered capture the CLI tests reconstruct: two spheres seen by a
//! 64x48 camera and a 228x285 projector 0.15 m apart at 0.5 m, 12 frames (3 periods
//! x 4 steps) saved as 16-bit PNGs, and the true rig written as `rig.json`.

use std::path::{Path, PathBuf};

use slscan::calibration::{write_rig, Head, PinholeModel, RigCalibration};
use slscan::io::images::save_gray_png;
use slscan::synth::{self, Lighting};

/// Writes `dir/images/frame_NN.png` and `dir/rig.json` for a camera with `camera`'s
/// intrinsics and lens; returns the image folder.
pub fn capture_with(dir: &Path, camera: PinholeModel) -> PathBuf {
    let (camera, projector) =
        synth::stereo_rig(camera, PinholeModel::ideal(228, 285, 450.0), 0.15, 0.5);
    let truth = synth::trace(&synth::two_spheres(0.5, 0.6), &camera, &projector);
    let light = Lighting {
        ambient: 0.1,
        gain: 0.7,
        noise_sigma: 0.003,
    };
    let frames = synth::render_fringe_set(&truth, &[9.0, 10.0, 11.0], 4, true, &light, 5);
    let images = dir.join("images");
    std::fs::create_dir_all(&images).unwrap();
    for (i, f) in frames.iter().enumerate() {
        save_gray_png(&images.join(format!("frame_{i:02}.png")), f, true).unwrap();
    }
    let rig = RigCalibration::single(Head {
        name: "A".into(),
        camera,
        projector,
        view_errors: vec![],
        port: None,
    });
    write_rig(&dir.join("rig.json"), &rig).unwrap();
    images
}
