//! Errors that cross the wire: serialisable, each carrying its offending
//! values, so the host can say exactly what the board refused.

use serde::{Deserialize, Serialize};

use crate::messages::ScanState;
use crate::plan::CapacityError;

/// Why a plan was refused. Indices are positions in the plan's cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum PlanError {
    /// The plan has no heads.
    NoHeads,
    /// The plan has no exposures.
    NoExposures,
    /// A head names a channel the board does not have.
    ChannelOutOfRange {
        /// Head index (0 = A).
        head: u8,
        /// The channel named.
        channel: u8,
        /// Channels the board has of that kind.
        available: u8,
    },
    /// Two heads (or a head's projector and camera) share an output or
    /// feedback channel.
    ChannelReused {
        /// The channel named twice.
        channel: u8,
    },
    /// `repeat_count` is 0 or above the board's maximum.
    RepeatCountOutOfRange {
        /// The requested count.
        count: u32,
        /// The board's maximum.
        max: u32,
    },
    /// The repeat period is zero or does not fit the 32-bit timer.
    PeriodOutOfRange {
        /// The requested period.
        period_ns: u32,
    },
    /// More exposures than the board holds.
    TooManyExposures {
        /// Exposures in the plan.
        count: u16,
        /// The board's maximum.
        max: u16,
    },
    /// More pattern slots than the board holds.
    TooManySlots {
        /// Slots in the plan.
        count: u16,
        /// The board's maximum.
        max: u16,
    },
    /// An exposure's slot range lies outside the plan's slot list.
    SlotRangeInvalid {
        /// Exposure index.
        exposure: u16,
    },
    /// An exposure names no head, or a head the plan does not have.
    UnknownHead {
        /// Exposure index.
        exposure: u16,
        /// The head mask.
        heads: u8,
    },
    /// Exposures are not listed in order of start time.
    ExposuresOutOfOrder {
        /// Index of the exposure that starts before its predecessor.
        exposure: u16,
    },
    /// An exposure is shorter than its camera allows.
    ExposureTooShort {
        /// Exposure index.
        exposure: u16,
        /// Requested exposure time.
        duration_ns: u32,
        /// The camera's minimum.
        min_ns: u32,
    },
    /// An exposure (or a projector trigger pulse in it) does not end before
    /// the cycle's repeat period, counted in timer ticks.
    ExposureBeyondPeriod {
        /// Exposure index.
        exposure: u16,
        /// End of the exposure from the cycle start.
        end_ns: u64,
        /// The repeat period.
        period_ns: u32,
    },
    /// Two exposures of one camera overlap or come faster than its frame
    /// rate (also across the cycle wrap when the plan repeats).
    OverlappingExposures {
        /// Head index.
        head: u8,
        /// The earlier exposure.
        first: u16,
        /// The later exposure.
        second: u16,
    },
    /// A pattern is shown shorter than, or triggered sooner after the
    /// previous one than, the DMD's minimum pattern period.
    PatternPeriodTooShort {
        /// Exposure index.
        exposure: u16,
        /// Slot index within the exposure.
        slot: u16,
        /// Requested display time or trigger spacing, whichever is short.
        period_ns: u64,
        /// The projector's minimum.
        min_ns: u32,
    },
    /// A pattern's slot starts before the previous pattern's display ended.
    SlotsOverlap {
        /// Exposure index.
        exposure: u16,
        /// Slot index within the exposure.
        slot: u16,
    },
    /// A pattern's light (after latency, +-jitter) is not inside its
    /// exposure (after latency, +-jitter) with the plan's margin.
    PatternOutsideExposure {
        /// Exposure index.
        exposure: u16,
        /// Slot index within the exposure.
        slot: u16,
        /// Head index.
        head: u8,
    },
}

impl core::fmt::Display for PlanError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        // The Debug form carries every offending value with its unit.
        write!(f, "invalid scan plan: {self:?}")
    }
}

/// A frame could not be read or written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum FrameError {
    /// More bytes arrived before a `0x00` delimiter than a frame may hold;
    /// they were dropped up to the next delimiter.
    Oversized {
        /// The frame limit in bytes.
        limit: u16,
    },
    /// The bytes between two delimiters are not valid COBS.
    Cobs,
    /// The decoded frame is shorter than its CRC.
    TooShort {
        /// Decoded length in bytes.
        len: u16,
    },
    /// The CRC-32 trailer does not match the payload.
    CrcMismatch {
        /// CRC carried by the frame.
        received: u32,
        /// CRC computed over the payload.
        computed: u32,
    },
    /// The payload is not a valid postcard message of the expected type.
    Deserialize,
    /// The message does not fit in [`crate::limits::MAX_PAYLOAD_BYTES`].
    PayloadTooLarge,
    /// The output buffer is too small for the encoded frame.
    OutputTooSmall {
        /// Bytes needed at most.
        needed: u16,
    },
}

/// A fault reported by the trigger hardware.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum HardwareFault {
    /// The edge table has more edges than the hardware's buffers.
    TableTooLarge {
        /// Edges in the table.
        edges: u16,
        /// Edges the hardware holds.
        capacity: u16,
    },
    /// The table names a channel the hardware does not drive.
    ChannelUnavailable {
        /// The channel.
        channel: u8,
    },
    /// `start` was asked for a tick that has already passed.
    StartInPast {
        /// The requested start tick.
        start_tick: u64,
        /// The timer when asked.
        now_tick: u64,
    },
    /// Input captures were lost because their buffer overflowed.
    CaptureOverflow {
        /// Captures lost.
        lost: u32,
    },
    /// The timer or its DMA missed a compare (an edge came out late or not
    /// at all).
    EdgeUnderrun {
        /// Output channel.
        channel: u8,
    },
    /// Nothing is loaded to start.
    NotLoaded,
    /// The host link (USB) went away mid-scan; the board stopped the scan.
    HostLinkLost,
}

/// Why the board refused a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum WireError {
    /// A frame was unreadable (sent unsolicited as `BoardFrame::LinkError`).
    Frame(FrameError),
    /// The host speaks another protocol version.
    UnsupportedVersion {
        /// The board's version.
        board: u16,
        /// The host's version.
        host: u16,
    },
    /// The plan failed validation.
    Plan(PlanError),
    /// The plan overflowed a fixed capacity while being uploaded.
    Capacity(CapacityError),
    /// `AddExposure` or `CommitPlan` came without a `BeginPlan`.
    NoPlanBegun,
    /// An exposure arrived out of sequence.
    ExposureOutOfSequence {
        /// The index the board expected next.
        expected: u16,
        /// The index received.
        received: u16,
    },
    /// `CommitPlan` came before all announced exposures.
    PlanIncomplete {
        /// Exposures announced in the header.
        announced: u16,
        /// Exposures received.
        received: u16,
    },
    /// `Arm` came without a committed plan.
    NoPlan,
    /// The request is not allowed in the sequencer's current state.
    BadState {
        /// The state the sequencer is in.
        state: ScanState,
    },
    /// The trigger hardware refused or faulted.
    Hardware(HardwareFault),
    /// Two edges of one output channel (or a channel's first edge and the
    /// cycle start, or its last edge and the next cycle's first) are closer
    /// than `BoardLimits::min_edge_spacing_ticks`.
    EdgesTooClose {
        /// Output channel.
        channel: u8,
        /// Tick (within the cycle) of the later edge.
        tick: u32,
        /// Ticks between the two.
        spacing_ticks: u32,
        /// The board's minimum.
        min_ticks: u32,
    },
    /// The compiled edge table did not fit or had colliding edges.
    EdgeTable {
        /// Output channel concerned.
        channel: u8,
        /// Tick within the cycle.
        tick: u32,
    },
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "bad frame: {self:?}")
    }
}

impl core::fmt::Display for WireError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            WireError::Frame(e) => write!(f, "{e}"),
            WireError::Plan(e) => write!(f, "{e}"),
            WireError::Capacity(e) => write!(f, "plan too large: {e}"),
            other => write!(f, "board refused: {other:?}"),
        }
    }
}

impl From<FrameError> for WireError {
    fn from(e: FrameError) -> Self {
        WireError::Frame(e)
    }
}
impl From<PlanError> for WireError {
    fn from(e: PlanError) -> Self {
        WireError::Plan(e)
    }
}
impl From<CapacityError> for WireError {
    fn from(e: CapacityError) -> Self {
        WireError::Capacity(e)
    }
}
impl From<HardwareFault> for WireError {
    fn from(e: HardwareFault) -> Self {
        WireError::Hardware(e)
    }
}

#[cfg(feature = "std")]
impl std::error::Error for FrameError {}
#[cfg(feature = "std")]
impl std::error::Error for WireError {}
#[cfg(feature = "std")]
impl std::error::Error for PlanError {}
#[cfg(feature = "std")]
impl std::error::Error for CapacityError {}
