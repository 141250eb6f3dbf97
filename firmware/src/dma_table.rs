//! board-core's compiled [`EdgeTable`] -> the words each trigger channel's
//! DMA writes into its timer compare register. Pure arithmetic, no chip
//! code: the firmware's timers.rs calls it, and the host parity test
//! (tests/tests/firmware_parity.rs) compiles this very file to prove that
//! what the DMA would play equals what the simulated board executes.
//!
//! The scheme (board/g474/timers.rs): one timer period is one plan cycle
//! (ARR = period - 1), each output channel toggles on compare match, and a
//! circular DMA writes the next compare value at each match. Two details:
//!
//! - Counter domain shift: every edge plays at `CNT = tick + shift`. No
//!   compare may sit on `CNT = 0`: it would fire again when the counter
//!   wraps to 0 and stops after the last cycle, raising a line after the
//!   scan. board-core keeps every first edge `min_edge_spacing_ticks` after
//!   the cycle start, so the shift is 0; a table with an edge at tick 0 is
//!   played one tick later in counter terms (shift 1, the counter starting
//!   one tick before `start_tick`), so absolute edge times do not move.
//! - Rotation: the compare register holds a channel's first edge before the
//!   start, so its DMA buffer is edges 2..n then edge 1 (written at edge
//!   n's match, ready for the next cycle).

use board_core::EdgeTable;
use protocol::{BoardLimits, HardwareFault};

/// Shortest time between consecutive edges of one channel, the cycle wrap
/// included: after a match the DMA must write the next compare value before
/// the counter reaches it. Worst case four channels match on one tick and
/// their DMA requests are served one after the other (README.md
/// "Worst-case timing": about 60 HCLK cycles); 170 ticks (1 us at 170 MHz)
/// leaves a margin of almost 3. The board declares the same number to the
/// host (`BoardLimits::min_edge_spacing_ticks`), whose plan compilation
/// refuses closer edges; the check here is the last line of defence.
pub const MIN_EDGE_SPACING_TICKS: u32 = BoardLimits::STM32G474.min_edge_spacing_ticks;

/// How one channel's compares are laid out for its DMA.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChannelLayout {
    /// Compare value loaded by the CPU before the start (the first edge).
    pub first_compare: u32,
    /// Edges per cycle = DMA transfers per cycle (0: the channel stays idle).
    pub edge_count: u16,
}

/// The counter-domain shift of `table` (see the module doc): 0 unless an
/// edge sits on tick 0, then 1; `EdgeUnderrun` on the channel that makes
/// shift 1 impossible (another edge at `period - 1`).
pub fn counter_shift(table: &EdgeTable) -> Result<u32, HardwareFault> {
    let period = table.period_ticks();
    if let Some(e) = table.edges().iter().find(|e| e.tick >= period) {
        return Err(HardwareFault::EdgeUnderrun { channel: e.channel });
    }
    if !table.edges().iter().any(|e| e.tick == 0) {
        return Ok(0);
    }
    match table.edges().iter().find(|e| e.tick == period - 1) {
        Some(e) => Err(HardwareFault::EdgeUnderrun { channel: e.channel }),
        None => Ok(1),
    }
}

/// Checks that every edge of `table` is on one of `channels` output
/// channels and that each channel fits `capacity` words.
pub fn check_channels(
    table: &EdgeTable,
    channels: u8,
    capacity: usize,
) -> Result<(), HardwareFault> {
    if let Some(e) = table.edges().iter().find(|e| e.channel >= channels) {
        return Err(HardwareFault::ChannelUnavailable { channel: e.channel });
    }
    for ch in 0..channels {
        let n = table.channel_ticks(ch).count();
        if n > capacity {
            return Err(HardwareFault::TableTooLarge {
                edges: n.min(u16::MAX as usize) as u16,
                capacity: capacity.min(u16::MAX as usize) as u16,
            });
        }
    }
    Ok(())
}

/// Writes channel `ch`'s DMA words (compare values in the shifted counter
/// domain, rotated by one) into `buf` and returns the layout. Refuses
/// (`EdgeUnderrun`) edges closer than [`MIN_EDGE_SPACING_TICKS`] to their
/// predecessor, the cycle wrap included, and an odd edge count (the line
/// would not end its cycle idle); `TableTooLarge` if `buf` is too short.
pub fn fill_channel(
    table: &EdgeTable,
    ch: u8,
    shift: u32,
    buf: &mut [u32],
) -> Result<ChannelLayout, HardwareFault> {
    let period = table.period_ticks();
    let n = table.channel_ticks(ch).count();
    if n == 0 {
        return Ok(ChannelLayout {
            first_compare: 0,
            edge_count: 0,
        });
    }
    if n > buf.len() || n > u16::MAX as usize {
        return Err(HardwareFault::TableTooLarge {
            edges: n.min(u16::MAX as usize) as u16,
            capacity: buf.len().min(u16::MAX as usize) as u16,
        });
    }
    if !n.is_multiple_of(2) {
        return Err(HardwareFault::EdgeUnderrun { channel: ch });
    }
    let mut previous: Option<u32> = None;
    let mut first = 0;
    for (i, tick) in table.channel_ticks(ch).enumerate() {
        let compare = tick
            .checked_add(shift)
            .filter(|c| *c < period)
            .ok_or(HardwareFault::EdgeUnderrun { channel: ch })?;
        if let Some(p) = previous {
            if compare < p.saturating_add(MIN_EDGE_SPACING_TICKS) {
                return Err(HardwareFault::EdgeUnderrun { channel: ch });
            }
        }
        previous = Some(compare);
        if i == 0 {
            first = compare;
        } else {
            buf[i - 1] = compare;
        }
    }
    // `previous` is the last compare; the wrap spacing is last -> period -> first.
    let last = previous.unwrap_or(first);
    if (period - last).saturating_add(first) < MIN_EDGE_SPACING_TICKS {
        return Err(HardwareFault::EdgeUnderrun { channel: ch });
    }
    buf[n - 1] = first;
    Ok(ChannelLayout {
        first_compare: first,
        edge_count: n as u16,
    })
}
