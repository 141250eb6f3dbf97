//! A simulated DMD projector in external-trigger pattern mode (DLPC350 /
//! DLPC900 style): each trigger-in rising edge advances to the next pattern
//! after a latency, and the controller mirrors its trigger input on its
//! trigger-out line after the same kind of latency.

use protocol::limits::ProjectorProfile;
use protocol::Level;

use super::delay::{Delay, DelayedLine};
use super::LineEdge;

/// How a simulated projector responds to its trigger input.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ProjectorConfig {
    /// From a trigger-in edge to the same edge on trigger-out; a rising edge
    /// also puts the next pattern on the mirrors after this delay.
    pub trigger_delay: Delay,
    /// How long each pattern stays on the mirrors, in nanoseconds (a following
    /// pattern ends it earlier), unless a display sequence is set
    /// ([`Projector::set_display_sequence`]).
    pub display_ns: u64,
    /// The shortest pattern period the DMD accepts (its 1-bit rate limit). A
    /// trigger arriving sooner after the previous accepted one is ignored, as a
    /// DLPC controller ignores triggers while a pattern is still loading.
    pub min_pattern_period_ns: u64,
}

impl ProjectorConfig {
    /// The behaviour `protocol` assumes for a projector model: its latency and
    /// peak jitter, its 1-bit rate limit, each pattern shown for one period.
    pub fn from_profile(profile: &ProjectorProfile) -> Self {
        Self {
            trigger_delay: Delay {
                latency_ns: profile.latency_ns as u64,
                jitter_ns: profile.jitter_ns as u64,
            },
            display_ns: profile.min_pattern_period_ns as u64,
            min_pattern_period_ns: profile.min_pattern_period_ns as u64,
        }
    }
}

/// One pattern as it was actually shown on the mirrors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Displayed {
    /// The pattern's place in the projector's sequence (0 = first accepted trigger).
    pub pattern_index: u32,
    /// The trigger-in rising edge that caused it, in virtual nanoseconds.
    pub trigger_ns: u64,
    /// When it appeared on the mirrors.
    pub start_ns: u64,
    /// When it left them (`display_ns` later, or when the next pattern appeared).
    pub end_ns: u64,
}

/// A simulated projector: feed it trigger-in edges in time order, read back
/// its trigger-out edges and what it displayed.
#[derive(Clone, Debug)]
pub struct Projector {
    config: ProjectorConfig,
    feedback: DelayedLine,
    last_accepted_rise_ns: Option<u64>,
    // Whether the current trigger-in pulse was accepted, so its falling edge
    // is mirrored too (an ignored pulse leaves trigger-out quiet).
    mirroring: bool,
    display_sequence_ns: Vec<u64>,
    displayed: Vec<Displayed>,
    ignored_triggers_ns: Vec<u64>,
}

impl Projector {
    /// A projector with `config`, its jitter reproducible from `seed`.
    pub fn new(config: ProjectorConfig, seed: u64) -> Self {
        Self {
            config,
            feedback: DelayedLine::new(config.trigger_delay, seed),
            last_accepted_rise_ns: None,
            mirroring: false,
            display_sequence_ns: Vec::new(),
            displayed: Vec::new(),
            ignored_triggers_ns: Vec::new(),
        }
    }

    /// The configuration this projector runs with.
    pub fn config(&self) -> &ProjectorConfig {
        &self.config
    }

    /// Sets how long each pattern is shown, pattern after pattern, the
    /// sequence repeating: the exposure times of the DMD controller's pattern
    /// table, which the host programs to match its scan plan. Empty: every
    /// pattern for `config.display_ns`.
    pub fn set_display_sequence(&mut self, display_ns: Vec<u64>) {
        self.display_sequence_ns = display_ns;
    }

    /// A trigger-in edge at `at_ns` (edges in time order). Returns the
    /// trigger-out edge it causes, or `None` when the DMD ignored the trigger
    /// (too soon after the last one) or the edge ends an ignored pulse.
    pub fn on_edge(&mut self, level: Level, at_ns: u64) -> Option<LineEdge> {
        match level {
            Level::High => self.on_rise(at_ns),
            Level::Low if self.mirroring => {
                self.mirroring = false;
                Some(self.feedback.mirror(Level::Low, at_ns))
            }
            Level::Low => None,
        }
    }

    fn on_rise(&mut self, at_ns: u64) -> Option<LineEdge> {
        let too_soon = self
            .last_accepted_rise_ns
            .is_some_and(|last_ns| at_ns < last_ns + self.config.min_pattern_period_ns);
        if too_soon || self.mirroring {
            self.ignored_triggers_ns.push(at_ns);
            return None;
        }
        self.last_accepted_rise_ns = Some(at_ns);
        self.mirroring = true;
        let edge = self.feedback.mirror(Level::High, at_ns);
        if let Some(previous) = self.displayed.last_mut() {
            previous.end_ns = previous.end_ns.min(edge.at_ns);
        }
        let pattern_index = self.displayed.len();
        let display_ns = match self.display_sequence_ns.len() {
            0 => self.config.display_ns,
            n => self.display_sequence_ns[pattern_index % n],
        };
        self.displayed.push(Displayed {
            pattern_index: pattern_index as u32,
            trigger_ns: at_ns,
            start_ns: edge.at_ns,
            end_ns: edge.at_ns + display_ns,
        });
        Some(edge)
    }

    /// Every pattern shown so far, in order.
    pub fn displayed(&self) -> &[Displayed] {
        &self.displayed
    }

    /// The trigger rising edges the DMD ignored because they came too fast.
    pub fn ignored_triggers_ns(&self) -> &[u64] {
        &self.ignored_triggers_ns
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::ProjectorModel;

    fn exact() -> ProjectorConfig {
        ProjectorConfig {
            trigger_delay: Delay::fixed(1_000),
            display_ns: 150_000,
            min_pattern_period_ns: 105_000,
        }
    }

    fn pulse(
        p: &mut Projector,
        rise_ns: u64,
        fall_ns: u64,
    ) -> (Option<LineEdge>, Option<LineEdge>) {
        (
            p.on_edge(Level::High, rise_ns),
            p.on_edge(Level::Low, fall_ns),
        )
    }

    #[test]
    fn trigger_out_mirrors_trigger_in_after_the_latency() {
        let mut p = Projector::new(exact(), 0);
        let (rise, fall) = pulse(&mut p, 10_000, 20_000);
        assert_eq!(
            rise,
            Some(LineEdge {
                level: Level::High,
                at_ns: 11_000
            })
        );
        assert_eq!(
            fall,
            Some(LineEdge {
                level: Level::Low,
                at_ns: 21_000
            })
        );
        assert_eq!(
            p.displayed(),
            &[Displayed {
                pattern_index: 0,
                trigger_ns: 10_000,
                start_ns: 11_000,
                end_ns: 161_000
            }]
        );
    }

    #[test]
    fn next_pattern_cuts_the_previous_one_short() {
        let mut p = Projector::new(exact(), 0);
        pulse(&mut p, 0, 10_000);
        pulse(&mut p, 120_000, 130_000);
        let shown = p.displayed();
        assert_eq!(shown[0].end_ns, 121_000);
        assert_eq!(shown[1].pattern_index, 1);
        assert_eq!(shown[1].start_ns, 121_000);
    }

    #[test]
    fn triggers_faster_than_the_dmd_rate_are_ignored_with_their_falling_edge() {
        let mut p = Projector::new(exact(), 0);
        assert!(pulse(&mut p, 0, 10_000).0.is_some());
        assert_eq!(pulse(&mut p, 104_999, 110_000), (None, None));
        assert!(pulse(&mut p, 105_000, 115_000).1.is_some());
        assert_eq!(p.ignored_triggers_ns(), &[104_999]);
        assert_eq!(p.displayed().len(), 2);
    }

    #[test]
    fn display_sequence_sets_each_pattern_and_repeats() {
        let mut p = Projector::new(exact(), 0);
        p.set_display_sequence(vec![10_000, 20_000]);
        for k in 0..3u64 {
            pulse(&mut p, k * 200_000, k * 200_000 + 5_000);
        }
        let shown: Vec<u64> = p
            .displayed()
            .iter()
            .map(|d| d.end_ns - d.start_ns)
            .collect();
        assert_eq!(shown, vec![10_000, 20_000, 10_000]);
    }

    #[test]
    fn jitter_stays_within_the_profile() {
        let profile = ProjectorModel::Dlpc900.profile();
        let config = ProjectorConfig::from_profile(&profile);
        let mut p = Projector::new(config, 42);
        for k in 0..200u64 {
            let t = k * 200_000;
            let (rise, fall) = pulse(&mut p, t, t + 10_000);
            for (edge, input_ns) in [(rise.unwrap(), t), (fall.unwrap(), t + 10_000)] {
                let d = edge.at_ns - input_ns;
                assert!(
                    d.abs_diff(profile.latency_ns as u64) <= profile.jitter_ns as u64,
                    "{d}"
                );
            }
        }
    }
}
