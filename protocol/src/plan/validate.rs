//! `ScanPlan::validate`: the checks that make a plan safe to sequence.
//!
//! Times are checked in nanoseconds with device latencies and their peak
//! jitter included, so that any edge whose feedback stays within its device's
//! jitter keeps every pattern inside its exposure with the plan's margin.

use super::{ExposureEntry, ScanPlan};
use crate::error::PlanError;
use crate::limits::{ns_to_ticks, ns_to_ticks_ceil, BoardLimits, CameraProfile, ProjectorProfile};

/// A plan that passed [`ScanPlan::validate`] for one board; only validation
/// makes one.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ValidPlan {
    plan: ScanPlan,
    board: BoardLimits,
}

impl ValidPlan {
    /// The validated plan.
    pub fn plan(&self) -> &ScanPlan {
        &self.plan
    }
    /// The timer clock it was validated for.
    pub fn timer_clock_hz(&self) -> u32 {
        self.board.timer_clock_hz
    }
    /// The board limits it was validated against.
    pub fn board(&self) -> &BoardLimits {
        &self.board
    }
    /// Gives the plan back.
    pub fn into_plan(self) -> ScanPlan {
        self.plan
    }
}

impl ScanPlan {
    /// Checks the plan against the board's limits and the heads' device
    /// profiles.
    pub fn validate(self, board: &BoardLimits) -> Result<ValidPlan, PlanError> {
        check_heads(&self, board)?;
        check_counts(&self, board)?;
        check_exposures(&self, board.timer_clock_hz)?;
        for head in 0..self.heads.len() {
            check_camera(&self, head, board.timer_clock_hz)?;
            check_projector(&self, head, board.timer_clock_hz)?;
        }
        Ok(ValidPlan {
            plan: self,
            board: *board,
        })
    }
}

fn check_heads(plan: &ScanPlan, board: &BoardLimits) -> Result<(), PlanError> {
    if plan.heads.is_empty() {
        return Err(PlanError::NoHeads);
    }
    // Said in heads before any channel number: a rig with one head too many
    // would otherwise read as "channel 4 out of range", which names the
    // symptom, not the cause.
    if plan.heads.len() > board.max_heads() {
        return Err(PlanError::TooManyHeadsForBoard {
            heads: plan.heads.len() as u8,
            output_channels: board.output_channels,
            feedback_channels: board.feedback_channels,
            max_heads: board.max_heads() as u8,
        });
    }
    let mut outputs_used = 0u32;
    let mut inputs_used = 0u32;
    for (i, head) in plan.heads.iter().enumerate() {
        let outs = [head.projector_trigger_channel, head.camera_trigger_channel];
        let ins = [
            head.projector_feedback_channel,
            head.camera_feedback_channel,
        ];
        for (channels, available, used) in [
            (outs, board.output_channels, &mut outputs_used),
            (ins, board.feedback_channels, &mut inputs_used),
        ] {
            for channel in channels {
                if channel >= available || channel >= 32 {
                    return Err(PlanError::ChannelOutOfRange {
                        head: i as u8,
                        channel,
                        available,
                    });
                }
                if *used & (1 << channel) != 0 {
                    return Err(PlanError::ChannelReused { channel });
                }
                *used |= 1 << channel;
            }
        }
    }
    Ok(())
}

fn check_counts(plan: &ScanPlan, board: &BoardLimits) -> Result<(), PlanError> {
    if plan.repeat_count == 0 || plan.repeat_count > board.max_repeat_count {
        return Err(PlanError::RepeatCountOutOfRange {
            count: plan.repeat_count,
            max: board.max_repeat_count,
        });
    }
    if plan.repeat_period_ns == 0
        || ns_to_ticks(plan.repeat_period_ns as u64, board.timer_clock_hz) > u32::MAX as u64
    {
        return Err(PlanError::PeriodOutOfRange {
            period_ns: plan.repeat_period_ns,
        });
    }
    if plan.exposures.is_empty() {
        return Err(PlanError::NoExposures);
    }
    if plan.exposures.len() > board.max_exposures as usize {
        return Err(PlanError::TooManyExposures {
            count: plan.exposures.len() as u16,
            max: board.max_exposures,
        });
    }
    if plan.slots.len() > board.max_slots_per_cycle as usize {
        return Err(PlanError::TooManySlots {
            count: plan.slots.len() as u16,
            max: board.max_slots_per_cycle,
        });
    }
    Ok(())
}

/// Whether an edge at `end_ns` comes out strictly before the next cycle's
/// start once both are timer ticks (a compare at the period never fires).
fn ends_in_cycle(plan: &ScanPlan, end_ns: u64, hz: u32) -> bool {
    ns_to_ticks(end_ns, hz) < ns_to_ticks(plan.repeat_period_ns as u64, hz)
}

fn check_exposures(plan: &ScanPlan, hz: u32) -> Result<(), PlanError> {
    let head_mask = (1u16 << plan.heads.len()) - 1;
    let mut previous_start = 0u32;
    for (i, e) in plan.exposures.iter().enumerate() {
        let exposure = i as u16;
        let end = e.first_slot as usize + e.slot_count as usize;
        if end > plan.slots.len() {
            return Err(PlanError::SlotRangeInvalid { exposure });
        }
        if e.heads.0 == 0 || e.heads.0 as u16 & !head_mask != 0 {
            return Err(PlanError::UnknownHead {
                exposure,
                heads: e.heads.0,
            });
        }
        if e.start_ns < previous_start {
            return Err(PlanError::ExposuresOutOfOrder { exposure });
        }
        previous_start = e.start_ns;
        let end_ns = e.start_ns as u64 + e.duration_ns as u64;
        if !ends_in_cycle(plan, end_ns, hz) {
            return Err(PlanError::ExposureBeyondPeriod {
                exposure,
                end_ns,
                period_ns: plan.repeat_period_ns,
            });
        }
    }
    Ok(())
}

fn exposures_of(plan: &ScanPlan, head: usize) -> impl Iterator<Item = (u16, &ExposureEntry)> + '_ {
    plan.exposures
        .iter()
        .enumerate()
        .filter(move |(_, e)| e.heads.contains(head))
        .map(|(i, e)| (i as u16, e))
}

fn check_camera(plan: &ScanPlan, head: usize, hz: u32) -> Result<(), PlanError> {
    let camera: CameraProfile = plan.heads[head].camera.profile();
    let mut first: Option<(u16, &ExposureEntry)> = None;
    let mut previous: Option<(u16, &ExposureEntry)> = None;
    for (i, e) in exposures_of(plan, head) {
        if e.duration_ns < camera.min_exposure_ns {
            return Err(PlanError::ExposureTooShort {
                exposure: i,
                duration_ns: e.duration_ns,
                min_ns: camera.min_exposure_ns,
            });
        }
        if let Some((p, prev)) = previous {
            check_camera_pair(&camera, head, (p, prev, 0), (i, e), hz)?;
        }
        first.get_or_insert((i, e));
        previous = Some((i, e));
    }
    // The next cycle's first exposure follows this cycle's last one.
    if let (Some((f, fe)), Some((l, le)), true) = (first, previous, plan.repeat_count > 1) {
        check_camera_pair(
            &camera,
            head,
            (l, le, plan.repeat_period_ns as u64),
            (f, fe),
            hz,
        )
        .map_err(|_| PlanError::OverlappingExposures {
            head: head as u8,
            first: l,
            second: f,
        })?;
    }
    Ok(())
}

/// A time as plan nanoseconds and as the tick the board plays it at.
#[derive(Clone, Copy)]
struct Instant {
    ns: u64,
    ticks: u64,
}

impl Instant {
    fn at(ns: u64, hz: u32) -> Instant {
        Instant {
            ns,
            ticks: ns_to_ticks(ns, hz),
        }
    }
    /// This instant in the cycle that starts at `cycle_start` (ticks add up
    /// as the timer plays them: cycle start tick + offset tick).
    fn after(self, cycle_start: Instant) -> Instant {
        Instant {
            ns: self.ns + cycle_start.ns,
            ticks: self.ticks + cycle_start.ticks,
        }
    }
}

/// Whether `later` is at least `min_ns` after `earlier`, both in plan time
/// and as played (whole ticks; the minimum rounded up to whole ticks), so
/// tick rounding never takes a device below its limit.
fn spaced(later: Instant, earlier: Instant, min_ns: u32, hz: u32) -> bool {
    later.ns >= earlier.ns + min_ns as u64
        && later.ticks >= earlier.ticks + ns_to_ticks_ceil(min_ns as u64, hz)
}

/// Whether `later.0` as the board plays it (whole ticks) plus `later.1` ns
/// comes no sooner than `earlier.0` played plus `earlier.1` ns; exact, in
/// units of 1 / (1e9 * hz) s, so tick rounding cannot eat into a margin.
fn played_at_least(later: (u64, i64), earlier: (u64, i64), hz: u32) -> bool {
    let ticks = ns_to_ticks(later.0, hz) as i128 - ns_to_ticks(earlier.0, hz) as i128;
    ticks * 1_000_000_000 >= (earlier.1 - later.1) as i128 * hz as i128
}

/// `earlier` carries a shift subtracted from its times (the repeat period
/// for the cycle wrap).
fn check_camera_pair(
    camera: &CameraProfile,
    head: usize,
    earlier: (u16, &ExposureEntry, u64),
    later: (u16, &ExposureEntry),
    hz: u32,
) -> Result<(), PlanError> {
    let (p, prev, period_ns) = earlier;
    let (i, e) = later;
    // The later exposure may belong to the next cycle (the wrap check).
    let period = Instant::at(period_ns, hz);
    let next_start = Instant::at(e.start_ns as u64, hz).after(period);
    let prev_start = Instant::at(prev.start_ns as u64, hz);
    let prev_end = Instant::at(prev.start_ns as u64 + prev.duration_ns as u64, hz);
    if !spaced(next_start, prev_end, camera.min_gap_ns, hz)
        || !spaced(next_start, prev_start, camera.min_frame_period_ns, hz)
    {
        return Err(PlanError::OverlappingExposures {
            head: head as u8,
            first: p,
            second: i,
        });
    }
    Ok(())
}

fn check_projector(plan: &ScanPlan, head: usize, hz: u32) -> Result<(), PlanError> {
    let projector: ProjectorProfile = plan.heads[head].projector.profile();
    let camera: CameraProfile = plan.heads[head].camera.profile();
    let min_period = projector.min_pattern_period_ns as u64;
    // Absolute (from cycle start) trigger time and display end of the
    // previous pattern of this projector.
    let mut previous: Option<(u64, u64)> = None;
    // Exposure index and trigger time of the cycle's first pattern.
    let mut first: Option<(u16, u64)> = None;
    for (i, e) in exposures_of(plan, head) {
        // The camera integrates from its trigger's rise + latency (late by
        // up to the jitter) to its fall + latency (early by up to the
        // jitter); the pattern's light, from its trigger + latency (early by
        // up to the jitter) to display end + latency (late by the jitter),
        // must fall inside with the margin to spare.
        let (margin, p_lat, p_jit) = (
            plan.margin_ns as i64,
            projector.latency_ns as i64,
            projector.jitter_ns as i64,
        );
        let (c_lat, c_jit) = (camera.latency_ns as i64, camera.jitter_ns as i64);
        let exposure_start = e.start_ns as u64;
        let exposure_end = e.start_ns as u64 + e.duration_ns as u64;
        for (s, slot) in plan.slots_of(e).iter().enumerate() {
            let slot_index = s as u16;
            let trigger = e.start_ns as u64 + slot.offset_ns as u64;
            let display_end = trigger + slot.display_ns as u64;
            let spacing = previous.map_or(u64::MAX, |(t, _)| trigger.saturating_sub(t));
            let spaced_in_ticks = previous.is_none_or(|(t, _)| {
                spaced(
                    Instant::at(trigger, hz),
                    Instant::at(t, hz),
                    projector.min_pattern_period_ns,
                    hz,
                )
            });
            if let Some((_, prev_end)) = previous {
                if trigger < prev_end {
                    return Err(PlanError::SlotsOverlap {
                        exposure: i,
                        slot: slot_index,
                    });
                }
            }
            let period = spacing.min(slot.display_ns as u64);
            if period < min_period || !spaced_in_ticks {
                return Err(PlanError::PatternPeriodTooShort {
                    exposure: i,
                    slot: slot_index,
                    period_ns: period,
                    min_ns: projector.min_pattern_period_ns,
                });
            }
            let starts_inside = played_at_least(
                (trigger, p_lat - p_jit),
                (exposure_start, c_lat + c_jit + margin),
                hz,
            );
            let ends_inside = played_at_least(
                (exposure_end, c_lat - c_jit - margin),
                (trigger, slot.display_ns as i64 + p_lat + p_jit),
                hz,
            );
            if !starts_inside || !ends_inside {
                return Err(PlanError::PatternOutsideExposure {
                    exposure: i,
                    slot: slot_index,
                    head: head as u8,
                });
            }
            let pulse_end = trigger + projector.trigger_pulse_ns as u64;
            if !ends_in_cycle(plan, pulse_end, hz) {
                return Err(PlanError::ExposureBeyondPeriod {
                    exposure: i,
                    end_ns: pulse_end,
                    period_ns: plan.repeat_period_ns,
                });
            }
            first.get_or_insert((i, trigger));
            previous = Some((trigger, display_end));
        }
    }
    // The next cycle's first pattern follows this cycle's last one. Implied
    // today by `display >= min period` and patterns inside exposures inside
    // the cycle; checked anyway so relaxing those cannot let a wrap through.
    if let (Some((exposure, first)), Some((last, last_end)), true) =
        (first, previous, plan.repeat_count > 1)
    {
        let period = Instant::at(plan.repeat_period_ns as u64, hz);
        let next = Instant::at(first, hz).after(period);
        if next.ns < last_end {
            return Err(PlanError::SlotsOverlap { exposure, slot: 0 });
        }
        if !spaced(
            next,
            Instant::at(last, hz),
            projector.min_pattern_period_ns,
            hz,
        ) {
            return Err(PlanError::PatternPeriodTooShort {
                exposure,
                slot: 0,
                period_ns: next.ns - last,
                min_ns: projector.min_pattern_period_ns,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use crate::plan::{examples, HeadSet, PatternSlot};

    const BOARD: BoardLimits = BoardLimits::STM32G474;

    #[test]
    fn examples_are_valid() {
        for plan in examples::all() {
            plan.validate(&BOARD).unwrap();
        }
    }

    #[test]
    fn pattern_period_below_dmd_limit_is_refused() {
        // 24 patterns at 5 kHz on a DLPC350 (minimum 235 us).
        let mut plan = examples::multiplexed_24_at_5khz(1);
        plan.heads[0].projector = crate::limits::ProjectorModel::Dlpc350;
        assert!(matches!(
            plan.validate(&BOARD),
            Err(PlanError::PatternPeriodTooShort {
                exposure: 0,
                slot: 0,
                period_ns: 200_000,
                min_ns: 235_000
            })
        ));
    }

    #[test]
    fn pattern_outside_exposure_is_refused() {
        let mut plan = examples::multiplexed_24_at_5khz(1);
        let last = plan.slots.len() - 1;
        plan.slots[last].display_ns += 50_000;
        assert!(matches!(
            plan.validate(&BOARD),
            Err(PlanError::PatternOutsideExposure {
                exposure: 0,
                slot: 23,
                head: 0
            })
        ));
    }

    #[test]
    fn overlapping_exposures_are_refused() {
        let mut plan = examples::dual_head_psp(1);
        plan.exposures[1].start_ns = plan.exposures[0].start_ns + 1000;
        assert!(matches!(
            plan.validate(&BOARD),
            Err(PlanError::OverlappingExposures {
                head: 0,
                first: 0,
                second: 1
            })
        ));
    }

    #[test]
    fn too_many_slots_is_refused() {
        let mut board = BOARD;
        board.max_slots_per_cycle = 10;
        assert!(matches!(
            examples::multiplexed_24_at_5khz(1).validate(&board),
            Err(PlanError::TooManySlots { count: 24, max: 10 })
        ));
    }

    #[test]
    fn channel_out_of_range_and_reuse_are_refused() {
        let mut plan = examples::dual_head_psp(1);
        plan.heads[1].camera_trigger_channel = 9;
        assert!(matches!(
            plan.validate(&BOARD),
            Err(PlanError::ChannelOutOfRange {
                head: 1,
                channel: 9,
                ..
            })
        ));
        let mut plan = examples::dual_head_psp(1);
        plan.heads[1].camera_trigger_channel = plan.heads[0].camera_trigger_channel;
        assert!(matches!(
            plan.validate(&BOARD),
            Err(PlanError::ChannelReused { .. })
        ));
    }

    /// A board with a line each way per device of four heads.
    const EIGHT_LINES: BoardLimits = BoardLimits {
        output_channels: 8,
        feedback_channels: 8,
        ..BOARD
    };

    #[test]
    fn heads_up_to_the_boards_lines_are_accepted() {
        for heads in 1..=2 {
            examples::all_heads_psp(heads, 1).validate(&BOARD).unwrap();
        }
        for heads in 1..=crate::limits::MAX_HEADS {
            let plan = examples::all_heads_psp(heads, 1);
            assert_eq!(plan.heads.len(), heads);
            plan.validate(&EIGHT_LINES).unwrap();
        }
    }

    #[test]
    fn more_heads_than_the_board_has_lines_are_refused_in_heads() {
        for heads in 3..=4 {
            let e = examples::all_heads_psp(heads, 1)
                .validate(&BOARD)
                .unwrap_err();
            assert_eq!(
                e,
                PlanError::TooManyHeadsForBoard {
                    heads: heads as u8,
                    output_channels: 4,
                    feedback_channels: 4,
                    max_heads: 2
                }
            );
        }
        // Enough trigger lines but too few feedback inputs is refused too,
        // naming both counts.
        let six_out = BoardLimits {
            output_channels: 8,
            feedback_channels: 6,
            ..BOARD
        };
        examples::all_heads_psp(3, 1).validate(&six_out).unwrap();
        let e = examples::all_heads_psp(4, 1)
            .validate(&six_out)
            .unwrap_err();
        assert_eq!(
            std::string::ToString::to_string(&e),
            "the plan drives 4 heads; this board has 8 trigger lines and 6 feedback lines \
             (two of each per head), 3 heads"
        );
    }

    #[test]
    fn unknown_head_is_refused() {
        let mut plan = examples::flood_preliminaries(1);
        plan.exposures[0].heads = HeadSet::B;
        assert!(matches!(
            plan.validate(&BOARD),
            Err(PlanError::UnknownHead {
                exposure: 0,
                heads: 2
            })
        ));
    }

    #[test]
    fn slots_overlapping_are_refused() {
        let mut plan = examples::multiplexed_24_at_5khz(1);
        plan.slots[1] = PatternSlot {
            offset_ns: plan.slots[1].offset_ns - 1_000,
            ..plan.slots[1]
        };
        assert!(matches!(
            plan.validate(&BOARD),
            Err(PlanError::SlotsOverlap {
                exposure: 0,
                slot: 1
            })
        ));
    }
}
