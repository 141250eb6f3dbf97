//! A plan checked against the DMD controller of a head: the board may only
//! trigger patterns the controller holds, no faster than it shows them.
//!
//! The controller's own limits ([`ControllerLimits`]) bound what can be
//! uploaded; this adds what the plan asks of the uploaded set, so a plan
//! whose slots are shorter than the controller's exposure at the set's bit
//! depth, or that steps past the set's LUT, is refused before the board
//! starts (a DLPC that misses triggers shows the wrong pattern in every
//! later slot, silently).

use super::ScanPlan;
use crate::limits::{ControllerLimitError, ControllerLimits};

/// What head `head`'s controller holds: `patterns` patterns of `bit_depth`
/// bits, each shown for `exposure_us` (the LUT's exposure).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoadedSet {
    /// Patterns in the LUT.
    pub patterns: u32,
    /// Bits per pattern (1..=8).
    pub bit_depth: u8,
    /// Exposure each pattern is shown for, microseconds.
    pub exposure_us: u32,
}

impl ScanPlan {
    /// Checks head `head`'s slots against its controller's `limits` and the
    /// set it holds: every slot shows a pattern of the set, for at least the
    /// set's exposure and the controller's minimum at its bit depth.
    pub fn check_controller(
        &self,
        head: usize,
        limits: &ControllerLimits,
        set: &LoadedSet,
    ) -> Result<(), ControllerLimitError> {
        let min_us = limits.min_exposure_us(set.bit_depth)?.max(set.exposure_us);
        let min_ns = u64::from(min_us) * 1000;
        for exposure in self.exposures().filter(|e| e.entry.heads.contains(head)) {
            for slot in exposure.slots {
                if u32::from(slot.pattern_index) >= set.patterns {
                    return Err(ControllerLimitError::PatternNotLoaded {
                        exposure: exposure.index as u32,
                        pattern_index: slot.pattern_index,
                        loaded: set.patterns,
                    });
                }
                if u64::from(slot.display_ns) < min_ns {
                    return Err(ControllerLimitError::SlotTooShort {
                        exposure: exposure.index as u32,
                        pattern_index: slot.pattern_index,
                        display_ns: slot.display_ns,
                        bit_depth: set.bit_depth,
                        min_us,
                    });
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::limits::ProjectorModel;
    use crate::plan::{HeadSet, PatternSlot};

    fn plan(display_ns: u32, pattern_index: u16) -> ScanPlan {
        let mut plan = crate::plan::examples::head_only(0, 1);
        plan.slots.clear();
        plan.exposures.clear();
        let slot = PatternSlot {
            pattern_index,
            offset_ns: 0,
            display_ns,
        };
        plan.push_exposure(HeadSet::A, 0, display_ns, &[slot])
            .unwrap();
        plan
    }

    const SET: LoadedSet = LoadedSet {
        patterns: 12,
        bit_depth: 8,
        exposure_us: 10_000,
    };

    #[test]
    fn slots_as_long_as_the_set_exposure_pass() {
        let limits = ProjectorModel::Dlpc350.controller();
        assert_eq!(
            plan(10_000_000, 11).check_controller(0, &limits, &SET),
            Ok(())
        );
        // Head B has no slots in this plan: nothing to refuse.
        assert_eq!(plan(1_000, 99).check_controller(1, &limits, &SET), Ok(()));
    }

    #[test]
    fn a_slot_shorter_than_the_exposure_is_refused_with_the_minimum() {
        let limits = ProjectorModel::Dlpc350.controller();
        assert_eq!(
            plan(9_999_000, 0).check_controller(0, &limits, &SET),
            Err(ControllerLimitError::SlotTooShort {
                exposure: 0,
                pattern_index: 0,
                display_ns: 9_999_000,
                bit_depth: 8,
                min_us: 10_000
            })
        );
        // The controller's own minimum wins over a shorter LUT exposure.
        let short_lut = LoadedSet {
            exposure_us: 100,
            ..SET
        };
        let min_8bit = limits.min_exposure_us(8).unwrap();
        assert!(matches!(
            plan(min_8bit * 1000 - 1, 0).check_controller(0, &limits, &short_lut),
            Err(ControllerLimitError::SlotTooShort { min_us, .. }) if min_us == min_8bit
        ));
    }

    #[test]
    fn a_slot_past_the_loaded_set_is_refused() {
        let limits = ProjectorModel::Dlpc900.controller();
        assert_eq!(
            plan(20_000_000, 12).check_controller(0, &limits, &SET),
            Err(ControllerLimitError::PatternNotLoaded {
                exposure: 0,
                pattern_index: 12,
                loaded: 12
            })
        );
    }
}
