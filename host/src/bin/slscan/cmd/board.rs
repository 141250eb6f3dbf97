//! `slscan board`: talk to the sync board on a serial port, or to a simulated
//! board that `--sim` starts on a pseudo-terminal (the same serial client
//! either way).

use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{bail, Context};
use protocol::{DeviceInfo, Event, ScanState};
use slscan::board::plan_file::load_plan;
use slscan::board::transport::DEFAULT_BAUD;
use slscan::board::{BoardClient, ClientConfig, ScanOutcome, SerialTransport};

/// Options of `slscan board`.
#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: BoardCommand,
}

#[derive(clap::Subcommand)]
enum BoardCommand {
    /// Handshake and print what the board is and can do.
    Info(InfoArgs),
    /// Upload a plan (JSON ScanPlan), run it, stream the board's events.
    RunPlan(RunPlanArgs),
    /// Stop whatever the board is running (all trigger outputs to idle).
    Abort(InfoArgs),
}

#[derive(clap::Args)]
struct InfoArgs {
    #[command(flatten)]
    connection: Connection,
}

#[derive(clap::Args)]
struct RunPlanArgs {
    /// The plan, a JSON `ScanPlan` (examples in host/examples/plans/).
    plan: PathBuf,
    /// Delay from the board receiving `Start` to the first cycle, in microseconds.
    #[arg(long, default_value_t = 1_000)]
    start_delay_us: u32,
    #[command(flatten)]
    connection: Connection,
}

/// Where the board is and how patient to be with it.
#[derive(clap::Args)]
struct Connection {
    /// Serial port of the sync board, e.g. /dev/ttyACM0.
    #[arg(long, required_unless_present = "sim", conflicts_with = "sim")]
    port: Option<PathBuf>,
    /// Start a simulated board (hil-sim) on a pseudo-terminal and talk to it
    /// through that path.
    #[arg(long)]
    sim: bool,
    /// Seed of the simulated devices' jitter (with --sim).
    #[arg(long, default_value_t = 1, requires = "sim")]
    sim_seed: u64,
    /// How long one attempt waits for an answer, in milliseconds.
    #[arg(long, default_value_t = 500)]
    timeout_ms: u64,
    /// Attempts per request before giving up.
    #[arg(long, default_value_t = 3)]
    attempts: u32,
    /// Baud rate (ignored by USB CDC-ACM boards and ptys).
    #[arg(long, default_value_t = DEFAULT_BAUD)]
    baud: u32,
}

/// Runs `slscan board`. Output goes to stdout; a closed pipe (`| head`)
/// ends the command quietly.
pub fn run(args: Args) -> anyhow::Result<()> {
    match run_command(args) {
        Err(err)
            if err
                .downcast_ref::<std::io::Error>()
                .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe) =>
        {
            Ok(())
        }
        other => other,
    }
}

fn run_command(args: Args) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    match args.command {
        BoardCommand::Info(args) => with_board(&args.connection, |client, info| {
            print_info(&mut out, info)?;
            let status = client.status().context("reading the board status")?;
            writeln!(
                out,
                "state           {:?} at tick {}",
                status.state, status.now_tick
            )?;
            Ok(())
        }),
        BoardCommand::Abort(args) => with_board(&args.connection, |client, _info| {
            let report = client.abort().context("aborting")?;
            let status = client.status().context("reading the board status")?;
            writeln!(
                out,
                "state           {:?} at tick {}",
                status.state, status.now_tick
            )?;
            writeln!(
                out,
                "last scan       {} cycles planned, {} feedback edges checked",
                report.cycles, report.expected
            )?;
            Ok(())
        }),
        BoardCommand::RunPlan(args) => {
            let plan = load_plan(&args.plan)?;
            let delay_ns = args.start_delay_us.saturating_mul(1_000);
            with_board(&args.connection, |client, info| {
                let hz = info.limits.timer_clock_hz;
                let mut printed = Ok(());
                let outcome = client
                    .run_plan(&plan, delay_ns, |event| {
                        if printed.is_ok() {
                            printed = print_event(&mut out, event, hz);
                        }
                    })
                    .with_context(|| format!("running plan {}", args.plan.display()))?;
                printed?;
                print_outcome(&mut out, &outcome, hz)?;
                check_outcome(&outcome)
            })
        }
    }
}

#[cfg(feature = "sim")]
type SimulatedBoard = slscan::sim::board::PtyBoard;
#[cfg(not(feature = "sim"))]
type SimulatedBoard = std::convert::Infallible;

/// Starts a simulated board on a pseudo-terminal: the board and its path.
#[cfg(feature = "sim")]
fn start_simulated_board(seed: u64) -> anyhow::Result<(SimulatedBoard, PathBuf)> {
    let board = slscan::sim::board::PtyBoard::start(seed)
        .context("starting the simulated board on a pseudo-terminal")?;
    let Some(path) = board.path().map(std::path::Path::to_path_buf) else {
        bail!("the simulated board has no pty path");
    };
    Ok((board, path))
}

#[cfg(not(feature = "sim"))]
fn start_simulated_board(_seed: u64) -> anyhow::Result<(SimulatedBoard, PathBuf)> {
    Err(super::no_simulator("board --sim"))
}

/// Connects (starting the simulated board first with `--sim`), shakes hands
/// and hands the client to `job`.
fn with_board(
    connection: &Connection,
    job: impl FnOnce(&mut BoardClient<SerialTransport>, &DeviceInfo) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let config = ClientConfig {
        attempt_timeout: Duration::from_millis(connection.timeout_ms.max(1)),
        attempts: connection.attempts.max(1),
    };
    // Held until the job ends (dropped after the client, declared before
    // it): dropping it stops the simulated board.
    let mut _simulated = None;
    let path: PathBuf = match (&connection.port, connection.sim) {
        (Some(port), _) => port.clone(),
        (None, true) => {
            let (board, path) = start_simulated_board(connection.sim_seed)?;
            _simulated = Some(board);
            eprintln!("slscan: simulated board on {}", path.display());
            path
        }
        (None, false) => bail!("say where the board is: --port PATH or --sim"),
    };
    let transport = SerialTransport::open(&path, connection.baud)?;
    let (mut client, info) = BoardClient::connect(transport, config)
        .with_context(|| format!("handshake with the board on {}", path.display()))?;
    let result = job(&mut client, &info);
    drop(client);
    result
}

fn print_info(out: &mut impl Write, info: &DeviceInfo) -> std::io::Result<()> {
    let v = info.firmware_version;
    let l = info.limits;
    writeln!(out, "protocol        {}", info.protocol_version)?;
    writeln!(out, "firmware        {}.{}.{}", v.major, v.minor, v.patch)?;
    writeln!(out, "board id        {:#018x}", info.board_id)?;
    writeln!(out, "reset cause     {:?}", info.reset_cause)?;
    writeln!(
        out,
        "timer clock     {} MHz ({:.3} ns per tick)",
        l.timer_clock_hz as f64 / 1e6,
        1e9 / l.timer_clock_hz as f64
    )?;
    writeln!(
        out,
        "channels        {} trigger outputs, {} feedback inputs",
        l.output_channels, l.feedback_channels
    )?;
    writeln!(
        out,
        "heads           {} (a projector and a camera trigger, two feedback lines each)",
        l.max_heads()
    )?;
    writeln!(
        out,
        "capacity        {} exposures, {} pattern slots per cycle, {} repeats, frames <= {} B",
        l.max_exposures, l.max_slots_per_cycle, l.max_repeat_count, l.max_frame_bytes
    )?;
    writeln!(out, "edge spacing    >= {} ticks", l.min_edge_spacing_ticks)?;
    Ok(())
}

/// Board ticks as microseconds, for people.
fn ticks_us(ticks: u64, hz: u32) -> f64 {
    ticks as f64 * 1e6 / hz.max(1) as f64
}

/// One line per event. Events this version does not know in detail (the
/// protocol may add some) are printed as they are.
fn print_event(out: &mut impl Write, event: &Event, hz: u32) -> std::io::Result<()> {
    if let Event::ScanFinished { state, .. } = event {
        return writeln!(out, "event  scan finished: {state:?}");
    }
    match *event {
        Event::StateChanged { state, tick } => {
            writeln!(out, "event  tick {tick:>14}  state -> {state:?}")
        }
        Event::FeedbackLate {
            feedback_channel: ch,
            level,
            cycle,
            expected_tick,
            measured_tick,
        } => {
            let error_us = (measured_tick as f64 - expected_tick as f64) * 1e6 / hz.max(1) as f64;
            writeln!(
                out,
                "event  tick {measured_tick:>14}  feedback {ch} {level:?} LATE in cycle {cycle}: \
                 {error_us:+.3} us"
            )
        }
        Event::FeedbackMissing {
            feedback_channel: ch,
            level,
            cycle,
            expected_tick,
        } => writeln!(
            out,
            "event  tick {expected_tick:>14}  feedback {ch} {level:?} MISSING in cycle {cycle}"
        ),
        Event::FeedbackUnexpected {
            feedback_channel: ch,
            level,
            measured_tick,
        } => writeln!(
            out,
            "event  tick {measured_tick:>14}  feedback {ch} {level:?} UNEXPECTED"
        ),
        Event::PatternOutsideExposure {
            head,
            cycle,
            exposure,
            slot,
            light_ticks: (light_on, light_off),
            exposure_ticks: (open, close),
        } => writeln!(
            out,
            "event  tick {light_on:>14}  head {head} cycle {cycle} exposure {exposure} slot {slot}: \
             light {light_on}..{light_off} OUTSIDE exposure {open}..{close}"
        ),
        ref other => writeln!(out, "event  {other:?}"),
    }
}

fn print_outcome(out: &mut impl Write, outcome: &ScanOutcome, hz: u32) -> std::io::Result<()> {
    let s = outcome.summary;
    let r = outcome.report;
    writeln!(
        out,
        "plan            {} edges per cycle, period {} ticks ({:.3} us), {} cycles",
        s.edges_per_cycle,
        s.period_ticks,
        ticks_us(s.period_ticks as u64, hz),
        s.repeat_count
    )?;
    writeln!(out, "started         tick {}", outcome.start_tick)?;
    writeln!(out, "ended           {:?}", outcome.state)?;
    writeln!(
        out,
        "feedback        {} expected, {} on time, {} late, {} missing, {} unexpected; \
         worst error {} ticks ({:.3} us)",
        r.expected,
        r.on_time,
        r.late,
        r.missing,
        r.unexpected,
        r.worst_error_ticks,
        ticks_us(r.worst_error_ticks as u64, hz)
    )?;
    writeln!(
        out,
        "patterns        {} checked inside their exposure by the board, {} outside, {} unchecked",
        r.patterns_checked - r.out_of_window.min(r.patterns_checked),
        r.out_of_window,
        r.patterns_unchecked
    )?;
    if r.events_dropped > 0 {
        writeln!(
            out,
            "events dropped  {} (counters stay exact)",
            r.events_dropped
        )?;
    }
    Ok(())
}

/// A scan that did not finish, or whose feedback deviated, is a failure.
fn check_outcome(outcome: &ScanOutcome) -> anyhow::Result<()> {
    let r = outcome.report;
    if outcome.state != ScanState::Done {
        bail!("the scan ended {:?}, not Done", outcome.state);
    }
    if r.out_of_window > 0 {
        bail!(
            "{} of {} patterns were lit outside their camera exposure",
            r.out_of_window,
            r.patterns_checked
        );
    }
    if r.late + r.missing + r.unexpected > 0 {
        bail!(
            "the scan finished with {} late, {} missing and {} unexpected feedback edges",
            r.late,
            r.missing,
            r.unexpected
        );
    }
    Ok(())
}
