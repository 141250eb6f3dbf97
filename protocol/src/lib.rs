//! The wire contract shared by the sync board and the host.
//!
//! ```text
//!  host                                              board (STM32 or hil-sim)
//!  HostFrame { id, Request } --postcard-CRC-COBS-->  FrameAccumulator -> dispatch
//!  BoardFrame::Response { id, .. }  <--------------  answer to each request
//!  BoardFrame::Event(..)            <--------------  feedback checks, scan end
//!  BoardFrame::LinkError(..)        <--------------  a frame was unreadable
//! ```
//!
//! - [`messages`]: every request, response and event, one table.
//! - [`framing`]: COBS + CRC-32 frames and the resynchronising accumulator.
//! - [`plan`]: `ScanPlan -> validate(&BoardLimits) -> ValidPlan`, examples.
//! - [`limits`]: capacities, board limits, device timing profiles, tick
//!   conversion.
//! - [`error`]: errors that cross the wire.
//!
//! Why not postcard-rpc: its typed endpoints fit, but the board side must be
//! one synchronous, allocation-free dispatch (bytes in, frames out) that the
//! STM32's USB task, hil-sim's virtual-clock board and the fuzz targets all
//! call the same way, and every frame needs an end-to-end CRC over a UART-like
//! pty; postcard-rpc's server is tied to its async transports and its COBS
//! frames carry no CRC. So we keep its shape (one shared wire crate, request
//! ids, typed errors) on plain postcard + COBS + CRC-32.
//!
//! `no_std`, no allocation: every collection is a `heapless` container whose
//! capacity is a constant in [`limits`].
#![cfg_attr(not(feature = "std"), no_std)]
#![warn(missing_docs)]

pub mod error;
pub mod framing;
pub mod limits;
pub mod messages;
pub mod plan;
pub mod state;

pub use error::{FrameError, HardwareFault, WireError};
pub use framing::{decode_payload, encode_frame, FrameAccumulator};
pub use limits::{
    BoardLimits, CameraModel, ControllerLimitError, ControllerLimits, ProjectorModel,
};
pub use messages::{
    BoardFrame, BoardStatus, DeviceInfo, Event, FirmwareVersion, HostFrame, Level, PlanSummary,
    Request, RequestId, ResetCause, Response, ScanReport, ScanState, PROTOCOL_VERSION,
};
pub use plan::{
    CapacityError, Exposure, ExposureEntry, HeadConfig, HeadSet, PatternSlot, PlanError,
    PlanHeader, ScanPlan, ValidPlan,
};
