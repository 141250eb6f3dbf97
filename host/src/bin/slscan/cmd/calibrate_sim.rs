//! `slscan calibrate --sim`: board views rendered by the digital twin
//! (`sim::calibration::twin_head`, the twin's single head, or with
//! `--two-heads` a second one; `--scene NAME` hands over to
//! [`super::calibrate_scene`]), calibrated by the product's own algorithms,
//! and printed beside the twin's true devices.

use std::io::Cursor;
use std::path::Path;

use anyhow::{bail, Context};
use slscan::calibration::board::Target;
use slscan::calibration::head::{
    calibrate_head, calibrate_head_to_head, BoardCapture, HeadOptions,
};
use slscan::calibration::rodrigues::rotation_angle_between;
use slscan::calibration::{write_rig, RigCalibration};
use slscan::io::write_atomically;
use slscan::sim::calibration::twin_head::{self, TwinHead};
use slscan::sim::twin::{Detail, SensorModel};
use slscan::synth::targets::BitDepth;

use super::calibrate_sim_options::SimOptions;
use super::calibration_print::{print_head, print_truth_comparison};
use super::transcript::{say, with_spinner};

/// Renders with `args`, calibrates head `head` (and with `--two-heads` or
/// `--scene` the second, `args.head_b`) and writes the rig file `out`.
pub fn run(args: &SimOptions, head: &str, out: &Path, options: &HeadOptions) -> anyhow::Result<()> {
    if args.views < 3 {
        bail!(
            "--views {} is too few: a calibration with distortion needs >= 3",
            args.views
        );
    }
    let base = SensorModel::mono12();
    let read_noise_e = match args.noise {
        Some(n) if n.is_finite() && n >= 0.0 => n * base.full_well_e / base.gain,
        Some(n) => bail!("--noise {n} is not a non-negative grey level"),
        None => base.read_noise_e,
    };
    let sensor = SensorModel {
        read_noise_e,
        bits: args.bits,
        ..base
    };
    if let Some(scene) = &args.scene {
        let scene_args = super::calibrate_scene::SceneArgs {
            scene,
            camera_px: args.camera,
            views: args.views,
            names: [head, &args.head_b],
            pixel_samples: args.pixel_samples,
            out,
        };
        return super::calibrate_scene::run(&scene_args, &sensor, options);
    }
    let mut sim = TwinHead::standard(args.views, &Detail::default());
    sim.pixel_samples = args.pixel_samples;
    let bit_depth = if args.bits == 16 {
        BitDepth::Sixteen
    } else {
        BitDepth::Eight
    };
    let target = Target::Checkerboard(twin_head::board());
    let (second, true_head_to_head) = sim.second_head();
    let mut heads = vec![(head.to_string(), sim)];
    if args.two_heads {
        heads.push((args.head_b.clone(), second));
    }
    let mut calibrated = Vec::new();
    let mut first_views = Vec::new();
    for (name, sim) in &heads {
        let what = format!(
            "rendering head {name}'s {} board views with the digital twin",
            args.views
        );
        let captures = with_spinner(&what, || sim.render(&sensor, 1, true))
            .with_context(|| format!("rendering head {name} with the digital twin"))?;
        if let Some(dir) = &args.save_images {
            let dir = if args.two_heads {
                dir.join(name)
            } else {
                dir.clone()
            };
            save_captures(&dir, &captures, bit_depth)?;
        }
        let cal = with_spinner(&format!("calibrating head {name}"), || {
            calibrate_head(name, &target, &captures, &sim.projector_spec(), options)
        })
        .with_context(|| format!("calibrating simulated head {name}"))?;
        say!("== head {name}");
        print_head(&cal);
        print_truth_comparison(&sim.truth, &cal);
        first_views.extend(captures.into_iter().next().map(|c| c.image));
        calibrated.push(cal.head);
    }
    let head_to_head = match (args.two_heads, &calibrated[..], &first_views[..]) {
        (true, [a, b], [img_a, img_b]) => {
            // One board pose both heads saw: the first view.
            let pair = calibrate_head_to_head(
                &a.camera,
                &b.camera,
                &target,
                &[(img_a.clone(), img_b.clone())],
                options,
            )
            .context("head-to-head extrinsics")?;
            let angle = rotation_angle_between(&pair.a_to_b.rotation, &true_head_to_head.rotation);
            let dt = (pair.a_to_b.translation_m - true_head_to_head.translation_m).norm();
            say!(
                "head-to-head from one shared view: rms {:.4} px; recovered - true: rotation {:.4} deg, translation {:.3} mm",
                pair.rms_px,
                angle.to_degrees(),
                dt * 1e3
            );
            Some(pair.a_to_b)
        }
        _ => None,
    };
    let rig = RigCalibration {
        heads: calibrated,
        head_poses: head_to_head.into_iter().collect(),
        stereo_heads: vec![],
    };
    write_rig(out, &rig).with_context(|| format!("writing {}", out.display()))?;
    say!("wrote {}", out.display());
    Ok(())
}

fn save_captures(dir: &Path, captures: &[BoardCapture], depth: BitDepth) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for c in captures {
        let path = dir.join(format!("{}.png", c.name));
        let dynamic = image::DynamicImage::ImageLuma16(image::ImageBuffer::from_fn(
            c.image.width(),
            c.image.height(),
            |x, y| {
                image::Luma([(c.image.get_pixel(x, y)[0].clamp(0.0, 1.0) * 65535.0).round() as u16])
            },
        ));
        let dynamic = match depth {
            BitDepth::Eight => image::DynamicImage::ImageLuma8(dynamic.to_luma8()),
            BitDepth::Sixteen => dynamic,
        };
        let mut bytes = Vec::new();
        dynamic
            .write_to(&mut Cursor::new(&mut bytes), image::ImageFormat::Png)
            .with_context(|| format!("encoding {}", path.display()))?;
        write_atomically(&path, |w| w.write_all(&bytes))
            .with_context(|| format!("writing {}", path.display()))?;
        if let Some((px, py)) = &c.phase {
            for (axis, map) in [("x", px), ("y", py)] {
                let path = dir.join(format!("{}.phase_{axis}.npy", c.name));
                slscan::calibration::phase_file::write_phase_map(&path, map)
                    .with_context(|| format!("writing {}", path.display()))?;
            }
        }
    }
    say!("wrote {} views to {}", captures.len(), dir.display());
    Ok(())
}
