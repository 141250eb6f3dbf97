//! Every message on the wire, in one table.
//!
//! | host -> board (`HostFrame { id, request }`) | board -> host (`BoardFrame::Response { id, .. }`) |
//! |---|---|
//! | `Hello { protocol_version }` | `Hello(DeviceInfo)` or `Refused(UnsupportedVersion)` |
//! | `GetInfo` | `Info(DeviceInfo)` |
//! | `BeginPlan(PlanHeader)` | `PlanBegun` |
//! | `AddExposure { index, exposure }` (one per exposure) | `ExposureAdded { index }` |
//! | `CommitPlan` (validates, compiles) | `PlanCommitted(PlanSummary)` |
//! | `Arm` (loads the edge table into the timers) | `Armed` |
//! | `Start { delay_ns }` | `Started { start_tick }`, then events |
//! | `Abort` | `Aborted(ScanReport)` |
//! | `GetStatus` | `Status(BoardStatus)` |
//! | `Ping { nonce }` | `Pong { nonce }` |
//!
//! Any request may instead get `Refused(WireError)`. Unsolicited:
//! `BoardFrame::Event(Event)` (feedback checks, state changes, the final
//! report) and `BoardFrame::LinkError(WireError::Frame(..))` when a frame was
//! unreadable (its request id is unknown, so the host fails the request it
//! is waiting on).

use serde::{Deserialize, Serialize};

use crate::error::{HardwareFault, WireError};
use crate::limits::BoardLimits;
use crate::plan::{Exposure, PlanHeader};
pub use crate::state::ScanState;

/// Version of this wire contract; bumped on any incompatible change.
pub const PROTOCOL_VERSION: u16 = 1;

/// Identifies a request; the board echoes it in the response.
pub type RequestId = u32;

/// Logic level of a trigger or feedback line (lines are active high; idle
/// is `Low`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Level {
    /// Low (idle).
    Low,
    /// High (active).
    High,
}

/// A frame from the host.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct HostFrame {
    /// Chosen by the host, echoed in the response.
    pub id: RequestId,
    /// The request.
    pub request: Request,
}

/// Host -> board requests.
// No allocator on the board: the exposure chunk is inline (~400 bytes), and
// requests are handled one at a time, so the size is paid once.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum Request {
    /// Handshake: the host's protocol version.
    Hello {
        /// [`PROTOCOL_VERSION`] of the host.
        protocol_version: u16,
    },
    /// Ask for the device info again.
    GetInfo,
    /// Start uploading a plan (discards any plan being uploaded).
    BeginPlan(PlanHeader),
    /// One exposure of the plan being uploaded, in order from 0.
    AddExposure {
        /// Position of the exposure in the cycle.
        index: u16,
        /// The exposure with its slots.
        exposure: Exposure,
    },
    /// Validate and compile the uploaded plan.
    CommitPlan,
    /// Load the compiled edge table into the timers.
    Arm,
    /// Start the armed scan `delay_ns` from now (board time), or after
    /// `BoardLimits::min_start_delay_ticks` if that is later.
    Start {
        /// Delay before the first cycle.
        delay_ns: u32,
    },
    /// Stop now: all outputs to idle.
    Abort,
    /// Ask for the sequencer's state and counters.
    GetStatus,
    /// Liveness check.
    Ping {
        /// Echoed back.
        nonce: u32,
    },
}

/// Firmware version (semantic).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct FirmwareVersion {
    /// Major.
    pub major: u16,
    /// Minor.
    pub minor: u16,
    /// Patch.
    pub patch: u16,
}

/// What the board is and can do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeviceInfo {
    /// The board's [`PROTOCOL_VERSION`].
    pub protocol_version: u16,
    /// Firmware version.
    pub firmware_version: FirmwareVersion,
    /// Unique board id (MCU unique id hash; fixed per simulated board).
    pub board_id: u64,
    /// Timer clock, channel counts and capacities.
    pub limits: BoardLimits,
    /// Why the board last (re)started.
    pub reset_cause: ResetCause,
}

/// Why the board last started.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ResetCause {
    /// Power-on or reset pin.
    PowerOn,
    /// The independent watchdog fired (firmware hung).
    Watchdog,
    /// Software reset (after a firmware update, say).
    Software,
    /// A simulated board (hil-sim).
    Simulated,
}

/// The compiled plan, as the board sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlanSummary {
    /// Edges in one cycle.
    pub edges_per_cycle: u16,
    /// Cycle length in timer ticks.
    pub period_ticks: u32,
    /// Number of cycles.
    pub repeat_count: u32,
}

/// Counters of a scan's feedback check.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct ScanReport {
    /// Cycles the scan was set to run.
    pub cycles: u32,
    /// Feedback edges expected so far.
    pub expected: u32,
    /// Feedback edges within tolerance.
    pub on_time: u32,
    /// Feedback edges outside tolerance (early or late) but attributable.
    pub late: u32,
    /// Expected feedback edges that never came.
    pub missing: u32,
    /// Feedback edges that matched nothing.
    pub unexpected: u32,
    /// Largest |measured - expected| of attributed edges, in timer ticks.
    pub worst_error_ticks: u32,
    /// Events that did not fit the event queue (counters stay exact).
    pub events_dropped: u32,
    /// Patterns whose measured light was compared with their measured
    /// exposure (both feedback lines seen).
    pub patterns_checked: u32,
    /// ... whose light was not entirely inside the exposure.
    pub out_of_window: u32,
    /// Patterns dropped unchecked because too many waited for their
    /// exposure's end.
    pub patterns_unchecked: u32,
}

/// State, time and counters of the board.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct BoardStatus {
    /// Sequencer state.
    pub state: ScanState,
    /// The board's timer now.
    pub now_tick: u64,
    /// Whether a compiled plan is held.
    pub plan_loaded: bool,
    /// The current or last scan's counters.
    pub report: ScanReport,
}

/// Board -> host responses.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum Response {
    /// Handshake accepted.
    Hello(DeviceInfo),
    /// Device info.
    Info(DeviceInfo),
    /// Plan upload started.
    PlanBegun,
    /// Exposure stored.
    ExposureAdded {
        /// Its index.
        index: u16,
    },
    /// Plan validated and compiled.
    PlanCommitted(PlanSummary),
    /// Edge table loaded.
    Armed,
    /// Scan started; the first cycle begins at `start_tick`.
    Started {
        /// Board timer tick of the cycle start.
        start_tick: u64,
    },
    /// Scan stopped; outputs idle.
    Aborted(ScanReport),
    /// Status.
    Status(BoardStatus),
    /// Liveness answer.
    Pong {
        /// The request's nonce.
        nonce: u32,
    },
    /// The request was refused.
    Refused(WireError),
}

/// Unsolicited board -> host notifications.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Event {
    /// The sequencer changed state.
    StateChanged {
        /// New state.
        state: ScanState,
        /// Board tick of the change.
        tick: u64,
    },
    /// A feedback edge came outside its device's jitter tolerance (late, or
    /// early when `measured_tick < expected_tick`).
    FeedbackLate {
        /// Feedback input.
        feedback_channel: u8,
        /// Edge level.
        level: Level,
        /// Cycle number.
        cycle: u32,
        /// Expected board tick.
        expected_tick: u64,
        /// Captured board tick.
        measured_tick: u64,
    },
    /// An expected feedback edge never came.
    FeedbackMissing {
        /// Feedback input.
        feedback_channel: u8,
        /// Edge level.
        level: Level,
        /// Cycle number.
        cycle: u32,
        /// Expected board tick.
        expected_tick: u64,
    },
    /// A feedback edge that matched no expected edge.
    FeedbackUnexpected {
        /// Feedback input.
        feedback_channel: u8,
        /// Edge level.
        level: Level,
        /// Captured board tick.
        measured_tick: u64,
    },
    /// A pattern's measured light (projector trigger-out rise + display
    /// time) was not entirely inside its measured exposure (camera
    /// exposure-active).
    PatternOutsideExposure {
        /// Head index (0 = A).
        head: u8,
        /// Cycle number.
        cycle: u32,
        /// Exposure index in the cycle.
        exposure: u16,
        /// Slot index in the plan's slot list.
        slot: u16,
        /// Measured light, board ticks (start, end).
        light_ticks: (u64, u64),
        /// Measured exposure, board ticks (start, end).
        exposure_ticks: (u64, u64),
    },
    /// The trigger hardware faulted; the scan stops (`ScanFinished` follows).
    HardwareFault {
        /// What the hardware reported.
        fault: HardwareFault,
        /// Board tick when it was seen.
        tick: u64,
    },
    /// The scan ended (done, aborted or faulted) with these counters.
    ScanFinished {
        /// Final state.
        state: ScanState,
        /// Counters.
        report: ScanReport,
    },
}

/// A frame from the board.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum BoardFrame {
    /// The answer to request `id`.
    Response {
        /// The request's id.
        id: RequestId,
        /// The answer.
        response: Response,
    },
    /// An unsolicited event.
    Event(Event),
    /// A frame from the host could not be read.
    LinkError(WireError),
}
