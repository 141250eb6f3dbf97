//! `slscan scan`.

/// Options of `slscan scan`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `slscan scan`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("PLACEHOLDER: `slscan scan` is not implemented yet")
}
