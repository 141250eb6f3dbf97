//! `slscan fuse A.ply B.ply --out merged.ply`: registers B onto A as
//! `slscan register` does, then merges the two into one cloud in A's frame
//! (points of B within the merge radius of a point of A are averaged with
//! it by their quality).

use std::path::PathBuf;

use anyhow::Context;
use slscan::fusion::{merge_clouds, DuplicateRule, MergeParams};
use slscan::io::ply::write_ply;
use slscan::scan::clouds::from_fusion;

use super::register::{moved_b, print_registration, register_clouds, RegistrationArgs};

/// Options of `slscan fuse`.
#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    clouds: RegistrationArgs,
    /// The merged cloud (binary PLY, metres).
    #[arg(long)]
    out: PathBuf,
    /// A point of B this close to a point of A is the same surface point, mm
    /// (about the clouds' point spacing).
    #[arg(long, default_value_t = 0.5)]
    merge_radius_mm: f64,
}

/// Runs `slscan fuse`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if !(args.merge_radius_mm.is_finite() && args.merge_radius_mm > 0.0) {
        anyhow::bail!("--merge-radius-mm {} is not positive", args.merge_radius_mm);
    }
    // An earlier merged cloud must not pass for this run's when it fails.
    slscan::io::outputs::OutputSet::new([args.out.clone()]).clear()?;
    let registered = register_clouds(&args.clouds)?;
    print_registration(&registered);
    let params = MergeParams {
        radius_m: args.merge_radius_mm * 1e-3,
        rule: DuplicateRule::WeightedMean,
        default_sigma_m: 1e-4,
    };
    let (merged, counts) = merge_clouds(&registered.a.cloud, &moved_b(&registered), &params)
        .context("merging the clouds")?;
    println!("merged: {} points ({counts:?})", merged.points.len());
    write_ply(&args.out, &from_fusion(&merged))
        .with_context(|| format!("writing {}", args.out.display()))?;
    println!("wrote {}", args.out.display());
    Ok(())
}
