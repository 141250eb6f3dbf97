//! Fault injection, gathered in one [`FaultPlan`]: a byte-stream filter per
//! direction of the serial link (dropped bytes, flipped bits, corrupted
//! frames, a board that goes silent), a board that vanishes at a tick of its
//! clock, cameras that miss triggers and projectors slower than their
//! profile.
//!
//! Positions are counted in bytes or frames of one direction's stream, so a
//! fault lands at the same place on every run, however the OS splits the bytes
//! into reads.

use std::collections::{BTreeMap, BTreeSet};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The frame delimiter of the protocol's COBS framing: a zero byte ends
/// every frame and appears nowhere else.
pub const FRAME_DELIMITER: u8 = 0x00;

/// Faults on one direction of the byte stream.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct StreamFaults {
    /// Byte offsets (0-based, in this direction's stream) to drop.
    pub drop_bytes: BTreeSet<u64>,
    /// `(byte offset, bit 0..=7)` pairs to flip.
    pub flip_bits: BTreeSet<(u64, u8)>,
    /// Frames (0-based, counted by their delimiters) whose first byte gets
    /// its lowest bit flipped: corrupts exactly those frames whatever their
    /// lengths.
    pub flip_frames: BTreeSet<u64>,
    /// Pass this many bytes, then drop everything after (a board that stops
    /// answering, a cable pulled mid-stream).
    pub silent_after_bytes: Option<u64>,
    /// Pass this many whole frames (counted by their delimiters), then drop
    /// everything after. Robust to message sizes changing.
    pub silent_after_frames: Option<u64>,
    /// Seeded random noise on top of the listed faults.
    pub noise: Option<Noise>,
}

/// Random byte drops and bit flips at given rates, reproducible from a seed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Noise {
    /// Chance per byte of dropping it, in parts per million.
    pub drop_ppm: u32,
    /// Chance per byte of flipping one random bit, in parts per million.
    pub flip_ppm: u32,
    /// Seed of the generator.
    pub seed: u64,
}

/// A camera that misses one trigger.
///
/// Triggers are counted per camera from the last plan commit (the simulated
/// rig is rebuilt for each committed plan).
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub struct MissedTrigger {
    /// Which head's camera (0 = head A).
    pub camera: u8,
    /// Which of the triggers that camera receives (0-based) it misses.
    pub trigger_index: u64,
}

/// Every fault the simulated board injects.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct FaultPlan {
    /// Faults on the bytes from the host to the board.
    pub to_board: StreamFaults,
    /// Faults on the bytes from the board to the host.
    pub to_host: StreamFaults,
    /// Triggers the cameras miss.
    pub missed_triggers: BTreeSet<MissedTrigger>,
    /// Extra trigger latency, in nanoseconds, of a head's DMD (0 = head A)
    /// beyond its profile: a slow or misconfigured projector whose patterns
    /// light up late, and may leave their exposure.
    pub projector_lag_ns: BTreeMap<u8, u64>,
    /// The board vanishes (hears and says nothing more, like a board whose
    /// USB died) once its virtual clock reaches this tick: "goes silent
    /// mid-scan" at a point fixed in board time, whatever the host's pace.
    pub vanish_at_tick: Option<u64>,
}

impl FaultPlan {
    /// No faults at all.
    pub fn none() -> Self {
        Self::default()
    }

    /// The trigger indices camera `camera` misses.
    pub fn missed_by_camera(&self, camera: u8) -> BTreeSet<u64> {
        self.missed_triggers
            .iter()
            .filter(|m| m.camera == camera)
            .map(|m| m.trigger_index)
            .collect()
    }
}

/// Applies [`StreamFaults`] to one direction of the stream as it flows.
#[derive(Clone, Debug)]
pub struct ByteFilter {
    faults: StreamFaults,
    rng: Option<ChaCha8Rng>,
    bytes_in: u64,
    frames_in: u64,
    at_frame_start: bool,
    silent: bool,
    dropped: u64,
    flipped: u64,
}

impl ByteFilter {
    /// A filter that injects `faults`.
    pub fn new(faults: StreamFaults) -> Self {
        let rng = faults.noise.map(|n| ChaCha8Rng::seed_from_u64(n.seed));
        Self {
            faults,
            rng,
            bytes_in: 0,
            frames_in: 0,
            at_frame_start: true,
            silent: false,
            dropped: 0,
            flipped: 0,
        }
    }

    /// A filter that passes everything.
    pub fn transparent() -> Self {
        Self::new(StreamFaults::default())
    }

    /// Passes `input` through the faults, appending what survives to `out`.
    pub fn apply(&mut self, input: &[u8], out: &mut Vec<u8>) {
        for &byte in input {
            let offset = self.bytes_in;
            self.bytes_in += 1;
            if self.faults.silent_after_bytes.is_some_and(|n| offset >= n)
                || self
                    .faults
                    .silent_after_frames
                    .is_some_and(|n| self.frames_in >= n)
            {
                self.silent = true;
            }
            // Frame of this byte, and whether it opens it (follows a delimiter).
            let frame = self.frames_in;
            let opens_frame = std::mem::replace(&mut self.at_frame_start, byte == FRAME_DELIMITER)
                && byte != FRAME_DELIMITER;
            if byte == FRAME_DELIMITER {
                self.frames_in += 1;
            }
            if self.silent || self.faults.drop_bytes.contains(&offset) || self.noise_drops() {
                self.dropped += 1;
                continue;
            }
            let original = byte;
            let mut byte = byte;
            for bit in 0..8u8 {
                if self.faults.flip_bits.contains(&(offset, bit)) {
                    byte ^= 1 << bit;
                }
            }
            if let Some(bit) = self.noise_flip() {
                byte ^= 1 << bit;
            }
            if opens_frame && self.faults.flip_frames.contains(&frame) {
                byte ^= 1;
            }
            if byte != original {
                self.flipped += 1;
            }
            out.push(byte);
        }
    }

    /// True once a silence fault has struck: nothing passes any more.
    pub fn is_silent(&self) -> bool {
        self.silent
    }

    /// Bytes seen so far (before faults).
    pub fn bytes_in(&self) -> u64 {
        self.bytes_in
    }

    /// Bytes dropped so far (listed, random or silenced).
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Bytes altered by bit flips so far.
    pub fn flipped(&self) -> u64 {
        self.flipped
    }

    fn noise_drops(&mut self) -> bool {
        match (self.faults.noise, self.rng.as_mut()) {
            (Some(n), Some(rng)) if n.drop_ppm > 0 => rng.random_range(0..1_000_000) < n.drop_ppm,
            _ => false,
        }
    }

    fn noise_flip(&mut self) -> Option<u8> {
        let (Some(n), Some(rng)) = (self.faults.noise, self.rng.as_mut()) else {
            return None;
        };
        (n.flip_ppm > 0 && rng.random_range(0..1_000_000) < n.flip_ppm)
            .then(|| rng.random_range(0..8))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(faults: StreamFaults, chunks: &[&[u8]]) -> Vec<u8> {
        let mut filter = ByteFilter::new(faults);
        let mut out = Vec::new();
        for chunk in chunks {
            filter.apply(chunk, &mut out);
        }
        out
    }

    #[test]
    fn transparent_filter_passes_everything() {
        let data: Vec<u8> = (0..=255).collect();
        assert_eq!(run(StreamFaults::default(), &[&data]), data);
    }

    #[test]
    fn drops_and_flips_land_on_stream_offsets_whatever_the_chunking() {
        let faults = StreamFaults {
            drop_bytes: [1, 4].into(),
            flip_bits: [(2, 0), (5, 7)].into(),
            ..StreamFaults::default()
        };
        let data = [10u8, 11, 12, 13, 14, 15];
        let whole = run(faults.clone(), &[&data]);
        let split = run(faults, &[&data[..2], &data[2..3], &data[3..]]);
        assert_eq!(whole, vec![10, 13, 13, 15 ^ 0x80]);
        assert_eq!(split, whole);
    }

    #[test]
    fn silent_after_bytes_cuts_the_stream_for_good() {
        let faults = StreamFaults {
            silent_after_bytes: Some(3),
            ..StreamFaults::default()
        };
        let mut filter = ByteFilter::new(faults);
        let mut out = Vec::new();
        filter.apply(&[1, 2, 3, 4, 5], &mut out);
        filter.apply(&[6], &mut out);
        assert_eq!(out, vec![1, 2, 3]);
        assert!(filter.is_silent());
        assert_eq!(filter.dropped(), 3);
    }

    #[test]
    fn silent_after_frames_passes_whole_frames_only() {
        let faults = StreamFaults {
            silent_after_frames: Some(2),
            ..StreamFaults::default()
        };
        let stream = [1u8, 2, 0, 3, 0, 4, 5, 0, 6, 0];
        assert_eq!(run(faults, &[&stream]), vec![1, 2, 0, 3, 0]);
    }

    #[test]
    fn flip_frames_hits_the_first_byte_of_exactly_those_frames() {
        let faults = StreamFaults {
            flip_frames: [0, 2].into(),
            ..StreamFaults::default()
        };
        let stream = [4u8, 5, 0, 6, 7, 0, 8, 0, 0, 9, 0];
        // Frame 0 = [4, 5], 1 = [6, 7], 2 = [8], then an empty one, 4 = [9].
        assert_eq!(
            run(faults, &[&stream[..4], &stream[4..]]),
            vec![5, 5, 0, 6, 7, 0, 9, 0, 0, 9, 0]
        );
    }

    #[test]
    fn noise_is_reproducible_and_roughly_at_its_rate() {
        let faults = StreamFaults {
            noise: Some(Noise {
                drop_ppm: 100_000,
                flip_ppm: 100_000,
                seed: 9,
            }),
            ..StreamFaults::default()
        };
        let data = vec![0x55u8; 10_000];
        let mut filter = ByteFilter::new(faults.clone());
        let mut out = Vec::new();
        filter.apply(&data, &mut out);
        assert_eq!(out, run(faults, &[&data[..5_000], &data[5_000..]]));
        // 10 % each, so about 1000 of 10 000; bounds far outside binomial spread.
        assert!(
            (700..1_300).contains(&filter.dropped()),
            "{}",
            filter.dropped()
        );
        assert!(
            (600..1_300).contains(&filter.flipped()),
            "{}",
            filter.flipped()
        );
        assert_eq!(out.len() as u64, 10_000 - filter.dropped());
    }

    #[test]
    fn missed_triggers_are_sorted_per_camera() {
        let plan = FaultPlan {
            missed_triggers: [
                MissedTrigger {
                    camera: 1,
                    trigger_index: 3,
                },
                MissedTrigger {
                    camera: 0,
                    trigger_index: 5,
                },
                MissedTrigger {
                    camera: 1,
                    trigger_index: 0,
                },
            ]
            .into(),
            ..FaultPlan::none()
        };
        assert_eq!(plan.missed_by_camera(1), [0, 3].into());
        assert_eq!(plan.missed_by_camera(0), [5].into());
        assert!(plan.missed_by_camera(2).is_empty());
    }
}
