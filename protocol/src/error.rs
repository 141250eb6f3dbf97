//! Errors that cross the wire: serialisable, each carrying its offending
//! values, so the host can say exactly what the board refused.

use serde::{Deserialize, Serialize};

use crate::plan::CapacityError;
use crate::state::ScanState;

/// Why a plan was refused. Indices are positions in the plan's cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
pub enum PlanError {
    /// The plan has no heads.
    #[error("the plan has no heads")]
    NoHeads,
    /// The plan has no exposures.
    #[error("the plan has no exposures")]
    NoExposures,
    /// A head names a channel the board does not have.
    #[error("head {head} names channel {channel}, the board has {available}")]
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
    #[error("channel {channel} is used twice")]
    ChannelReused {
        /// The channel named twice.
        channel: u8,
    },
    /// `repeat_count` is 0 or above the board's maximum.
    #[error("repeat count {count} is outside 1..={max}")]
    RepeatCountOutOfRange {
        /// The requested count.
        count: u32,
        /// The board's maximum.
        max: u32,
    },
    /// The repeat period is zero or does not fit the 32-bit timer.
    #[error("repeat period {period_ns} ns is zero or too long for the 32-bit timer")]
    PeriodOutOfRange {
        /// The requested period.
        period_ns: u32,
    },
    /// More exposures than the board holds.
    #[error("{count} exposures, the board holds {max}")]
    TooManyExposures {
        /// Exposures in the plan.
        count: u16,
        /// The board's maximum.
        max: u16,
    },
    /// More pattern slots than the board holds.
    #[error("{count} pattern slots, the board holds {max}")]
    TooManySlots {
        /// Slots in the plan.
        count: u16,
        /// The board's maximum.
        max: u16,
    },
    /// An exposure's slot range lies outside the plan's slot list.
    #[error("exposure {exposure} names slots outside the plan")]
    SlotRangeInvalid {
        /// Exposure index.
        exposure: u16,
    },
    /// An exposure names no head, or a head the plan does not have.
    #[error("exposure {exposure} names heads {heads:#04b} the plan does not have")]
    UnknownHead {
        /// Exposure index.
        exposure: u16,
        /// The head mask.
        heads: u8,
    },
    /// Exposures are not listed in order of start time.
    #[error("exposure {exposure} starts before the one listed before it")]
    ExposuresOutOfOrder {
        /// Index of the exposure that starts before its predecessor.
        exposure: u16,
    },
    /// An exposure is shorter than its camera allows.
    #[error("exposure {exposure} lasts {duration_ns} ns, the camera needs {min_ns} ns")]
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
    #[error("exposure {exposure} ends at {end_ns} ns, not before the {period_ns} ns period")]
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
    #[error(
        "head {head}: exposures {first} and {second} overlap or come faster than the camera allows"
    )]
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
    #[error("exposure {exposure} slot {slot}: pattern period {period_ns} ns is below the DMD minimum {min_ns} ns")]
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
    #[error("exposure {exposure} slot {slot} starts before the previous pattern ends")]
    SlotsOverlap {
        /// Exposure index.
        exposure: u16,
        /// Slot index within the exposure.
        slot: u16,
    },
    /// A pattern's light (after latency, +-jitter) is not inside its
    /// exposure (after latency, +-jitter) with the plan's margin.
    #[error("exposure {exposure} slot {slot} head {head}: the pattern is not inside the exposure with the margin")]
    PatternOutsideExposure {
        /// Exposure index.
        exposure: u16,
        /// Slot index within the exposure.
        slot: u16,
        /// Head index.
        head: u8,
    },
    /// The plan has more heads than the board has lines for: each head needs
    /// two trigger outputs and two feedback inputs. Listed last so the
    /// variants before it keep their postcard index on the wire.
    #[error("the plan drives {heads} heads; this board has {output_channels} trigger lines and {feedback_channels} feedback lines (two of each per head), {max_heads} heads")]
    TooManyHeadsForBoard {
        /// Heads in the plan.
        heads: u8,
        /// The board's trigger outputs.
        output_channels: u8,
        /// The board's feedback inputs.
        feedback_channels: u8,
        /// Heads the board can drive (`BoardLimits::max_heads`).
        max_heads: u8,
    },
}

/// A frame could not be read or written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
pub enum FrameError {
    /// More bytes arrived before a `0x00` delimiter than a frame may hold;
    /// they were dropped up to the next delimiter.
    #[error("frame longer than {limit} bytes")]
    Oversized {
        /// The frame limit in bytes.
        limit: u16,
    },
    /// The bytes between two delimiters are not valid COBS.
    #[error("frame is not valid COBS")]
    Cobs,
    /// The decoded frame is shorter than its CRC.
    #[error("frame of {len} bytes is shorter than its CRC")]
    TooShort {
        /// Decoded length in bytes.
        len: u16,
    },
    /// The CRC-32 trailer does not match the payload.
    #[error("CRC mismatch: frame carries {received:#010x}, payload gives {computed:#010x}")]
    CrcMismatch {
        /// CRC carried by the frame.
        received: u32,
        /// CRC computed over the payload.
        computed: u32,
    },
    /// The payload is not a valid postcard message of the expected type.
    #[error("payload is not a valid message")]
    Deserialize,
    /// The message does not fit in [`crate::limits::MAX_PAYLOAD_BYTES`].
    #[error("message longer than one frame")]
    PayloadTooLarge,
    /// The output buffer is too small for the encoded frame.
    #[error("output buffer too small: {needed} bytes needed")]
    OutputTooSmall {
        /// Bytes needed at most.
        needed: u16,
    },
}

/// A fault reported by the trigger hardware.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
pub enum HardwareFault {
    /// The edge table has more edges than the hardware's buffers.
    #[error("edge table of {edges} edges, the hardware holds {capacity}")]
    TableTooLarge {
        /// Edges in the table.
        edges: u16,
        /// Edges the hardware holds.
        capacity: u16,
    },
    /// The table names a channel the hardware does not drive.
    #[error("the hardware does not drive channel {channel}")]
    ChannelUnavailable {
        /// The channel.
        channel: u8,
    },
    /// `start` was asked for a tick that has already passed.
    #[error("start tick {start_tick} is not after now ({now_tick})")]
    StartInPast {
        /// The requested start tick.
        start_tick: u64,
        /// The timer when asked.
        now_tick: u64,
    },
    /// Input captures were lost because their buffer overflowed.
    #[error("{lost} feedback captures lost")]
    CaptureOverflow {
        /// Captures lost.
        lost: u32,
    },
    /// The timer or its DMA missed a compare (an edge came out late or not
    /// at all).
    #[error("channel {channel}: the timer missed an edge")]
    EdgeUnderrun {
        /// Output channel.
        channel: u8,
    },
    /// Nothing is loaded to start.
    #[error("nothing loaded to start")]
    NotLoaded,
    /// The host link (USB) went away mid-scan; the board stopped the scan.
    #[error("the host link went away mid-scan")]
    HostLinkLost,
}

/// Why the board refused a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
pub enum WireError {
    /// A frame was unreadable (sent unsolicited as `BoardFrame::LinkError`).
    #[error(transparent)]
    Frame(#[from] FrameError),
    /// The host speaks another protocol version.
    #[error("board speaks protocol {board}, host {host}")]
    UnsupportedVersion {
        /// The board's version.
        board: u16,
        /// The host's version.
        host: u16,
    },
    /// The plan failed validation.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// The plan overflowed a fixed capacity while being uploaded.
    #[error(transparent)]
    Capacity(#[from] CapacityError),
    /// `AddExposure` or `CommitPlan` came without a `BeginPlan`.
    #[error("no plan upload begun")]
    NoPlanBegun,
    /// An exposure arrived out of sequence.
    #[error("exposure {received} arrived, {expected} was next")]
    ExposureOutOfSequence {
        /// The index the board expected next.
        expected: u16,
        /// The index received.
        received: u16,
    },
    /// `CommitPlan` came before all announced exposures.
    #[error("{received} of {announced} exposures uploaded")]
    PlanIncomplete {
        /// Exposures announced in the header.
        announced: u16,
        /// Exposures received.
        received: u16,
    },
    /// `Arm` came without a committed plan.
    #[error("no committed plan")]
    NoPlan,
    /// The request is not allowed in the sequencer's current state.
    #[error("not allowed while {state:?}")]
    BadState {
        /// The state the sequencer is in.
        state: ScanState,
    },
    /// The trigger hardware refused or faulted.
    #[error(transparent)]
    Hardware(#[from] HardwareFault),
    /// Two edges of one output channel (or a channel's first edge and the
    /// cycle start, or its last edge and the next cycle's first) are closer
    /// than `BoardLimits::min_edge_spacing_ticks`.
    #[error("channel {channel}: edges {spacing_ticks} ticks apart at tick {tick}, the board needs {min_ticks}")]
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
    #[error("channel {channel}: edge table does not fit or edges collide at tick {tick}")]
    EdgeTable {
        /// Output channel concerned.
        channel: u8,
        /// Tick within the cycle.
        tick: u32,
    },
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::string::ToString;

    use super::*;

    #[test]
    fn messages_carry_the_offending_values() {
        let e = PlanError::PatternPeriodTooShort {
            exposure: 0,
            slot: 3,
            period_ns: 200_000,
            min_ns: 235_000,
        };
        assert_eq!(
            e.to_string(),
            "exposure 0 slot 3: pattern period 200000 ns is below the DMD minimum 235000 ns"
        );
        assert_eq!(CapacityError::TooManyHeads.to_string(), "more than 4 heads");
        let wire: WireError = FrameError::CrcMismatch {
            received: 1,
            computed: 2,
        }
        .into();
        assert_eq!(
            wire.to_string(),
            "CRC mismatch: frame carries 0x00000001, payload gives 0x00000002"
        );
        assert_eq!(WireError::from(e).to_string(), e.to_string());
    }
}
