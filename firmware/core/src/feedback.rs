//! Matching captured feedback edges against the edges the plan expects.
//!
//! Each feedback line mirrors one output channel through a device: the
//! camera's exposure-active line follows its trigger, the projector's
//! trigger-out follows its trigger-in, each after the device's latency. A
//! [`LineCursor`] walks the expected edges of one line (the output channel's
//! edges of every cycle, shifted by the latency) in time order.

use protocol::limits::{ns_to_ticks, MAX_OUTPUT_CHANNELS};
use protocol::{Level, ValidPlan};

use crate::edge_table::EdgeTable;

/// How one feedback input follows one output channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FeedbackLine {
    /// The output channel it mirrors.
    pub output_channel: u8,
    /// The feedback input.
    pub feedback_channel: u8,
    /// Nominal output -> feedback latency.
    pub latency_ticks: u32,
    /// Largest |measured - expected| counted as on time: the device's peak
    /// jitter plus one tick of rounding.
    pub tolerance_ticks: u32,
    /// Head index (0 = A).
    pub head: u8,
    /// Which device of the head answers on this line.
    pub role: LineRole,
}

/// The device behind a feedback line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineRole {
    /// Projector trigger-out: rises when a pattern appears.
    Projector,
    /// Camera exposure-active: high while the sensor integrates.
    Camera,
}

/// The feedback lines of a plan: per head, projector then camera.
pub fn feedback_lines(plan: &ValidPlan) -> heapless::Vec<FeedbackLine, MAX_OUTPUT_CHANNELS> {
    let hz = plan.timer_clock_hz();
    let mut lines = heapless::Vec::new();
    for (h, head) in plan.plan().heads.iter().enumerate() {
        let p = head.projector.profile();
        let c = head.camera.profile();
        for (out, fb, latency, jitter, role) in [
            (
                head.projector_trigger_channel,
                head.projector_feedback_channel,
                p.latency_ns,
                p.jitter_ns,
                LineRole::Projector,
            ),
            (
                head.camera_trigger_channel,
                head.camera_feedback_channel,
                c.latency_ns,
                c.jitter_ns,
                LineRole::Camera,
            ),
        ] {
            // MAX_HEADS * 2 == MAX_OUTPUT_CHANNELS (asserted in protocol::limits),
            // so this never fails.
            let _ = lines.push(FeedbackLine {
                output_channel: out,
                feedback_channel: fb,
                latency_ticks: ns_to_ticks(latency as u64, hz) as u32,
                tolerance_ticks: ns_to_ticks(jitter as u64, hz) as u32 + 1,
                head: h as u8,
                role,
            });
        }
    }
    lines
}

/// An expected feedback edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Expected {
    /// Absolute board tick.
    pub tick: u64,
    /// Level after the edge.
    pub level: Level,
    /// Cycle number.
    pub cycle: u32,
    /// Exposure (index in the cycle) the edge belongs to.
    pub exposure: u16,
    /// Slot (index in `ScanPlan::slots`) of a projector edge, else
    /// `Edge::NO_SLOT`.
    pub slot: u16,
}

/// Position in one line's expected edges.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LineCursor {
    cycle: u32,
    index: usize,
    exhausted: bool,
    /// (cycle, tick in cycle) of the edge last stepped past.
    previous: Option<(u32, u32)>,
}

impl LineCursor {
    /// A cursor at the first expected edge of `line`.
    pub fn start(table: &EdgeTable, line: &FeedbackLine) -> LineCursor {
        let mut c = LineCursor {
            cycle: 0,
            index: 0,
            exhausted: false,
            previous: None,
        };
        c.seek(table, line);
        c
    }

    /// Moves to the first edge of `line`'s output at or after the current
    /// position, wrapping into the next cycle.
    fn seek(&mut self, table: &EdgeTable, line: &FeedbackLine) {
        let edges = table.edges();
        loop {
            if self.cycle >= table.repeat_count() {
                self.exhausted = true;
                return;
            }
            match edges[self.index.min(edges.len())..]
                .iter()
                .position(|e| e.channel == line.output_channel)
            {
                Some(offset) => {
                    self.index += offset;
                    return;
                }
                None => {
                    if self.index == 0 {
                        // The channel has no edges at all.
                        self.exhausted = true;
                        return;
                    }
                    self.index = 0;
                    self.cycle += 1;
                }
            }
        }
    }

    /// The expected edge under the cursor for a scan started at `start_tick`.
    pub fn peek(
        &self,
        table: &EdgeTable,
        line: &FeedbackLine,
        start_tick: u64,
    ) -> Option<Expected> {
        if self.exhausted {
            return None;
        }
        let e = table.edges().get(self.index)?;
        Some(Expected {
            tick: start_tick
                + self.cycle as u64 * table.period_ticks() as u64
                + e.tick as u64
                + line.latency_ticks as u64,
            level: e.level,
            cycle: self.cycle,
            exposure: e.exposure,
            slot: e.slot,
        })
    }

    /// Steps past the edge under the cursor.
    pub fn advance(&mut self, table: &EdgeTable, line: &FeedbackLine) {
        if self.exhausted {
            return;
        }
        if let Some(e) = table.edges().get(self.index) {
            self.previous = Some((self.cycle, e.tick));
        }
        self.index += 1;
        self.seek(table, line);
    }

    /// Whether every expected edge has been consumed.
    pub fn is_exhausted(&self) -> bool {
        self.exhausted
    }

    /// How far after an expected edge a capture may come and still be
    /// attributed to it (as late): half the gap to the line's next expected
    /// edge (half a cycle after the last one), at least the tolerance.
    pub fn late_limit(&self, table: &EdgeTable, line: &FeedbackLine, start_tick: u64) -> u64 {
        let Some(now) = self.peek(table, line, start_tick) else {
            return line.tolerance_ticks as u64;
        };
        let mut next = *self;
        next.advance(table, line);
        // The scan's last edge has no successor: allow half a cycle, so a
        // missing last edge is still declared, soon after the scan ends.
        let half_gap = next
            .peek(table, line, start_tick)
            .map_or(table.period_ticks() as u64 / 2, |n| (n.tick - now.tick) / 2);
        half_gap.max(line.tolerance_ticks as u64)
    }

    /// How far before an expected edge a capture may come and still be
    /// attributed to it (as early): half the gap to the line's previous
    /// expected edge, and never more than the latency (feedback cannot
    /// precede the output edge that causes it); at least the tolerance. With
    /// [`LineCursor::late_limit`] the windows of neighbouring edges never
    /// overlap.
    pub fn early_limit(&self, table: &EdgeTable, line: &FeedbackLine, start_tick: u64) -> u64 {
        let Some(now) = self.peek(table, line, start_tick) else {
            return line.tolerance_ticks as u64;
        };
        let half_gap = self.previous.map_or(u64::MAX, |(cycle, tick)| {
            let previous = start_tick
                + cycle as u64 * table.period_ticks() as u64
                + tick as u64
                + line.latency_ticks as u64;
            (now.tick - previous.min(now.tick)) / 2
        });
        half_gap
            .min(line.latency_ticks as u64)
            .max(line.tolerance_ticks as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::plan::examples;
    use protocol::BoardLimits;

    #[test]
    fn cursor_walks_every_cycle_in_order() {
        let plan = examples::multiplexed_24_at_5khz(3)
            .validate(&BoardLimits::STM32G474)
            .unwrap();
        let table = EdgeTable::compile(&plan).unwrap();
        let lines = feedback_lines(&plan);
        let cam = lines[1];
        let mut c = LineCursor::start(&table, &cam);
        let mut ticks = heapless::Vec::<u64, 8>::new();
        while let Some(e) = c.peek(&table, &cam, 1000) {
            ticks.push(e.tick).unwrap();
            c.advance(&table, &cam);
        }
        let lat = cam.latency_ticks as u64;
        let p = table.period_ticks() as u64;
        assert_eq!(
            &ticks[..],
            &[
                340,
                816_850,
                p + 340,
                p + 816_850,
                2 * p + 340,
                2 * p + 816_850
            ]
            .map(|t| 1000 + lat + t)
        );
        assert!(c.is_exhausted());
    }
}
