//! A simulated hardware-triggered camera: a trigger-in pulse starts an
//! exposure after a latency, the exposure-active output is high while the
//! sensor integrates, and a trigger during exposure or readout is lost.

use std::collections::BTreeSet;

use super::delay::{Delay, DelaySource};
use super::Pulse;

/// How long the sensor integrates after a trigger.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum ExposureMode {
    /// The exposure lasts as long as the trigger pulse is high (GenICam
    /// `ExposureMode = TriggerWidth`): the board's edge table sets the exposure.
    TriggerWidth,
    /// A fixed exposure set in the camera (`ExposureMode = Timed`).
    Timed {
        /// The exposure time in nanoseconds.
        exposure_ns: u64,
    },
}

/// How a simulated camera responds to its trigger input.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct CameraConfig {
    /// From the trigger-in rising edge to the start of exposure (exposure-active rises).
    pub trigger_to_exposure: Delay,
    /// How the exposure length is set.
    pub mode: ExposureMode,
    /// Sensor readout after each exposure, in nanoseconds; triggers arriving
    /// before it ends are lost (the camera is busy).
    pub readout_ns: u64,
    /// Fault injection: indices (0-based, counting every trigger the camera
    /// received) of triggers the camera silently misses.
    pub missed_triggers: BTreeSet<u64>,
}

impl Default for CameraConfig {
    /// A global-shutter industrial camera in trigger-width mode: a few
    /// microseconds of latency, about one microsecond of jitter, 1 ms readout.
    fn default() -> Self {
        Self {
            trigger_to_exposure: Delay {
                latency_ns: 5_000,
                jitter_ns: 1_000,
            },
            mode: ExposureMode::TriggerWidth,
            readout_ns: 100_000,
            missed_triggers: BTreeSet::new(),
        }
    }
}

/// One exposure the camera actually made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Exposure {
    /// The frame's number (0 = first frame taken).
    pub frame_index: u32,
    /// Which received trigger started it.
    pub trigger_index: u64,
    /// The exposure-active pulse: integration from `rise_ns` to `fall_ns`.
    pub active: Pulse,
}

/// Why a trigger produced no frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MissReason {
    /// The camera was still exposing or reading out the previous frame.
    Busy,
    /// The fault injector told it to miss this trigger.
    Injected,
}

/// A simulated camera: feed it trigger pulses in time order, read back its
/// exposure-active pulses and the frames it took.
#[derive(Clone, Debug)]
pub struct Camera {
    config: CameraConfig,
    delay: DelaySource,
    triggers_received: u64,
    busy_until_ns: u64,
    exposures: Vec<Exposure>,
    missed: Vec<(u64, MissReason)>,
}

impl Camera {
    /// A camera with `config`, its jitter reproducible from `seed`.
    pub fn new(config: CameraConfig, seed: u64) -> Self {
        let delay = DelaySource::new(config.trigger_to_exposure, seed);
        Self {
            config,
            delay,
            triggers_received: 0,
            busy_until_ns: 0,
            exposures: Vec::new(),
            missed: Vec::new(),
        }
    }

    /// The configuration this camera runs with.
    pub fn config(&self) -> &CameraConfig {
        &self.config
    }

    /// A trigger pulse on the camera's input. Returns its exposure-active
    /// pulse, or `None` when no frame was taken (see [`Camera::missed`]).
    pub fn on_trigger(&mut self, trigger: Pulse) -> Option<Pulse> {
        let trigger_index = self.triggers_received;
        self.triggers_received += 1;
        if self.config.missed_triggers.contains(&trigger_index) {
            self.missed.push((trigger_index, MissReason::Injected));
            return None;
        }
        if self.triggers_received > 1 && trigger.rise_ns < self.busy_until_ns {
            self.missed.push((trigger_index, MissReason::Busy));
            return None;
        }
        let rise_ns = trigger.rise_ns + self.delay.next_ns();
        let exposure_ns = match self.config.mode {
            ExposureMode::TriggerWidth => trigger.width_ns(),
            ExposureMode::Timed { exposure_ns } => exposure_ns,
        };
        let active = Pulse {
            rise_ns,
            fall_ns: rise_ns + exposure_ns,
        };
        self.busy_until_ns = active.fall_ns + self.config.readout_ns;
        self.exposures.push(Exposure {
            frame_index: self.exposures.len() as u32,
            trigger_index,
            active,
        });
        Some(active)
    }

    /// Every frame taken so far, in order.
    pub fn exposures(&self) -> &[Exposure] {
        &self.exposures
    }

    /// Triggers that produced no frame, with the reason.
    pub fn missed(&self) -> &[(u64, MissReason)] {
        &self.missed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exact(mode: ExposureMode) -> CameraConfig {
        CameraConfig {
            trigger_to_exposure: Delay::fixed(3_000),
            mode,
            readout_ns: 50_000,
            missed_triggers: BTreeSet::new(),
        }
    }

    fn pulse(rise_ns: u64, fall_ns: u64) -> Pulse {
        Pulse { rise_ns, fall_ns }
    }

    #[test]
    fn trigger_width_mode_exposes_for_the_pulse_width() {
        let mut cam = Camera::new(exact(ExposureMode::TriggerWidth), 0);
        // One 4.8 ms exposure, as for 24 patterns at 5 kHz.
        let active = cam.on_trigger(pulse(1_000, 4_801_000)).unwrap();
        assert_eq!(active, pulse(4_000, 4_804_000));
        assert_eq!(cam.exposures()[0].frame_index, 0);
    }

    #[test]
    fn timed_mode_ignores_the_pulse_width() {
        let mut cam = Camera::new(
            exact(ExposureMode::Timed {
                exposure_ns: 20_000,
            }),
            0,
        );
        assert_eq!(cam.on_trigger(pulse(0, 10)).unwrap(), pulse(3_000, 23_000));
    }

    #[test]
    fn trigger_during_readout_is_lost() {
        let mut cam = Camera::new(
            exact(ExposureMode::Timed {
                exposure_ns: 20_000,
            }),
            0,
        );
        cam.on_trigger(pulse(0, 10)).unwrap();
        // Busy until 23_000 + 50_000.
        assert!(cam.on_trigger(pulse(72_999, 73_100)).is_none());
        assert!(cam.on_trigger(pulse(73_000, 73_100)).is_some());
        assert_eq!(cam.missed(), &[(1, MissReason::Busy)]);
        assert_eq!(cam.exposures()[1].trigger_index, 2);
        assert_eq!(cam.exposures()[1].frame_index, 1);
    }

    #[test]
    fn injected_miss_drops_exactly_that_trigger() {
        let mut config = exact(ExposureMode::TriggerWidth);
        config.missed_triggers.insert(1);
        let mut cam = Camera::new(config, 0);
        let got: Vec<bool> = (0..4u64)
            .map(|k| {
                cam.on_trigger(pulse(k * 1_000_000, k * 1_000_000 + 100))
                    .is_some()
            })
            .collect();
        assert_eq!(got, vec![true, false, true, true]);
        assert_eq!(cam.missed(), &[(1, MissReason::Injected)]);
    }
}
