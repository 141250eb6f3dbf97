//! `slscan board`.

/// Options of `slscan board`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `slscan board`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("PLACEHOLDER: `slscan board` is not implemented yet")
}
