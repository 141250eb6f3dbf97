//! The one trait between the sequencer core and trigger hardware.
//!
//! Implemented by the STM32 binary (32-bit timer, one compare channel per
//! trigger line in toggle mode, circular DMA feeding the compare registers,
//! input capture + DMA on the feedback lines) and by hil-sim (a virtual
//! clock). The core never sees a register.

use protocol::{HardwareFault, Level};

use crate::edge_table::EdgeTable;

/// A timestamped edge on a feedback input, captured by the hardware.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Capture {
    /// Feedback input that changed.
    pub feedback_channel: u8,
    /// Level after the change.
    pub level: Level,
    /// Timer tick of the change (same time base as [`TriggerHardware::now_ticks`]).
    pub tick: u64,
}

/// Timer-driven trigger outputs and timestamped feedback inputs.
///
/// Time is the timer's free-running tick count at `BoardLimits::timer_clock_hz`,
/// extended to 64 bits by the implementation.
pub trait TriggerHardware {
    /// Copies one cycle's edges into the hardware's compare buffers. Outputs
    /// stay at their idle level (`Low`). Each output channel's edges
    /// alternate `High`, `Low`, starting `High` and ending `Low` within the
    /// cycle, so a toggle-on-compare timer can play them, and every tick is
    /// below `table.period_ticks()`.
    fn load(&mut self, table: &EdgeTable) -> Result<(), HardwareFault>;

    /// Plays the loaded cycle `repeat_count` times, cycle `k` starting at
    /// `start_tick + k * period_ticks`, each edge at cycle start + its tick
    /// (e.g. timer period = cycle, circular DMA, stop after `repeat_count`
    /// update events). Fails if `start_tick` has already passed.
    fn start(&mut self, start_tick: u64, repeat_count: u32) -> Result<(), HardwareFault>;

    /// Stops the timers and drives every output to its idle level (`Low`),
    /// now. Must be safe to call in any state.
    fn stop(&mut self);

    /// The timer now.
    fn now_ticks(&self) -> u64;

    /// The oldest unread feedback capture. Every edge that happened at or
    /// before `now_ticks()` must be readable here, per channel in time order.
    fn pop_capture(&mut self) -> Option<Capture>;

    /// A fault the hardware detected since `load` (capture overflow, DMA
    /// underrun), if any.
    fn fault(&self) -> Option<HardwareFault>;
}
