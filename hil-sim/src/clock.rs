//! The simulated board's virtual clock: the sync board's trigger timer
//! (170 MHz on the STM32G474), counted in ticks, converted to nanoseconds for
//! the device models and for people.
//!
//! Simulating the real timer's tick (rather than a 1 GHz one) makes the
//! simulated board compile and play exactly the edge table the STM32 would.
//! Time only moves when the simulation says so (`advance_to`): no wall clock.

use protocol::limits::{ns_to_ticks, ticks_to_ns};

/// A monotonic virtual timer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VirtualClock {
    now_ticks: u64,
    timer_clock_hz: u32,
}

impl VirtualClock {
    /// A clock at tick 0 counting at `timer_clock_hz`.
    pub fn new(timer_clock_hz: u32) -> Self {
        VirtualClock {
            now_ticks: 0,
            timer_clock_hz,
        }
    }

    /// The timer's frequency.
    pub fn timer_clock_hz(&self) -> u32 {
        self.timer_clock_hz
    }

    /// Ticks since the simulation began.
    pub fn now_ticks(&self) -> u64 {
        self.now_ticks
    }

    /// Virtual nanoseconds since the simulation began (rounded to nearest).
    pub fn now_ns(&self) -> u64 {
        self.ticks_to_ns(self.now_ticks)
    }

    /// Moves the clock forward to `tick`; never backwards (an earlier tick
    /// is ignored).
    pub fn advance_to(&mut self, tick: u64) {
        self.now_ticks = self.now_ticks.max(tick);
    }

    /// Nanoseconds of a tick count (rounded to nearest).
    pub fn ticks_to_ns(&self, ticks: u64) -> u64 {
        ticks_to_ns(ticks, self.timer_clock_hz)
    }

    /// The tick nearest to a nanosecond time.
    pub fn ns_to_ticks(&self, ns: u64) -> u64 {
        ns_to_ticks(ns, self.timer_clock_hz)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn never_runs_backwards_and_converts_at_170_mhz() {
        let mut clock = VirtualClock::new(170_000_000);
        clock.advance_to(170);
        clock.advance_to(100);
        assert_eq!(clock.now_ticks(), 170);
        assert_eq!(clock.now_ns(), 1_000);
        assert_eq!(clock.ns_to_ticks(200_000), 34_000);
    }
}
