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

/// Heads per plan (a head = one projector + one camera): as many as the
/// widest board's trigger lines allow, two lines per head (projector trigger,
/// camera trigger). A board with fewer lines says so in
/// [`BoardLimits::output_channels`] and validation refuses plans with more
/// heads than it can drive ([`BoardLimits::max_heads`]).
pub const MAX_HEADS: usize = MAX_OUTPUT_CHANNELS / 2;
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
/// Timer edges one output channel can carry in a cycle. Validation gives each
/// channel to one device of one head, so a channel carries at most a
/// projector's two edges per slot of the cycle or a camera's two per
/// exposure, however many heads the plan has: DMA buffers sized per channel
/// by this stay the same size when `MAX_HEADS` grows.
pub const MAX_EDGES_PER_CHANNEL: usize = 2 * MAX_SLOTS_PER_CYCLE;

// Two trigger lines per head, and a channel index must fit the `u32` bit
// masks validation keeps of the channels used.
const _: () = assert!(MAX_HEADS * 2 == MAX_OUTPUT_CHANNELS && MAX_OUTPUT_CHANNELS <= 32);
const _: () = assert!(MAX_EDGES_PER_CHANNEL >= 2 * MAX_EXPOSURES);

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
    /// (2 projectors, 2 cameras), 4 feedback inputs. Four lines because
    /// TIM2 is the one 32-bit timer the firmware can give the triggers (TIM5,
    /// the other, is the free-running board clock): so 2 heads.
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

    /// Heads this board can drive: each needs two trigger outputs (projector,
    /// camera) and two feedback inputs (projector trigger-out, camera
    /// exposure-active), and no plan holds more than [`MAX_HEADS`].
    ///
    /// ```
    /// use protocol::BoardLimits;
    /// assert_eq!(BoardLimits::STM32G474.max_heads(), 2);
    /// let eight_lines = BoardLimits { output_channels: 8, feedback_channels: 8, ..BoardLimits::STM32G474 };
    /// assert_eq!(eight_lines.max_heads(), 4);
    /// ```
    pub const fn max_heads(&self) -> usize {
        let by_outputs = self.output_channels as usize / 2;
        let by_feedback = self.feedback_channels as usize / 2;
        let lines = if by_outputs < by_feedback {
            by_outputs
        } else {
            by_feedback
        };
        if lines < MAX_HEADS {
            lines
        } else {
            MAX_HEADS
        }
    }
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

/// What a DMD controller holds and refuses, checked by the host before it
/// uploads anything (`slscan::rig::dlpc`) and enforced by hil-sim's
/// byte-level controller. Figures from TI's programmer's guides where they
/// state one (DLPC350: DLPU010, DLPC900: DLPU018), assumed otherwise; each
/// field of [`ProjectorModel::controller`] says which.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ControllerLimits {
    /// DMD size in mirrors (width, height).
    pub dmd_px: (u16, u16),
    /// Shortest pattern exposure per bit depth, in microseconds: index 0 is
    /// 1-bit, index 7 is 8-bit.
    pub min_exposure_us: [u32; 8],
    /// Entries of the pattern LUT (one per displayed pattern).
    pub max_lut_entries: u16,
    /// 24-bit images the controller's image store holds.
    pub max_images: u16,
    /// Bytes the image store holds, counted as the controller stores an
    /// image (DLPC350: packed frames in flash; DLPC900: decoded bit planes).
    pub image_memory_bytes: u32,
}

/// Why a pattern set cannot go to a controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
pub enum ControllerLimitError {
    /// Bit depths are 1 to 8.
    #[error("bit depth {bit_depth} is not 1 to 8")]
    BitDepth {
        /// Depth asked for.
        bit_depth: u8,
    },
    /// An exposure shorter than the controller shows at that bit depth.
    #[error(
        "exposure {exposure_us} us is under the {min_us} us minimum for {bit_depth}-bit patterns"
    )]
    ExposureTooShort {
        /// Bit depth of the patterns.
        bit_depth: u8,
        /// Exposure asked for.
        exposure_us: u32,
        /// The controller's minimum at that depth.
        min_us: u32,
    },
    /// More patterns than LUT entries.
    #[error("{patterns} patterns, the pattern LUT holds {max}")]
    LutTooLong {
        /// Patterns asked for.
        patterns: u32,
        /// LUT entries.
        max: u16,
    },
    /// More images than the image store holds, by count or by bytes.
    #[error("{images} images of {bytes} bytes, the controller holds {max_images} images / {max_bytes} bytes")]
    OverMemory {
        /// 24-bit images the set packs into.
        images: u32,
        /// Their bytes as stored.
        bytes: u64,
        /// Images the store holds.
        max_images: u16,
        /// Bytes the store holds.
        max_bytes: u32,
    },
    /// A plan slot shorter than the controller shows a pattern of the
    /// loaded set (its LUT exposure, at least the minimum for its depth).
    #[error("exposure {exposure}: pattern {pattern_index} is shown {display_ns} ns, the controller needs {min_us} us for its {bit_depth}-bit patterns")]
    SlotTooShort {
        /// Exposure index in the plan's cycle.
        exposure: u32,
        /// The slot's pattern.
        pattern_index: u16,
        /// The slot's display time.
        display_ns: u32,
        /// Bit depth of the loaded set.
        bit_depth: u8,
        /// The least the controller shows one pattern for.
        min_us: u32,
    },
    /// A plan slot steps to a pattern the loaded set does not have.
    #[error("exposure {exposure}: pattern {pattern_index} is not loaded (the controller holds {loaded})")]
    PatternNotLoaded {
        /// Exposure index in the plan's cycle.
        exposure: u32,
        /// The slot's pattern.
        pattern_index: u16,
        /// Patterns in the controller's LUT.
        loaded: u32,
    },
    /// Patterns of another size than the DMD.
    #[error("pattern is {got:?}, the DMD is {dmd:?} (width, height)")]
    DmdSize {
        /// Pattern size.
        got: (u32, u32),
        /// DMD size.
        dmd: (u16, u16),
    },
}

impl ControllerLimits {
    /// Shortest exposure at `bit_depth` (1..=8), or an error naming the depth.
    pub fn min_exposure_us(&self, bit_depth: u8) -> Result<u32, ControllerLimitError> {
        match bit_depth {
            1..=8 => Ok(self.min_exposure_us[bit_depth as usize - 1]),
            _ => Err(ControllerLimitError::BitDepth { bit_depth }),
        }
    }

    /// Patterns of one bit depth that one 24-bit image carries.
    pub const fn patterns_per_image(bit_depth: u8) -> u32 {
        if bit_depth == 0 || bit_depth > 24 {
            0
        } else {
            24 / bit_depth as u32
        }
    }

    /// Checks a set of `patterns` patterns of `bit_depth` bits, each shown
    /// `exposure_us`, whose images take `image_bytes` bytes as stored, before
    /// anything is sent.
    pub fn check_set(
        &self,
        patterns: u32,
        bit_depth: u8,
        exposure_us: u32,
        image_bytes: u64,
    ) -> Result<(), ControllerLimitError> {
        let min_us = self.min_exposure_us(bit_depth)?;
        if exposure_us < min_us {
            return Err(ControllerLimitError::ExposureTooShort {
                bit_depth,
                exposure_us,
                min_us,
            });
        }
        if patterns > u32::from(self.max_lut_entries) {
            return Err(ControllerLimitError::LutTooLong {
                patterns,
                max: self.max_lut_entries,
            });
        }
        let images = patterns.div_ceil(Self::patterns_per_image(bit_depth));
        if images > u32::from(self.max_images) || image_bytes > u64::from(self.image_memory_bytes) {
            return Err(ControllerLimitError::OverMemory {
                images,
                bytes: image_bytes,
                max_images: self.max_images,
                max_bytes: self.image_memory_bytes,
            });
        }
        Ok(())
    }
}

impl ProjectorModel {
    /// What this model's DMD controller holds and refuses.
    pub const fn controller(self) -> ControllerLimits {
        match self {
            // DLPC350 + DLP4500 (LightCrafter 4500), DLPU010:
            // - DMD 912 x 1140 (diamond pixels).
            // - Minimum exposures per bit depth, the guide's pattern
            //   exposure table (1-bit 235 us ... 8-bit 8333 us); open
            //   drivers round them up (250 ... 8500 us).
            // - Pattern LUT 128 entries, image index LUT 64 entries
            //   (TI's dlpc350_api.cpp, DLPC350_SetPatternConfig "range 1
            //   through 64").
            // - Image store: assumed 32 MiB of the EVM's flash for images,
            //   counted as uncompressed 24-bit frames (912 * 1140 * 3 bytes
            //   each: 10 frames).
            ProjectorModel::Dlpc350 => ControllerLimits {
                dmd_px: (912, 1140),
                min_exposure_us: [235, 700, 1570, 1700, 2000, 2500, 4500, 8333],
                max_lut_entries: 128,
                max_images: 64,
                image_memory_bytes: 32 * 1024 * 1024,
            },
            // DLPC900 + DLP6500 (LightCrafter 6500), DLPU018:
            // - DMD 1920 x 1080.
            // - Minimum exposures per bit depth, the guide's table for
            //   the DLP6500 (1-bit 105 us ... 8-bit 4046 us).
            // - Pattern on-the-fly: up to 400 1-bit patterns at 1080p,
            //   i.e. 400 bit planes of 1920 x 1080 decoded (103,680,000
            //   bytes); the image index of 0x1A2A is 5 bits, but 400
            //   planes make 16 whole 24-bit images.
            ProjectorModel::Dlpc900 => ControllerLimits {
                dmd_px: (1920, 1080),
                min_exposure_us: [105, 304, 394, 823, 1215, 1487, 1998, 4046],
                max_lut_entries: 400,
                max_images: 16,
                image_memory_bytes: 400 * 1920 * 1080 / 8,
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
    fn controller_limits_refuse_short_exposures_long_luts_and_full_memory() {
        let c = ProjectorModel::Dlpc350.controller();
        assert_eq!(c.check_set(12, 8, 10_000, 4 * 3_119_040), Ok(()));
        assert_eq!(
            c.check_set(12, 8, 8_000, 0),
            Err(ControllerLimitError::ExposureTooShort {
                bit_depth: 8,
                exposure_us: 8_000,
                min_us: 8_333
            })
        );
        assert!(matches!(
            c.check_set(129, 1, 1_000, 0),
            Err(ControllerLimitError::LutTooLong { max: 128, .. })
        ));
        assert!(matches!(
            c.check_set(33, 8, 10_000, 11 * 3_119_040),
            Err(ControllerLimitError::OverMemory { images: 11, .. })
        ));
        assert!(matches!(
            c.check_set(3, 9, 10_000, 0),
            Err(ControllerLimitError::BitDepth { bit_depth: 9 })
        ));
        let d = ProjectorModel::Dlpc900.controller();
        assert_eq!(d.min_exposure_us(1), Ok(105));
        assert!(d.check_set(51, 8, 5_000, 0).is_err());
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
