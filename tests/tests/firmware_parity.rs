//! The STM32 firmware plays exactly what the simulated board plays (issue 4).
//!
//! For the seed-001 plan (24 patterns at 5 kHz in one exposure) and the
//! seed-000 dual-head plan, board-core compiles one edge table; then
//! - the firmware path: the words the firmware's DMA buffers would hold
//!   (firmware/src/dma_table.rs, compiled here from the very same file),
//!   replayed through a register-level model of TIM2 (toggle on compare,
//!   compare register rewritten by a circular DMA at each match, counter
//!   period = plan cycle, one-pulse stop after the last cycle);
//! - the simulated board: hil-sim's `SimHardware`, which hil-sim's board
//!   and the end-to-end tests run;
//!
//! must produce the same output edges, tick for tick, over several cycles;
//! and so for 48 random valid plans of every capture mode.
//!
//! The firmware's other pure piece, the extension of 16/32-bit counter
//! values to the 64-bit board clock (firmware/src/tick_extend.rs, same file
//! again), is checked exhaustively on narrow counters at the end.

#[path = "../../firmware/src/dma_table.rs"]
mod dma_table;
#[path = "../../firmware/src/tick_extend.rs"]
mod tick_extend;

use board_core::{EdgeTable, TriggerHardware};
use hil_sim::sim_hardware::{RecordedEdge, SimHardware, SimHead};
use protocol::limits::MAX_EDGES;
use protocol::plan::examples;
use protocol::plan::random::{random_kind, random_plan, SplitMix64};
use protocol::{BoardLimits, Level, ScanPlan};

/// Output channels of the G474 board (TIM2 CH1..CH4).
const CHANNELS: u8 = 4;
/// Where both players start cycle 0 (the sim's clock starts at 0).
const START_TICK: u64 = 1_000_000;

fn compile(plan: &ScanPlan) -> EdgeTable {
    let valid = plan
        .clone()
        .validate(&BoardLimits::STM32G474)
        .expect("example plan is valid");
    EdgeTable::compile(&valid).expect("example plan compiles")
}

fn flip(level: Level) -> Level {
    match level {
        Level::Low => Level::High,
        Level::High => Level::Low,
    }
}

/// What the firmware's TIM2 + DMA1 would output for `table`, from the DMA
/// words dma_table.rs lays out. Register model per channel: CCR holds the
/// armed compare; when the counter equals it the output toggles and the
/// DMA writes the next word; a word at or below the counter value of the
/// match can only match after the counter wraps (next cycle). The counter
/// starts `shift` ticks before `start_tick` and stops after `repeat` cycles.
fn play_firmware(table: &EdgeTable, start_tick: u64, repeat: u32) -> Vec<RecordedEdge> {
    dma_table::check_channels(table, CHANNELS, MAX_EDGES).expect("fits the board");
    let shift = dma_table::counter_shift(table).expect("a counter shift exists");
    let period = u64::from(table.period_ticks());
    let strobe = start_tick - u64::from(shift);
    let mut played = Vec::new();
    for ch in 0..CHANNELS {
        let mut words = vec![0u32; MAX_EDGES];
        let layout = dma_table::fill_channel(table, ch, shift, &mut words).expect("channel fits");
        let n = usize::from(layout.edge_count);
        if n == 0 {
            continue;
        }
        // At the final one-pulse stop the counter rests at 0: a compare
        // there would raise the line after the scan.
        assert_ne!(layout.first_compare, 0, "channel {ch}: compare at CNT = 0");
        let mut ccr = layout.first_compare;
        let mut next_word = 0;
        let mut level = Level::Low;
        let mut cycle = 0u64;
        let mut last_match: Option<u32> = None;
        loop {
            if last_match.is_some_and(|m| ccr <= m) {
                cycle += 1;
            }
            if cycle >= u64::from(repeat) {
                break;
            }
            assert!(
                u64::from(ccr) < period,
                "channel {ch}: compare {ccr} beyond ARR"
            );
            level = flip(level);
            played.push(RecordedEdge {
                tick: strobe + cycle * period + u64::from(ccr),
                channel: ch,
                level,
            });
            last_match = Some(ccr);
            ccr = words[next_word];
            next_word = (next_word + 1) % n;
        }
        assert_eq!(level, Level::Low, "channel {ch} must end the scan idle");
    }
    played.sort();
    played
}

/// What hil-sim's simulated board outputs for the same table and start.
fn play_sim(plan: &ScanPlan, table: &EdgeTable, start_tick: u64, repeat: u32) -> Vec<RecordedEdge> {
    let heads = plan
        .heads
        .iter()
        .enumerate()
        .map(|(i, wiring)| SimHead::from_profiles(*wiring, i as u64))
        .collect();
    let mut hw = SimHardware::new(BoardLimits::STM32G474, heads);
    hw.set_recording(true);
    hw.load(table).expect("sim loads the table");
    hw.start(start_tick, repeat).expect("sim starts");
    hw.advance_to(start_tick + u64::from(repeat) * u64::from(table.period_ticks()) + 1);
    let mut played = hw.recorded().to_vec();
    played.sort();
    played
}

fn assert_parity(plan: &ScanPlan, repeat: u32) {
    let table = compile(plan);
    let firmware = play_firmware(&table, START_TICK, repeat);
    let sim = play_sim(plan, &table, START_TICK, repeat);
    assert_eq!(
        firmware.len(),
        table.edges().len() * repeat as usize,
        "the firmware must play every edge of every cycle"
    );
    assert_eq!(
        firmware, sim,
        "firmware DMA playback differs from the simulated board"
    );
}

#[test]
fn multiplexed_24_at_5khz_firmware_plays_what_the_sim_plays() {
    // One cycle, and three to cover the circular DMA across cycle wraps.
    assert_parity(&examples::multiplexed_24_at_5khz(1), 1);
    assert_parity(&examples::multiplexed_24_at_5khz(3), 3);
}

#[test]
fn dual_head_firmware_plays_what_the_sim_plays() {
    assert_parity(&examples::dual_head_psp(1), 1);
    assert_parity(&examples::dual_head_psp(2), 2);
}

#[test]
fn random_valid_plans_firmware_plays_what_the_sim_plays() {
    // Every capture mode, pattern periods down to the DMD limit (the
    // generator's slack is sometimes zero), up to 3 cycles each.
    let mut bits = SplitMix64(0x5EED_F1A3);
    for _ in 0..48 {
        let kind = random_kind(&mut bits);
        let plan = random_plan(kind, &mut bits);
        let table = compile(&plan);
        let repeat = table.repeat_count().min(3);
        let firmware = play_firmware(&table, START_TICK, repeat);
        let sim = play_sim(&plan, &table, START_TICK, repeat);
        assert_eq!(firmware.len(), table.edges().len() * repeat as usize);
        assert_eq!(
            firmware, sim,
            "{kind:?}: firmware DMA playback differs from the sim"
        );
    }
}

#[test]
fn dma_words_are_the_channel_ticks_shifted_and_rotated_by_one() {
    let table = compile(&examples::multiplexed_24_at_5khz(1));
    // board-core keeps first edges off the cycle start, so no compare sits
    // on CNT = 0 and the counter domain is the table's own.
    let shift = dma_table::counter_shift(&table).unwrap();
    assert_eq!(shift, 0);
    assert!(table.edges().iter().all(|e| e.tick > 0));
    for ch in 0..CHANNELS {
        let ticks: Vec<u32> = table.channel_ticks(ch).map(|t| t + shift).collect();
        let mut words = vec![0u32; MAX_EDGES];
        let layout = dma_table::fill_channel(&table, ch, shift, &mut words).unwrap();
        assert_eq!(usize::from(layout.edge_count), ticks.len());
        if let Some((first, rest)) = ticks.split_first() {
            assert_eq!(layout.first_compare, *first);
            assert_eq!(&words[..rest.len()], rest);
            assert_eq!(words[rest.len()], *first);
        }
    }
    // Projector (channel 0): 24 pulses; camera (channel 1): one exposure.
    assert_eq!(table.channel_ticks(0).count(), 48);
    assert_eq!(table.channel_ticks(1).count(), 2);
}

#[test]
fn a_buffer_too_small_is_refused_not_overrun() {
    let table = compile(&examples::multiplexed_24_at_5khz(1));
    let mut words = [0u32; 10];
    assert_eq!(
        dma_table::fill_channel(&table, 0, 0, &mut words),
        Err(protocol::HardwareFault::TableTooLarge {
            edges: 48,
            capacity: 10
        })
    );
    assert_eq!(
        dma_table::check_channels(&table, 1, MAX_EDGES),
        Err(protocol::HardwareFault::ChannelUnavailable { channel: 1 })
    );
}

/// Every capture time `t_c` of a `bits`-wide counter, read `delay` ticks
/// later (less than half a wrap, as the IRQ priorities guarantee), in both
/// states the interrupt can leave the wrap count in: up to date (no wrap
/// since the capture) or one wrap flagged but not yet counted (within half a
/// wrap of the read). The extended value must be `t_c` exactly.
#[test]
fn counter_values_extend_to_the_exact_64_bit_tick() {
    for bits in [4u32, 8, 12] {
        let period = 1u64 << bits;
        let half = period / 2;
        let mut checked = 0u32;
        for t_c in 0..6 * period {
            let low = (t_c % period) as u32;
            for delay in 0..half {
                let t_r = t_c + delay;
                let wraps_at_read = t_r / period;
                // Up to date: only valid when no wrap came between capture and read.
                if t_r / period == t_c / period {
                    let ext = tick_extend::extend(wraps_at_read as u32, false, low, bits);
                    assert_eq!(ext, t_c, "bits {bits}, t_c {t_c}, read {t_r}, up to date");
                    checked += 1;
                }
                // The last wrap (at `wraps_at_read * period`) flagged, not counted.
                let last_wrap = wraps_at_read * period;
                if wraps_at_read >= 1 && t_r - last_wrap < half {
                    let counted = (wraps_at_read - 1) as u32;
                    let ext = tick_extend::extend(counted, true, low, bits);
                    assert_eq!(ext, t_c, "bits {bits}, t_c {t_c}, read {t_r}, wrap pending");
                    checked += 1;
                }
            }
        }
        assert!(
            checked as u64 > 6 * period * half / 2,
            "too few cases checked"
        );
    }
    // The TIM5 clock reads its counter directly (delay 0) at full width.
    assert_eq!(tick_extend::extend(3, false, 7, 32), (3 << 32) + 7);
    assert_eq!(tick_extend::extend(3, true, 7, 32), (4 << 32) + 7);
    assert_eq!(
        tick_extend::extend(3, true, u32::MAX, 32),
        (3 << 32) + u64::from(u32::MAX)
    );
}
