//! Board client errors: "the link failed" kept apart from "the board refused".

use std::path::PathBuf;

use protocol::{FrameError, Response, ScanReport, ScanState, WireError};

/// The link to the board failed: the request may or may not have reached it.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The serial port could not be opened (absent, busy, no permission).
    #[error("could not open serial port {path}")]
    Open {
        /// The port path, e.g. `/dev/ttyACM0`.
        path: PathBuf,
        /// Why.
        source: serialport::Error,
    },
    /// The port failed while reading or writing (unplugged, closed by the board).
    #[error("serial port failed during {operation}")]
    PortGone {
        /// `"read"` or `"write"`.
        operation: &'static str,
        /// The OS error.
        source: std::io::Error,
    },
    /// No answer to a request, even after retries.
    #[error(
        "no answer to {request} (id {id}) after {attempts} attempts, {waited_ms} ms \
         ({corrupt_frames} corrupt frames received meanwhile)"
    )]
    Timeout {
        /// The request's name.
        request: &'static str,
        /// Its id (the same in every attempt).
        id: u32,
        /// Attempts made.
        attempts: u32,
        /// Host time spent waiting, in milliseconds.
        waited_ms: u64,
        /// Unreadable frames received while waiting.
        corrupt_frames: u32,
    },
    /// The board kept reporting our request frames as unreadable.
    #[error("board could not read {request} (id {id}) in {attempts} attempts: {error}")]
    Unreadable {
        /// The request's name.
        request: &'static str,
        /// Its id.
        id: u32,
        /// Attempts made.
        attempts: u32,
        /// The board's last complaint.
        error: WireError,
    },
    /// No event arrived in time while a scan was expected to report.
    #[error("no event from the board in {waited_ms} ms")]
    EventTimeout {
        /// Host time spent waiting, in milliseconds.
        waited_ms: u64,
    },
    /// A request could not be encoded (a bug: every request fits a frame).
    #[error("could not encode {request}: {error}")]
    Encode {
        /// The request's name.
        request: &'static str,
        /// Why.
        error: FrameError,
    },
}

/// Anything the board client can fail with.
#[derive(Debug, thiserror::Error)]
pub enum BoardError {
    /// The link failed (timeout, port gone, unreadable frames).
    #[error("link to the board failed")]
    Link(#[from] LinkError),
    /// The plan has more heads than the connected board reported lines for
    /// (`DeviceInfo::limits`); nothing was sent. Checked on the host because
    /// a board built for fewer heads cannot even decode such a plan's header
    /// and would answer with a bare decode error.
    #[error("plan not sent: {0}")]
    PlanExceedsBoard(protocol::PlanError),
    /// The board answered and refused the request.
    #[error("board refused {request} (id {id}): {error}")]
    Refused {
        /// The request's name.
        request: &'static str,
        /// Its id.
        id: u32,
        /// The board's reason, with its values.
        error: WireError,
    },
    /// The board answered with a response that does not belong to the request
    /// (a protocol mismatch between host and firmware).
    #[error("board answered {request} (id {id}) with unexpected {response:?}")]
    UnexpectedResponse {
        /// The request's name.
        request: &'static str,
        /// Its id.
        id: u32,
        /// What came back.
        response: Box<Response>,
    },
    /// The board still reports the scan running well past its planned end.
    #[error("scan still {state:?} at board tick {now_tick}, planned to end at tick {end_tick}")]
    ScanOverran {
        /// The state the board reports.
        state: ScanState,
        /// The board's clock.
        now_tick: u64,
        /// The planned end.
        end_tick: u64,
    },
    /// The scan ended other than `Done`.
    #[error("scan ended {state:?}: {report:?}")]
    ScanNotDone {
        /// The final state (aborted or faulted).
        state: ScanState,
        /// The board's counters.
        report: ScanReport,
    },
}

impl BoardError {
    /// True when the link failed (as opposed to the board refusing).
    pub fn is_link_failure(&self) -> bool {
        matches!(self, BoardError::Link(_))
    }
}
