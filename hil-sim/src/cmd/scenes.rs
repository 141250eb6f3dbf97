//! `hil-sim scenes`.

/// Options of `hil-sim scenes`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `hil-sim scenes`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("PLACEHOLDER: `hil-sim scenes` is not implemented yet")
}
