//! The soak: many random valid plans through the board core on the virtual
//! clock, each checked three ways.
//!
//! 1. The sequencer's own feedback check (`ScanReport`: missing, late,
//!    unexpected feedback edges, worst feedback error) — what a real board
//!    reports.
//! 2. Output edges as the simulated timer played them against an
//!    independent expansion of the plan (tick by tick).
//! 3. Ground truth from the device models: triggers a device ignored or
//!    missed, and patterns whose light fell outside their camera exposure
//!    (or inside it by less than the plan's margin).

use board_core::{Dispatcher, TriggerHardware};
use protocol::limits::ns_to_ticks;
use protocol::plan::random::{random_kind, random_plan, PlanKind};
use protocol::{BoardLimits, Request, Response, ScanPlan, ScanReport, ScanState};
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::board::sim_device_info;
use crate::sim_hardware::{camera_config, projector_config, RecordedEdge, SimHardware, SimHead};

/// Why one soak scan could not be run at all.
#[derive(Debug, thiserror::Error)]
pub enum SoakError {
    /// The board refused a request of a plan that should be valid.
    #[error("board answered {response:?} to {request}")]
    Refused {
        /// The request's name.
        request: &'static str,
        /// The answer.
        response: Box<Response>,
    },
    /// The scan did not finish within 10 s of virtual time after its end.
    #[error("scan still {state:?} 10 s after its last cycle")]
    Stuck {
        /// The sequencer's state then.
        state: ScanState,
    },
}

/// Counters of one scan or many.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SoakTotals {
    /// Scans run.
    pub scans: u64,
    /// Scans per kind: dual-head, head-only, multiplexed, flood.
    pub by_kind: [u64; 4],
    /// Scans that ended `Done`.
    pub done: u64,
    /// Feedback edges the sequencer expected.
    pub feedback_expected: u64,
    /// ... that never came (the sequencer's count).
    pub feedback_missing: u64,
    /// ... that came outside the device's jitter tolerance.
    pub feedback_late: u64,
    /// Feedback edges that matched nothing.
    pub feedback_unexpected: u64,
    /// Worst |measured - expected| of a feedback edge, in ticks.
    pub worst_feedback_error_ticks: u64,
    /// Output edges played.
    pub output_edges: u64,
    /// Output edges missing, extra, or not at their planned tick.
    pub output_mismatches: u64,
    /// Worst |played - planned| of an output edge, in ticks.
    pub worst_output_error_ticks: u64,
    /// Triggers a device ignored (projector too fast) or missed (camera busy
    /// or injected).
    pub device_missed: u64,
    /// Patterns shown.
    pub patterns: u64,
    /// Patterns whose light was not entirely inside their exposure.
    pub out_of_window: u64,
    /// Patterns inside their exposure, but by less than the plan's margin.
    pub inside_margin: u64,
    /// Patterns the board itself judged from its captures.
    pub patterns_checked: u64,
    /// ... that it found outside their exposure (`ScanReport::out_of_window`).
    pub measured_out_of_window: u64,
    /// Patterns the board dropped unchecked (queue full).
    pub patterns_unchecked: u64,
}

impl SoakTotals {
    /// Adds `other`'s counts; keeps the worst errors.
    pub fn merge(&mut self, other: &SoakTotals) {
        self.scans += other.scans;
        for (a, b) in self.by_kind.iter_mut().zip(other.by_kind) {
            *a += b;
        }
        self.done += other.done;
        self.feedback_expected += other.feedback_expected;
        self.feedback_missing += other.feedback_missing;
        self.feedback_late += other.feedback_late;
        self.feedback_unexpected += other.feedback_unexpected;
        self.worst_feedback_error_ticks = self
            .worst_feedback_error_ticks
            .max(other.worst_feedback_error_ticks);
        self.output_edges += other.output_edges;
        self.output_mismatches += other.output_mismatches;
        self.worst_output_error_ticks = self
            .worst_output_error_ticks
            .max(other.worst_output_error_ticks);
        self.device_missed += other.device_missed;
        self.patterns += other.patterns;
        self.out_of_window += other.out_of_window;
        self.inside_margin += other.inside_margin;
        self.patterns_checked += other.patterns_checked;
        self.measured_out_of_window += other.measured_out_of_window;
        self.patterns_unchecked += other.patterns_unchecked;
    }
}

/// Index of a kind in `SoakTotals::by_kind`.
fn kind_index(kind: PlanKind) -> usize {
    match kind {
        PlanKind::DualHead => 0,
        PlanKind::HeadOnly(_) => 1,
        PlanKind::Multiplexed => 2,
        PlanKind::Flood => 3,
    }
}

/// Scan `index` of a soak with `seed`: its own random stream, so results do
/// not depend on how scans are spread over threads.
pub fn soak_scan(seed: u64, index: u64, faults: &DeviceFaults) -> Result<SoakTotals, SoakError> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let mut bits = || rng.next_u64();
    let kind = random_kind(&mut bits);
    let plan = random_plan(kind, &mut bits);
    let device_seed = bits();
    let mut totals = run_scan(&plan, device_seed, faults)?;
    totals.by_kind[kind_index(kind)] = 1;
    Ok(totals)
}

/// Device faults a soak can inject to see its checks catch them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeviceFaults {
    /// Every camera misses this trigger index (counted from 0 per scan).
    pub camera_miss: Option<u64>,
    /// Device latency jitter is this many times the profile's (1 = spec).
    pub jitter_scale: u64,
}

impl DeviceFaults {
    /// Devices exactly as their profiles say.
    pub const NONE: DeviceFaults = DeviceFaults {
        camera_miss: None,
        jitter_scale: 1,
    };
}

/// The simulated heads of `plan`, seeded from `device_seed`, with `faults`.
fn sim_heads(plan: &ScanPlan, device_seed: u64, faults: &DeviceFaults) -> Vec<SimHead> {
    plan.heads
        .iter()
        .enumerate()
        .map(|(i, h)| {
            let mut projector = projector_config(h.projector);
            let mut camera = camera_config(h.camera);
            projector.trigger_delay.jitter_ns *= faults.jitter_scale;
            camera.trigger_delay.jitter_ns *= faults.jitter_scale;
            if let Some(k) = faults.camera_miss {
                camera.missed_triggers.insert(k);
            }
            SimHead::new(*h, projector, camera, device_seed.wrapping_add(i as u64))
        })
        .collect()
}

/// Runs `plan` on a fresh simulated board through the dispatcher (upload,
/// commit, arm, start) and checks it, devices misbehaving as `faults` says.
pub fn run_scan(
    plan: &ScanPlan,
    device_seed: u64,
    faults: &DeviceFaults,
) -> Result<SoakTotals, SoakError> {
    let limits = BoardLimits::STM32G474;
    let heads = sim_heads(plan, device_seed, faults);
    let mut hw = SimHardware::new(limits, heads);
    let mut board = Dispatcher::new(sim_device_info(0x5153_494D, limits));
    let start_tick = upload_and_start(&mut board, &mut hw, plan)?;
    let report = drive_to_end(&mut board, &mut hw, start_tick)?;
    let mut totals = SoakTotals {
        scans: 1,
        done: (board.sequencer().state() == ScanState::Done) as u64,
        ..SoakTotals::default()
    };
    add_report(&mut totals, &report);
    check_outputs(
        &mut totals,
        plan,
        hw.recorded(),
        start_tick,
        limits.timer_clock_hz,
    );
    check_devices(&mut totals, plan, &hw);
    Ok(totals)
}

fn ask(
    board: &mut Dispatcher,
    hw: &mut SimHardware,
    name: &'static str,
    request: Request,
) -> Result<Response, SoakError> {
    let response = board.handle(&request, hw);
    match response {
        Response::Refused(_) => Err(SoakError::Refused {
            request: name,
            response: Box::new(response),
        }),
        ok => Ok(ok),
    }
}

fn upload_and_start(
    board: &mut Dispatcher,
    hw: &mut SimHardware,
    plan: &ScanPlan,
) -> Result<u64, SoakError> {
    ask(board, hw, "BeginPlan", Request::BeginPlan(plan.header()))?;
    for index in 0..plan.exposures.len() {
        let exposure = plan.wire_exposure(index).unwrap_or_else(|| unreachable!());
        ask(
            board,
            hw,
            "AddExposure",
            Request::AddExposure {
                index: index as u16,
                exposure,
            },
        )?;
    }
    ask(board, hw, "CommitPlan", Request::CommitPlan)?;
    ask(board, hw, "Arm", Request::Arm)?;
    match ask(board, hw, "Start", Request::Start { delay_ns: 10_000 })? {
        Response::Started { start_tick } => Ok(start_tick),
        other => Err(SoakError::Refused {
            request: "Start",
            response: Box::new(other),
        }),
    }
}

/// Jumps the clock from event to event, polling the sequencer after each,
/// as the board's main loop would, until the scan ends.
fn drive_to_end(
    board: &mut Dispatcher,
    hw: &mut SimHardware,
    start_tick: u64,
) -> Result<ScanReport, SoakError> {
    let hz = hw.clock().timer_clock_hz();
    let poll_step = ns_to_ticks(1_000_000, hz); // the board polls every 1 ms
    let end = start_tick + board.sequencer().table().total_ticks();
    let give_up = end + ns_to_ticks(10_000_000_000, hz);
    loop {
        let now = hw.now_ticks();
        let target = hw
            .next_event_tick()
            .unwrap_or(now + poll_step)
            .min(now + poll_step)
            .max(now + 1);
        hw.advance_to(target);
        let seq = board.sequencer_mut();
        seq.poll(hw);
        while seq.pop_event().is_some() {}
        match seq.state() {
            ScanState::Done | ScanState::Aborted | ScanState::Faulted => return Ok(seq.report()),
            state if hw.now_ticks() > give_up => return Err(SoakError::Stuck { state }),
            _ => {}
        }
    }
}

fn add_report(totals: &mut SoakTotals, report: &ScanReport) {
    totals.feedback_expected += report.expected as u64;
    totals.feedback_missing += report.missing as u64;
    totals.feedback_late += report.late as u64;
    totals.feedback_unexpected += report.unexpected as u64;
    totals.worst_feedback_error_ticks = report.worst_error_ticks as u64;
    totals.patterns_checked += report.patterns_checked as u64;
    totals.measured_out_of_window += report.out_of_window as u64;
    totals.patterns_unchecked += report.patterns_unchecked as u64;
}

/// The plan's output edges, expanded independently of `EdgeTable`: every
/// cycle, exposure, head and slot, at start + cycle * period + its offset.
pub fn expected_outputs(plan: &ScanPlan, start_tick: u64, hz: u32) -> Vec<RecordedEdge> {
    let period = ns_to_ticks(plan.repeat_period_ns as u64, hz);
    let mut edges = Vec::new();
    let mut pulse = |base: u64, channel: u8, rise_ns: u64, fall_ns: u64| {
        for (ns, level) in [
            (rise_ns, protocol::Level::High),
            (fall_ns, protocol::Level::Low),
        ] {
            edges.push(RecordedEdge {
                tick: base + ns_to_ticks(ns, hz),
                channel,
                level,
            });
        }
    };
    for cycle in 0..plan.repeat_count as u64 {
        let base = start_tick + cycle * period;
        for exposure in plan.exposures() {
            let e = exposure.entry;
            for (_, head) in plan
                .heads
                .iter()
                .enumerate()
                .filter(|(h, _)| e.heads.contains(*h))
            {
                let start = e.start_ns as u64;
                pulse(
                    base,
                    head.camera_trigger_channel,
                    start,
                    start + e.duration_ns as u64,
                );
                let width = head.projector.profile().trigger_pulse_ns as u64;
                for slot in exposure.slots {
                    let rise = start + slot.offset_ns as u64;
                    pulse(base, head.projector_trigger_channel, rise, rise + width);
                }
            }
        }
    }
    edges.sort();
    edges
}

fn check_outputs(
    totals: &mut SoakTotals,
    plan: &ScanPlan,
    played: &[RecordedEdge],
    start_tick: u64,
    hz: u32,
) {
    let expected = expected_outputs(plan, start_tick, hz);
    let mut played = played.to_vec();
    played.sort();
    totals.output_edges += played.len() as u64;
    totals.output_mismatches += played.len().abs_diff(expected.len()) as u64;
    for (p, e) in played.iter().zip(&expected) {
        let error = p.tick.abs_diff(e.tick);
        if error != 0 || p.channel != e.channel || p.level != e.level {
            totals.output_mismatches += 1;
        }
        if p.channel == e.channel && p.level == e.level {
            totals.worst_output_error_ticks = totals.worst_output_error_ticks.max(error);
        }
    }
}

/// Ground truth: every pattern the DMD showed against the exposure the
/// camera actually made for it.
fn check_devices(totals: &mut SoakTotals, plan: &ScanPlan, hw: &SimHardware) {
    let margin = plan.margin_ns as u64;
    for (h, head) in hw.heads().iter().enumerate() {
        let missed = head.projector.ignored_triggers_ns().len() + head.camera.missed().len();
        totals.device_missed += missed as u64;
        let shown = head.projector.displayed();
        totals.patterns += shown.len() as u64;
        if missed > 0 {
            // The pairing of patterns and exposures is lost: count none of
            // them as in or out of window.
            continue;
        }
        let mut shown = shown.iter();
        let mut exposures = head.camera.exposures().iter();
        for _cycle in 0..plan.repeat_count {
            for exposure in plan.exposures().filter(|x| x.entry.heads.contains(h)) {
                let Some(taken) = exposures.next() else {
                    return;
                };
                let window = (taken.start_ns, taken.end_ns.unwrap_or(u64::MAX));
                for slot in exposure.slots {
                    let Some(pattern) = shown.next() else { return };
                    let light = (pattern.start_ns, pattern.start_ns + slot.display_ns as u64);
                    if light.0 < window.0 || light.1 > window.1 {
                        totals.out_of_window += 1;
                    } else if light.0 < window.0 + margin || light.1 + margin > window.1 {
                        totals.inside_margin += 1;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::plan::examples;

    #[test]
    fn every_example_runs_clean() {
        for (i, plan) in examples::all().iter().enumerate() {
            let t = run_scan(plan, i as u64, &DeviceFaults::NONE).unwrap();
            assert_eq!(t.done, 1, "example {i}: {t:?}");
            assert_eq!(
                (t.feedback_missing, t.feedback_late, t.feedback_unexpected),
                (0, 0, 0),
                "example {i}: {t:?}"
            );
            assert_eq!(
                (t.output_mismatches, t.worst_output_error_ticks),
                (0, 0),
                "example {i}: {t:?}"
            );
            assert_eq!(
                (t.device_missed, t.out_of_window, t.inside_margin),
                (0, 0, 0),
                "example {i}: {t:?}"
            );
            assert_eq!(t.patterns_checked, t.patterns, "example {i}: {t:?}");
            assert_eq!(
                t.measured_out_of_window + t.patterns_unchecked,
                0,
                "example {i}: {t:?}"
            );
            assert!(t.output_edges > 0 && t.patterns > 0 && t.feedback_expected == t.output_edges);
        }
    }

    #[test]
    fn a_camera_missing_a_trigger_is_reported_missing() {
        let plan = examples::multiplexed_24_at_5khz(3);
        let t = run_scan(
            &plan,
            7,
            &DeviceFaults {
                camera_miss: Some(1),
                jitter_scale: 1,
            },
        )
        .unwrap();
        // The second exposure never happened: its rising and falling
        // exposure-active edges are missing, nothing else.
        assert_eq!(t.feedback_missing, 2, "{t:?}");
        assert_eq!(t.device_missed, 1);
        assert_eq!(t.feedback_late + t.feedback_unexpected, 0);
        assert_eq!(t.done, 1);
    }

    #[test]
    fn jitter_beyond_the_profile_is_reported_late() {
        let plan = examples::multiplexed_24_at_5khz(3);
        let t = run_scan(
            &plan,
            3,
            &DeviceFaults {
                camera_miss: None,
                jitter_scale: 20,
            },
        )
        .unwrap();
        assert!(t.feedback_late > 0, "{t:?}");
        // 20 x 100 ns peak jitter: errors beyond the 100 ns tolerance, below 2 us.
        assert!(
            t.worst_feedback_error_ticks > 18 && t.worst_feedback_error_ticks <= 341,
            "{t:?}"
        );
        assert_eq!(t.output_mismatches, 0);
    }

    #[test]
    fn the_boards_window_check_agrees_with_device_ground_truth() {
        let faults = DeviceFaults {
            camera_miss: None,
            jitter_scale: 10,
        };
        let mut all = SoakTotals::default();
        for i in 0..300 {
            all.merge(&soak_scan(3, i, &faults).unwrap());
        }
        assert_eq!(all.patterns_checked, all.patterns, "{all:?}");
        assert!(all.out_of_window > 100, "{all:?}");
        // The board sees captures rounded to 5.9 ns ticks, the devices log
        // nanoseconds: only patterns within a tick of an exposure edge may
        // be judged differently.
        let diff = all.measured_out_of_window.abs_diff(all.out_of_window);
        assert!(diff * 100 <= all.out_of_window, "{all:?}");
    }

    #[test]
    fn the_same_scan_index_gives_the_same_result() {
        let a = soak_scan(5, 17, &DeviceFaults::NONE).unwrap();
        assert_eq!(a, soak_scan(5, 17, &DeviceFaults::NONE).unwrap());
    }

    #[test]
    fn random_scans_run_clean() {
        let mut all = SoakTotals::default();
        for i in 0..300 {
            all.merge(&soak_scan(1, i, &DeviceFaults::NONE).unwrap());
        }
        assert_eq!(all.scans, 300);
        assert!(all.by_kind.iter().all(|&n| n > 0), "{all:?}");
        assert_eq!(all.done, 300);
        assert_eq!(
            all.feedback_missing + all.feedback_late + all.feedback_unexpected,
            0,
            "{all:?}"
        );
        assert_eq!(
            all.output_mismatches + all.device_missed + all.out_of_window,
            0,
            "{all:?}"
        );
    }
}
