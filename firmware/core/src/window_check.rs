//! Is each pattern inside its exposure, as measured? From the feedback the
//! board captured: a pattern's light runs from its projector trigger-out
//! rise for its display time, the exposure from the camera's exposure-active
//! rise to its fall.
//!
//! Captures of different lines may arrive in any order (one DMA stream per
//! line on the STM32), so patterns wait for their exposure's window and
//! windows are kept until their patterns have come, both in small queues.

use heapless::{Deque, Vec};
use protocol::limits::{ns_to_ticks, MAX_HEADS, MAX_SLOTS_PER_CYCLE, MAX_SLOTS_PER_EXPOSURE};
use protocol::{Level, ValidPlan};

/// Patterns waiting for their exposure's window (two exposures' worth per
/// head); when full the oldest is dropped unchecked.
const PENDING_PATTERNS: usize = 2 * MAX_SLOTS_PER_EXPOSURE * MAX_HEADS;
/// Closed exposure windows kept for late-arriving patterns.
const KEPT_WINDOWS: usize = 4 * MAX_HEADS;

/// Which exposure of which head in which cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExposureKey {
    /// Head index (0 = A).
    pub head: u8,
    /// Cycle number.
    pub cycle: u32,
    /// Exposure index in the cycle.
    pub exposure: u16,
}

/// The verdict on one pattern.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PatternVerdict {
    /// Its exposure.
    pub key: ExposureKey,
    /// Its slot (index in `ScanPlan::slots`).
    pub slot: u16,
    /// Measured light, board ticks: trigger-out rise .. + display time.
    pub light: (u64, u64),
    /// Measured exposure, board ticks: exposure-active rise .. fall.
    pub window: (u64, u64),
}

impl PatternVerdict {
    /// Whether the light lies entirely inside the exposure.
    pub fn inside(&self) -> bool {
        self.light.0 >= self.window.0 && self.light.1 <= self.window.1
    }
}

#[derive(Debug, Clone, Copy)]
struct Pending {
    key: ExposureKey,
    slot: u16,
    light: (u64, u64),
}

/// The pattern-in-exposure check of one scan.
#[derive(Debug)]
pub struct WindowCheck {
    display_ticks: Vec<u32, MAX_SLOTS_PER_CYCLE>,
    open: [Option<(ExposureKey, u64)>; MAX_HEADS],
    windows: Deque<(ExposureKey, (u64, u64)), KEPT_WINDOWS>,
    pending: Deque<Pending, PENDING_PATTERNS>,
}

impl Default for WindowCheck {
    fn default() -> Self {
        Self::new()
    }
}

impl WindowCheck {
    /// A check with no plan.
    pub const fn new() -> Self {
        WindowCheck {
            display_ticks: Vec::new(),
            open: [None; MAX_HEADS],
            windows: Deque::new(),
            pending: Deque::new(),
        }
    }

    /// Takes the display time of every slot of `plan`.
    pub fn load(&mut self, plan: &ValidPlan) {
        let hz = plan.timer_clock_hz();
        self.display_ticks.clear();
        for slot in &plan.plan().slots {
            // Same capacity as the plan's slot list.
            let _ = self
                .display_ticks
                .push(ns_to_ticks(slot.display_ns as u64, hz) as u32);
        }
        self.reset();
    }

    /// Forgets every window and pattern (a new scan starts).
    pub fn reset(&mut self) {
        self.open = [None; MAX_HEADS];
        self.windows.clear();
        self.pending.clear();
    }

    /// A matched camera exposure-active edge.
    pub fn camera(
        &mut self,
        key: ExposureKey,
        level: Level,
        tick: u64,
        out: &mut impl FnMut(PatternVerdict),
    ) {
        let Some(open) = self.open.get_mut(key.head as usize) else {
            return;
        };
        match level {
            Level::High => *open = Some((key, tick)),
            Level::Low => {
                let Some((open_key, rise)) = open.take() else {
                    return;
                };
                if open_key != key {
                    return;
                }
                let window = (rise, tick);
                if self.windows.is_full() {
                    self.windows.pop_front();
                }
                let _ = self.windows.push_back((key, window));
                // Patterns that came before their window closed.
                for _ in 0..self.pending.len() {
                    let Some(p) = self.pending.pop_front() else {
                        break;
                    };
                    if p.key == key {
                        out(PatternVerdict {
                            key,
                            slot: p.slot,
                            light: p.light,
                            window,
                        });
                    } else {
                        let _ = self.pending.push_back(p);
                    }
                }
            }
        }
    }

    /// A matched projector trigger-out rise: pattern `slot` appeared.
    /// Returns whether a pattern was dropped unchecked to make room.
    pub fn projector_rise(
        &mut self,
        key: ExposureKey,
        slot: u16,
        tick: u64,
        out: &mut impl FnMut(PatternVerdict),
    ) -> bool {
        let display = self.display_ticks.get(slot as usize).copied().unwrap_or(0) as u64;
        let light = (tick, tick + display);
        if let Some((_, window)) = self.windows.iter().find(|(k, _)| *k == key) {
            out(PatternVerdict {
                key,
                slot,
                light,
                window: *window,
            });
            return false;
        }
        let dropped = self.pending.is_full() && self.pending.pop_front().is_some();
        let _ = self.pending.push_back(Pending { key, slot, light });
        dropped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const KEY: ExposureKey = ExposureKey {
        head: 0,
        cycle: 2,
        exposure: 1,
    };

    fn check() -> WindowCheck {
        let mut c = WindowCheck::new();
        c.display_ticks.extend([100, 100]);
        c
    }

    #[test]
    fn patterns_before_or_after_their_window_closes_are_judged() {
        let mut c = check();
        let mut got = std::vec::Vec::new();
        c.camera(KEY, Level::High, 1_000, &mut |v| got.push(v));
        c.projector_rise(KEY, 0, 1_050, &mut |v| got.push(v));
        assert!(got.is_empty(), "judged only once the window is known");
        c.camera(KEY, Level::Low, 1_300, &mut |v| got.push(v));
        c.projector_rise(KEY, 1, 1_250, &mut |v| got.push(v));
        assert_eq!(got.len(), 2);
        assert!(got[0].inside());
        assert_eq!(
            (got[1].light, got[1].window),
            ((1_250, 1_350), (1_000, 1_300))
        );
        assert!(!got[1].inside());
    }

    #[test]
    fn patterns_of_another_exposure_wait() {
        let mut c = check();
        let mut got = std::vec::Vec::new();
        let other = ExposureKey { exposure: 2, ..KEY };
        c.projector_rise(other, 0, 5_000, &mut |v| got.push(v));
        c.camera(KEY, Level::High, 1_000, &mut |v| got.push(v));
        c.camera(KEY, Level::Low, 1_300, &mut |v| got.push(v));
        assert!(got.is_empty());
        c.camera(other, Level::High, 4_900, &mut |v| got.push(v));
        c.camera(other, Level::Low, 5_200, &mut |v| got.push(v));
        assert_eq!(got.len(), 1);
        assert!(got[0].inside());
    }
}
