//! `hil-sim dataset KIND --count N --seed S --out DIR`: write a reproducible
//! training set (see `hil_sim::twin::dataset` for what each kind holds).

use std::path::PathBuf;

use hil_sim::twin::dataset::{write_dataset, AliasedPeriods, DatasetKind, DatasetSpec};
use hil_sim::twin::Turbidity;

/// Options of `hil-sim dataset`.
#[derive(clap::Args)]
pub struct Args {
    /// Which pairs: aliased (simultaneous dual-head), multiplexed (24-pattern colour long exposure), underwater.
    kind: DatasetKind,
    /// Number of samples.
    #[arg(long, default_value_t = 16)]
    count: usize,
    /// Seed; the same seed writes the same files.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output folder (created).
    #[arg(long)]
    out: PathBuf,
    /// Camera image width, pixels.
    #[arg(long, default_value_t = 512)]
    width: u32,
    /// Camera image height, pixels.
    #[arg(long, default_value_t = 512)]
    height: u32,
    /// DMD width, pixels.
    #[arg(long, default_value_t = 1280)]
    dmd_width: u32,
    /// DMD height, pixels.
    #[arg(long, default_value_t = 800)]
    dmd_height: u32,
    /// Underwater only: one turbidity for all samples (default: random T1..T4 per sample).
    #[arg(long)]
    turbidity: Option<Turbidity>,
    /// Aliased only: the scan's periods (73/64/56/50 fringes over the DMD) or seed 000's (100..130 px).
    #[arg(long, value_enum, default_value_t = AliasedPeriods::Scan)]
    periods: AliasedPeriods,
    /// Aliased only: least sensor noise scale (1 = the simulated scan's), drawn log-uniformly per sample.
    #[arg(long, default_value_t = 0.7)]
    noise_min: f64,
    /// Aliased only: greatest sensor noise scale.
    #[arg(long, default_value_t = 1.4)]
    noise_max: f64,
}

/// Writes the dataset with a progress bar.
pub fn run(args: Args) -> anyhow::Result<()> {
    let spec = DatasetSpec {
        kind: args.kind,
        count: args.count,
        seed: args.seed,
        width: args.width,
        height: args.height,
        projector: (args.dmd_width, args.dmd_height),
        turbidity: args.turbidity,
        periods: args.periods,
        noise_scale: (args.noise_min, args.noise_max),
    };
    let bar = indicatif::ProgressBar::new(args.count as u64);
    write_dataset(&spec, &args.out, |_| bar.inc(1))?;
    bar.finish_and_clear();
    println!(
        "wrote {} {:?} samples (seed {}) to {}",
        args.count,
        args.kind,
        args.seed,
        args.out.display()
    );
    Ok(())
}
