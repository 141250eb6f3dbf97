//! A simulated DMD projector in external-trigger pattern mode (DLPC350 /
//! DLPC900 style): each trigger-in rising edge advances to the next pattern
//! after a latency, and the controller answers on its trigger-out line.

use super::delay::{Delay, DelaySource};
use super::Pulse;

/// How a simulated projector responds to its trigger input.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ProjectorConfig {
    /// From the trigger-in rising edge to the pattern on the mirrors; trigger-out
    /// rises at the same moment.
    pub trigger_to_display: Delay,
    /// How long trigger-out stays high, in nanoseconds.
    pub trigger_out_width_ns: u64,
    /// How long each pattern stays on the mirrors, in nanoseconds (a following
    /// pattern ends it earlier).
    pub display_ns: u64,
    /// The shortest pattern period the DMD accepts (its 1-bit rate limit). A
    /// trigger arriving sooner after the previous accepted one is ignored, as a
    /// DLPC controller ignores triggers while a pattern is still loading.
    pub min_pattern_period_ns: u64,
}

impl Default for ProjectorConfig {
    /// A DLPC900-class DMD: 1-bit patterns up to 9.5 kHz (105 us), a few
    /// microseconds of trigger latency with sub-microsecond jitter.
    fn default() -> Self {
        Self {
            trigger_to_display: Delay {
                latency_ns: 2_000,
                jitter_ns: 200,
            },
            trigger_out_width_ns: 10_000,
            display_ns: 100_000,
            min_pattern_period_ns: 105_000,
        }
    }
}

/// One pattern as it was actually shown on the mirrors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Displayed {
    /// The pattern's place in the projector's sequence (0 = first accepted trigger).
    pub pattern_index: u32,
    /// The trigger-in edge that caused it, in virtual nanoseconds.
    pub trigger_ns: u64,
    /// When it appeared on the mirrors.
    pub start_ns: u64,
    /// When it left them (`display_ns` later, or when the next pattern appeared).
    pub end_ns: u64,
}

/// A simulated projector: feed it trigger-in edges in time order, read back
/// its trigger-out pulses and what it displayed.
#[derive(Clone, Debug)]
pub struct Projector {
    config: ProjectorConfig,
    delay: DelaySource,
    last_accepted_trigger_ns: Option<u64>,
    displayed: Vec<Displayed>,
    ignored_triggers_ns: Vec<u64>,
}

impl Projector {
    /// A projector with `config`, its jitter reproducible from `seed`.
    pub fn new(config: ProjectorConfig, seed: u64) -> Self {
        Self {
            config,
            delay: DelaySource::new(config.trigger_to_display, seed),
            last_accepted_trigger_ns: None,
            displayed: Vec::new(),
            ignored_triggers_ns: Vec::new(),
        }
    }

    /// The configuration this projector runs with.
    pub fn config(&self) -> &ProjectorConfig {
        &self.config
    }

    /// A trigger-in rising edge at `trigger_ns`. Returns the trigger-out pulse,
    /// or `None` when the DMD ignored the trigger (too soon after the last one).
    pub fn on_trigger(&mut self, trigger_ns: u64) -> Option<Pulse> {
        if let Some(last_ns) = self.last_accepted_trigger_ns {
            if trigger_ns < last_ns + self.config.min_pattern_period_ns {
                self.ignored_triggers_ns.push(trigger_ns);
                return None;
            }
        }
        self.last_accepted_trigger_ns = Some(trigger_ns);
        let start_ns = trigger_ns + self.delay.next_ns();
        if let Some(previous) = self.displayed.last_mut() {
            previous.end_ns = previous.end_ns.min(start_ns);
        }
        self.displayed.push(Displayed {
            pattern_index: self.displayed.len() as u32,
            trigger_ns,
            start_ns,
            end_ns: start_ns + self.config.display_ns,
        });
        Some(Pulse {
            rise_ns: start_ns,
            fall_ns: start_ns + self.config.trigger_out_width_ns,
        })
    }

    /// Every pattern shown so far, in order.
    pub fn displayed(&self) -> &[Displayed] {
        &self.displayed
    }

    /// The trigger edges the DMD ignored because they came too fast.
    pub fn ignored_triggers_ns(&self) -> &[u64] {
        &self.ignored_triggers_ns
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exact() -> ProjectorConfig {
        ProjectorConfig {
            trigger_to_display: Delay::fixed(1_000),
            trigger_out_width_ns: 5_000,
            display_ns: 150_000,
            min_pattern_period_ns: 105_000,
        }
    }

    #[test]
    fn trigger_out_follows_trigger_in_after_the_latency() {
        let mut p = Projector::new(exact(), 0);
        let pulse = p.on_trigger(10_000).unwrap();
        assert_eq!(
            pulse,
            Pulse {
                rise_ns: 11_000,
                fall_ns: 16_000
            }
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
        p.on_trigger(0).unwrap();
        p.on_trigger(120_000).unwrap();
        let shown = p.displayed();
        assert_eq!(shown[0].end_ns, 121_000);
        assert_eq!(shown[1].pattern_index, 1);
        assert_eq!(shown[1].start_ns, 121_000);
    }

    #[test]
    fn triggers_faster_than_the_dmd_rate_are_ignored() {
        let mut p = Projector::new(exact(), 0);
        assert!(p.on_trigger(0).is_some());
        assert!(p.on_trigger(104_999).is_none());
        assert!(p.on_trigger(105_000).is_some());
        assert_eq!(p.ignored_triggers_ns(), &[104_999]);
        assert_eq!(p.displayed().len(), 2);
    }

    #[test]
    fn jitter_stays_within_the_model() {
        let config = ProjectorConfig::default();
        let mut p = Projector::new(config, 42);
        for k in 0..200u64 {
            let t = k * 200_000;
            let pulse = p.on_trigger(t).unwrap();
            let d = pulse.rise_ns - t;
            assert!(d >= config.trigger_to_display.latency_ns);
            assert!(d <= config.trigger_to_display.max_ns());
        }
    }
}
