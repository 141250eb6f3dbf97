//! `slscan patterns`.

/// Options of `slscan patterns`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `slscan patterns`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("PLACEHOLDER: `slscan patterns` is not implemented yet")
}
