//! `hil-sim serve`: the simulated sync board on a pseudo-terminal, until
//! stopped (Ctrl-C). Prints the pty path on stdout, alone on its line, so a
//! script can capture it; any serial client opens it like /dev/ttyACM0.

use std::io::Write;
use std::time::Duration;

use anyhow::Context;
use hil_sim::board::{spawn_board_on_pty, SimBoard, SimBoardConfig};
use hil_sim::faults::{FaultPlan, MissedTrigger, Noise, StreamFaults};
use protocol::BoardLimits;

/// Options of `hil-sim serve`.
#[derive(clap::Args)]
pub struct Args {
    /// Seed of the simulated devices' jitter.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Fault: the board stops answering after sending this many frames.
    #[arg(long)]
    silent_after_frames: Option<u64>,
    /// Fault: the board vanishes (hears and says nothing) once its virtual
    /// clock reaches this tick (170 MHz ticks; a fresh board starts at 0).
    #[arg(long)]
    vanish_at_tick: Option<u64>,
    /// Fault: camera HEAD (0 = A) misses its trigger number INDEX (0-based,
    /// counted from the last plan commit). Repeatable.
    #[arg(long, value_name = "HEAD:INDEX", value_parser = parse_missed_trigger)]
    miss_trigger: Vec<MissedTrigger>,
    /// Fault: the DMD of head HEAD (0 = A) lags NS nanoseconds beyond its
    /// profile. Repeatable.
    #[arg(long, value_name = "HEAD:NS", value_parser = parse_projector_lag)]
    projector_lag: Vec<(u8, u64)>,
    /// Fault: random bit flips on both directions, per million bytes.
    #[arg(long, default_value_t = 0)]
    flip_ppm: u32,
    /// Fault: random byte drops on both directions, per million bytes.
    #[arg(long, default_value_t = 0)]
    drop_ppm: u32,
    /// Trigger outputs and feedback inputs the board has, each (two of each
    /// per head): 4 is the STM32G474 board (2 heads); 6 or 8 simulate a
    /// board for 3 or 4 heads (issue 21).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(2..=protocol::limits::MAX_OUTPUT_CHANNELS as i64))]
    lines: u8,
}

fn parse_missed_trigger(text: &str) -> Result<MissedTrigger, String> {
    let (head, index) = text
        .split_once(':')
        .ok_or_else(|| format!("expected HEAD:INDEX, got {text:?}"))?;
    Ok(MissedTrigger {
        camera: head.parse().map_err(|e| format!("head {head:?}: {e}"))?,
        trigger_index: index.parse().map_err(|e| format!("index {index:?}: {e}"))?,
    })
}

fn parse_projector_lag(text: &str) -> Result<(u8, u64), String> {
    let (head, lag) = text
        .split_once(':')
        .ok_or_else(|| format!("expected HEAD:NS, got {text:?}"))?;
    Ok((
        head.parse().map_err(|e| format!("head {head:?}: {e}"))?,
        lag.parse().map_err(|e| format!("lag {lag:?}: {e}"))?,
    ))
}

impl Args {
    fn faults(&self) -> FaultPlan {
        let noise = (self.flip_ppm > 0 || self.drop_ppm > 0).then_some(Noise {
            drop_ppm: self.drop_ppm,
            flip_ppm: self.flip_ppm,
            seed: self.seed,
        });
        FaultPlan {
            to_board: StreamFaults {
                noise,
                ..StreamFaults::default()
            },
            to_host: StreamFaults {
                noise: noise.map(|n| Noise {
                    seed: n.seed.wrapping_add(1),
                    ..n
                }),
                silent_after_frames: self.silent_after_frames,
                ..StreamFaults::default()
            },
            missed_triggers: self.miss_trigger.iter().copied().collect(),
            vanish_at_tick: self.vanish_at_tick,
            projector_lag_ns: self.projector_lag.iter().copied().collect(),
        }
    }
}

/// Runs `hil-sim serve`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = SimBoardConfig {
        seed: args.seed,
        faults: args.faults(),
    };
    let limits = BoardLimits {
        output_channels: args.lines,
        feedback_channels: args.lines,
        ..BoardLimits::STM32G474
    };
    let board = spawn_board_on_pty(SimBoard::with_limits(config, limits))
        .context("starting the simulated board")?;
    let path = board
        .path()
        .context("the simulated board has no pty path")?
        .to_path_buf();
    let mut stdout = std::io::stdout();
    writeln!(stdout, "{}", path.display())?;
    stdout.flush()?;
    tracing::info!(
        "simulated sync board on {}; try `slscan board info --port {}`; Ctrl-C stops it",
        path.display(),
        path.display()
    );
    while !board.is_finished() {
        std::thread::sleep(Duration::from_millis(200));
    }
    board.stop().context("the simulated board stopped")?;
    Ok(())
}
