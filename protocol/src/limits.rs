//! Capacities of the wire and the board, and timing profiles of the devices a
//! head can be built from.
//!
//! Every heapless capacity in the crate is one of the constants below, so a
//! board's RAM budget and a host's validation read the same numbers. Device
//! profiles are data sheet figures where the data sheet states one and
//! assumed model figures otherwise; each field says which.

use serde::{Deserialize, Serialize};

/// Largest encoded frame on the wire in bytes, COBS overhead and the `0x00`
/// terminator included. Small MCU receive buffers are sized by this.
pub const MAX_FRAME_BYTES: usize = 512;
/// Largest postcard payload of one frame in bytes (before the 4-byte CRC and
/// COBS): `MAX_FRAME_BYTES` minus CRC, terminator and worst-case COBS overhead.
pub const MAX_PAYLOAD_BYTES: usize = 500;
/// Length of the CRC-32 trailer of each frame.
pub const CRC_BYTES: usize = 4;

/// Heads per plan (a head = one projector + one camera).
pub const MAX_HEADS: usize = 2;
/// Exposures in one cycle of a plan (ADFP needs 31, dual-head PSP 16 + refs).
pub const MAX_EXPOSURES: usize = 64;
/// Pattern slots inside one exposure (seed 001 needs 24); one exposure with
/// this many slots still fits in one frame.
pub const MAX_SLOTS_PER_EXPOSURE: usize = 32;
/// Pattern slots in one cycle of a plan, all exposures together.
pub const MAX_SLOTS_PER_CYCLE: usize = 256;
/// Trigger output channels a board may have.
pub const MAX_OUTPUT_CHANNELS: usize = 8;
/// Timer edges in one cycle's edge table: a rising and a falling edge per
/// projector slot per head plus per camera exposure per head.
pub const MAX_EDGES: usize = 2 * MAX_HEADS * (MAX_SLOTS_PER_CYCLE + MAX_EXPOSURES);

const _: () = assert!(
    MAX_PAYLOAD_BYTES + CRC_BYTES + (MAX_PAYLOAD_BYTES + CRC_BYTES) / 254 + 2 <= MAX_FRAME_BYTES
);

/// What a board can do; sent to the host in `DeviceInfo` and used by
/// validation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct BoardLimits {
    /// Frequency of the timer that produces the trigger edges, in Hz
    /// (STM32G474: 170 MHz).
    pub timer_clock_hz: u32,
    /// Number of trigger output channels (`0..output_channels`).
    pub output_channels: u8,
    /// Number of feedback input-capture lines (`0..feedback_channels`).
    pub feedback_channels: u8,
    /// Largest encoded frame the board accepts, in bytes.
    pub max_frame_bytes: u16,
    /// Most exposures per cycle.
    pub max_exposures: u16,
    /// Most pattern slots per cycle.
    pub max_slots_per_cycle: u16,
    /// Most repetitions of the cycle.
    pub max_repeat_count: u32,
    /// Shortest time between two edges of one output channel, also from the
    /// cycle start to a channel's first edge and across the cycle wrap (the
    /// STM32's DMA must rewrite the compare register in between: 1 us).
    pub min_edge_spacing_ticks: u32,
    /// Shortest delay from a `Start` request to the first cycle: the board
    /// arms a hardware compare after decoding the request, so a nearer
    /// start is moved out to this (STM32G474: 100 us), on every board alike.
    pub min_start_delay_ticks: u32,
}

impl BoardLimits {
    /// The STM32G474 sync board: 170 MHz 32-bit timer, 4 trigger outputs
    /// (2 projectors, 2 cameras), 4 feedback inputs.
    pub const STM32G474: BoardLimits = BoardLimits {
        timer_clock_hz: 170_000_000,
        output_channels: 4,
        feedback_channels: 4,
        max_frame_bytes: MAX_FRAME_BYTES as u16,
        max_exposures: MAX_EXPOSURES as u16,
        max_slots_per_cycle: MAX_SLOTS_PER_CYCLE as u16,
        max_repeat_count: 1_000_000,
        min_edge_spacing_ticks: 170,
        min_start_delay_ticks: 17_000,
    };
}

/// Projector (DMD controller) models a head can use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ProjectorModel {
    /// TI DLPC350 (LightCrafter 4500): 1-bit patterns at up to ~4.2 kHz.
    Dlpc350,
    /// DLPC900-class controller: 1-bit patterns at up to ~9.5 kHz.
    Dlpc900,
}

/// Camera models a head can use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum CameraModel {
    /// 6 MP global-shutter mono camera (seed 000: 3072x2048), up to ~30 fps.
    Mono6Mp,
    /// High-speed colour camera, up to 208 fps (seed 001).
    Colour208Hz,
}

/// Timing profile of a projector model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProjectorProfile {
    /// Shortest 1-bit pattern period (data sheet: DLPC350 235 us, DLPC900 105 us).
    pub min_pattern_period_ns: u32,
    /// Width of the trigger-in pulse the board emits per pattern (assumed).
    pub trigger_pulse_ns: u32,
    /// Trigger-in to pattern on the mirrors, and to trigger-out (assumed).
    pub latency_ns: u32,
    /// Peak deviation of that latency (assumed).
    pub jitter_ns: u32,
}

/// Timing profile of a camera model. The camera runs in trigger-width mode:
/// the exposure lasts as long as the trigger line is high.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct CameraProfile {
    /// Shortest exposure (assumed).
    pub min_exposure_ns: u32,
    /// Shortest time from one exposure start to the next (1 / max frame rate).
    pub min_frame_period_ns: u32,
    /// Shortest gap between the end of one exposure and the next trigger
    /// (overlapped readout: the sensor re-arms quickly; assumed).
    pub min_gap_ns: u32,
    /// Trigger edge to exposure-active edge (assumed).
    pub latency_ns: u32,
    /// Peak deviation of that latency (assumed).
    pub jitter_ns: u32,
}

impl ProjectorModel {
    /// The timing profile of this model.
    pub const fn profile(self) -> ProjectorProfile {
        match self {
            ProjectorModel::Dlpc350 => ProjectorProfile {
                min_pattern_period_ns: 235_000,
                trigger_pulse_ns: 20_000,
                latency_ns: 1_000,
                jitter_ns: 200,
            },
            ProjectorModel::Dlpc900 => ProjectorProfile {
                min_pattern_period_ns: 105_000,
                trigger_pulse_ns: 10_000,
                latency_ns: 1_000,
                jitter_ns: 100,
            },
        }
    }
}

impl CameraModel {
    /// The timing profile of this model.
    pub const fn profile(self) -> CameraProfile {
        match self {
            CameraModel::Mono6Mp => CameraProfile {
                min_exposure_ns: 20_000,
                min_frame_period_ns: 33_333_334,
                min_gap_ns: 20_000,
                latency_ns: 2_000,
                jitter_ns: 300,
            },
            CameraModel::Colour208Hz => CameraProfile {
                min_exposure_ns: 10_000,
                min_frame_period_ns: 4_807_000,
                min_gap_ns: 2_000,
                latency_ns: 1_500,
                jitter_ns: 100,
            },
        }
    }
}

/// Timer ticks of a `timer_clock_hz` clock closest to `ns` (ties round up).
/// Monotonic in `ns`, so an ordering of times survives the conversion.
///
/// ```
/// use protocol::limits::ns_to_ticks;
/// assert_eq!(ns_to_ticks(200_000, 170_000_000), 34_000); // one 5 kHz pattern
/// assert_eq!(ns_to_ticks(4_807_692, 170_000_000), 817_308); // 208 Hz frame, rounded
/// ```
pub const fn ns_to_ticks(ns: u64, timer_clock_hz: u32) -> u64 {
    ((ns as u128 * timer_clock_hz as u128 + 500_000_000) / 1_000_000_000) as u64
}

/// Fewest whole ticks of a `timer_clock_hz` clock lasting at least `ns`.
pub const fn ns_to_ticks_ceil(ns: u64, timer_clock_hz: u32) -> u64 {
    ((ns as u128 * timer_clock_hz as u128).div_ceil(1_000_000_000)) as u64
}

/// Nanoseconds of `ticks` ticks of a `timer_clock_hz` clock, rounded to nearest.
pub const fn ticks_to_ns(ticks: u64, timer_clock_hz: u32) -> u64 {
    if timer_clock_hz == 0 {
        return 0;
    }
    ((ticks as u128 * 1_000_000_000 + timer_clock_hz as u128 / 2) / timer_clock_hz as u128) as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_conversion_at_170_mhz() {
        assert_eq!(ns_to_ticks(1_000_000_000, 170_000_000), 170_000_000);
        assert_eq!(ns_to_ticks(200_000, 170_000_000), 34_000);
        // 3 ns = 0.51 ticks rounds up, 2 ns = 0.34 rounds down.
        assert_eq!(ns_to_ticks(3, 170_000_000), 1);
        assert_eq!(ns_to_ticks(2, 170_000_000), 0);
        assert_eq!(ticks_to_ns(34_000, 170_000_000), 200_000);
    }

    #[test]
    fn profiles_match_data_sheet_pattern_rates() {
        assert_eq!(
            ProjectorModel::Dlpc350.profile().min_pattern_period_ns,
            235_000
        );
        assert_eq!(
            ProjectorModel::Dlpc900.profile().min_pattern_period_ns,
            105_000
        );
    }
}
