//! `slscan reconstruct`.

/// Options of `slscan reconstruct`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `slscan reconstruct`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("PLACEHOLDER: `slscan reconstruct` is not implemented yet")
}
