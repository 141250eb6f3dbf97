//! `slscan reconstruct`: a folder of fringe images + a rig file -> PLY and pictures.
//!
//! Frames are taken in file-name order. Without a description they are ours: all steps
//! of the finest period first, then the next period (`--periods`), columns first; with
//! `--both`, the same again for rows (the fused pipeline decodes them). A capture of
//! another system is described by a manifest (`--manifest`, or `capture.json` in the
//! frame folder) or a preset (`--preset`); see `slscan::capture`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use slscan::calibration::read_rig;
use slscan::capture::decode::{decode, AxisCoordinates};
use slscan::capture::manifest::{read_manifest, FILE_NAME as MANIFEST_FILE};
use slscan::capture::presets::{Preset, PresetOptions};
use slscan::capture::triangulate::triangulate;
use slscan::capture::CaptureSpec;

use super::reconstruct_stereo::{reconstruct_stereo, StereoInputs};
use slscan::io::images::{list_images, load_set, save_bytes, ExposureLimits, ImageError};
use slscan::io::npy::{write_npy_f32, write_npy_u8};
use slscan::io::outputs::OutputSet;
use slscan::io::ply::write_ply;
use slscan::io::report_html::{render, write_html, Page, PagePicture, Table};
use slscan::pictures::{head_pictures, summarise_frames, HeadPictures, KINDS};
use slscan::raster::Raster;
use slscan::reconstruct::{Directions, ReconstructConfig, Reconstruction, Reconstructor};
use slscan::unwrap::PixelStatus;

/// Options of `slscan reconstruct`.
#[derive(clap::Args)]
pub struct Args {
    /// Folder of fringe images (PNG/TIFF, 8- or 16-bit, or 2-D .npy arrays of
    /// u8, u16 or floats in [0, 1]), sorted by name.
    #[arg(long)]
    images: PathBuf,
    /// Rig calibration file (JSON).
    #[arg(long)]
    rig: PathBuf,
    /// Head to use (default: the first).
    #[arg(long)]
    head: Option<String>,
    /// Fringe periods, projector pixels, finest first [default: 100,110,120; the
    /// preset's with --preset].
    #[arg(long, value_delimiter = ',')]
    periods: Option<Vec<f64>>,
    /// Phase steps per period [default: 4; the preset's with --preset].
    #[arg(long)]
    steps: Option<usize>,
    /// Frames hold columns then rows (two-ray triangulation).
    #[arg(long)]
    both: bool,
    /// The capture's pattern family: slscan, heterodyne (any --steps >= 3 and
    /// --periods), sinus-comple-gray (SLMaster / OpenCV SinusCompleGrayCodePattern:
    /// 12 steps of one 32 px period, phase 2 pi (u mod P)/P - pi, then n + 1 Gray
    /// bits), opencv-graycode (OpenCV GrayCodePattern with inverses, then white and
    /// black).
    #[arg(long, conflicts_with = "manifest")]
    preset: Option<String>,
    /// Capture manifest (JSON) describing the frames; default: capture.json in the
    /// --images folder when there is one.
    #[arg(long)]
    manifest: Option<PathBuf>,
    /// The right camera's frames of a stereo head (two calibrated cameras, an
    /// uncalibrated projector; the rig's stereo head, or --head): --images holds the
    /// left camera's frames, the same sequence.
    #[arg(long, value_name = "DIR")]
    stereo: Option<PathBuf>,
    /// The projector's size, pixels (needed with --stereo: a stereo head's projector
    /// is not calibrated, but its size bounds the decoded coordinates).
    #[arg(long, value_name = "WxH", value_parser = super::parse::parse_size, requires = "stereo")]
    projector_size: Option<(u32, u32)>,
    /// Smallest usable modulation (frame units, 0..1).
    #[arg(long, default_value_t = 0.05)]
    min_modulation: f32,
    /// Intensity noise sigma of the camera at half scale (frame units) for the
    /// quality estimate and the fringe-order checks.
    #[arg(long, default_value_t = 0.01)]
    noise_sigma: f32,
    /// Share of that noise's variance that is shot noise, 0..1 (then each point's
    /// quality follows its pixel's level; a camera with full well W and read noise r
    /// electrons has (W/2) / (W/2 + r^2)). 0 gives every pixel the half-scale noise.
    #[arg(long, default_value_t = 0.0)]
    shot_noise_share: f32,
    /// Saturated share tolerated per frame, percent.
    #[arg(long, default_value_t = 5.0)]
    max_saturated_percent: f64,
    /// Output PLY file (its report page is written beside it, .html).
    #[arg(long)]
    out: PathBuf,
    /// Folder for the pictures (camera mean, projector column, depth,
    /// fringe modulation; PNG with scales and legends) and depth.npy.
    #[arg(long)]
    pictures: Option<PathBuf>,
    /// Folder for the decoded maps as data: phase.npy (absolute phase of the
    /// finest column period, radians, NaN where not valid), modulation.npy
    /// (frame units) and status.npy (uint8: 0 valid, 1 masked, 2 unreliable,
    /// 3 unreached), one value per camera pixel.
    #[arg(long, value_name = "DIR")]
    write_phase: Option<PathBuf>,
    /// Print each stage's time (phase, unwrapping, triangulation, cloud,
    /// loading and writing) in a table.
    #[arg(long, short)]
    verbose: bool,
}

/// The maps `--write-phase` writes.
const PHASE_FILES: [&str; 3] = ["phase.npy", "modulation.npy", "status.npy"];

/// Runs `slscan reconstruct`: checks the arguments, clears this command's
/// earlier outputs, reconstructs, then writes the pictures, `depth.npy`, the
/// report page and the cloud last; when anything fails, none of this run's
/// files is left.
pub fn run(args: Args) -> anyhow::Result<()> {
    check_args(&args)?;
    let outputs = output_set(&args);
    outputs.clear()?;
    let result = reconstruct_and_write(&args);
    if result.is_err() {
        outputs.discard();
    }
    result
}

/// Every file this command writes: the cloud, its report page beside it
/// (`cloud.ply` -> `cloud.html`) and, with `--pictures`, the pictures and `depth.npy`.
fn output_set(args: &Args) -> OutputSet {
    let mut set = OutputSet::new([args.out.clone(), page_path(&args.out)]);
    if let Some(dir) = &args.pictures {
        set = set.with(OutputSet::in_dir(
            dir,
            KINDS
                .iter()
                .map(|k| format!("{k}.png"))
                .chain(["depth.npy".to_string()]),
        ));
    }
    if let Some(dir) = &args.write_phase {
        set = set.with(OutputSet::in_dir(dir, PHASE_FILES));
    }
    set
}

/// The report page's path: the cloud's with `.html`.
fn page_path(cloud: &Path) -> PathBuf {
    cloud.with_extension("html")
}

/// What can be refused before any image is read.
fn check_args(args: &Args) -> anyhow::Result<()> {
    if let Some(periods) = &args.periods {
        anyhow::ensure!(!periods.is_empty(), "--periods: give at least one period");
        if let Some(p) = periods.iter().find(|p| !(p.is_finite() && **p > 0.0)) {
            anyhow::bail!("--periods: {p} is not a positive number of projector pixels");
        }
    }
    if let Some(steps) = args.steps {
        anyhow::ensure!(
            steps >= 3,
            "--steps {steps}: phase shifting needs at least 3"
        );
    }
    if args.manifest.is_some() {
        for (given, flag) in [
            (args.periods.is_some(), "--periods"),
            (args.steps.is_some(), "--steps"),
            (args.both, "--both"),
        ] {
            anyhow::ensure!(
                !given,
                "{flag} conflicts with --manifest: the manifest describes the frames"
            );
        }
    }
    anyhow::ensure!(
        !args.out.is_dir(),
        "--out {} is a folder; give the PLY file to write",
        args.out.display()
    );
    for (flag, dir) in [
        ("--pictures", &args.pictures),
        ("--write-phase", &args.write_phase),
    ] {
        if let Some(dir) = dir {
            anyhow::ensure!(
                !dir.exists() || dir.is_dir(),
                "{flag} {} exists and is not a folder",
                dir.display()
            );
        }
    }
    Ok(())
}

fn reconstruct_and_write(args: &Args) -> anyhow::Result<()> {
    let rig = read_rig(&args.rig)?;
    let mut timings = Vec::new();
    let (head_name, out, frames, described) = match &args.stereo {
        Some(right) => {
            let head = match &args.head {
                Some(name) => rig.stereo_head(name).with_context(|| {
                    format!(
                        "rig {} has no stereo head named {name:?}",
                        args.rig.display()
                    )
                })?,
                None => rig.stereo_heads.first().with_context(|| {
                    format!("--stereo: rig {} has no stereo head", args.rig.display())
                })?,
            };
            let projector = args
                .projector_size
                .context("--stereo needs --projector-size WxH (the projector is not calibrated)")?;
            let spec = match decoding(args, projector)? {
                Decoding::Described(spec) => spec,
                Decoding::Ours(config) => Preset::Slscan.spec(
                    &PresetOptions {
                        steps: Some(config.steps),
                        periods_px: Some(config.periods_px),
                        both: args.both,
                    },
                    projector,
                )?,
            };
            let inputs = StereoInputs {
                head,
                spec: &spec,
                left: &args.images,
                right,
                projector,
                noise_sigma: args.noise_sigma,
            };
            let (out, frames, axes) = reconstruct_stereo(&inputs, &mut timings)?;
            (head.name.clone(), out, frames, Some((spec, axes)))
        }
        None => {
            let head = match &args.head {
                Some(name) => rig.head(name).with_context(|| {
                    format!("rig {} has no head named {name:?}", args.rig.display())
                })?,
                None => rig.heads.first().with_context(|| {
                    format!(
                        "rig {} has no projector head (a stereo head's frames need --stereo)",
                        args.rig.display()
                    )
                })?,
            };
            let projector = (head.projector.width_px, head.projector.height_px);
            let decoding = decoding(args, projector)?;
            let paths = list_images(&args.images)?;
            match decoding {
                Decoding::Ours(config) => {
                    let (out, frames) = reconstruct_ours(args, head, config, &paths, &mut timings)?;
                    (head.name.clone(), out, frames, None)
                }
                Decoding::Described(spec) => {
                    let (out, frames, axes) =
                        reconstruct_described(args, head, &spec, &paths, &mut timings)?;
                    (head.name.clone(), out, frames, Some((spec, axes)))
                }
            }
        }
    };
    let finest_period_px = match &described {
        Some((_, axes)) => axes[0].reference_period_px,
        None => args.periods.as_ref().map_or(100.0, |p| p[0]),
    };
    anyhow::ensure!(
        !out.cloud.is_empty(),
        "no valid points: {} masked (modulation < {}), {} unreliable of {} pixels",
        out.count(PixelStatus::Masked),
        args.min_modulation,
        out.count(PixelStatus::Unreliable),
        out.pixels.len()
    );
    let clock = Instant::now();
    let pictures = head_pictures(&HeadPictures {
        head: &format!("head {head_name}"),
        reconstruction: &out,
        finest_period_px,
        frames: &summarise_frames(&frames),
        error_m: None,
    })?;
    let mut page_pictures = Vec::new();
    if let Some(dir) = &args.pictures {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for p in &pictures {
            save_bytes(&dir.join(format!("{}.png", p.kind)), &p.png)?;
        }
        write_npy_f32(&dir.join("depth.npy"), &out.depth_m())
            .with_context(|| format!("writing {}", dir.join("depth.npy").display()))?;
    }
    for p in pictures {
        page_pictures.push(PagePicture {
            file: format!("{}.png", p.kind),
            caption: p.caption,
            png: p.png,
        });
    }
    if let Some(dir) = &args.write_phase {
        write_maps(dir, &out)?;
    }
    lap(&mut timings, "pictures and maps", clock);
    let summary = format!(
        "{} points -> {} ({} valid, {} masked, {} unreliable pixels)",
        out.cloud.len(),
        args.out.display(),
        out.count(PixelStatus::Valid),
        out.count(PixelStatus::Masked),
        out.count(PixelStatus::Unreliable)
    );
    let page = render(&Page {
        title: format!("slscan reconstruct: {}", args.images.display()),
        warnings: vec![],
        tables: vec![Table {
            heading: "Reconstruction".into(),
            rows: vec![
                (
                    "frames".into(),
                    format!("{} from {}", frames.len(), args.images.display()),
                ),
                (
                    "rig".into(),
                    format!("{}, head {head_name}", args.rig.display()),
                ),
                ("capture".into(), capture_row(described.as_ref())),
                ("points".into(), out.cloud.len().to_string()),
                (
                    "valid pixels".into(),
                    out.count(PixelStatus::Valid).to_string(),
                ),
                (
                    "masked pixels".into(),
                    out.count(PixelStatus::Masked).to_string(),
                ),
                (
                    "unreliable pixels".into(),
                    out.count(PixelStatus::Unreliable).to_string(),
                ),
            ],
        }]
        .into_iter()
        .chain(described.as_ref().map(|(_, axes)| checks_table(axes)))
        .collect(),
        timings_ms: timings.clone(),
        pictures: page_pictures,
        text: None,
        raw: None,
    });
    write_html(&page_path(&args.out), &page)?;
    let clock = Instant::now();
    write_ply(&args.out, &out.cloud)?;
    lap(&mut timings, "write", clock);
    println!("{summary}");
    if args.verbose {
        println!("stage                 ms");
        for (stage, ms) in &timings {
            println!("{stage:<20} {ms:>5.0}");
        }
    }
    Ok(())
}

/// How the frames will be decoded.
enum Decoding {
    /// Ours, through the fused pipeline.
    Ours(ReconstructConfig),
    /// A described capture (manifest or preset).
    Described(CaptureSpec),
}

/// The manifest (given, or `capture.json` beside the frames), else the preset, else
/// ours from `--periods`, `--steps` and `--both`.
fn decoding(args: &Args, projector: (u32, u32)) -> anyhow::Result<Decoding> {
    let beside = args.images.join(MANIFEST_FILE);
    let manifest = args
        .manifest
        .clone()
        .or_else(|| beside.is_file().then_some(beside));
    if let Some(path) = manifest {
        for (given, flag) in [
            (args.periods.is_some(), "--periods"),
            (args.steps.is_some(), "--steps"),
            (args.both, "--both"),
            (args.preset.is_some(), "--preset"),
        ] {
            anyhow::ensure!(
                !given,
                "{flag} conflicts with the capture manifest {}, which describes the frames",
                path.display()
            );
        }
        return Ok(Decoding::Described(read_manifest(&path, projector)?));
    }
    if let Some(name) = &args.preset {
        let options = PresetOptions {
            steps: args.steps,
            periods_px: args.periods.clone(),
            both: args.both,
        };
        let mut spec = Preset::from_name(name)
            .map_err(slscan::capture::CaptureError::from)?
            .spec(&options, projector)?;
        spec.thresholds.min_modulation = args.min_modulation;
        spec.validate(projector)?;
        return Ok(Decoding::Described(spec));
    }
    let mut config = ReconstructConfig::new(
        args.periods
            .clone()
            .unwrap_or_else(|| vec![100.0, 110.0, 120.0]),
    );
    config.steps = args.steps.unwrap_or(4);
    config.min_modulation = args.min_modulation;
    config.noise_sigma = args.noise_sigma;
    config.shot_noise_share = args.shot_noise_share;
    config.directions = if args.both {
        Directions::Both
    } else {
        Directions::Columns
    };
    Ok(Decoding::Ours(config))
}

/// Ours: the fused pipeline (or, with `--verbose` and columns only, the staged one,
/// timed per stage; the results are the same).
fn reconstruct_ours(
    args: &Args,
    head: &slscan::calibration::Head,
    config: ReconstructConfig,
    paths: &[PathBuf],
    timings: &mut Vec<(String, f64)>,
) -> anyhow::Result<(Reconstruction, Vec<Raster<f32>>)> {
    let per_direction = config.frames_per_direction();
    let expected = per_direction * if args.both { 2 } else { 1 };
    if paths.len() != expected {
        return Err(ImageError::MissingFrames {
            dir: args.images.clone(),
            expected,
            found: paths.len(),
        }
        .into());
    }
    let limits = ExposureLimits {
        max_saturated_percent: args.max_saturated_percent,
        ..ExposureLimits::default()
    };
    let clock = Instant::now();
    let frames = load_set(paths, &limits)?;
    lap(timings, "load", clock);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let clock = Instant::now();
    let ours = PresetOptions {
        steps: Some(config.steps),
        periods_px: Some(config.periods_px.clone()),
        both: args.both,
    };
    let rec = Reconstructor::from_head(head, config)?;
    let (u, v) = refs.split_at(per_direction);
    let out = if args.verbose && !args.both {
        let (out, t) = rec.reconstruct_staged(u)?;
        for (stage, s) in [
            ("phase", t.phase_s),
            ("unwrap", t.unwrap_s),
            ("triangulate", t.triangulate_s),
            ("cloud", t.cloud_s),
        ] {
            timings.push((stage.to_string(), s * 1e3));
        }
        out
    } else {
        let out = rec.reconstruct(u, args.both.then_some(v))?;
        lap(timings, "reconstruct", clock);
        out
    };
    explain_failed_orders(head, &out, &ours, &refs, args.noise_sigma)?;
    Ok((out, frames))
}

/// Share of the modulated pixels whose orders may fail in a capture of ours before
/// the capture is suspected of another convention.
const SUSPECT_UNRELIABLE: f64 = 0.25;

/// When most modulated pixels failed the fused pipeline's order checks, the frames
/// are likely of another convention: the described decoder's self-checks then name
/// the cause (phase origin, direction, the periods' order) instead of a near-empty
/// cloud. A capture that passes them keeps the fused result.
fn explain_failed_orders(
    head: &slscan::calibration::Head,
    out: &Reconstruction,
    ours: &PresetOptions,
    frames: &[&Raster<f32>],
    noise_sigma: f32,
) -> anyhow::Result<()> {
    let unreliable = out.count(PixelStatus::Unreliable);
    let usable = unreliable + out.count(PixelStatus::Valid);
    if usable == 0 || (unreliable as f64) <= SUSPECT_UNRELIABLE * usable as f64 {
        return Ok(());
    }
    let projector = (head.projector.width_px, head.projector.height_px);
    let spec = Preset::Slscan.spec(ours, projector)?;
    decode(&spec, frames, projector, noise_sigma).with_context(|| {
        format!(
            "{unreliable} of {usable} modulated pixels failed the fringe-order checks, \
             so the frames were checked for another convention"
        )
    })?;
    tracing::warn!(
        unreliable,
        usable,
        "most modulated pixels failed the fringe-order checks, though the frames follow \
         our convention: too noisy for these periods?"
    );
    Ok(())
}

/// A described capture: the frame count checked before any frame is read, then
/// decode (with the self-checks) and triangulate.
fn reconstruct_described(
    args: &Args,
    head: &slscan::calibration::Head,
    spec: &CaptureSpec,
    paths: &[PathBuf],
    timings: &mut Vec<(String, f64)>,
) -> anyhow::Result<(Reconstruction, Vec<Raster<f32>>, Vec<AxisCoordinates>)> {
    spec.check_frame_count(paths.len())
        .with_context(|| format!("frames in {}", args.images.display()))?;
    // White, black and Gray frames may be dark or saturate as a whole: the
    // per-pixel masks judge them, not the whole-frame exposure check.
    let limits = ExposureLimits {
        max_saturated_percent: 100.0,
        min_range: 0.0,
        ..ExposureLimits::default()
    };
    let clock = Instant::now();
    let frames = load_set(paths, &limits)?;
    lap(timings, "load", clock);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let projector = (head.projector.width_px, head.projector.height_px);
    let clock = Instant::now();
    let axes = decode(spec, &refs, projector, args.noise_sigma)?;
    lap(timings, "decode", clock);
    let clock = Instant::now();
    let out = triangulate(head, &axes, true)?;
    lap(timings, "triangulate", clock);
    Ok((out, frames, axes))
}

/// The capture's description for the page.
fn capture_row(described: Option<&(CaptureSpec, Vec<AxisCoordinates>)>) -> String {
    match described {
        None => "ours (heterodyne, fused pipeline)".into(),
        Some((spec, _)) => format!(
            "{}: {}; unwrapping {}",
            spec.name,
            spec.breakdown(),
            spec.unwrapping.name()
        ),
    }
}

/// The self-checks as measured, for the page.
fn checks_table(axes: &[AxisCoordinates]) -> Table {
    Table {
        heading: "Convention self-checks (all passed)".into(),
        rows: axes
            .iter()
            .flat_map(|a| &a.checks)
            .map(|c| {
                (
                    format!("{}: {}", slscan::capture::axis_name(c.axis), c.check),
                    format!(
                        "{:.2} % of {} (limit {:.0} %)",
                        100.0 * c.share,
                        c.pixels,
                        100.0 * c.limit
                    ),
                )
            })
            .collect(),
    }
}

/// `--write-phase`: the absolute phase, modulation and status maps as `.npy`.
fn write_maps(dir: &Path, out: &slscan::reconstruct::Reconstruction) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let status = out.status();
    let codes = Raster {
        width: status.width,
        height: status.height,
        data: status.data.iter().map(|s| *s as u8).collect(),
    };
    let [phase, modulation, status] = PHASE_FILES.map(|f| dir.join(f));
    write_npy_f32(&phase, &out.phase_u())
        .with_context(|| format!("writing {}", phase.display()))?;
    write_npy_f32(&modulation, &out.modulation())
        .with_context(|| format!("writing {}", modulation.display()))?;
    write_npy_u8(&status, &codes).with_context(|| format!("writing {}", status.display()))
}

/// Logs a stage's time and keeps it for the page.
pub(super) fn lap(timings: &mut Vec<(String, f64)>, stage: &str, start: Instant) {
    let ms = start.elapsed().as_secs_f64() * 1e3;
    tracing::info!(stage, ms = format_args!("{ms:.0}"), "stage done");
    timings.push((stage.to_string(), ms));
}
