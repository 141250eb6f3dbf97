//! `slscan calibrate`: board captures in, calibration JSON out.
//!
//! `--images DIR` reads real captures: every PNG/TIFF (8 or 16 bit, grey or
//! colour) is one board pose. With `--projector WxH`, each view `STEM.png`
//! also needs its absolute phase maps `STEM.phase_x.npy` and
//! `STEM.phase_y.npy`, and the whole head (camera, projector, camera ->
//! projector) is written as a rig file; without it only the camera is
//! calibrated and written as a camera file. `--sim` renders the views with
//! the digital twin instead (`calibration::twin_head`: the twin's single
//! head, 640x480 camera, 1280x800 DMD, its 8x6-corner 20 mm checkerboard,
//! x/y fringe phase maps decoded and unwrapped by slscan) and prints the
//! recovered values next to the twin's true devices.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use hil_sim::twin::scenes::Detail;
use hil_sim::twin::SensorModel;
use serde::Serialize;
use slscan::calibration::board::{Checkerboard, CircleGrid, GrayImage, Target};
use slscan::calibration::bundle::CameraCalibrationOptions;
use slscan::calibration::detect::load_gray;
use slscan::calibration::head::{
    calibrate_camera_stage, calibrate_head, calibrate_head_to_head, BoardCapture, CameraStage,
    HeadCalibration, HeadOptions, ProjectorSpec,
};
use slscan::calibration::rodrigues::rotation_angle_between;
use slscan::calibration::synthetic::BitDepth;
use slscan::calibration::twin_head::{self, TwinHead};
use slscan::calibration::{write_rig, Head, PinholeModel, RigCalibration};
use slscan::io::write_atomically;

/// Options of `slscan calibrate`.
#[derive(clap::Args)]
pub struct Args {
    /// Folder of board captures (PNG/TIFF, 8 or 16 bit), one board pose per file.
    #[arg(long, value_name = "DIR", required_unless_present = "sim")]
    images: Option<PathBuf>,
    /// Render the views with the digital twin instead, and compare with its true devices.
    #[arg(long, conflicts_with = "images")]
    sim: bool,
    /// Output JSON: a rig file (head calibrated) or a camera file (camera only).
    #[arg(long, short, value_name = "FILE")]
    out: PathBuf,
    /// Calibration target in the images (ignored with --sim, which shows a checkerboard).
    #[arg(long, value_enum, default_value_t = TargetKind::Checkerboard)]
    target: TargetKind,
    /// Inner corners (or circles) along the board's x axis (ignored with --sim).
    #[arg(long, default_value_t = 9)]
    cols: usize,
    /// Inner corners (or circles) along the board's y axis (ignored with --sim).
    #[arg(long, default_value_t = 6)]
    rows: usize,
    /// Side of one square, or circle centre spacing, millimetres (ignored with --sim).
    #[arg(long, default_value_t = 25.0)]
    square_mm: f64,
    /// Projector DMD size as WIDTHxHEIGHT; calibrates the projector from phase maps.
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    projector: Option<(u32, u32)>,
    /// Fringe period of the phase maps, projector pixels.
    #[arg(long, default_value_t = 18.0)]
    period_px: f64,
    /// Name of the head in the rig file.
    #[arg(long, default_value = "A")]
    head: String,
    /// Also estimate k3 (needs many well-spread views; default keeps k3 = 0).
    #[arg(long)]
    with_k3: bool,
    /// --sim: number of board poses (at most 15).
    #[arg(long, default_value_t = 12)]
    views: usize,
    /// --sim: sensor read noise, grey levels (0..1), photon shot noise on top; default:
    /// the twin's 12-bit sensor (6 e- of a 10 ke- full well, 0.0006).
    #[arg(long)]
    noise: Option<f64>,
    /// --sim: bit depth of the rendered images (8 or 16).
    #[arg(long, default_value_t = 8, value_parser = parse_bits)]
    bits: u8,
    /// --sim: simulate and calibrate two heads and their head-to-head pose.
    #[arg(long, requires = "sim")]
    two_heads: bool,
    /// --sim: rays per camera pixel and axis of the board renders (each pixel
    /// integrates over its area); 1 renders one aliased ray per pixel.
    #[arg(long, default_value_t = hil_sim::twin::CALIBRATION_PIXEL_SAMPLES,
          value_parser = clap::value_parser!(u32).range(1..=16))]
    pixel_samples: u32,
    /// --sim --two-heads / --scene: name of the second head.
    #[arg(long, default_value = "B")]
    head_b: String,
    /// --sim: calibrate the two heads of this built-in dual-head twin scene (same
    /// devices and head poses as `scan --sim --scene NAME`), e.g. `large-part`.
    #[arg(
        long,
        value_name = "NAME",
        requires = "sim",
        conflicts_with = "two_heads"
    )]
    scene: Option<String>,
    /// --sim --scene: camera image size as WIDTHxHEIGHT (must match the scan's).
    #[arg(long, value_name = "WxH", value_parser = parse_size, default_value = "640x480")]
    camera: (u32, u32),
    /// --sim: also write the rendered board images (PNG) and phase maps (.npy) here
    /// (one folder per head with --two-heads).
    #[arg(long, value_name = "DIR")]
    save_images: Option<PathBuf>,
}

/// Which calibration target the images show.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum TargetKind {
    /// A checkerboard; `--cols x --rows` inner corners.
    Checkerboard,
    /// A symmetric grid of dark circles on white; `--cols x --rows` circles.
    Circles,
}

fn parse_bits(s: &str) -> Result<u8, String> {
    match s.trim() {
        "8" => Ok(8),
        "16" => Ok(16),
        other => Err(format!("{other:?}: bit depth is 8 or 16")),
    }
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("{s:?} is not WIDTHxHEIGHT"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|n| *n > 0)
            .ok_or_else(|| format!("{v:?} in {s:?} is not a positive integer"))
    };
    Ok((parse(w)?, parse(h)?))
}

/// Runs `slscan calibrate`.
pub fn run(args: Args) -> anyhow::Result<()> {
    // Make the output's folder first: finding it missing after minutes of rendering and
    // solving would lose the work.
    if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    let mut options = HeadOptions::default();
    options.camera = CameraCalibrationOptions {
        fix_k3: !args.with_k3,
        ..options.camera
    };
    options.projector.fix_k3 = !args.with_k3;
    if args.sim {
        run_sim(&args, &options)
    } else {
        let dir = args
            .images
            .as_deref()
            .context("--images DIR or --sim is required")?;
        run_images(&args, dir, &options)
    }
}

fn run_sim(args: &Args, options: &HeadOptions) -> anyhow::Result<()> {
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
            names: [&args.head, &args.head_b],
            pixel_samples: args.pixel_samples,
            out: &args.out,
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
    let mut heads = vec![(args.head.clone(), sim)];
    if args.two_heads {
        heads.push((args.head_b.clone(), second));
    }
    let mut calibrated = Vec::new();
    let mut first_views = Vec::new();
    for (name, sim) in &heads {
        let captures = sim
            .render(&sensor, 1, true)
            .with_context(|| format!("rendering head {name} with the digital twin"))?;
        if let Some(dir) = &args.save_images {
            let dir = if args.two_heads {
                dir.join(name)
            } else {
                dir.clone()
            };
            save_captures(&dir, &captures, bit_depth)?;
        }
        let cal = calibrate_head(name, &target, &captures, &sim.projector_spec(), options)
            .with_context(|| format!("calibrating simulated head {name}"))?;
        println!("== head {name}");
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
            println!(
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
        head_to_head,
    };
    write_rig(&args.out, &rig).with_context(|| format!("writing {}", args.out.display()))?;
    println!("wrote {}", args.out.display());
    Ok(())
}

fn target_of(args: &Args) -> anyhow::Result<Target> {
    if args.cols < 2 || args.rows < 2 {
        bail!(
            "--cols {} --rows {}: a board needs >= 2x2 inner corners",
            args.cols,
            args.rows
        );
    }
    if !(args.square_mm.is_finite() && args.square_mm > 0.0) {
        bail!("--square-mm {} is not a positive length", args.square_mm);
    }
    Ok(match args.target {
        TargetKind::Checkerboard => Target::Checkerboard(Checkerboard {
            cols: args.cols,
            rows: args.rows,
            square_m: args.square_mm * 1e-3,
        }),
        // The detector does not use the diameter; it only matters for renders.
        TargetKind::Circles => Target::CircleGrid(CircleGrid {
            cols: args.cols,
            rows: args.rows,
            spacing_m: args.square_mm * 1e-3,
            diameter_m: 0.4 * args.square_mm * 1e-3,
        }),
    })
}

/// Board images in `dir`, sorted by name (phase maps and hidden files excluded).
fn board_images(dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
        let path = entry?.path();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let hidden = path
            .file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| n.starts_with('.'));
        if !hidden && matches!(ext.as_deref(), Some("png" | "tif" | "tiff")) {
            files.push(path);
        }
    }
    files.sort();
    if files.is_empty() {
        bail!("{} holds no PNG or TIFF images", dir.display());
    }
    Ok(files)
}

fn run_images(args: &Args, dir: &Path, options: &HeadOptions) -> anyhow::Result<()> {
    let board = target_of(args)?;
    let mut captures = Vec::new();
    for path in board_images(dir)? {
        let image = load_gray(&path)?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let phase = match args.projector {
            Some(_) => Some(load_phase_pair(dir, &name)?),
            None => None,
        };
        captures.push(BoardCapture { name, image, phase });
    }
    tracing::info!(views = captures.len(), "loaded board captures");
    match args.projector {
        Some((width_px, height_px)) => {
            let spec = ProjectorSpec {
                width_px,
                height_px,
                period_px: args.period_px,
            };
            let cal = calibrate_head(&args.head, &board, &captures, &spec, options)?;
            print_head(&cal);
            write_rig(&args.out, &RigCalibration::single(cal.head))
                .with_context(|| format!("writing {}", args.out.display()))?;
        }
        None => {
            let stage = calibrate_camera_stage(&board, &captures, options)?;
            print_camera_stage(&stage);
            write_camera_file(&args.out, &stage)?;
        }
    }
    println!("wrote {}", args.out.display());
    Ok(())
}

/// Phase maps `STEM.phase_x.npy`, `STEM.phase_y.npy` of view `stem`.
fn load_phase_pair(dir: &Path, stem: &str) -> anyhow::Result<(GrayImage, GrayImage)> {
    let load = |axis: &str| -> anyhow::Result<GrayImage> {
        let path = dir.join(format!("{stem}.phase_{axis}.npy"));
        slscan::calibration::phase_file::read_phase_map(&path)
            .with_context(|| format!("phase map for view {stem}"))
    };
    Ok((load("x")?, load("y")?))
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
    println!("wrote {} views to {}", captures.len(), dir.display());
    Ok(())
}

fn print_device(what: &str, d: &PinholeModel) {
    let (k, dist) = (d.intrinsics, d.distortion);
    println!(
        "{what} {}x{}: fx {:.3} fy {:.3} cx {:.3} cy {:.3} | k1 {:.5} k2 {:.5} p1 {:.6} p2 {:.6} k3 {:.5}",
        d.width_px, d.height_px, k.fx, k.fy, k.cx, k.cy, dist.k1, dist.k2, dist.p1, dist.p2, dist.k3
    );
}

fn print_camera_stage(stage: &CameraStage) {
    print_device("camera", &stage.camera);
    println!("view            camera_rms_px");
    for (name, rms) in stage.names.iter().zip(&stage.calibration.view_rms_px) {
        println!("{name:<15} {rms:.4}");
    }
    for (name, err) in &stage.skipped {
        println!("{name:<15} skipped: {err}");
    }
    println!("camera reprojection RMS {:.4} px", stage.calibration.rms_px);
}

pub(super) fn print_head(cal: &HeadCalibration) {
    print_device("camera", &cal.head.camera);
    print_device("projector", &cal.head.projector);
    let t = cal.head.projector.pose.translation_m * 1e3;
    println!(
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
    println!("view            camera_rms_px  projector_rms_px");
    for e in &cal.head.view_errors {
        println!(
            "{:<15} {:<14.4} {:.4}",
            e.view,
            e.camera_rms_px,
            e.projector_rms_px.unwrap_or(f64::NAN)
        );
    }
    for (name, err) in &cal.camera.skipped {
        println!("{name:<15} skipped: {err}");
    }
    println!(
        "reprojection RMS: camera {:.4} px, projector {:.4} px (joint {:.4} px)",
        cal.head.camera_rms_px().unwrap_or(f64::NAN),
        cal.head.projector_rms_px().unwrap_or(f64::NAN),
        cal.pair.rms_px
    );
}

pub(super) fn print_truth_comparison(truth: &Head, cal: &HeadCalibration) {
    let pairs = [
        ("camera", &cal.head.camera, &truth.camera),
        ("projector", &cal.head.projector, &truth.projector),
    ];
    println!("recovered - true (digital twin):");
    for (what, got, truth) in pairs {
        let (g, t) = (got.intrinsics, truth.intrinsics);
        println!(
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
    println!(
        "  camera->projector: rotation {:.4} deg, translation {:.3} mm",
        angle.to_degrees(),
        dt * 1e3
    );
}

/// The camera-only calibration file: the rig file's device fields (OpenCV
/// names), without a projector.
#[derive(Serialize)]
struct CameraFile<'a> {
    format: &'static str,
    version: u32,
    width_px: u32,
    height_px: u32,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    k1: f64,
    k2: f64,
    p1: f64,
    p2: f64,
    k3: f64,
    rms_px: f64,
    view_errors: Vec<CameraViewError<'a>>,
}

#[derive(Serialize)]
struct CameraViewError<'a> {
    view: &'a str,
    camera_rms_px: f64,
}

fn write_camera_file(path: &Path, stage: &CameraStage) -> anyhow::Result<()> {
    let (k, d) = (stage.camera.intrinsics, stage.camera.distortion);
    let doc = CameraFile {
        format: "slscan-camera",
        version: 1,
        width_px: stage.camera.width_px,
        height_px: stage.camera.height_px,
        fx: k.fx,
        fy: k.fy,
        cx: k.cx,
        cy: k.cy,
        k1: d.k1,
        k2: d.k2,
        p1: d.p1,
        p2: d.p2,
        k3: d.k3,
        rms_px: stage.calibration.rms_px,
        view_errors: stage
            .names
            .iter()
            .zip(&stage.calibration.view_rms_px)
            .map(|(view, rms)| CameraViewError {
                view,
                camera_rms_px: *rms,
            })
            .collect(),
    };
    let text = serde_json::to_string_pretty(&doc)?;
    write_atomically(path, |w| w.write_all(text.as_bytes()))
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
