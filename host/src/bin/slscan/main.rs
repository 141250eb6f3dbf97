//! `slscan`: the scanner's command line. Wiring only: one file per subcommand in `cmd/`.

mod cmd;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "slscan", version, about = "Structured-light 3D scanner host")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Talk to the sync board (real port or simulated).
    Board(cmd::board::Args),
    /// Write a fringe / Gray-code pattern set as PNG.
    Patterns(cmd::patterns::Args),
    /// Calibrate cameras and projectors from checkerboard captures.
    Calibrate(cmd::calibrate::Args),
    /// Import or export OpenCV calibration files (cv::FileStorage YAML/XML).
    Calibration(cmd::calibration_io::Args),
    /// Reconstruct a point cloud from a folder of fringe images.
    Reconstruct(cmd::reconstruct::Args),
    /// Plan, capture and reconstruct a scan end to end.
    // Boxed: its many options would make every other command's value as large.
    Scan(Box<cmd::scan::Args>),
    /// List the DMD controllers on the USB bus (feature `hid`).
    Devices(cmd::devices::Args),
    /// Register cloud B onto cloud A (PLY files from any tool) by ICP.
    Register(cmd::register::Args),
    /// Register cloud B onto cloud A and merge them into one cloud.
    Fuse(cmd::fuse::Args),
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        // No colour codes in a redirected log.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Board(args) => cmd::board::run(args),
        Command::Patterns(args) => cmd::patterns::run(args),
        Command::Calibrate(args) => cmd::calibrate::run(args),
        Command::Calibration(args) => cmd::calibration_io::run(args),
        Command::Reconstruct(args) => cmd::reconstruct::run(args),
        Command::Scan(args) => cmd::scan::run(*args),
        Command::Devices(args) => cmd::devices::run(args),
        Command::Register(args) => cmd::register::run(args),
        Command::Fuse(args) => cmd::fuse::run(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("slscan: error: {}", error_chain(&err));
            std::process::ExitCode::from(1)
        }
    }
}

/// The error and its causes as "a: b: c", leaving out a cause whose text the message
/// before it already ends with (many errors print their source inline as well).
fn error_chain(err: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in err.chain() {
        let text = cause.to_string();
        if out.ends_with(&text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cause_printed_inline_is_not_repeated() {
        #[derive(Debug, thiserror::Error)]
        #[error("rig file x.json: {source}")]
        struct Inline {
            source: std::io::Error,
        }
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let err = anyhow::Error::new(Inline { source: io }).context("writing x.json");
        assert_eq!(
            error_chain(&err),
            "writing x.json: rig file x.json: no such file"
        );
        let plain = anyhow::anyhow!("inner").context("outer");
        assert_eq!(error_chain(&plain), "outer: inner");
    }
}
