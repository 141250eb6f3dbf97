//! The board sequencer's states: what a status reply, a state-change event
//! and a wrong-state error all report.

use serde::{Deserialize, Serialize};

/// Sequencer states.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ScanState {
    /// No scan loaded into the timers.
    Idle,
    /// Edge table loaded, waiting for `Start`.
    Armed,
    /// Edges are being emitted.
    Running,
    /// All cycles ran and all feedback was checked.
    Done,
    /// Stopped by `Abort`.
    Aborted,
    /// Stopped by a hardware fault.
    Faulted,
}
