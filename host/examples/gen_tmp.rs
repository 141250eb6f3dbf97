use slscan::calibration::{write_rig, Head, PinholeModel, RigCalibration};
use slscan::io::images::save_gray_png;
use slscan::synth::{self, Lighting};
fn main() {
    let dir = std::path::Path::new("/tmp/big6mp");
    std::fs::create_dir_all(dir.join("images")).unwrap();
    let (camera, projector) = synth::stereo_rig(
        PinholeModel::ideal(3072, 2048, 4000.0),
        PinholeModel::ideal(1920, 1080, 2200.0),
        0.15,
        0.5,
    );
    let truth = synth::trace(&synth::two_spheres(0.5, 0.56), &camera, &projector);
    let light = Lighting {
        ambient: 0.1,
        gain: 0.7,
        noise_sigma: 0.01,
    };
    let frames = synth::render_fringe_set(&truth, &[100.0, 110.0, 120.0], 4, true, &light, 1);
    for (i, f) in frames.iter().enumerate() {
        save_gray_png(&dir.join(format!("images/frame_{i:02}.png")), f, true).unwrap();
    }
    write_rig(
        &dir.join("rig.json"),
        &RigCalibration::single(Head {
            name: "A".into(),
            camera,
            projector,
            view_errors: vec![],
        }),
    )
    .unwrap();
}
