//! `slscan calibrate --sim --scene NAME`: calibrates every head of a built-in
//! twin scene of two to four heads (`large-part`, `ring-3`, `ring-4`, ...) and
//! each head's pose from head A from rendered checkerboard views
//! (`sim::calibration::twin_scene`), prints recovered against true values and
//! writes the rig file `scan --sim --calibration FILE` reads.

use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use nalgebra::Matrix3;
use slscan::calibration::head::HeadOptions;
use slscan::calibration::rodrigues::rotation_angle_between;
use slscan::calibration::truth_error::{rig_error, PoseError};
use slscan::calibration::{write_rig, PinholeModel};
use slscan::sim::calibration::twin_scene::{calibrate_scene, scene_heads};
use slscan::sim::twin::{Detail, SensorModel};

use super::calibration_print::{print_head, print_truth_comparison};
use super::transcript::{say, with_spinner};

/// What to calibrate and where to write it.
pub struct SceneArgs<'a> {
    /// Built-in scene name.
    pub scene: &'a str,
    /// Camera image size, pixels.
    pub camera_px: (u32, u32),
    /// Board views per head.
    pub views: usize,
    /// Names of the first heads (the rest are named by their letter: C, D).
    pub names: [&'a str; 2],
    /// Rays per camera pixel and axis of the board renders.
    pub pixel_samples: u32,
    /// Rig file to write.
    pub out: &'a Path,
}

/// Runs the scene calibration with `sensor` and writes `args.out`.
pub fn run(args: &SceneArgs, sensor: &SensorModel, options: &HeadOptions) -> anyhow::Result<()> {
    let start = Instant::now();
    let scene = args.scene;
    let detail = Detail {
        camera: args.camera_px,
        ..Detail::default()
    };
    let mut heads = scene_heads(scene, &detail, args.views, args.names)
        .with_context(|| format!("setting up the heads of scene {scene}"))?;
    for head in &mut heads.heads {
        head.pixel_samples = args.pixel_samples;
    }
    let pair_name = |p: &[usize; 2]| format!("{}-{}", heads.names[p[0]], heads.names[p[1]]);
    let shared: Vec<String> = heads
        .pairs
        .iter()
        .map(|p| format!("{} {}", pair_name(&p.heads), p.world_from_board.len()))
        .collect();
    say!(
        "scene {scene}: {} heads, {} board views per head, shared views per pair: {}, camera {}x{}",
        heads.heads.len(),
        heads.heads[0].world_from_board.len(),
        shared.join(", "),
        detail.camera.0,
        detail.camera.1
    );
    let what = format!(
        "rendering and calibrating the {} heads of scene {scene}",
        heads.heads.len()
    );
    let cal = with_spinner(&what, || calibrate_scene(&heads, sensor, 1, options))
        .with_context(|| format!("calibrating the heads of scene {scene}"))?;
    for (h, head) in cal.heads.iter().enumerate() {
        say!("== head {}", head.head.name);
        print_head(head);
        print_truth_comparison(&heads.heads[h].truth, head);
    }
    for (shared, pair) in heads.pairs.iter().zip(&cal.pairs) {
        say!(
            "head-to-head {} from {} of {} shared views: rms {:.4} px",
            pair_name(&shared.heads),
            pair.view_rms_a_px.len(),
            shared.world_from_board.len(),
            pair.rms_px
        );
    }
    if let Some(e) = &cal.loop_error {
        say!(
            "ring closed by {}: loop error {:.4} deg / {:.3} mm, spread over the {} pairs",
            pair_name(&heads.pairs[heads.pairs.len() - 1].heads),
            rotation_angle_between(&e.rotation, &Matrix3::identity()).to_degrees(),
            e.translation_m.norm() * 1e3,
            heads.pairs.len()
        );
    }
    say!("recovered vs true (digital twin):");
    for (h, head) in cal.rig.heads.iter().enumerate() {
        let truth = &heads.truth.heads[h];
        print_device_vs_truth(&head.name, "camera", &head.camera, &truth.camera);
        print_device_vs_truth(&head.name, "projector", &head.projector, &truth.projector);
    }
    let errors = rig_error(&cal.rig, &heads.truth);
    for e in &errors.heads {
        print_pose_error(
            &format!("{} camera->projector", e.name),
            &e.camera_to_projector,
        );
    }
    let first = &heads.names[0];
    for (h, e) in errors.head_poses.iter().enumerate() {
        let name = &heads.names[h + 1];
        print_pose_error(&format!("head pose (camera {first} -> camera {name})"), e);
    }
    write_rig(args.out, &cal.rig).with_context(|| format!("writing {}", args.out.display()))?;
    say!(
        "wrote {} in {:.1} s",
        args.out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

fn print_device_vs_truth(head: &str, what: &str, got: &PinholeModel, truth: &PinholeModel) {
    let (g, t) = (got.intrinsics, truth.intrinsics);
    say!(
        "  {head} {what:<9} fx {:.2} (true {:.2})  fy {:.2} ({:.2})  cx {:.2} ({:.2})  cy {:.2} ({:.2})",
        g.fx, t.fx, g.fy, t.fy, g.cx, t.cx, g.cy, t.cy
    );
}

fn print_pose_error(what: &str, e: &PoseError) {
    say!(
        "  {what}: rotation error {:.4} deg, translation error {:.3} mm",
        e.rotation_deg,
        e.translation_mm
    );
}
