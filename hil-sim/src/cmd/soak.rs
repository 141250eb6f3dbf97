//! `hil-sim soak`.

/// Options of `hil-sim soak`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `hil-sim soak`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("PLACEHOLDER: `hil-sim soak` is not implemented yet")
}
