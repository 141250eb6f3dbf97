//! Every compiled edge table, for random valid plans of every kind: sorted,
//! playable by a toggle-mode timer, equal to an independent expansion of the
//! plan, and putting each pattern's light inside its exposure with the
//! plan's margin, in played ticks.

use board_core::EdgeTable;
use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use protocol::limits::{ns_to_ticks, BoardLimits};
use protocol::plan::random::{random_kind, random_plan, SplitMix64};
use protocol::{Level, ScanPlan};

const BOARD: BoardLimits = BoardLimits::STM32G474;

/// The plan's pulses per channel, in order, straight from the plan: (rise
/// tick, fall tick) within one cycle.
fn reference_pulses(plan: &ScanPlan, channel: u8) -> Vec<(u32, u32)> {
    let hz = BOARD.timer_clock_hz;
    let t = |ns: u64| ns_to_ticks(ns, hz) as u32;
    let mut pulses = Vec::new();
    for x in plan.exposures() {
        let start = x.entry.start_ns as u64;
        for (h, head) in plan.heads.iter().enumerate() {
            if !x.entry.heads.contains(h) {
                continue;
            }
            if head.camera_trigger_channel == channel {
                pulses.push((t(start), t(start + x.entry.duration_ns as u64)));
            }
            if head.projector_trigger_channel == channel {
                let width = head.projector.profile().trigger_pulse_ns as u64;
                for s in x.slots {
                    let rise = start + s.offset_ns as u64;
                    pulses.push((t(rise), t(rise + width)));
                }
            }
        }
    }
    pulses
}

/// The table's pulses on a channel: consecutive High, Low pairs.
fn table_pulses(table: &EdgeTable, channel: u8) -> Vec<(u32, u32)> {
    let edges: Vec<_> = table.channel_edges(channel).collect();
    assert!(
        edges.len().is_multiple_of(2),
        "channel {channel}: odd edge count"
    );
    edges
        .chunks(2)
        .map(|p| {
            assert_eq!(
                (p[0].level, p[1].level),
                (Level::High, Level::Low),
                "channel {channel} does not alternate"
            );
            (p[0].tick, p[1].tick)
        })
        .collect()
}

/// `a_ticks` played + `a_ns` >= `b_ticks` played + `b_ns`, exactly.
fn at_least(a_ticks: u32, a_ns: i64, b_ticks: u32, b_ns: i64) -> bool {
    (a_ticks as i128 - b_ticks as i128) * 1_000_000_000
        >= (b_ns - a_ns) as i128 * BOARD.timer_clock_hz as i128
}

fn check(plan: &ScanPlan) -> Result<(), TestCaseError> {
    let valid = plan
        .clone()
        .validate(&BOARD)
        .map_err(|e| TestCaseError::fail(format!("{e:?}")))?;
    let table = EdgeTable::compile(&valid).map_err(|e| TestCaseError::fail(format!("{e:?}")))?;
    let edges = table.edges();
    prop_assert!(edges
        .windows(2)
        .all(|w| (w[0].tick, w[0].channel) < (w[1].tick, w[1].channel)));
    prop_assert!(edges.iter().all(|e| e.tick < table.period_ticks()));
    prop_assert_eq!(
        table.period_ticks() as u64,
        ns_to_ticks(plan.repeat_period_ns as u64, BOARD.timer_clock_hz)
    );
    prop_assert_eq!(table.repeat_count(), plan.repeat_count);
    for channel in 0..BOARD.output_channels {
        let got = table_pulses(&table, channel);
        prop_assert_eq!(
            &got,
            &reference_pulses(plan, channel),
            "channel {}",
            channel
        );
        // DMA spacing, from the cycle start and across the wrap.
        let ticks: Vec<u32> = table.channel_ticks(channel).collect();
        if let (Some(first), Some(last)) = (ticks.first(), ticks.last()) {
            prop_assert!(*first >= BOARD.min_edge_spacing_ticks);
            prop_assert!(ticks
                .windows(2)
                .all(|w| w[1] - w[0] >= BOARD.min_edge_spacing_ticks));
            if plan.repeat_count > 1 {
                prop_assert!(table.period_ticks() - last + first >= BOARD.min_edge_spacing_ticks);
            }
        }
    }
    // Each pattern inside its exposure, with the margin, in played time.
    let margin = plan.margin_ns as i64;
    for (h, head) in plan.heads.iter().enumerate() {
        let (p, c) = (head.projector.profile(), head.camera.profile());
        let (p_lat, p_jit, c_lat, c_jit) = (
            p.latency_ns as i64,
            p.jitter_ns as i64,
            c.latency_ns as i64,
            c.jitter_ns as i64,
        );
        let cam = table_pulses(&table, head.camera_trigger_channel);
        let mut proj = table_pulses(&table, head.projector_trigger_channel).into_iter();
        let mut cam = cam.into_iter();
        for x in plan.exposures().filter(|x| x.entry.heads.contains(h)) {
            let (cam_rise, cam_fall) = cam.next().expect("a camera pulse per exposure");
            for s in x.slots {
                let (proj_rise, _) = proj.next().expect("a projector pulse per slot");
                prop_assert!(
                    at_least(proj_rise, p_lat - p_jit, cam_rise, c_lat + c_jit + margin),
                    "pattern starts too early: exposure {} head {}",
                    x.index,
                    h
                );
                prop_assert!(
                    at_least(
                        cam_fall,
                        c_lat - c_jit - margin,
                        proj_rise,
                        s.display_ns as i64 + p_lat + p_jit
                    ),
                    "pattern ends too late: exposure {} head {}",
                    x.index,
                    h
                );
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, rng_seed: RngSeed::Fixed(0x5eed), ..ProptestConfig::default() })]

    #[test]
    fn every_random_plan_compiles_to_a_correct_table(seed in any::<u64>()) {
        let mut bits = SplitMix64(seed);
        let kind = random_kind(&mut bits);
        check(&random_plan(kind, &mut bits))?;
    }
}

#[test]
fn every_example_compiles_to_a_correct_table() {
    for plan in protocol::plan::examples::all() {
        check(&plan).unwrap();
    }
}

#[test]
fn a_margin_too_large_is_refused_before_compiling() {
    let mut plan = protocol::plan::examples::multiplexed_24_at_5khz(1);
    plan.margin_ns = 5_000;
    assert!(matches!(
        plan.validate(&BOARD),
        Err(protocol::PlanError::PatternOutsideExposure { .. })
    ));
}
