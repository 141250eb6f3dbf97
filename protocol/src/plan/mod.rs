//! `ScanPlan`: what the board sequences, in trigger-pin time.
//!
//! A plan is one *cycle* of exposures repeated `repeat_count` times every
//! `repeat_period_ns`. Each exposure raises the camera trigger of every head
//! it names for `duration_ns` (cameras run in trigger-width mode) and pulses
//! that head's projector trigger once per pattern slot. All times are offsets
//! on the board's output pins: exposure starts from the cycle start, slot
//! starts from their exposure's start. Device latencies are accounted for by
//! [`ScanPlan::validate`], not by shifting edges.
//!
//! ```text
//! cycle 0                                     cycle 1 (= + repeat_period_ns)
//! |--exposure 0----------|   |--exposure 1--|  |--exposure 0--- ...
//!   [s0][s1][s2]...[s23]        [s0]             [s0][s1]...
//! ```
//!
//! Slots are stored flat (`slots`), each exposure naming its range, so a
//! board holds a full plan in a few KiB. On the wire a plan travels in
//! chunks: a [`PlanHeader`] then one [`Exposure`] (with its slots inline) per
//! request, because a whole plan exceeds [`crate::limits::MAX_FRAME_BYTES`].

pub mod controller;
pub mod examples;
pub mod random;
mod validate;

pub use crate::error::PlanError;
pub use validate::ValidPlan;

use heapless::Vec;
use serde::{Deserialize, Serialize};

use crate::limits::{
    CameraModel, ProjectorModel, MAX_EXPOSURES, MAX_HEADS, MAX_SLOTS_PER_CYCLE,
    MAX_SLOTS_PER_EXPOSURE,
};

// A head set is a `u8` mask, one bit per head.
const _: () = assert!(MAX_HEADS <= 8);

/// A set of heads, as a bit mask (bit 0 = head A, bit 1 = head B, bit 2 =
/// head C, bit 3 = head D).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct HeadSet(pub u8);

impl HeadSet {
    /// Head A only.
    pub const A: HeadSet = HeadSet(0b0001);
    /// Head B only.
    pub const B: HeadSet = HeadSet(0b0010);
    /// Head C only.
    pub const C: HeadSet = HeadSet(0b0100);
    /// Head D only.
    pub const D: HeadSet = HeadSet(0b1000);
    /// Heads A and B.
    pub const BOTH: HeadSet = HeadSet(0b0011);

    /// Head `index` (0 = A) alone; `None` past [`MAX_HEADS`].
    ///
    /// ```
    /// use protocol::HeadSet;
    /// assert_eq!(HeadSet::single(2), Some(HeadSet::C));
    /// assert_eq!(HeadSet::single(4), None);
    /// ```
    pub const fn single(index: usize) -> Option<HeadSet> {
        if index < MAX_HEADS {
            Some(HeadSet(1 << index))
        } else {
            None
        }
    }

    /// The first `count` heads (A, B, ...) together; `None` past
    /// [`MAX_HEADS`]. `all(0)` is the empty set, which validation refuses.
    ///
    /// ```
    /// use protocol::HeadSet;
    /// assert_eq!(HeadSet::all(2), Some(HeadSet::BOTH));
    /// assert_eq!(HeadSet::all(4), Some(HeadSet(0b1111)));
    /// assert_eq!(HeadSet::all(5), None);
    /// ```
    pub const fn all(count: usize) -> Option<HeadSet> {
        if count <= MAX_HEADS {
            Some(HeadSet(((1u16 << count) - 1) as u8))
        } else {
            None
        }
    }

    /// Whether head `index` (0 = A) is in the set.
    pub const fn contains(self, index: usize) -> bool {
        index < 8 && self.0 & (1 << index) != 0
    }
}

/// Wiring and device models of one head.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct HeadConfig {
    /// Projector model (selects its timing profile).
    pub projector: ProjectorModel,
    /// Camera model (selects its timing profile).
    pub camera: CameraModel,
    /// Output channel wired to the projector's trigger input.
    pub projector_trigger_channel: u8,
    /// Output channel wired to the camera's trigger input.
    pub camera_trigger_channel: u8,
    /// Feedback input wired to the projector's trigger-out line.
    pub projector_feedback_channel: u8,
    /// Feedback input wired to the camera's exposure-active line.
    pub camera_feedback_channel: u8,
}

/// One DMD pattern shown inside an exposure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct PatternSlot {
    /// Index of the pattern in the projector's preloaded sequence.
    pub pattern_index: u16,
    /// Projector trigger rising edge, from the exposure's start.
    pub offset_ns: u32,
    /// How long the pattern is shown (the time to the next slot at least).
    pub display_ns: u32,
}

/// An exposure as it travels on the wire: its slots inline.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Exposure {
    /// Heads whose camera exposes and whose projector shows the slots.
    pub heads: HeadSet,
    /// Camera trigger rising edge, from the cycle start.
    pub start_ns: u32,
    /// Camera trigger high time = exposure time.
    pub duration_ns: u32,
    /// Patterns shown during the exposure, in time order.
    pub slots: Vec<PatternSlot, MAX_SLOTS_PER_EXPOSURE>,
}

/// An exposure inside a stored plan: its slots are `first_slot..first_slot +
/// slot_count` of [`ScanPlan::slots`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ExposureEntry {
    /// Heads whose camera exposes and whose projector shows the slots.
    pub heads: HeadSet,
    /// Camera trigger rising edge, from the cycle start.
    pub start_ns: u32,
    /// Camera trigger high time = exposure time.
    pub duration_ns: u32,
    /// Index of the first slot in [`ScanPlan::slots`].
    pub first_slot: u16,
    /// Number of slots.
    pub slot_count: u16,
}

/// Everything of a plan except its exposures: the first chunk on the wire.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlanHeader {
    /// The heads (1 to [`MAX_HEADS`], at most the board's
    /// `BoardLimits::max_heads`); head A is index 0.
    pub heads: Vec<HeadConfig, MAX_HEADS>,
    /// How many times the cycle runs (>= 1).
    pub repeat_count: u32,
    /// Time from one cycle start to the next (the camera frame period when
    /// the cycle holds one exposure).
    pub repeat_period_ns: u32,
    /// Guard kept between each pattern's light and its exposure's edges,
    /// after device latencies.
    pub margin_ns: u32,
    /// Number of exposures that will follow.
    pub exposure_count: u16,
}

/// A scan plan as parsed; validate it into a [`ValidPlan`] before use.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ScanPlan {
    /// The heads (1 to [`MAX_HEADS`], at most the board's
    /// `BoardLimits::max_heads`); head A is index 0.
    pub heads: Vec<HeadConfig, MAX_HEADS>,
    /// How many times the cycle runs (>= 1).
    pub repeat_count: u32,
    /// Time from one cycle start to the next.
    pub repeat_period_ns: u32,
    /// Guard between each pattern's light and its exposure's edges.
    pub margin_ns: u32,
    /// The exposures of one cycle.
    pub exposures: Vec<ExposureEntry, MAX_EXPOSURES>,
    /// All pattern slots, exposure after exposure.
    pub slots: Vec<PatternSlot, MAX_SLOTS_PER_CYCLE>,
}

/// A plan did not fit the fixed capacities (see [`crate::limits`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
pub enum CapacityError {
    /// More than [`MAX_HEADS`] heads.
    #[error("more than {MAX_HEADS} heads")]
    TooManyHeads,
    /// More than [`MAX_EXPOSURES`] exposures.
    #[error("more than {MAX_EXPOSURES} exposures")]
    TooManyExposures,
    /// More than [`MAX_SLOTS_PER_EXPOSURE`] slots in one exposure.
    #[error("more than {MAX_SLOTS_PER_EXPOSURE} slots in one exposure")]
    TooManySlotsInExposure,
    /// More than [`MAX_SLOTS_PER_CYCLE`] slots in the cycle.
    #[error("more than {MAX_SLOTS_PER_CYCLE} slots in one cycle")]
    TooManySlotsInCycle,
}

/// A borrowed exposure of a stored plan with its slots.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExposureView<'a> {
    /// Index of the exposure in the cycle.
    pub index: usize,
    /// The stored entry.
    pub entry: &'a ExposureEntry,
    /// Its slots (empty if the entry's range is out of bounds).
    pub slots: &'a [PatternSlot],
}

impl ScanPlan {
    /// An empty plan with the given heads and repetition.
    pub fn new(
        heads: &[HeadConfig],
        repeat_count: u32,
        repeat_period_ns: u32,
        margin_ns: u32,
    ) -> Result<ScanPlan, CapacityError> {
        Ok(ScanPlan {
            heads: Vec::from_slice(heads).map_err(|_| CapacityError::TooManyHeads)?,
            repeat_count,
            repeat_period_ns,
            margin_ns,
            exposures: Vec::new(),
            slots: Vec::new(),
        })
    }

    /// An empty plan from a wire header (its `exposure_count` is a promise
    /// checked by the receiver, not stored).
    pub fn from_header(header: &PlanHeader) -> ScanPlan {
        ScanPlan {
            heads: header.heads.clone(),
            repeat_count: header.repeat_count,
            repeat_period_ns: header.repeat_period_ns,
            margin_ns: header.margin_ns,
            exposures: Vec::new(),
            slots: Vec::new(),
        }
    }

    /// The wire header of this plan.
    pub fn header(&self) -> PlanHeader {
        PlanHeader {
            heads: self.heads.clone(),
            repeat_count: self.repeat_count,
            repeat_period_ns: self.repeat_period_ns,
            margin_ns: self.margin_ns,
            exposure_count: self.exposures.len() as u16,
        }
    }

    /// Appends an exposure with its slots.
    pub fn push_exposure(
        &mut self,
        heads: HeadSet,
        start_ns: u32,
        duration_ns: u32,
        slots: &[PatternSlot],
    ) -> Result<(), CapacityError> {
        if slots.len() > MAX_SLOTS_PER_EXPOSURE {
            return Err(CapacityError::TooManySlotsInExposure);
        }
        if self.exposures.is_full() {
            return Err(CapacityError::TooManyExposures);
        }
        if self.slots.len() + slots.len() > MAX_SLOTS_PER_CYCLE {
            return Err(CapacityError::TooManySlotsInCycle);
        }
        let first_slot = self.slots.len() as u16;
        // Capacities were checked above, so neither extend can fail.
        self.slots
            .extend_from_slice(slots)
            .map_err(|_| CapacityError::TooManySlotsInCycle)?;
        self.exposures
            .push(ExposureEntry {
                heads,
                start_ns,
                duration_ns,
                first_slot,
                slot_count: slots.len() as u16,
            })
            .map_err(|_| CapacityError::TooManyExposures)?;
        Ok(())
    }

    /// Appends a wire exposure.
    pub fn push_wire_exposure(&mut self, exposure: &Exposure) -> Result<(), CapacityError> {
        self.push_exposure(
            exposure.heads,
            exposure.start_ns,
            exposure.duration_ns,
            &exposure.slots,
        )
    }

    /// The slots of exposure `entry` (empty when its range is out of bounds;
    /// validation rejects such plans).
    pub fn slots_of(&self, entry: &ExposureEntry) -> &[PatternSlot] {
        let start = entry.first_slot as usize;
        let end = start + entry.slot_count as usize;
        self.slots.get(start..end).unwrap_or(&[])
    }

    /// The exposures with their slots, in cycle order.
    pub fn exposures(&self) -> impl Iterator<Item = ExposureView<'_>> + '_ {
        self.exposures
            .iter()
            .enumerate()
            .map(move |(index, entry)| ExposureView {
                index,
                entry,
                slots: self.slots_of(entry),
            })
    }

    /// Exposure `index` in its wire form, or `None` past the end.
    pub fn wire_exposure(&self, index: usize) -> Option<Exposure> {
        let entry = self.exposures.get(index)?;
        let slots = Vec::from_slice(self.slots_of(entry)).ok()?;
        Some(Exposure {
            heads: entry.heads,
            start_ns: entry.start_ns,
            duration_ns: entry.duration_ns,
            slots,
        })
    }

    /// Total duration of the scan: `repeat_count * repeat_period_ns`.
    pub fn total_ns(&self) -> u64 {
        self.repeat_count as u64 * self.repeat_period_ns as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_exposures_rebuild_the_plan() {
        let plan = examples::multiplexed_24_at_5khz(3);
        let mut rebuilt = ScanPlan::from_header(&plan.header());
        for i in 0..plan.exposures.len() {
            rebuilt
                .push_wire_exposure(&plan.wire_exposure(i).unwrap())
                .unwrap();
        }
        assert_eq!(rebuilt, plan);
    }

    #[test]
    fn capacity_is_a_typed_error() {
        let mut plan = examples::multiplexed_24_at_5khz(1);
        let slots = [PatternSlot {
            pattern_index: 0,
            offset_ns: 0,
            display_ns: 1,
        }; 33];
        assert_eq!(
            plan.push_exposure(HeadSet::A, 0, 1, &slots),
            Err(CapacityError::TooManySlotsInExposure)
        );
    }
}
