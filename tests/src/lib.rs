//! Helpers shared by the cross-crate integration tests in `tests/tests.rs`:
//! a simulated board on a real pseudo-terminal with the host's serial client
//! connected to it, and the trigger timeline a plan specifies, computed from
//! the plan alone (not from board-core's edge-table compiler) so the board's
//! recorded edges can be compared with it tick by tick.

use std::path::Path;
use std::time::Duration;

use hil_sim::board::{spawn_on_pty, SimBoardConfig, SimBoardHandle};
use hil_sim::pty::PtyError;
use hil_sim::sim_hardware::RecordedEdge;
use protocol::limits::ns_to_ticks;
use protocol::{DeviceInfo, Level, ScanPlan};
use slscan::board::{BoardClient, BoardError, ClientConfig, SerialTransport};

/// Timeouts for tests that expect answers: generous, so a loaded 2-core CI
/// machine never turns a slow answer into a failure.
pub const PATIENT: ClientConfig = ClientConfig {
    attempt_timeout: Duration::from_secs(2),
    attempts: 3,
};

/// Timeouts for tests that expect silence: short, so they end quickly.
pub const IMPATIENT: ClientConfig = ClientConfig {
    attempt_timeout: Duration::from_millis(200),
    attempts: 2,
};

/// A simulated board served on a pty, and the host's serial client
/// connected through the pty's path (handshake done).
pub struct PtyRig {
    /// The board (its thread, its logs).
    pub board: SimBoardHandle,
    /// The host client on `/dev/pts/N`.
    pub client: BoardClient<SerialTransport>,
    /// What the board said in the handshake.
    pub info: DeviceInfo,
}

/// Why a [`PtyRig`] could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum RigError {
    /// No pseudo-terminal for the board.
    #[error("simulated board")]
    Pty(#[from] PtyError),
    /// Opening the pty as a serial port, or the handshake, failed.
    #[error("host client")]
    Board(#[from] BoardError),
}

/// Starts a board with `config` on a pty and connects a client to it.
pub fn pty_rig(config: SimBoardConfig, client: ClientConfig) -> Result<PtyRig, RigError> {
    let board = spawn_on_pty(config)?;
    let path = board.path().unwrap_or(Path::new("")).to_path_buf();
    let transport = SerialTransport::open(&path, 115_200).map_err(BoardError::from)?;
    let (client, info) = BoardClient::connect(transport, client)?;
    Ok(PtyRig {
        board,
        client,
        info,
    })
}

/// A trigger output edge: board tick, channel, level after it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct TimedEdge {
    /// Board tick.
    pub tick: u64,
    /// Output channel.
    pub channel: u8,
    /// Level after the edge.
    pub level: Level,
}

impl From<&RecordedEdge> for TimedEdge {
    fn from(e: &RecordedEdge) -> Self {
        TimedEdge {
            tick: e.tick,
            channel: e.channel,
            level: e.level,
        }
    }
}

/// The trigger edges `plan` specifies when its first cycle starts at board
/// tick `start_tick`, sorted by (tick, channel, level).
///
/// The specification, from `protocol::plan`: the board's timer runs cycles
/// of `round(repeat_period_ns)` ticks; in each, every exposure raises the
/// camera trigger of each head it names from `start_ns` for `duration_ns`,
/// and that head's projector trigger for the projector's `trigger_pulse_ns`
/// at each slot's `offset_ns` after the exposure start; every in-cycle time
/// is rounded to the nearest tick once.
pub fn planned_edges(plan: &ScanPlan, start_tick: u64, timer_clock_hz: u32) -> Vec<TimedEdge> {
    let ticks = |ns: u64| ns_to_ticks(ns, timer_clock_hz);
    let period_ticks = ticks(plan.repeat_period_ns as u64);
    let mut edges = Vec::new();
    for cycle in 0..plan.repeat_count as u64 {
        let cycle_tick = start_tick + cycle * period_ticks;
        let mut pulse = |channel: u8, from_ns: u64, to_ns: u64| {
            edges.push(TimedEdge {
                tick: cycle_tick + ticks(from_ns),
                channel,
                level: Level::High,
            });
            edges.push(TimedEdge {
                tick: cycle_tick + ticks(to_ns),
                channel,
                level: Level::Low,
            });
        };
        for exposure in plan.exposures() {
            let e = exposure.entry;
            for (h, head) in plan.heads.iter().enumerate() {
                if !e.heads.contains(h) {
                    continue;
                }
                let start_ns = e.start_ns as u64;
                pulse(
                    head.camera_trigger_channel,
                    start_ns,
                    start_ns + e.duration_ns as u64,
                );
                let pulse_ns = head.projector.profile().trigger_pulse_ns as u64;
                for slot in exposure.slots {
                    let rise_ns = start_ns + slot.offset_ns as u64;
                    pulse(head.projector_trigger_channel, rise_ns, rise_ns + pulse_ns);
                }
            }
        }
    }
    edges.sort();
    edges
}

/// The recorded edges of a board, in the same order as [`planned_edges`].
pub fn recorded_edges(board: &SimBoardHandle) -> Vec<TimedEdge> {
    let mut edges: Vec<TimedEdge> = board
        .board()
        .hardware()
        .recorded()
        .iter()
        .map(TimedEdge::from)
        .collect();
    edges.sort();
    edges
}
