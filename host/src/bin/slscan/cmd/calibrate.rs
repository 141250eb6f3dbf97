//! `slscan calibrate`: board captures in, calibration JSON out.
//!
//! `--images DIR` reads real captures: every PNG/TIFF (8 or 16 bit, grey or
//! colour) is one board pose. With `--projector WxH`, each view `STEM.png`
//! also needs its absolute phase maps `STEM.phase_x.npy` and
//! `STEM.phase_y.npy`, and the whole head (camera, projector, camera ->
//! projector) is written as a rig file; without it only the camera is
//! calibrated and written as a camera file. `--sim` renders the views with
//! the digital twin instead (`calibrate_sim`, `sim::calibration::twin_head`: the twin's single
//! head, 640x480 camera, 1280x800 DMD, its 8x6-corner 20 mm checkerboard,
//! x/y fringe phase maps decoded and unwrapped by slscan) and prints the
//! recovered values next to the twin's true devices.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use serde::Serialize;
use slscan::calibration::board::{Checkerboard, CircleGrid, GrayImage, Target};
use slscan::calibration::bundle::CameraCalibrationOptions;
use slscan::calibration::detect::load_gray;
use slscan::calibration::head::{
    calibrate_camera_stage, calibrate_head, BoardCapture, CameraStage, HeadOptions, ProjectorSpec,
};
use slscan::calibration::{write_rig, RigCalibration};
use slscan::io::outputs::OutputSet;
use slscan::io::report_html::{render, write_html, Page, Table};
use slscan::io::write_atomically;

use super::calibrate_sim_options::SimOptions;
use super::calibration_print::{print_camera_stage, print_head};
use super::parse::parse_size;
use super::transcript::{say, take, with_spinner};

/// Options of `slscan calibrate`.
#[derive(clap::Args)]
pub struct Args {
    /// Folder of board captures (PNG/TIFF, 8 or 16 bit), one board pose per file.
    #[arg(long, value_name = "DIR", required_unless_present = "sim")]
    pub(super) images: Option<PathBuf>,
    /// Render the views with the digital twin instead, and compare with its true devices.
    #[arg(long, conflicts_with = "images")]
    pub(super) sim: bool,
    /// Output JSON: a rig file (head calibrated) or a camera file (camera only).
    #[arg(long, short, value_name = "FILE")]
    pub(super) out: PathBuf,
    /// Calibration target in the images (ignored with --sim, which shows a checkerboard).
    #[arg(long, value_enum, default_value_t = TargetKind::Checkerboard)]
    target: TargetKind,
    /// Inner corners (or circles) along the board's x axis (ignored with --sim).
    #[arg(long, default_value_t = 9)]
    pub(super) cols: usize,
    /// Inner corners (or circles) along the board's y axis (ignored with --sim).
    #[arg(long, default_value_t = 6)]
    pub(super) rows: usize,
    /// Side of one square, or circle centre spacing, millimetres (ignored with --sim).
    #[arg(long, default_value_t = 25.0)]
    pub(super) square_mm: f64,
    /// Projector DMD size as WIDTHxHEIGHT; calibrates the projector from phase maps.
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    pub(super) projector: Option<(u32, u32)>,
    /// Fringe period of the phase maps, projector pixels.
    #[arg(long, default_value_t = 18.0)]
    pub(super) period_px: f64,
    /// Name of the head in the rig file.
    #[arg(long, default_value = "A")]
    pub(super) head: String,
    /// Also estimate k3 (needs many well-spread views; default keeps k3 = 0).
    #[arg(long)]
    pub(super) with_k3: bool,
    #[command(flatten)]
    pub(super) sim_options: SimOptions,
}

/// Which calibration target the images show.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum TargetKind {
    /// A checkerboard; `--cols x --rows` inner corners.
    Checkerboard,
    /// A symmetric grid of dark circles on white; `--cols x --rows` circles.
    Circles,
}

/// Runs `slscan calibrate`.
pub fn run(args: Args) -> anyhow::Result<()> {
    #[cfg(not(feature = "sim"))]
    if args.sim {
        // Before anything is made on disk.
        return Err(super::no_simulator("calibrate --sim"));
    }
    // Make the output's folder first: finding it missing after minutes of rendering and
    // solving would lose the work.
    if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    // An earlier run's file must not pass for this run's if it fails.
    let outputs = OutputSet::new([args.out.clone(), page_path(&args.out)]);
    outputs.clear()?;
    let result = calibrate(&args).and_then(|()| write_page(&args));
    if result.is_err() {
        outputs.discard();
    }
    result
}

/// The report page: the calibration file's with `.html`.
fn page_path(out: &Path) -> PathBuf {
    out.with_extension("html")
}

/// `OUT.html`: what the calibration printed, views it skipped as warnings.
fn write_page(args: &Args) -> anyhow::Result<()> {
    let lines = take();
    let warnings = lines
        .iter()
        .filter(|l| l.contains("skipped:"))
        .map(|l| {
            format!(
                "view {}",
                l.split_whitespace().collect::<Vec<_>>().join(" ")
            )
        })
        .collect();
    let source = match &args.images {
        Some(dir) => dir.display().to_string(),
        None => "digital-twin renders".into(),
    };
    let html = render(&Page {
        title: format!("slscan calibrate: {source}"),
        warnings,
        tables: vec![Table {
            heading: "Calibration".into(),
            rows: vec![
                ("board views".into(), source),
                ("calibration file".into(), args.out.display().to_string()),
            ],
        }],
        timings_ms: vec![],
        pictures: vec![],
        text: Some(lines.join("\n")),
        raw: std::fs::read_to_string(&args.out).ok(),
    });
    Ok(write_html(&page_path(&args.out), &html)?)
}

fn calibrate(args: &Args) -> anyhow::Result<()> {
    let mut options = HeadOptions::default();
    options.camera = CameraCalibrationOptions {
        fix_k3: !args.with_k3,
        ..options.camera
    };
    options.projector.fix_k3 = !args.with_k3;
    if args.sim {
        run_sim(args, &options)
    } else {
        let dir = args
            .images
            .as_deref()
            .context("--images DIR or --sim is required")?;
        run_images(args, dir, &options)
    }
}

#[cfg(feature = "sim")]
fn run_sim(args: &Args, options: &HeadOptions) -> anyhow::Result<()> {
    super::calibrate_sim::run(&args.sim_options, &args.head, &args.out, options)
}

#[cfg(not(feature = "sim"))]
fn run_sim(_: &Args, _: &HeadOptions) -> anyhow::Result<()> {
    Err(super::no_simulator("calibrate --sim"))
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
            let cal = with_spinner("calibrating the head", || {
                calibrate_head(&args.head, &board, &captures, &spec, options)
            })?;
            print_head(&cal);
            write_rig(&args.out, &RigCalibration::single(cal.head))
                .with_context(|| format!("writing {}", args.out.display()))?;
        }
        None => {
            let stage = with_spinner("calibrating the camera", || {
                calibrate_camera_stage(&board, &captures, options)
            })?;
            print_camera_stage(&stage);
            write_camera_file(&args.out, &stage)?;
        }
    }
    say!("wrote {}", args.out.display());
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

#[cfg(all(test, feature = "sim"))]
mod tests {
    #[test]
    fn pixel_samples_default_is_the_twins() {
        assert_eq!(
            super::super::calibrate_sim_options::CALIBRATION_PIXEL_SAMPLES,
            slscan::sim::twin::CALIBRATION_PIXEL_SAMPLES
        );
    }
}
