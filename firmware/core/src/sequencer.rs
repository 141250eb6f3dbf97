//! The scan state machine: idle -> armed -> running -> done | aborted |
//! faulted, and the feedback check while running.
//!
//! The sequencer never times edges itself: the hardware plays the edge
//! table. It checks the captured feedback against the table, one
//! [`LineCursor`] per feedback line, and queues events for the link.

use heapless::{Deque, Vec};
use protocol::limits::{MAX_OUTPUT_CHANNELS, MAX_SLOTS_PER_EXPOSURE};
use protocol::{Event, HardwareFault, Level, ScanReport, ScanState, ValidPlan, WireError};

use crate::edge_table::EdgeTable;
use crate::feedback::{feedback_lines, Expected, FeedbackLine, LineCursor, LineRole};
use crate::hardware::{Capture, TriggerHardware};
use crate::window_check::{ExposureKey, PatternVerdict, WindowCheck};

/// Events held between two link polls; overflow is counted in
/// `ScanReport::events_dropped`.
pub const EVENT_QUEUE: usize = 32;

/// The sequencer: plan table, state, feedback check, event queue.
#[derive(Debug)]
pub struct Sequencer {
    state: ScanState,
    table: EdgeTable,
    loaded: bool,
    lines: Vec<FeedbackLine, MAX_OUTPUT_CHANNELS>,
    cursors: Vec<LineCursor, MAX_OUTPUT_CHANNELS>,
    start_tick: u64,
    report: ScanReport,
    events: Deque<Event, EVENT_QUEUE>,
    windows: WindowCheck,
}

impl Default for Sequencer {
    fn default() -> Self {
        Self::new()
    }
}

impl Sequencer {
    /// An idle sequencer without a plan.
    pub const fn new() -> Self {
        Sequencer {
            state: ScanState::Idle,
            table: EdgeTable::new(),
            loaded: false,
            lines: Vec::new(),
            cursors: Vec::new(),
            start_tick: 0,
            report: ScanReport {
                cycles: 0,
                expected: 0,
                on_time: 0,
                late: 0,
                missing: 0,
                unexpected: 0,
                worst_error_ticks: 0,
                events_dropped: 0,
                patterns_checked: 0,
                out_of_window: 0,
                patterns_unchecked: 0,
            },
            events: Deque::new(),
            windows: WindowCheck::new(),
        }
    }

    /// Current state.
    pub fn state(&self) -> ScanState {
        self.state
    }
    /// Counters of the current or last scan.
    pub fn report(&self) -> ScanReport {
        self.report
    }
    /// The compiled table (empty before a plan is loaded).
    pub fn table(&self) -> &EdgeTable {
        &self.table
    }
    /// Whether a compiled plan is held.
    pub fn plan_loaded(&self) -> bool {
        self.loaded
    }
    /// Board tick at which the running or last scan started.
    pub fn start_tick(&self) -> u64 {
        self.start_tick
    }
    /// The oldest queued event.
    pub fn pop_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    fn busy(&self) -> bool {
        matches!(self.state, ScanState::Armed | ScanState::Running)
    }

    /// Compiles `plan` into the sequencer's table. Refused while armed or
    /// running.
    pub fn load(&mut self, plan: &ValidPlan) -> Result<(), WireError> {
        if self.busy() {
            return Err(WireError::BadState { state: self.state });
        }
        self.loaded = false;
        self.table.compile_from(plan)?;
        self.lines = feedback_lines(plan);
        self.windows.load(plan);
        self.loaded = true;
        self.set_state(ScanState::Idle, 0);
        Ok(())
    }

    /// Loads the table into the hardware: idle -> armed.
    pub fn arm<H: TriggerHardware>(&mut self, hw: &mut H) -> Result<(), WireError> {
        if self.busy() {
            return Err(WireError::BadState { state: self.state });
        }
        if !self.loaded {
            return Err(WireError::NoPlan);
        }
        hw.stop();
        hw.load(&self.table)?;
        let now = hw.now_ticks();
        self.set_state(ScanState::Armed, now);
        Ok(())
    }

    /// Starts the armed scan `delay_ticks` from now: armed -> running.
    /// Returns the first cycle's start tick.
    pub fn start<H: TriggerHardware>(
        &mut self,
        hw: &mut H,
        delay_ticks: u64,
    ) -> Result<u64, WireError> {
        if self.state != ScanState::Armed {
            return Err(WireError::BadState { state: self.state });
        }
        let start = hw.now_ticks() + delay_ticks.max(1);
        if let Err(fault) = hw.start(start, self.table.repeat_count()) {
            hw.stop();
            self.set_state(ScanState::Faulted, hw.now_ticks());
            return Err(fault.into());
        }
        self.start_tick = start;
        self.report = ScanReport {
            cycles: self.table.repeat_count(),
            ..ScanReport::default()
        };
        self.windows.reset();
        self.cursors.clear();
        for line in &self.lines {
            // `cursors` has the same capacity as `lines`.
            let _ = self.cursors.push(LineCursor::start(&self.table, line));
        }
        self.set_state(ScanState::Running, start);
        Ok(start)
    }

    /// Stops at once, outputs idle: armed/running -> aborted. A no-op
    /// (outputs still forced idle) in other states.
    pub fn abort<H: TriggerHardware>(&mut self, hw: &mut H) -> ScanReport {
        hw.stop();
        if self.busy() {
            let now = hw.now_ticks();
            self.finish(ScanState::Aborted, now);
        }
        self.report
    }

    /// Reads captures, checks them, detects the end of the scan and
    /// hardware faults. Call often while running (each loop turn on the
    /// board; after each clock jump in hil-sim).
    pub fn poll<H: TriggerHardware>(&mut self, hw: &mut H) {
        if self.state != ScanState::Running {
            // Drain stray captures so they do not count in the next scan.
            while hw.pop_capture().is_some() {}
            return;
        }
        if let Some(fault) = hw.fault() {
            self.fault(hw, fault);
            return;
        }
        while let Some(capture) = hw.pop_capture() {
            self.check_capture(capture);
        }
        let now = hw.now_ticks();
        self.expire_missing(now);
        let end = self.start_tick + self.table.total_ticks();
        if now >= end && self.cursors.iter().all(|c| c.is_exhausted()) {
            hw.stop();
            self.finish(ScanState::Done, now);
        }
    }

    fn fault<H: TriggerHardware>(&mut self, hw: &mut H, fault: HardwareFault) {
        hw.stop();
        let now = hw.now_ticks();
        self.push_event(Event::HardwareFault { fault, tick: now });
        self.finish(ScanState::Faulted, now);
    }

    fn finish(&mut self, state: ScanState, tick: u64) {
        self.set_state(state, tick);
        self.push_event(Event::ScanFinished {
            state,
            report: self.report,
        });
    }

    fn set_state(&mut self, state: ScanState, tick: u64) {
        if self.state != state {
            self.state = state;
            self.push_event(Event::StateChanged { state, tick });
        }
    }

    fn push_event(&mut self, event: Event) {
        if self.events.push_back(event).is_err() {
            self.report.events_dropped = self.report.events_dropped.saturating_add(1);
        }
    }

    fn line_index(&self, feedback_channel: u8) -> Option<usize> {
        self.lines
            .iter()
            .position(|l| l.feedback_channel == feedback_channel)
    }

    /// Attributes one capture to its line's expected edges: on time (within
    /// the device's jitter), off time (early or late, counted as `late`),
    /// or unexpected; expected edges it skips past are missing.
    fn check_capture(&mut self, c: Capture) {
        let Some(i) = self.line_index(c.feedback_channel) else {
            self.unexpected(c);
            return;
        };
        let line = self.lines[i];
        loop {
            let Some(e) = self.cursors[i].peek(&self.table, &line, self.start_tick) else {
                self.unexpected(c);
                return;
            };
            let tol = line.tolerance_ticks as u64;
            let cursor = &self.cursors[i];
            let early_limit = cursor.early_limit(&self.table, &line, self.start_tick);
            let late_limit = cursor.late_limit(&self.table, &line, self.start_tick);
            // Before this edge's window, or of the wrong level before it:
            // belongs to no expected edge.
            if c.tick + early_limit < e.tick || (c.level != e.level && c.tick < e.tick) {
                self.unexpected(c);
                return;
            }
            let error = c.tick.abs_diff(e.tick);
            let limit = if c.tick < e.tick {
                early_limit
            } else {
                late_limit
            };
            if c.level == e.level && error <= limit {
                self.report.expected += 1;
                self.report.worst_error_ticks = self
                    .report
                    .worst_error_ticks
                    .max(error.min(u32::MAX as u64) as u32);
                if error <= tol {
                    self.report.on_time += 1;
                } else {
                    self.report.late += 1;
                    self.push_event(Event::FeedbackLate {
                        feedback_channel: line.feedback_channel,
                        level: e.level,
                        cycle: e.cycle,
                        expected_tick: e.tick,
                        measured_tick: c.tick,
                    });
                }
                self.cursors[i].advance(&self.table, &line);
                self.check_window(&line, &e, c.tick);
                return;
            }
            self.missing(i, e.level, e.cycle, e.tick);
        }
    }

    /// Feeds a matched feedback edge to the pattern-in-exposure check and
    /// reports its verdicts.
    fn check_window(&mut self, line: &FeedbackLine, e: &Expected, tick: u64) {
        let key = ExposureKey {
            head: line.head,
            cycle: e.cycle,
            exposure: e.exposure,
        };
        let mut verdicts: Vec<PatternVerdict, MAX_SLOTS_PER_EXPOSURE> = Vec::new();
        let mut collect = |v: PatternVerdict| {
            // At most one exposure's patterns resolve at once.
            let _ = verdicts.push(v);
        };
        match (line.role, e.level) {
            (LineRole::Camera, level) => self.windows.camera(key, level, tick, &mut collect),
            (LineRole::Projector, Level::High) => {
                if self.windows.projector_rise(key, e.slot, tick, &mut collect) {
                    self.report.patterns_unchecked += 1;
                }
            }
            (LineRole::Projector, Level::Low) => {}
        }
        for v in verdicts {
            self.report.patterns_checked += 1;
            if !v.inside() {
                self.report.out_of_window += 1;
                self.push_event(Event::PatternOutsideExposure {
                    head: v.key.head,
                    cycle: v.key.cycle,
                    exposure: v.key.exposure,
                    slot: v.slot,
                    light_ticks: v.light,
                    exposure_ticks: v.window,
                });
            }
        }
    }

    /// Expected edges whose late window closed before `now` without a
    /// capture are missing.
    fn expire_missing(&mut self, now: u64) {
        for i in 0..self.lines.len() {
            let line = self.lines[i];
            while let Some(e) = self.cursors[i].peek(&self.table, &line, self.start_tick) {
                let limit = self.cursors[i].late_limit(&self.table, &line, self.start_tick);
                if e.tick + limit >= now {
                    break;
                }
                self.missing(i, e.level, e.cycle, e.tick);
            }
        }
    }

    fn missing(&mut self, i: usize, level: Level, cycle: u32, expected_tick: u64) {
        let line = self.lines[i];
        self.report.expected += 1;
        self.report.missing += 1;
        self.push_event(Event::FeedbackMissing {
            feedback_channel: line.feedback_channel,
            level,
            cycle,
            expected_tick,
        });
        self.cursors[i].advance(&self.table, &line);
    }

    fn unexpected(&mut self, c: Capture) {
        self.report.unexpected += 1;
        self.push_event(Event::FeedbackUnexpected {
            feedback_channel: c.feedback_channel,
            level: c.level,
            measured_tick: c.tick,
        });
    }
}
