//! Writes a camera-size capture for timing `slscan reconstruct`: 12 formula-rendered
//! 16-bit fringe frames (3 periods x 4 steps, 3072x2048, the pipeline bench's scene: a
//! plane with the two calibration spheres) and the matching rig file.
//!
//! ```sh
//! cargo run --release -p slscan --example synth_capture -- out/capture6mp
//! cargo run --release -p slscan -- reconstruct --images out/capture6mp/images \
//!     --rig out/capture6mp/rig.json --out out/capture6mp/cloud.ply
//! ```

use std::path::PathBuf;

use slscan::calibration::{write_rig, Head, PinholeModel, RigCalibration};
use slscan::io::images::save_gray_png;
use slscan::synth::{self, Lighting};

fn main() -> anyhow::Result<()> {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "out/capture6mp".into()),
    );
    let images = dir.join("images");
    std::fs::create_dir_all(&images)?;
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
    // `reconstruct`'s default periods.
    let frames = synth::render_fringe_set(&truth, &[100.0, 110.0, 120.0], 4, true, &light, 1);
    for (i, frame) in frames.iter().enumerate() {
        save_gray_png(&images.join(format!("frame_{i:02}.png")), frame, true)?;
    }
    let head = Head {
        name: "A".into(),
        camera,
        projector,
        view_errors: vec![],
        port: None,
    };
    write_rig(&dir.join("rig.json"), &RigCalibration::single(head))?;
    println!(
        "wrote {} frames and rig.json into {}",
        frames.len(),
        dir.display()
    );
    Ok(())
}
