//! `ValidPlan` -> one cycle of timer edges: pure arithmetic.
//!
//! Every edge time is converted from its absolute nanosecond offset in the
//! cycle (`limits::ns_to_ticks`, monotonic), so ordering and margins proved
//! in nanoseconds by validation hold in ticks too.

use heapless::Vec;
use protocol::limits::{ns_to_ticks, MAX_EDGES};
use protocol::{Level, ValidPlan, WireError};

/// One output transition within a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Edge {
    /// Ticks from the cycle start.
    pub tick: u32,
    /// Output channel.
    pub channel: u8,
    /// Level after the edge.
    pub level: Level,
    /// Index, in the cycle, of the exposure the edge belongs to.
    pub exposure: u16,
    /// For a projector edge, the index of its slot in `ScanPlan::slots`;
    /// [`Edge::NO_SLOT`] for a camera edge.
    pub slot: u16,
}

impl Edge {
    /// `slot` of a camera edge.
    pub const NO_SLOT: u16 = u16::MAX;
}

/// One cycle of edges sorted by (tick, channel), with the cycle's period and
/// repetition.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EdgeTable {
    period_ticks: u32,
    repeat_count: u32,
    timer_clock_hz: u32,
    edges: Vec<Edge, MAX_EDGES>,
}

impl Default for EdgeTable {
    fn default() -> Self {
        Self::new()
    }
}

impl EdgeTable {
    /// An empty table.
    pub const fn new() -> Self {
        EdgeTable {
            period_ticks: 0,
            repeat_count: 0,
            timer_clock_hz: 0,
            edges: Vec::new(),
        }
    }

    /// Compiles `plan` into a new table.
    pub fn compile(plan: &ValidPlan) -> Result<EdgeTable, WireError> {
        let mut table = EdgeTable::new();
        table.compile_from(plan)?;
        Ok(table)
    }

    /// Compiles `plan` into this table in place (no large stack copy on an
    /// MCU). On error the table is left empty.
    pub fn compile_from(&mut self, plan: &ValidPlan) -> Result<(), WireError> {
        let result = self.fill(plan);
        if result.is_err() {
            *self = EdgeTable::new();
        }
        result
    }

    fn fill(&mut self, valid: &ValidPlan) -> Result<(), WireError> {
        let plan = valid.plan();
        let hz = valid.timer_clock_hz();
        self.edges.clear();
        self.timer_clock_hz = hz;
        self.repeat_count = plan.repeat_count;
        self.period_ticks = ticks_u32(plan.repeat_period_ns as u64, hz, 0)?;
        for exposure in plan.exposures() {
            let e = exposure.entry;
            let start = e.start_ns as u64;
            let end = start + e.duration_ns as u64;
            for (h, head) in plan.heads.iter().enumerate() {
                if !e.heads.contains(h) {
                    continue;
                }
                let cam = head.camera_trigger_channel;
                let (rise, fall) = (ticks_u32(start, hz, cam)?, ticks_u32(end, hz, cam)?);
                let owner = (exposure.index as u16, Edge::NO_SLOT);
                self.pulse(cam, rise, fall, owner)?;
                let pulse_ns = head.projector.profile().trigger_pulse_ns as u64;
                let proj = head.projector_trigger_channel;
                for (k, slot) in exposure.slots.iter().enumerate() {
                    let rise = start + slot.offset_ns as u64;
                    let (rise, fall) = (
                        ticks_u32(rise, hz, proj)?,
                        ticks_u32(rise + pulse_ns, hz, proj)?,
                    );
                    let owner = (exposure.index as u16, e.first_slot + k as u16);
                    self.pulse(proj, rise, fall, owner)?;
                }
            }
        }
        self.edges.sort_unstable_by_key(|e| (e.tick, e.channel));
        self.check_channels(valid.board().min_edge_spacing_ticks)
    }

    /// A High-then-Low pair on `channel`, owned by (exposure, slot).
    fn pulse(
        &mut self,
        channel: u8,
        rise: u32,
        fall: u32,
        owner: (u16, u16),
    ) -> Result<(), WireError> {
        let (exposure, slot) = owner;
        let overflow = WireError::EdgeTable {
            channel,
            tick: rise,
        };
        if fall <= rise || fall >= self.period_ticks {
            return Err(overflow);
        }
        self.edges
            .push(Edge {
                tick: rise,
                channel,
                level: Level::High,
                exposure,
                slot,
            })
            .map_err(|_| overflow)?;
        self.edges
            .push(Edge {
                tick: fall,
                channel,
                level: Level::Low,
                exposure,
                slot,
            })
            .map_err(|_| overflow)
    }

    /// Validation forbids overlapping pulses on a channel, but rounding and
    /// the timer's DMA need tick-level checks: per channel the levels must
    /// alternate from idle (toggle-mode playback), and edges must be at least
    /// `min_spacing` apart, from the cycle start and across the cycle wrap.
    fn check_channels(&self, min_spacing: u32) -> Result<(), WireError> {
        let mut level = [Level::Low; 256];
        let mut first = [None::<u32>; 256];
        let mut last = [None::<u32>; 256];
        for e in &self.edges {
            let c = e.channel as usize;
            if e.level == level[c] {
                return Err(WireError::EdgeTable {
                    channel: e.channel,
                    tick: e.tick,
                });
            }
            let spacing = e.tick - last[c].unwrap_or(0);
            if spacing < min_spacing {
                return Err(too_close(e.channel, e.tick, spacing, min_spacing));
            }
            level[c] = e.level;
            first[c].get_or_insert(e.tick);
            last[c] = Some(e.tick);
        }
        if self.repeat_count > 1 {
            for c in 0..256 {
                if let (Some(f), Some(l)) = (first[c], last[c]) {
                    let spacing = self.period_ticks - l + f;
                    if spacing < min_spacing {
                        return Err(too_close(c as u8, f, spacing, min_spacing));
                    }
                }
            }
        }
        Ok(())
    }

    /// Cycle length in ticks.
    pub fn period_ticks(&self) -> u32 {
        self.period_ticks
    }
    /// Number of cycles.
    pub fn repeat_count(&self) -> u32 {
        self.repeat_count
    }
    /// Timer clock the ticks are for.
    pub fn timer_clock_hz(&self) -> u32 {
        self.timer_clock_hz
    }
    /// All edges of one cycle, sorted by (tick, channel).
    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }
    /// Edges of one output channel, in time order (a timer channel's
    /// compare list).
    pub fn channel_edges(&self, channel: u8) -> impl Iterator<Item = &Edge> + '_ {
        self.edges.iter().filter(move |e| e.channel == channel)
    }
    /// Compare values of one output channel in time order: the ticks at
    /// which the line toggles, starting from idle `Low`; an even count.
    /// This is what a toggle-mode timer's DMA buffer holds, and what
    /// hil-sim's simulated timer plays.
    pub fn channel_ticks(&self, channel: u8) -> impl Iterator<Item = u32> + '_ {
        self.channel_edges(channel).map(|e| e.tick)
    }
    /// Ticks from the first cycle's start to the last cycle's end.
    pub fn total_ticks(&self) -> u64 {
        self.period_ticks as u64 * self.repeat_count as u64
    }
}

fn too_close(channel: u8, tick: u32, spacing_ticks: u32, min_ticks: u32) -> WireError {
    WireError::EdgesTooClose {
        channel,
        tick,
        spacing_ticks,
        min_ticks,
    }
}

/// `ns` as ticks, refused if it does not fit a 32-bit timer.
fn ticks_u32(ns: u64, hz: u32, channel: u8) -> Result<u32, WireError> {
    let t = ns_to_ticks(ns, hz);
    u32::try_from(t).map_err(|_| WireError::EdgeTable {
        channel,
        tick: u32::MAX,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::plan::examples;
    use protocol::BoardLimits;

    fn compiled(plan: protocol::ScanPlan) -> EdgeTable {
        EdgeTable::compile(&plan.validate(&BoardLimits::STM32G474).unwrap()).unwrap()
    }

    #[test]
    fn multiplexed_plan_has_24_pulses_inside_the_exposure() {
        let t = compiled(examples::multiplexed_24_at_5khz(1));
        assert_eq!(t.edges().len(), 2 + 48);
        let proj: heapless::Vec<&Edge, 64> = t.channel_edges(0).collect();
        assert_eq!(proj.len(), 48);
        // 200 us at 170 MHz = 34 000 ticks between triggers; first at 2 + 2 us = 680 ticks.
        assert_eq!(proj[0].tick, 680);
        assert_eq!(proj[2].tick - proj[0].tick, 34_000);
        let cam: heapless::Vec<&Edge, 4> = t.channel_edges(1).collect();
        assert_eq!((cam[0].tick, cam[1].tick), (340, 816_850));
        // 4 807 692 ns * 0.17 = 817 307.64 ticks, rounded to nearest.
        assert_eq!(t.period_ticks(), 817_308);
    }

    #[test]
    fn dual_head_fires_both_heads_together() {
        let t = compiled(examples::dual_head_psp(1));
        let a: heapless::Vec<u32, 64> = t.channel_edges(1).map(|e| e.tick).collect();
        let b: heapless::Vec<u32, 64> = t.channel_edges(3).map(|e| e.tick).collect();
        assert_eq!(a, b);
        assert_eq!(a.len(), 32);
    }
}
