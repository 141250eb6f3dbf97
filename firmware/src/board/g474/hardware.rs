//! board-core's `TriggerHardware` on the G474: TIM5 clock and strobe
//! (timebase.rs), TIM2 + DMA edges (timers.rs), TIM3 feedback (capture.rs).

use board_core::{Capture, EdgeTable, TriggerHardware};
use protocol::{HardwareFault, Level};

use super::capture::FeedbackCapture;
use super::pins::FEEDBACK_ACTIVE_HIGH;
use super::timebase::Timebase;
use super::timers::TriggerTimers;

/// The trigger hardware the sequencer drives.
pub struct G474Hardware {
    timebase: Timebase,
    timers: TriggerTimers,
    capture: FeedbackCapture,
    /// Board tick at which TIM2/TIM3 started (`start_tick - shift`).
    strobe_tick: u64,
    /// Captures lost since `load` (over-capture or full queue).
    captures_lost: u32,
}

impl G474Hardware {
    /// Binds the three drivers together.
    pub fn new(timebase: Timebase, timers: TriggerTimers, capture: FeedbackCapture) -> Self {
        G474Hardware {
            timebase,
            timers,
            capture,
            strobe_tick: 0,
            captures_lost: 0,
        }
    }

    /// Waits for the next cycle end of a running scan (or an IRQ stop).
    pub async fn wait_cycle(&self) {
        self.timers.wait_cycle().await;
    }
}

impl TriggerHardware for G474Hardware {
    fn load(&mut self, table: &EdgeTable) -> Result<(), HardwareFault> {
        self.stop();
        self.captures_lost = 0;
        self.timers.load(table)
    }

    fn start(&mut self, start_tick: u64, repeat_count: u32) -> Result<(), HardwareFault> {
        if !self.timers.arm(repeat_count) {
            return Err(HardwareFault::NotLoaded);
        }
        self.capture.arm();
        let strobe = start_tick.saturating_sub(u64::from(self.timers.shift_ticks()));
        if let Err(now_tick) = self.timebase.fire_strobe_at(strobe) {
            self.stop();
            defmt::warn!(
                "start refused: start tick {=u64} too close to now {=u64}",
                start_tick,
                now_tick
            );
            return Err(HardwareFault::StartInPast {
                start_tick,
                now_tick,
            });
        }
        self.strobe_tick = strobe;
        defmt::info!(
            "scan armed: strobe at tick {=u64}, cycle 0 at {=u64}, {=u32} cycles",
            strobe,
            start_tick,
            repeat_count
        );
        Ok(())
    }

    fn stop(&mut self) {
        self.timers.stop();
        self.capture.stop();
        self.timebase.disarm_strobe();
    }

    fn now_ticks(&self) -> u64 {
        self.timebase.now_ticks()
    }

    fn pop_capture(&mut self) -> Option<Capture> {
        let raw = self.capture.pop()?;
        if raw.lost_before {
            self.captures_lost = self.captures_lost.saturating_add(1);
        }
        let active = raw.level_high == FEEDBACK_ACTIVE_HIGH[usize::from(raw.channel)];
        Some(Capture {
            feedback_channel: raw.channel,
            level: if active { Level::High } else { Level::Low },
            tick: self.strobe_tick + raw.ticks_since_strobe,
        })
    }

    fn fault(&self) -> Option<HardwareFault> {
        if let Some(channel) = self.timers.underrun() {
            return Some(HardwareFault::EdgeUnderrun { channel });
        }
        (self.captures_lost > 0).then_some(HardwareFault::CaptureOverflow {
            lost: self.captures_lost,
        })
    }
}
