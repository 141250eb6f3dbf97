//! Example plans for the capture modes of the seed papers, shared by tests
//! of every crate (protocol, board-core, hil-sim, host, integration).
//!
//! Wiring of the examples: head A = projector trigger 0, camera trigger 1,
//! projector trigger-out feedback 0, camera exposure-active feedback 1;
//! head B = 2, 3, 2, 3; head C = 4, 5, 4, 5; head D = 6, 7, 6, 7 (C and D
//! only on a board with 8 lines each way).

use super::{HeadConfig, HeadSet, PatternSlot, ScanPlan};
use crate::limits::{CameraModel, ProjectorModel, MAX_HEADS};

/// Camera exposure spacing of the slow-camera examples (Mono6Mp at ~29 fps).
pub const SLOW_FRAME_NS: u32 = 34_000_000;
/// Exposure time of the slow-camera examples.
pub const SLOW_EXPOSURE_NS: u32 = 12_000_000;
/// Pattern display time inside a slow-camera exposure.
pub const SLOW_DISPLAY_NS: u32 = 10_000_000;
/// Projector trigger offset inside a slow-camera exposure.
pub const SLOW_SLOT_OFFSET_NS: u32 = 5_000;
/// Camera frame period of seed 001: 208 Hz.
pub const FAST_FRAME_NS: u32 = 1_000_000_000 / 208;
/// One pattern period at 5 kHz.
pub const PATTERN_5KHZ_NS: u32 = 200_000;
/// Exposure time holding 24 patterns at 5 kHz plus margins.
pub const FAST_EXPOSURE_NS: u32 = 4_803_000;
/// Camera trigger of the first exposure, after the cycle start (the board
/// needs `min_edge_spacing_ticks` before a channel's first edge).
pub const CYCLE_LEAD_NS: u32 = 2_000;
/// First projector trigger inside the long exposure.
pub const FAST_SLOT_OFFSET_NS: u32 = 2_000;

/// Head wiring of the examples: head `index` (0 = A, 1 = B, 2 = C, 3 = D).
pub const fn head(index: u8, projector: ProjectorModel, camera: CameraModel) -> HeadConfig {
    HeadConfig {
        projector,
        camera,
        projector_trigger_channel: 2 * index,
        camera_trigger_channel: 2 * index + 1,
        projector_feedback_channel: 2 * index,
        camera_feedback_channel: 2 * index + 1,
    }
}

fn slow_heads() -> [HeadConfig; 2] {
    [
        head(0, ProjectorModel::Dlpc350, CameraModel::Mono6Mp),
        head(1, ProjectorModel::Dlpc350, CameraModel::Mono6Mp),
    ]
}

/// One slow exposure per pattern index, every `SLOW_FRAME_NS`, on `heads`.
fn slow_sequence(plan: &mut ScanPlan, heads: HeadSet, patterns: u16) {
    for k in 0..patterns {
        let slot = PatternSlot {
            pattern_index: k,
            offset_ns: SLOW_SLOT_OFFSET_NS,
            display_ns: SLOW_DISPLAY_NS,
        };
        // Capacities hold 64 exposures; examples use at most 16.
        let _ = plan.push_exposure(
            heads,
            CYCLE_LEAD_NS + k as u32 * SLOW_FRAME_NS,
            SLOW_EXPOSURE_NS,
            &[slot],
        );
    }
}

/// Seed 000: both projectors show the same 4-step x 4-frequency sequence at
/// once and both cameras expose together (16 exposures).
pub fn dual_head_psp(repeat_count: u32) -> ScanPlan {
    let mut plan = new_plan(&slow_heads(), repeat_count, 16 * SLOW_FRAME_NS, 1_000);
    slow_sequence(&mut plan, HeadSet::BOTH, 16);
    plan
}

/// Seed 000 on a rig of `heads` heads (clamped to `1..=MAX_HEADS`): every
/// projector shows the same 4-step x 4-frequency sequence at once and every
/// camera exposes together. Three or four heads need a board with 6 or 8
/// lines each way; `BoardLimits::STM32G474` refuses them.
pub fn all_heads_psp(heads: usize, repeat_count: u32) -> ScanPlan {
    let count = heads.clamp(1, MAX_HEADS);
    let mut wiring = [head(0, ProjectorModel::Dlpc350, CameraModel::Mono6Mp); MAX_HEADS];
    for (index, w) in wiring.iter_mut().enumerate() {
        *w = head(index as u8, ProjectorModel::Dlpc350, CameraModel::Mono6Mp);
    }
    let mut plan = new_plan(&wiring[..count], repeat_count, 16 * SLOW_FRAME_NS, 1_000);
    let set = HeadSet::all(count).unwrap_or(HeadSet::A);
    slow_sequence(&mut plan, set, 16);
    plan
}

/// Seed 000 reference run: the dual-head rig, but only head `head` (0 = A,
/// 1 = B) projects and exposes.
pub fn head_only(head: u8, repeat_count: u32) -> ScanPlan {
    let mut plan = new_plan(&slow_heads(), repeat_count, 16 * SLOW_FRAME_NS, 1_000);
    slow_sequence(&mut plan, HeadSet(1 << (head & 1)), 16);
    plan
}

/// Seed 001: 24 binary patterns at 5 kHz inside one 4.8 ms exposure of a
/// 208 Hz colour camera, on a DLPC900-class projector; the cycle is one
/// camera frame, repeated `repeat_count` times.
pub fn multiplexed_24_at_5khz(repeat_count: u32) -> ScanPlan {
    let heads = [head(0, ProjectorModel::Dlpc900, CameraModel::Colour208Hz)];
    let mut plan = new_plan(&heads, repeat_count, FAST_FRAME_NS, 500);
    let mut slots = [PatternSlot {
        pattern_index: 0,
        offset_ns: 0,
        display_ns: 0,
    }; 24];
    for (k, slot) in slots.iter_mut().enumerate() {
        *slot = PatternSlot {
            pattern_index: k as u16,
            offset_ns: FAST_SLOT_OFFSET_NS + k as u32 * PATTERN_5KHZ_NS,
            display_ns: PATTERN_5KHZ_NS,
        };
    }
    let _ = plan.push_exposure(HeadSet::A, CYCLE_LEAD_NS, FAST_EXPOSURE_NS, &slots);
    plan
}

/// Seeds 003/004: the uniform floods before adaptive projection: 7 grey
/// levels (pattern indices 0..7), one exposure each, on one head.
pub fn flood_preliminaries(repeat_count: u32) -> ScanPlan {
    let heads = [head(0, ProjectorModel::Dlpc350, CameraModel::Mono6Mp)];
    let mut plan = new_plan(&heads, repeat_count, 7 * SLOW_FRAME_NS, 1_000);
    slow_sequence(&mut plan, HeadSet::A, 7);
    plan
}

/// Every example: dual-head, head A only, head B only, 24 at 5 kHz, floods.
pub fn all() -> [ScanPlan; 5] {
    [
        dual_head_psp(2),
        head_only(0, 1),
        head_only(1, 1),
        multiplexed_24_at_5khz(3),
        flood_preliminaries(1),
    ]
}

fn new_plan(heads: &[HeadConfig], repeat_count: u32, period_ns: u32, margin_ns: u32) -> ScanPlan {
    match ScanPlan::new(heads, repeat_count, period_ns, margin_ns) {
        Ok(plan) => plan,
        // At most MAX_HEADS heads are passed above.
        Err(_) => unreachable!("examples use at most MAX_HEADS heads"),
    }
}
