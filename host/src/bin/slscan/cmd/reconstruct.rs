//! `slscan reconstruct`: a folder of fringe images + a rig file -> PLY and pictures.
//!
//! Frames are taken in file-name order: all steps of the finest period first, then the
//! next period (`--periods`), columns first; with `--both`, the same again for rows.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use slscan::calibration::read_rig;
use slscan::io::images::{list_images, load_set, save_bytes, ExposureLimits, ImageError};
use slscan::io::npy::{write_npy_f32, write_npy_u8};
use slscan::io::outputs::OutputSet;
use slscan::io::ply::write_ply;
use slscan::io::report_html::{render, write_html, Page, PagePicture, Table};
use slscan::pictures::{head_pictures, summarise_frames, HeadPictures, KINDS};
use slscan::raster::Raster;
use slscan::reconstruct::{Directions, ReconstructConfig, Reconstructor};
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
    /// Fringe periods, projector pixels, finest first.
    #[arg(long, value_delimiter = ',', default_values_t = [100.0, 110.0, 120.0])]
    periods: Vec<f64>,
    /// Phase steps per period.
    #[arg(long, default_value_t = 4)]
    steps: usize,
    /// Frames hold columns then rows (two-ray triangulation).
    #[arg(long)]
    both: bool,
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
    anyhow::ensure!(
        !args.periods.is_empty(),
        "--periods: give at least one period"
    );
    if let Some(p) = args.periods.iter().find(|p| !(p.is_finite() && **p > 0.0)) {
        anyhow::bail!("--periods: {p} is not a positive number of projector pixels");
    }
    anyhow::ensure!(
        args.steps >= 3,
        "--steps {}: phase shifting needs at least 3",
        args.steps
    );
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
    let head = match &args.head {
        Some(name) => rig
            .head(name)
            .with_context(|| format!("rig {} has no head named {name:?}", args.rig.display()))?,
        None => &rig.heads[0],
    };
    let mut config = ReconstructConfig::new(args.periods.clone());
    config.steps = args.steps;
    config.min_modulation = args.min_modulation;
    config.noise_sigma = args.noise_sigma;
    config.shot_noise_share = args.shot_noise_share;
    config.directions = if args.both {
        Directions::Both
    } else {
        Directions::Columns
    };
    let per_direction = config.frames_per_direction();
    let expected = per_direction * if args.both { 2 } else { 1 };
    let paths = list_images(&args.images)?;
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
    let mut timings = Vec::new();
    let clock = Instant::now();
    let frames = load_set(&paths, &limits)?;
    lap(&mut timings, "load", clock);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let clock = Instant::now();
    let rec = Reconstructor::from_head(head, config)?;
    let (u, v) = refs.split_at(per_direction);
    // --verbose, columns only: the staged pipeline (same result, timed per
    // stage); otherwise the fused single pass.
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
        lap(&mut timings, "reconstruct", clock);
        out
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
        head: &format!("head {}", head.name),
        reconstruction: &out,
        finest_period_px: args.periods[0],
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
                    format!("{}, head {}", args.rig.display(), head.name),
                ),
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
        }],
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
fn lap(timings: &mut Vec<(String, f64)>, stage: &str, start: Instant) {
    let ms = start.elapsed().as_secs_f64() * 1e3;
    tracing::info!(stage, ms = format_args!("{ms:.0}"), "stage done");
    timings.push((stage.to_string(), ms));
}
