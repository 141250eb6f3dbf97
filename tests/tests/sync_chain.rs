//! The whole trigger chain: host client -> serial port (a real pty) ->
//! simulated board (board-core on the virtual 170 MHz clock) -> simulated
//! DMDs and cameras, for the four plan kinds of the capture modes:
//! (a) dual-head simultaneous PSP, (b) head-A-only / head-B-only reference
//! runs, (c) 24 binary patterns at 5 kHz inside one long exposure, repeated
//! at 208 Hz, (d) the uniform floods before adaptive projection.
//!
//! Each run checks: the board's own feedback check found every edge on time;
//! the edges the board's timers played equal, tick for tick, the timeline
//! the plan specifies (computed from the plan alone); and each camera
//! exposure contained exactly the patterns the plan puts in it.

use hil_sim::board::SimBoardConfig;
use hil_sim::devices::patterns_in_window;
use integration_tests::{planned_edges, pty_rig, recorded_edges, PtyRig, PATIENT};
use protocol::limits::ns_to_ticks;
use protocol::plan::examples;
use protocol::plan::random::{random_kind, random_plan, SplitMix64};
use protocol::{Level, ScanPlan, ScanState};
use slscan::board::ScanOutcome;

/// Delay from `Start` to the first cycle.
const START_DELAY_NS: u32 = 1_000_000;

/// Runs `plan` on a fresh simulated board through the pty and checks the
/// three things the module doc lists. Returns the rig and outcome for
/// mode-specific checks.
fn run_and_check(plan: &ScanPlan, seed: u64) -> (PtyRig, ScanOutcome) {
    let mut rig = pty_rig(
        SimBoardConfig {
            seed,
            ..SimBoardConfig::default()
        },
        PATIENT,
    )
    .expect("simulated board on a pty, client connected");
    let outcome = run_on(&mut rig, plan);
    (rig, outcome)
}

/// Runs `plan` on `rig`'s board and checks it (see the module doc).
fn run_on(rig: &mut PtyRig, plan: &ScanPlan) -> ScanOutcome {
    let outcome = rig
        .client
        .run_plan(plan, START_DELAY_NS, |_| {})
        .expect("the plan runs");

    assert_eq!(outcome.state, ScanState::Done);
    assert!(outcome.is_clean(), "feedback deviated: {outcome:#?}");

    let hz = rig.info.limits.timer_clock_hz;
    let planned = planned_edges(plan, outcome.start_tick, hz);
    let recorded = recorded_edges(&rig.board);
    assert_eq!(recorded.len(), planned.len());
    if let Some((i, (got, want))) = recorded
        .iter()
        .zip(&planned)
        .enumerate()
        .find(|(_, (got, want))| got != want)
    {
        panic!(
            "edge {i} of {}: played {got:?}, plan says {want:?}",
            planned.len()
        );
    }
    // Each output edge comes back once on its feedback line.
    assert_eq!(outcome.report.expected as usize, planned.len());
    // The board's own verdict: every pattern of every head and cycle was
    // checked from its captures, and lit inside its exposure.
    assert_eq!(
        outcome.report.patterns_checked as usize,
        planned_patterns(plan)
    );
    assert_eq!(outcome.report.out_of_window, 0);

    assert_cameras_saw_their_slots(plan, rig);
    outcome
}

/// Patterns a plan shows in all: per cycle, each slot once per head its
/// exposure names.
fn planned_patterns(plan: &ScanPlan) -> usize {
    let per_cycle: usize = plan
        .exposures()
        .map(|e| {
            e.slots.len()
                * (0..plan.heads.len())
                    .filter(|&h| e.entry.heads.contains(h))
                    .count()
        })
        .sum();
    per_cycle * plan.repeat_count as usize
}

/// Every camera exposure holds exactly its exposure's patterns, each shown
/// whole while the sensor integrates, and no device dropped a trigger.
fn assert_cameras_saw_their_slots(plan: &ScanPlan, rig: &PtyRig) {
    let board = rig.board.board();
    for (h, _) in plan.heads.iter().enumerate() {
        let sim = &board.hardware().heads()[h];
        let exposures = sim.camera.exposures();
        let shown = sim.projector.displayed();
        assert!(
            sim.camera.missed().is_empty(),
            "head {h}: {:?}",
            sim.camera.missed()
        );
        assert!(sim.projector.ignored_triggers_ns().is_empty(), "head {h}");
        let (mut frame, mut pattern) = (0usize, 0usize);
        for _cycle in 0..plan.repeat_count {
            for exposure in plan.exposures().filter(|e| e.entry.heads.contains(h)) {
                let cam = exposures[frame];
                let end_ns = cam.end_ns.expect("exposure ended");
                let seen = patterns_in_window(shown, cam.start_ns, end_ns);
                assert_eq!(seen.len(), exposure.slots.len(), "head {h} frame {frame}");
                for (k, &(index, overlap_ns)) in seen.iter().enumerate() {
                    let d = shown[pattern + k];
                    assert_eq!(index, d.pattern_index);
                    assert_eq!(
                        overlap_ns,
                        d.end_ns - d.start_ns,
                        "pattern {index} cut short"
                    );
                }
                frame += 1;
                pattern += exposure.slots.len();
            }
        }
        assert_eq!(exposures.len(), frame, "head {h}: frames taken");
        assert_eq!(shown.len(), pattern, "head {h}: patterns shown");
    }
}

#[test]
fn a_dual_head_simultaneous_phase_shifting() {
    let plan = examples::dual_head_psp(2);
    let (rig, outcome) = run_and_check(&plan, 1);
    // Both heads fire together: each projector and camera edge of head A has
    // its head-B twin at the very same tick.
    let edges = recorded_edges(&rig.board);
    let on = |channel: u8| -> Vec<(u64, Level)> {
        edges
            .iter()
            .filter(|e| e.channel == channel)
            .map(|e| (e.tick, e.level))
            .collect()
    };
    let [a, b] = [&plan.heads[0], &plan.heads[1]];
    assert_eq!(
        on(a.projector_trigger_channel),
        on(b.projector_trigger_channel)
    );
    assert_eq!(on(a.camera_trigger_channel), on(b.camera_trigger_channel));
    assert_eq!(on(a.camera_trigger_channel).len(), 2 * 16 * 2);
    assert!(
        outcome.report.worst_error_ticks > 0,
        "device jitter is simulated"
    );
}

#[test]
fn b_head_a_only_and_head_b_only_reference_runs() {
    for head in 0..2u8 {
        let plan = examples::head_only(head, 1);
        let (rig, _) = run_and_check(&plan, 2);
        let other = &plan.heads[1 - head as usize];
        let edges = recorded_edges(&rig.board);
        assert!(
            edges
                .iter()
                .all(|e| e.channel != other.projector_trigger_channel
                    && e.channel != other.camera_trigger_channel),
            "head {head} only: the other head's lines stay idle"
        );
        assert_eq!(edges.len(), 16 * 2 * 2);
    }
}

#[test]
fn c_24_patterns_at_5_khz_inside_one_exposure_repeated_at_208_hz() {
    let plan = examples::multiplexed_24_at_5khz(3);
    let (rig, outcome) = run_and_check(&plan, 3);
    let hz = rig.info.limits.timer_clock_hz as u64;
    let head = plan.heads[0];
    let edges = recorded_edges(&rig.board);
    let rises = |channel: u8| -> Vec<u64> {
        edges
            .iter()
            .filter(|e| e.channel == channel && e.level == Level::High)
            .map(|e| e.tick)
            .collect()
    };
    let camera = rises(head.camera_trigger_channel);
    let projector = rises(head.projector_trigger_channel);
    assert_eq!(camera.len(), 3);
    assert_eq!(projector.len(), 3 * 24);

    // The camera repeats at 208 Hz: one cycle of round(4_807_692 ns) ticks.
    let period_ticks = ns_to_ticks(plan.repeat_period_ns as u64, hz as u32);
    assert!(camera.windows(2).all(|w| w[1] - w[0] == period_ticks));
    // 170 MHz / 817_308 ticks = 207.99990 Hz: 208 Hz to within a tick.
    let frame_rate_mhz = (hz * 1_000 + period_ticks / 2) / period_ticks;
    assert_eq!(frame_rate_mhz, 208_000, "208.000 Hz, in mHz");

    let camera_falls: Vec<u64> = edges
        .iter()
        .filter(|e| e.channel == head.camera_trigger_channel && e.level == Level::Low)
        .map(|e| e.tick)
        .collect();
    for (cycle, patterns) in projector.chunks(24).enumerate() {
        // 24 patterns exactly 200 us apart: 5 kHz to the tick.
        for w in patterns.windows(2) {
            assert_eq!(w[1] - w[0], 34_000, "cycle {cycle}");
            assert_eq!(hz / (w[1] - w[0]), 5_000);
        }
        // All 24 inside this cycle's one camera trigger pulse.
        assert!(patterns[0] > camera[cycle] && patterns[23] < camera_falls[cycle]);
    }
    assert_eq!(outcome.report.expected, 3 * 25 * 2);
}

#[test]
fn d_uniform_flood_preliminaries_of_adaptive_projection() {
    let plan = examples::flood_preliminaries(1);
    let (rig, _) = run_and_check(&plan, 4);
    let board = rig.board.board();
    let head = &board.hardware().heads()[0];
    assert_eq!(
        head.camera.exposures().len(),
        7,
        "7 grey levels, one frame each"
    );
    assert_eq!(head.projector.displayed().len(), 7);
    // Each flood is shown for the plan's display time (the DMD's pattern
    // table follows the plan), wholly inside its exposure (checked above).
    for shown in head.projector.displayed() {
        assert_eq!(
            shown.end_ns - shown.start_ns,
            examples::SLOW_DISPLAY_NS as u64
        );
    }
}

#[test]
fn same_seed_same_timeline_and_feedback_ticks() {
    let plan = examples::multiplexed_24_at_5khz(2);
    let run = || {
        let (rig, outcome) = run_and_check(&plan, 9);
        let captures = rig.board.board().hardware().captures_log().to_vec();
        (recorded_edges(&rig.board), captures, outcome.report)
    };
    assert_eq!(run(), run());
}

#[test]
fn random_valid_plans_of_every_kind_one_after_another_on_one_board() {
    let mut rig = pty_rig(SimBoardConfig::default(), PATIENT).expect("pty rig");
    let mut bits = SplitMix64(0x5EED_0003);
    let mut last_start = 0;
    for _ in 0..12 {
        let kind = random_kind(&mut bits);
        let mut plan = random_plan(kind, &mut bits);
        // Keep the run short: a few cycles are as telling as many.
        plan.repeat_count = plan.repeat_count.min(3);
        let outcome = run_on(&mut rig, &plan);
        assert!(
            outcome.start_tick > last_start,
            "the board's clock only moves on"
        );
        last_start = outcome.start_tick;
    }
}
