//! `hil-sim scenes`: list the built-in twin scenes.

use hil_sim::twin::scenes::BUILT_IN;

/// Options of `hil-sim scenes` (none).
#[derive(clap::Args)]
pub struct Args {}

/// Prints one line per built-in scene: name and description.
pub fn run(_args: Args) -> anyhow::Result<()> {
    let width = BUILT_IN.iter().map(|b| b.name.len()).max().unwrap_or(0);
    for b in BUILT_IN {
        println!("{:width$}  {}", b.name, b.about);
    }
    Ok(())
}
