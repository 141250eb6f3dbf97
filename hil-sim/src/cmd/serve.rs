//! `hil-sim serve`.

/// Options of `hil-sim serve`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `hil-sim serve`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("PLACEHOLDER: `hil-sim serve` is not implemented yet")
}
