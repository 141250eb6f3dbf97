//! `slscan scan`: plan, capture, reconstruct and fuse a dual-head scan.
//!
//! Only the simulated rig exists (`--sim`): hil-sim's board on a pty, the
//! host's serial client, and cameras rendered by the digital twin.

use std::path::PathBuf;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use slscan::scan::{self, CalibrationSource, Mode, Progress, ScanConfig};

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
    /// Rig file to reconstruct with and to seed the ICP from (`slscan
    /// calibrate --sim --scene NAME --out FILE`); default with --sim: the
    /// digital twin's TRUE devices (labelled so in the report).
    #[arg(long, value_name = "FILE")]
    calibration: Option<PathBuf>,
}

/// `--mode` values.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum ModeArg {
    /// Head A alone, then head B alone.
    Sequential,
    /// Both heads at once, identical sequences; aliased overlap masked out (PLACEHOLDER for a de-aliaser).
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
    if let Some(periods) = args.periods {
        config.periods_px = periods;
    }
    if let Some(path) = args.calibration {
        config.calibration = CalibrationSource::File(path);
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
    if let Some(e) = &report.calibration_vs_truth {
        for h in &e.heads {
            println!(
                "  head {} vs twin truth: camera dfx {:+.2} dcx {:+.2} dcy {:+.2} px, projector dfx {:+.2} dcy {:+.2} px, camera->projector {:.3} deg / {:.2} mm",
                h.name, h.camera.dfx_px, h.camera.dcx_px, h.camera.dcy_px, h.projector.dfx_px,
                h.projector.dcy_px, h.camera_to_projector.rotation_deg, h.camera_to_projector.translation_mm
            );
        }
        if let Some(p) = &e.head_to_head {
            println!(
                "  head-to-head vs twin truth: {:.3} deg / {:.2} mm (the ICP's start)",
                p.rotation_deg, p.translation_mm
            );
        }
    }
    let fit = &report.truth_frame_fit;
    println!(
        "frames fitted onto the truth before measuring: head A {:.3} deg / {:.0} um, head B {:.3} deg / {:.0} um, fused {:.3} deg / {:.0} um",
        fit.heads[0].rotation_deg, fit.heads[0].translation_um, fit.heads[1].rotation_deg,
        fit.heads[1].translation_um, fit.fused.rotation_deg, fit.fused.translation_um
    );
    println!(
        "B->A pose used vs truth (frames fitted): {:.4} deg / {:.1} um",
        f.pose_error_vs_truth_deg, f.pose_error_vs_truth_um
    );
    for w in &report.warnings {
        eprintln!("slscan: WARNING: {w}");
    }
    println!("wrote {}", args.out.join("scan.ply").display());
    Ok(())
}
