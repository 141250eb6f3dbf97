//! `hil-sim`: serve the simulated board, soak the sequencer, render the twin.
//! Wiring only: each subcommand lives in its own file under `cmd/`.

mod cmd;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "hil-sim",
    version,
    about = "Hardware-in-the-loop simulator for the slscan scanner"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Serve the simulated sync board on a pseudo-terminal until stopped.
    Serve(cmd::serve::Args),
    /// Run many random valid plans through the sequencer on the virtual clock.
    Soak(cmd::soak::Args),
    /// Render a built-in scene to PNG pictures (image, depth, phase).
    Render(cmd::render::Args),
    /// List the built-in scenes.
    Scenes(cmd::scenes::Args),
    /// Write a reproducible training dataset.
    Dataset(cmd::dataset::Args),
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Serve(args) => cmd::serve::run(args),
        Command::Soak(args) => cmd::soak::run(args),
        Command::Render(args) => cmd::render::run(args),
        Command::Scenes(args) => cmd::scenes::run(args),
        Command::Dataset(args) => cmd::dataset::run(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("hil-sim: error: {err:#}");
            std::process::ExitCode::from(1)
        }
    }
}
