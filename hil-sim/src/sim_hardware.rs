//! `TriggerHardware` on the virtual clock: the simulated board's timers.
//!
//! It plays an edge table the way the STM32 does: each output channel's
//! compare list (`EdgeTable::channel_ticks`, the DMA buffer) toggles its line
//! once per entry, the list replayed every cycle. Output edges drive the
//! simulated devices (sync-link's `devices::{Projector, Camera}`), whose
//! trigger-out / exposure-active pulses come back, after latency and jitter,
//! as timestamped input captures.
//!
//! Event-driven: `advance_to` jumps from edge to edge; nothing runs per tick.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};

use board_core::{Capture, EdgeTable, TriggerHardware};
use protocol::limits::{CameraModel, ProjectorModel, MAX_OUTPUT_CHANNELS};
use protocol::{BoardLimits, HardwareFault, HeadConfig, Level};

use crate::clock::VirtualClock;
use crate::devices::{Camera, CameraConfig, Projector, ProjectorConfig};

/// An output edge as the simulated timer produced it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct RecordedEdge {
    /// Board tick.
    pub tick: u64,
    /// Output channel.
    pub channel: u8,
    /// Level after the edge.
    pub level: Level,
}

/// The simulated projector behaving as `model`'s profile says.
///
/// Device models count whole nanoseconds converted from board ticks, which
/// can read a spacing that is exactly at a limit (in ticks, as validation
/// guarantees) 1 ns short; the limits get that 1 ns back here.
pub fn projector_config(model: ProjectorModel) -> ProjectorConfig {
    let mut config = ProjectorConfig::from_profile(&model.profile());
    config.min_pattern_period_ns = config.min_pattern_period_ns.saturating_sub(1);
    config
}

/// The simulated camera behaving as `model`'s profile says (trigger-width
/// exposure), with the same 1 ns allowance as [`projector_config`].
pub fn camera_config(model: CameraModel) -> CameraConfig {
    let mut config = CameraConfig::from_profile(&model.profile());
    config.min_gap_ns = config.min_gap_ns.saturating_sub(1);
    config.min_frame_period_ns = config.min_frame_period_ns.saturating_sub(1);
    config
}

/// One simulated head: its wiring to the board and its two devices.
#[derive(Debug, Clone)]
pub struct SimHead {
    /// Which board channels the devices hang on.
    pub wiring: HeadConfig,
    /// The DMD.
    pub projector: Projector,
    /// The camera.
    pub camera: Camera,
}

impl SimHead {
    /// A head wired as `wiring` says, its devices as its models' profiles
    /// say, jitter seeded from `seed`.
    pub fn from_profiles(wiring: HeadConfig, seed: u64) -> Self {
        Self::new(
            wiring,
            projector_config(wiring.projector),
            camera_config(wiring.camera),
            seed,
        )
    }

    /// A head with explicit device configurations (fault injection).
    pub fn new(
        wiring: HeadConfig,
        projector: ProjectorConfig,
        camera: CameraConfig,
        seed: u64,
    ) -> Self {
        SimHead {
            wiring,
            projector: Projector::new(projector, seed.wrapping_mul(2).wrapping_add(1)),
            camera: Camera::new(camera, seed.wrapping_mul(2).wrapping_add(2)),
        }
    }
}

/// One output channel's compare list being played (a DMA stream).
#[derive(Debug, Clone)]
struct ChannelPlayer {
    channel: u8,
    ticks: Vec<u32>,
    index: usize,
    cycle: u32,
}

#[derive(Debug, Clone)]
struct Run {
    start_tick: u64,
    repeat_count: u32,
    period_ticks: u64,
    players: Vec<ChannelPlayer>,
}

impl Run {
    fn tick_of(&self, p: &ChannelPlayer, index: usize) -> u64 {
        self.start_tick + p.cycle as u64 * self.period_ticks + p.ticks[index] as u64
    }

    /// The next output edge: (tick, player index).
    fn next(&self) -> Option<(u64, usize)> {
        self.players
            .iter()
            .enumerate()
            .filter(|(_, p)| p.cycle < self.repeat_count && !p.ticks.is_empty())
            .map(|(i, p)| (self.tick_of(p, p.index), i))
            .min()
    }
}

/// The simulated board's timers, devices and input captures.
#[derive(Debug, Clone)]
pub struct SimHardware {
    clock: VirtualClock,
    limits: BoardLimits,
    heads: Vec<SimHead>,
    loaded: Option<Vec<ChannelPlayer>>,
    period_ticks: u64,
    run: Option<Run>,
    levels: [Level; MAX_OUTPUT_CHANNELS],
    pending: BinaryHeap<Reverse<(u64, u64, u8, Level)>>,
    pending_seq: u64,
    ready: VecDeque<Capture>,
    capture_capacity: usize,
    lost_captures: u32,
    recording: bool,
    recorded: Vec<RecordedEdge>,
    captured: Vec<Capture>,
}

impl SimHardware {
    /// A board with `limits` (its timer clock sets the tick) and `heads`.
    pub fn new(limits: BoardLimits, heads: Vec<SimHead>) -> Self {
        SimHardware {
            clock: VirtualClock::new(limits.timer_clock_hz),
            limits,
            heads,
            loaded: None,
            period_ticks: 0,
            run: None,
            levels: [Level::Low; MAX_OUTPUT_CHANNELS],
            pending: BinaryHeap::new(),
            pending_seq: 0,
            ready: VecDeque::new(),
            capture_capacity: usize::MAX,
            lost_captures: 0,
            recording: true,
            recorded: Vec::new(),
            captured: Vec::new(),
        }
    }

    /// The virtual clock.
    pub fn clock(&self) -> &VirtualClock {
        &self.clock
    }

    /// The simulated heads (device logs: what was displayed and exposed).
    pub fn heads(&self) -> &[SimHead] {
        &self.heads
    }

    /// The heads, mutably (fault injection between scans).
    pub fn heads_mut(&mut self) -> &mut [SimHead] {
        &mut self.heads
    }

    /// Whether output edges are being kept (on by default; the soak turns
    /// it off and checks edges as they come).
    pub fn set_recording(&mut self, on: bool) {
        self.recording = on;
    }

    /// Every output edge so far, in time order.
    pub fn recorded(&self) -> &[RecordedEdge] {
        &self.recorded
    }

    /// Every capture made readable so far (while recording), in time order.
    pub fn captures_log(&self) -> &[Capture] {
        &self.captured
    }

    /// Forgets the output edge and capture logs.
    pub fn clear_log(&mut self) {
        self.recorded.clear();
        self.captured.clear();
    }

    /// Takes the recorded output edges, leaving none.
    pub fn take_recorded(&mut self) -> Vec<RecordedEdge> {
        std::mem::take(&mut self.recorded)
    }

    /// Limits how many captures wait unread; more are lost and reported as
    /// `HardwareFault::CaptureOverflow` (fault injection).
    pub fn set_capture_capacity(&mut self, capacity: usize) {
        self.capture_capacity = capacity;
    }

    /// Whether the timers are playing a scan.
    pub fn is_playing(&self) -> bool {
        self.run.is_some()
    }

    /// The tick of the next thing that will happen (output edge or capture).
    pub fn next_event_tick(&self) -> Option<u64> {
        let output = self.run.as_ref().and_then(|r| r.next()).map(|(t, _)| t);
        let capture = self.pending.peek().map(|Reverse((t, ..))| *t);
        match (output, capture) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// Runs the simulation up to `tick`: plays every output edge at or
    /// before it, feeds the devices, and makes due captures readable.
    pub fn advance_to(&mut self, tick: u64) {
        while let Some((t, i)) = self.run.as_ref().and_then(|r| r.next()) {
            if t > tick {
                break;
            }
            self.play(t, i);
        }
        if self.run.as_ref().is_some_and(|r| r.next().is_none()) {
            // One-pulse mode: the timer stops itself after the last cycle.
            self.run = None;
        }
        while let Some(Reverse((t, _, channel, level))) = self.pending.peek().copied() {
            if t > tick {
                break;
            }
            self.pending.pop();
            if self.ready.len() >= self.capture_capacity {
                self.lost_captures += 1;
            } else {
                let capture = Capture {
                    feedback_channel: channel,
                    level,
                    tick: t,
                };
                if self.recording {
                    self.captured.push(capture);
                }
                self.ready.push_back(capture);
            }
        }
        self.clock.advance_to(tick);
    }

    fn play(&mut self, tick: u64, player: usize) {
        let Some(run) = self.run.as_mut() else { return };
        let p = &mut run.players[player];
        let channel = p.channel;
        // Toggle mode: the line flips; the table's level is not consulted.
        let level = match self.levels[channel as usize] {
            Level::Low => Level::High,
            Level::High => Level::Low,
        };
        p.index += 1;
        if p.index == p.ticks.len() {
            p.index = 0;
            p.cycle += 1;
        }
        self.levels[channel as usize] = level;
        if self.recording {
            self.recorded.push(RecordedEdge {
                tick,
                channel,
                level,
            });
        }
        self.drive_devices(channel, level, tick);
    }

    /// Hands an output edge to the device wired to `channel` and schedules
    /// the feedback edge it answers with.
    fn drive_devices(&mut self, channel: u8, level: Level, tick: u64) {
        let at_ns = self.clock.ticks_to_ns(tick);
        let mut feedback = Vec::new();
        for head in &mut self.heads {
            let w = head.wiring;
            if w.projector_trigger_channel == channel {
                if let Some(edge) = head.projector.on_edge(level, at_ns) {
                    feedback.push((w.projector_feedback_channel, edge));
                }
            }
            if w.camera_trigger_channel == channel {
                if let Some(edge) = head.camera.on_edge(level, at_ns) {
                    feedback.push((w.camera_feedback_channel, edge));
                }
            }
        }
        for (fb, edge) in feedback {
            let tick = self.clock.ns_to_ticks(edge.at_ns);
            self.push_pending(tick, fb, edge.level);
        }
    }

    fn push_pending(&mut self, tick: u64, channel: u8, level: Level) {
        self.pending_seq += 1;
        self.pending
            .push(Reverse((tick, self.pending_seq, channel, level)));
    }
}

impl TriggerHardware for SimHardware {
    fn load(&mut self, table: &EdgeTable) -> Result<(), HardwareFault> {
        self.stop();
        let mut players = Vec::new();
        for channel in 0..MAX_OUTPUT_CHANNELS as u8 {
            let ticks: Vec<u32> = table.channel_ticks(channel).collect();
            if ticks.is_empty() {
                continue;
            }
            if channel >= self.limits.output_channels {
                return Err(HardwareFault::ChannelUnavailable { channel });
            }
            players.push(ChannelPlayer {
                channel,
                ticks,
                index: 0,
                cycle: 0,
            });
        }
        self.period_ticks = table.period_ticks() as u64;
        self.loaded = Some(players);
        self.lost_captures = 0;
        Ok(())
    }

    fn start(&mut self, start_tick: u64, repeat_count: u32) -> Result<(), HardwareFault> {
        let now_tick = self.clock.now_ticks();
        if start_tick <= now_tick {
            return Err(HardwareFault::StartInPast {
                start_tick,
                now_tick,
            });
        }
        let players = self.loaded.clone().ok_or(HardwareFault::NotLoaded)?;
        self.run = Some(Run {
            start_tick,
            repeat_count,
            period_ticks: self.period_ticks,
            players,
        });
        Ok(())
    }

    fn stop(&mut self) {
        self.run = None;
        let now = self.clock.now_ticks();
        for channel in 0..MAX_OUTPUT_CHANNELS {
            if self.levels[channel] == Level::High {
                // Forced inactive: the line falls now, and the devices see it.
                self.levels[channel] = Level::Low;
                if self.recording {
                    self.recorded.push(RecordedEdge {
                        tick: now,
                        channel: channel as u8,
                        level: Level::Low,
                    });
                }
                self.drive_devices(channel as u8, Level::Low, now);
            }
        }
    }

    fn now_ticks(&self) -> u64 {
        self.clock.now_ticks()
    }

    fn pop_capture(&mut self) -> Option<Capture> {
        self.ready.pop_front()
    }

    fn fault(&self) -> Option<HardwareFault> {
        (self.lost_captures > 0).then_some(HardwareFault::CaptureOverflow {
            lost: self.lost_captures,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::plan::examples;

    fn table(plan: protocol::ScanPlan) -> EdgeTable {
        EdgeTable::compile(&plan.validate(&BoardLimits::STM32G474).unwrap()).unwrap()
    }

    #[test]
    fn plays_the_table_every_cycle_to_the_tick() {
        let plan = examples::multiplexed_24_at_5khz(3);
        let heads = plan
            .heads
            .iter()
            .map(|h| SimHead::from_profiles(*h, 1))
            .collect();
        let t = table(plan);
        let mut hw = SimHardware::new(BoardLimits::STM32G474, heads);
        hw.load(&t).unwrap();
        hw.start(1_000, 3).unwrap();
        hw.advance_to(u64::MAX / 2);
        assert!(!hw.is_playing());
        let mut expected: Vec<RecordedEdge> = (0..3u64)
            .flat_map(|k| {
                let t = &t;
                t.edges().iter().map(move |e| RecordedEdge {
                    tick: 1_000 + k * t.period_ticks() as u64 + e.tick as u64,
                    channel: e.channel,
                    level: e.level,
                })
            })
            .collect();
        expected.sort();
        let mut got = hw.recorded().to_vec();
        got.sort();
        assert_eq!(got, expected);
        // 24 patterns per cycle shown, 1 exposure per cycle taken.
        assert_eq!(hw.heads()[0].projector.displayed().len(), 72);
        assert_eq!(hw.heads()[0].camera.exposures().len(), 3);
    }

    #[test]
    fn start_in_the_past_is_refused() {
        let mut hw = SimHardware::new(BoardLimits::STM32G474, Vec::new());
        hw.load(&table(examples::flood_preliminaries(1))).unwrap();
        hw.advance_to(500);
        assert_eq!(
            hw.start(400, 1),
            Err(HardwareFault::StartInPast {
                start_tick: 400,
                now_tick: 500
            })
        );
    }
}
