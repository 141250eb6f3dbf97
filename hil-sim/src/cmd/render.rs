//! `hil-sim render`.

/// Options of `hil-sim render`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `hil-sim render`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("PLACEHOLDER: `hil-sim render` is not implemented yet")
}
