//! `hil-sim dataset`.

/// Options of `hil-sim dataset`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `hil-sim dataset`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("PLACEHOLDER: `hil-sim dataset` is not implemented yet")
}
