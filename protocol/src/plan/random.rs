//! Random *valid* plans of every capture mode, from any source of random
//! `u64`s (proptest's seed, the soak's ChaCha): one generator for the
//! property tests and for `hil-sim soak`.
//!
//! Plans are valid by construction (each time is derived from the device
//! profiles' limits plus a random slack that is sometimes zero, so pattern
//! periods go down to the DMD limit); callers still validate them, and a
//! refusal is a generator bug worth reporting.

use super::{HeadConfig, HeadSet, PatternSlot, ScanPlan};
use crate::limits::{
    CameraModel, CameraProfile, ProjectorModel, ProjectorProfile, MAX_HEADS, MAX_SLOTS_PER_EXPOSURE,
};

/// The capture modes of the seed papers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlanKind {
    /// Seed 000: both heads (every head of the rig, [`random_plan_on`])
    /// project and expose together.
    DualHead,
    /// Seed 000 reference run: one head of the rig (0 = A, 1 = B, ...).
    HeadOnly(u8),
    /// Seed 001: many binary patterns inside one long exposure, repeated.
    Multiplexed,
    /// Seeds 003/004: uniform floods, one long exposure each.
    Flood,
}

/// A random-number source: each call returns fresh random bits.
pub trait Bits {
    /// 64 random bits.
    fn next_u64(&mut self) -> u64;
    /// Uniform in `lo..=hi` (slightly biased for huge ranges; fine here).
    fn range(&mut self, lo: u64, hi: u64) -> u64 {
        if hi <= lo {
            return lo;
        }
        lo + self.next_u64() % (hi - lo + 1)
    }
    /// A slack that is zero one time in four (to hit limits exactly).
    fn slack(&mut self, max: u64) -> u64 {
        if self.next_u64().is_multiple_of(4) {
            0
        } else {
            self.range(0, max)
        }
    }
}

impl<F: FnMut() -> u64> Bits for F {
    fn next_u64(&mut self) -> u64 {
        self()
    }
}

/// SplitMix64: a tiny seeded generator for `no_std` callers and proptest.
#[derive(Debug, Clone)]
pub struct SplitMix64(pub u64);

impl Bits for SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

/// A random capture mode.
pub fn random_kind(bits: &mut impl Bits) -> PlanKind {
    match bits.range(0, 4) {
        0 => PlanKind::DualHead,
        1 => PlanKind::HeadOnly(0),
        2 => PlanKind::HeadOnly(1),
        3 => PlanKind::Multiplexed,
        _ => PlanKind::Flood,
    }
}

/// A random valid plan of `kind` on a dual-head rig (the STM32G474 board).
pub fn random_plan(kind: PlanKind, bits: &mut impl Bits) -> ScanPlan {
    random_plan_on(kind, 2, bits)
}

/// A random valid plan of `kind` on a rig of `rig_heads` heads (clamped to
/// `1..=MAX_HEADS`): [`PlanKind::DualHead`] then drives all of them at once
/// and [`PlanKind::HeadOnly`] one of them; the single-head kinds ignore it.
/// Draws the same random bits whatever `rig_heads` is, so a seed gives the
/// same timing on every rig size.
pub fn random_plan_on(kind: PlanKind, rig_heads: usize, bits: &mut impl Bits) -> ScanPlan {
    let rig_heads = rig_heads.clamp(1, MAX_HEADS);
    let projector = if bits.range(0, 1) == 0 {
        ProjectorModel::Dlpc350
    } else {
        ProjectorModel::Dlpc900
    };
    let camera = match kind {
        PlanKind::Multiplexed => CameraModel::Colour208Hz,
        _ if bits.range(0, 1) == 0 => CameraModel::Mono6Mp,
        _ => CameraModel::Colour208Hz,
    };
    let whole_rig = matches!(kind, PlanKind::DualHead | PlanKind::HeadOnly(_));
    let mut heads = [super::examples::head(0, projector, camera); MAX_HEADS];
    for (index, head) in heads.iter_mut().enumerate() {
        *head = super::examples::head(index as u8, projector, camera);
    }
    let heads: &[HeadConfig] = &heads[..if whole_rig { rig_heads } else { 1 }];
    let every_head = HeadSet::all(heads.len()).unwrap_or(HeadSet::A);
    let one_head = |h: u8| HeadSet::single(h as usize % heads.len()).unwrap_or(HeadSet::A);
    let (head_set, exposures, slots_per_exposure, repeat_max) = match kind {
        PlanKind::DualHead => (every_head, bits.range(1, 16), 1, 2),
        PlanKind::HeadOnly(h) => (one_head(h), bits.range(1, 16), 1, 2),
        PlanKind::Multiplexed => (HeadSet::A, 1, bits.range(1, 24), 6),
        PlanKind::Flood => (HeadSet::A, 7, 1, 1),
    };
    let long_display = !matches!(kind, PlanKind::Multiplexed);
    let margin_ns = bits.range(0, 2_000) as u32;
    let shape = Shape {
        p: projector.profile(),
        c: camera.profile(),
        margin_ns: margin_ns as u64,
        lead_ns: 2_000 + bits.slack(20_000),
    };
    let repeat = bits.range(1, repeat_max) as u32;
    let mut plan = ScanPlan::new(heads, repeat, 0, margin_ns).unwrap_or_else(|_| unreachable!());
    let mut start_ns = shape.lead_ns;
    let mut first_start = None;
    let mut last = (0u64, 0u64);
    for _ in 0..exposures {
        let (duration, slots) = shape.exposure(bits, slots_per_exposure as usize, long_display);
        let _ = plan.push_exposure(
            head_set,
            start_ns as u32,
            duration as u32,
            &slots[..slots_per_exposure as usize],
        );
        first_start.get_or_insert(start_ns);
        last = (start_ns, start_ns + duration);
        start_ns = shape.next_start(bits, start_ns, start_ns + duration);
    }
    // The cycle wraps to its first exposure: the next cycle's first start
    // must be as far from the last exposure as any next exposure would be.
    let wrap_start = shape.next_start(bits, last.0, last.1);
    let first = first_start.unwrap_or(0);
    plan.repeat_period_ns = (wrap_start - first).max(last.1 + 2_000) as u32;
    plan
}

/// Validation checks limits in played (170 MHz) ticks, where rounding each
/// end of an interval moves it by up to one tick (5.9 ns): generated
/// intervals get that much above their limit, no more.
const TICK_HEADROOM_NS: u64 = 6;

struct Shape {
    p: ProjectorProfile,
    c: CameraProfile,
    margin_ns: u64,
    lead_ns: u64,
}

impl Shape {
    /// Earliest projector trigger offset that keeps the pattern's light
    /// inside the exposure's light with the margin.
    fn first_offset(&self) -> u64 {
        let need = self.c.latency_ns as u64 + self.c.jitter_ns as u64 + self.margin_ns;
        let have = (self.p.latency_ns - self.p.jitter_ns) as u64;
        need.saturating_sub(have) + TICK_HEADROOM_NS
    }

    /// Duration and slots of one exposure.
    fn exposure(
        &self,
        bits: &mut impl Bits,
        count: usize,
        long: bool,
    ) -> (u64, [PatternSlot; MAX_SLOTS_PER_EXPOSURE]) {
        let min_period = self.p.min_pattern_period_ns as u64;
        let period = if long {
            bits.range(min_period, 15_000_000)
        } else {
            min_period + bits.slack(min_period / 2)
        };
        let mut slots = [PatternSlot {
            pattern_index: 0,
            offset_ns: 0,
            display_ns: 0,
        }; MAX_SLOTS_PER_EXPOSURE];
        let mut offset = self.first_offset() + bits.slack(5_000);
        for (k, slot) in slots.iter_mut().take(count).enumerate() {
            *slot = PatternSlot {
                pattern_index: k as u16,
                offset_ns: offset as u32,
                display_ns: period as u32,
            };
            offset += period;
        }
        // Light of the last pattern ends at `offset` + latency + jitter.
        let light_end = offset + (self.p.latency_ns + self.p.jitter_ns) as u64;
        let exposure_light_lag = self.c.latency_ns as u64 - self.c.jitter_ns as u64;
        let duration = (light_end + self.margin_ns)
            .saturating_sub(exposure_light_lag)
            .max(self.c.min_exposure_ns as u64)
            + TICK_HEADROOM_NS
            + bits.slack(10_000);
        (duration, slots)
    }

    /// Earliest start of the next exposure of the same camera, plus slack.
    fn next_start(&self, bits: &mut impl Bits, start: u64, end: u64) -> u64 {
        let by_gap = end + self.c.min_gap_ns as u64;
        let by_rate = start + self.c.min_frame_period_ns as u64;
        by_gap.max(by_rate) + TICK_HEADROOM_NS + bits.slack(50_000)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::limits::BoardLimits;

    #[test]
    fn thousands_of_random_plans_validate() {
        let mut bits = SplitMix64(1);
        for _ in 0..5_000 {
            let kind = random_kind(&mut bits);
            let plan = random_plan(kind, &mut bits);
            if let Err(e) = plan.clone().validate(&BoardLimits::STM32G474) {
                panic!("{kind:?} gave an invalid plan: {e:?}\n{plan:?}");
            }
        }
    }

    /// Rigs of 1 to 4 heads: every plan validates on a board with a line
    /// each way per device, and the STM32G474 (4 trigger lines) refuses
    /// exactly the plans with more than two heads, in heads.
    #[test]
    fn random_plans_on_every_rig_size_validate_where_the_board_has_lines() {
        let eight_lines = BoardLimits {
            output_channels: 8,
            feedback_channels: 8,
            ..BoardLimits::STM32G474
        };
        let mut bits = SplitMix64(7);
        let mut seen_heads = [false; MAX_HEADS + 1];
        for _ in 0..2_000 {
            let kind = random_kind(&mut bits);
            let rig = bits.range(1, MAX_HEADS as u64) as usize;
            let plan = random_plan_on(kind, rig, &mut bits);
            let heads = plan.heads.len();
            seen_heads[heads] = true;
            if let Err(e) = plan.clone().validate(&eight_lines) {
                panic!("{kind:?} on {rig} heads gave an invalid plan: {e:?}\n{plan:?}");
            }
            match plan.validate(&BoardLimits::STM32G474) {
                Ok(_) => assert!(heads <= 2, "{heads} heads accepted by a 2-head board"),
                Err(crate::error::PlanError::TooManyHeadsForBoard {
                    heads: h,
                    max_heads: 2,
                    ..
                }) => assert_eq!((h as usize, heads > 2), (heads, true)),
                Err(e) => panic!("{heads} heads refused for another reason: {e:?}"),
            }
        }
        assert_eq!(seen_heads, [false, true, true, true, true]);
    }
}
