//! A simulated hardware-triggered camera in trigger-width mode: the exposure
//! lasts as long as the trigger input is high, and the exposure-active output
//! mirrors the trigger after a latency. A trigger that comes while the sensor
//! is still busy with the previous frame is lost.

use std::collections::BTreeSet;

use protocol::limits::CameraProfile;
use protocol::Level;

use super::delay::{Delay, DelayedLine};
use super::LineEdge;

/// How a simulated camera responds to its trigger input.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct CameraConfig {
    /// From a trigger edge to the same edge on exposure-active.
    pub trigger_delay: Delay,
    /// Shortest time from one accepted trigger to the next (1 / max frame rate).
    pub min_frame_period_ns: u64,
    /// Shortest time from the end of one trigger pulse to the next trigger.
    pub min_gap_ns: u64,
    /// Fault injection: indices (0-based, counting every trigger pulse the
    /// camera received) of triggers the camera silently misses.
    pub missed_triggers: BTreeSet<u64>,
}

impl CameraConfig {
    /// The behaviour `protocol` assumes for a camera model, without faults.
    pub fn from_profile(profile: &CameraProfile) -> Self {
        Self {
            trigger_delay: Delay {
                latency_ns: profile.latency_ns as u64,
                jitter_ns: profile.jitter_ns as u64,
            },
            min_frame_period_ns: profile.min_frame_period_ns as u64,
            min_gap_ns: profile.min_gap_ns as u64,
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
    /// Integration start (exposure-active rising edge).
    pub start_ns: u64,
    /// Integration end (exposure-active falling edge); `None` while exposing.
    pub end_ns: Option<u64>,
}

/// Why a trigger produced no frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MissReason {
    /// Too soon after the previous frame (frame rate or re-arm gap).
    Busy,
    /// The fault injector told it to miss this trigger.
    Injected,
}

/// A simulated camera: feed it trigger edges in time order, read back its
/// exposure-active edges and the frames it took.
#[derive(Clone, Debug)]
pub struct Camera {
    config: CameraConfig,
    feedback: DelayedLine,
    triggers_received: u64,
    last_accepted_rise_ns: Option<u64>,
    last_fall_ns: Option<u64>,
    exposing: bool,
    exposures: Vec<Exposure>,
    missed: Vec<(u64, MissReason)>,
}

impl Camera {
    /// A camera with `config`, its jitter reproducible from `seed`.
    pub fn new(config: CameraConfig, seed: u64) -> Self {
        Self {
            feedback: DelayedLine::new(config.trigger_delay, seed),
            config,
            triggers_received: 0,
            last_accepted_rise_ns: None,
            last_fall_ns: None,
            exposing: false,
            exposures: Vec::new(),
            missed: Vec::new(),
        }
    }

    /// The configuration this camera runs with.
    pub fn config(&self) -> &CameraConfig {
        &self.config
    }

    /// A trigger edge at `at_ns` (edges in time order). Returns the
    /// exposure-active edge it causes, or `None` when no frame is being
    /// taken (see [`Camera::missed`]).
    pub fn on_edge(&mut self, level: Level, at_ns: u64) -> Option<LineEdge> {
        match level {
            Level::High => self.on_rise(at_ns),
            Level::Low => {
                self.last_fall_ns = Some(at_ns);
                if !std::mem::take(&mut self.exposing) {
                    return None;
                }
                let edge = self.feedback.mirror(Level::Low, at_ns);
                if let Some(exposure) = self.exposures.last_mut() {
                    exposure.end_ns = Some(edge.at_ns);
                }
                Some(edge)
            }
        }
    }

    fn on_rise(&mut self, at_ns: u64) -> Option<LineEdge> {
        let trigger_index = self.triggers_received;
        self.triggers_received += 1;
        if self.config.missed_triggers.contains(&trigger_index) {
            self.missed.push((trigger_index, MissReason::Injected));
            return None;
        }
        let too_soon = self
            .last_accepted_rise_ns
            .is_some_and(|last| at_ns < last + self.config.min_frame_period_ns)
            || self
                .last_fall_ns
                .is_some_and(|fall| at_ns < fall + self.config.min_gap_ns);
        if too_soon || self.exposing {
            self.missed.push((trigger_index, MissReason::Busy));
            return None;
        }
        self.last_accepted_rise_ns = Some(at_ns);
        self.exposing = true;
        let edge = self.feedback.mirror(Level::High, at_ns);
        self.exposures.push(Exposure {
            frame_index: self.exposures.len() as u32,
            trigger_index,
            start_ns: edge.at_ns,
            end_ns: None,
        });
        Some(edge)
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
    use protocol::CameraModel;

    fn exact() -> CameraConfig {
        CameraConfig {
            trigger_delay: Delay::fixed(3_000),
            min_frame_period_ns: 100_000,
            min_gap_ns: 2_000,
            missed_triggers: BTreeSet::new(),
        }
    }

    fn pulse(cam: &mut Camera, rise_ns: u64, fall_ns: u64) -> (Option<LineEdge>, Option<LineEdge>) {
        (
            cam.on_edge(Level::High, rise_ns),
            cam.on_edge(Level::Low, fall_ns),
        )
    }

    #[test]
    fn exposure_active_mirrors_the_trigger_pulse() {
        let mut cam = Camera::new(exact(), 0);
        // One 4.8 ms exposure, as for 24 patterns at 5 kHz.
        let (rise, fall) = pulse(&mut cam, 1_000, 4_801_000);
        assert_eq!(
            rise,
            Some(LineEdge {
                level: Level::High,
                at_ns: 4_000
            })
        );
        assert_eq!(
            fall,
            Some(LineEdge {
                level: Level::Low,
                at_ns: 4_804_000
            })
        );
        assert_eq!(
            cam.exposures(),
            &[Exposure {
                frame_index: 0,
                trigger_index: 0,
                start_ns: 4_000,
                end_ns: Some(4_804_000)
            }]
        );
    }

    #[test]
    fn trigger_above_the_frame_rate_is_lost() {
        let mut cam = Camera::new(exact(), 0);
        pulse(&mut cam, 0, 10_000);
        assert_eq!(pulse(&mut cam, 99_999, 100_500), (None, None));
        assert!(pulse(&mut cam, 200_000, 210_000).0.is_some());
        assert_eq!(cam.missed(), &[(1, MissReason::Busy)]);
        assert_eq!(cam.exposures()[1].trigger_index, 2);
        assert_eq!(cam.exposures()[1].frame_index, 1);
    }

    #[test]
    fn injected_miss_drops_exactly_that_trigger() {
        let mut config = exact();
        config.missed_triggers.insert(1);
        let mut cam = Camera::new(config, 0);
        let got: Vec<bool> = (0..4u64)
            .map(|k| {
                pulse(&mut cam, k * 1_000_000, k * 1_000_000 + 100)
                    .0
                    .is_some()
            })
            .collect();
        assert_eq!(got, vec![true, false, true, true]);
        assert_eq!(cam.missed(), &[(1, MissReason::Injected)]);
    }

    #[test]
    fn jitter_stays_within_the_profile() {
        let profile = CameraModel::Colour208Hz.profile();
        let mut cam = Camera::new(CameraConfig::from_profile(&profile), 5);
        let frame_ns = profile.min_frame_period_ns as u64;
        for k in 0..100u64 {
            let t = k * frame_ns;
            let (rise, fall) = pulse(&mut cam, t, t + 4_803_000);
            for (edge, input_ns) in [(rise.unwrap(), t), (fall.unwrap(), t + 4_803_000)] {
                let d = edge.at_ns - input_ns;
                assert!(
                    d.abs_diff(profile.latency_ns as u64) <= profile.jitter_ns as u64,
                    "{d}"
                );
            }
        }
    }
}
