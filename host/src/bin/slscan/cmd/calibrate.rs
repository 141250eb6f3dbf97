//! `slscan calibrate`.

/// Options of `slscan calibrate`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `slscan calibrate`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("PLACEHOLDER: `slscan calibrate` is not implemented yet")
}
