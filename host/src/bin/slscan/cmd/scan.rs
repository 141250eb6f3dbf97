//! `slscan scan`: plan, capture, reconstruct and fuse a dual-head scan.
//!
//! Only the simulated rig exists (`--sim`): hil-sim's board on a pty, the
//! host's serial client, and cameras rendered by the digital twin.

use std::path::PathBuf;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use slscan::scan::{self, Mode, Progress, ScanConfig};

/// Options of `slscan scan`.
#[derive(clap::Args)]
pub struct Args {
    /// Scan the simulated rig (board on a pty, digital-twin cameras).
    #[arg(long)]
    sim: bool,
    /// Built-in twin scene with two heads.
    #[arg(long, default_value = "large-part")]
    scene: String,
    /// How the heads share time.
    #[arg(long, value_enum, default_value_t = ModeArg::Sequential)]
    mode: ModeArg,
    /// Output folder (scan.ply, head_a.ply, head_b.ply, report.json, PNGs).
    #[arg(long)]
    out: PathBuf,
    /// Camera width, pixels.
    #[arg(long, default_value_t = 640)]
    width: u32,
    /// Camera height, pixels.
    #[arg(long, default_value_t = 480)]
    height: u32,
    /// Seed of device jitter and sensor noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Fringe periods, projector pixels, finest first (4 steps each);
    /// default: seed 004's three pitches over the DMD width (S = 64).
    #[arg(long, value_delimiter = ',')]
    periods: Option<Vec<f64>>,
    /// The simulated projectors' response: intensity = grey^gamma
    /// (1 = DMD pattern mode; about 2.2 through a video input).
    #[arg(long, default_value_t = 1.0)]
    sim_projector_gamma: f64,
    /// Pre-compensate the patterns for a projector response of this gamma
    /// (send grey^(1/gamma)).
    #[arg(long)]
    precompensate_gamma: Option<f64>,
}

/// `--mode` values.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum ModeArg {
    /// Head A alone, then head B alone.
    Sequential,
    /// Both heads at once, identical sequences; pixels the flat fields show lit by both projectors masked out (no de-aliaser yet).
    Simultaneous,
    /// Both at once, N = 8, head A on temporal bin 1, head B on bin 2, demultiplexed per pixel.
    SimultaneousMultiplexed,
}

/// Runs `slscan scan`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if !args.sim {
        anyhow::bail!(
            "PLACEHOLDER: only the simulated rig exists; pass --sim (no DMD or camera driver yet)"
        );
    }
    let mut config = ScanConfig::new(&args.scene);
    config.mode = match args.mode {
        ModeArg::Sequential => Mode::Sequential,
        ModeArg::Simultaneous => Mode::Simultaneous,
        ModeArg::SimultaneousMultiplexed => Mode::SimultaneousMultiplexed,
    };
    config.camera_px = (args.width, args.height);
    config.seed = args.seed;
    config.sim_projector_gamma = args.sim_projector_gamma;
    config.precompensate_gamma = args.precompensate_gamma;
    if let Some(periods) = args.periods {
        config.periods_px = periods;
    }
    let style = ProgressStyle::with_template("{prefix:>18} [{bar:30}] {pos}/{len} {elapsed}")
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ");
    let mut bar: Option<ProgressBar> = None;
    let mut on_progress = |p: Progress| match p {
        Progress::Stage { name, total } => {
            let b = ProgressBar::new(total)
                .with_style(style.clone())
                .with_prefix(name);
            bar = Some(b);
        }
        Progress::Step => {
            if let Some(b) = &bar {
                b.inc(1);
            }
        }
        Progress::Done => {
            if let Some(b) = bar.take() {
                b.finish();
            }
        }
    };
    let report = scan::scan_to_dir(&config, &args.out, &mut on_progress).with_context(|| {
        format!(
            "scan into {} failed; no scan.ply written",
            args.out.display()
        )
    })?;
    for h in &report.heads {
        println!(
            "head {}: {} points, RMSE {:.1} um (predicted {:.1} um; median {:.1} um, {} over 1 mm), coverage {:.3}",
            h.name, h.points, h.rmse_um, h.predicted_rms_um, h.median_error_um, h.outliers_over_1mm, h.coverage
        );
        println!(
            "head {} overlap (pixels lit by both projectors): {} of {} pixels reconstructed, RMSE {:.1} um",
            h.name, h.overlap_points, h.overlap_pixels, h.overlap_rmse_um
        );
        if let Some(m) = &h.aliased_mask {
            println!(
                "head {} overlap measured by flat fields: {} px lit by both projectors, true overlap {} px, IoU {:.4}, recall {:.4}",
                h.name, m.measured_overlap_pixels, m.true_overlap_pixels, m.iou, m.recall
            );
        }
    }
    let f = &report.fused;
    println!(
        "fused: {} points, RMSE {:.1} um (point-to-plane), coverage {:.3}",
        f.points, f.rmse_um, f.coverage
    );
    match &f.icp {
        Some(icp) => println!(
            "ICP correction of the calibrated pose: {:.4} deg / {:.1} um, overlap RMSE {:.1} um",
            icp.rotation_deg, icp.translation_um, icp.overlap_rmse_um
        ),
        None => println!("no ICP: the heads share no usable surface; calibrated pose used"),
    }
    println!("calibration: {}", report.calibration);
    for w in &report.warnings {
        eprintln!("slscan: WARNING: {w}");
    }
    println!("wrote {}", args.out.join("scan.ply").display());
    Ok(())
}
