//! `slscan reconstruct`: a folder of fringe images + a rig file -> PLY and pictures.
//!
//! Frames are taken in file-name order: all steps of the finest period first, then the
//! next period (`--periods`), columns first; with `--both`, the same again for rows.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use slscan::calibration::read_rig;
use slscan::io::images::{
    list_images, load_set, normalise_for_view, save_gray_png, ExposureLimits, ImageError,
};
use slscan::io::npy::write_npy_f32;
use slscan::io::ply::write_ply;
use slscan::raster::Raster;
use slscan::reconstruct::{Directions, ReconstructConfig, Reconstructor};
use slscan::unwrap::PixelStatus;

/// Options of `slscan reconstruct`.
#[derive(clap::Args)]
pub struct Args {
    /// Folder of fringe images (PNG/TIFF, 8- or 16-bit), sorted by name.
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
    /// Output PLY file.
    #[arg(long)]
    out: PathBuf,
    /// Folder for phase/depth/modulation pictures (PNG) and depth.npy.
    #[arg(long)]
    pictures: Option<PathBuf>,
}

/// Runs `slscan reconstruct`.
pub fn run(args: Args) -> anyhow::Result<()> {
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
    let clock = Instant::now();
    let frames = load_set(&paths, &limits)?;
    tracing::info!(
        stage = "load",
        frames = frames.len(),
        ms = ms_since(clock),
        "stage done"
    );
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let clock = Instant::now();
    let rec = Reconstructor::from_head(head, config)?;
    let (u, v) = refs.split_at(per_direction);
    let out = rec.reconstruct(u, args.both.then_some(v))?;
    tracing::info!(stage = "reconstruct", ms = ms_since(clock), "stage done");
    anyhow::ensure!(
        !out.cloud.is_empty(),
        "no valid points: {} masked (modulation < {}), {} unreliable of {} pixels",
        out.count(PixelStatus::Masked),
        args.min_modulation,
        out.count(PixelStatus::Unreliable),
        out.pixels.len()
    );
    let clock = Instant::now();
    write_ply(&args.out, &out.cloud)?;
    tracing::info!(stage = "write", ms = ms_since(clock), "stage done");
    if let Some(dir) = &args.pictures {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let depth = out.depth_m();
        save_gray_png(&dir.join("depth.png"), &normalise_for_view(&depth), true)?;
        save_gray_png(
            &dir.join("phase.png"),
            &normalise_for_view(&out.phase_u()),
            true,
        )?;
        let modulation = out.modulation();
        save_gray_png(
            &dir.join("modulation.png"),
            &normalise_for_view(&modulation),
            false,
        )?;
        write_npy_f32(&dir.join("depth.npy"), &depth)
            .with_context(|| format!("writing {}", dir.join("depth.npy").display()))?;
    }
    println!(
        "{} points -> {} ({} valid, {} masked, {} unreliable pixels)",
        out.cloud.len(),
        args.out.display(),
        out.count(PixelStatus::Valid),
        out.count(PixelStatus::Masked),
        out.count(PixelStatus::Unreliable)
    );
    Ok(())
}

/// Whole milliseconds since `start`, for the stage log.
fn ms_since(start: Instant) -> u128 {
    start.elapsed().as_millis()
}
