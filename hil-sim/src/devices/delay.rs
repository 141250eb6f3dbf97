//! A delay with bounded, seeded jitter: the latency model of every simulated
//! device line.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A device delay: `latency_ns` nominal, deviating by at most `jitter_ns`
/// either way, drawn uniformly (the meaning of `latency_ns` / `jitter_ns` in
/// `protocol::limits` device profiles). Bounded, not Gaussian, so tests can
/// state hard limits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Delay {
    /// The nominal delay, in virtual nanoseconds.
    pub latency_ns: u64,
    /// The peak deviation from `latency_ns`, in virtual nanoseconds (0 = no jitter).
    pub jitter_ns: u64,
}

impl Delay {
    /// A delay without jitter.
    pub const fn fixed(latency_ns: u64) -> Self {
        Self {
            latency_ns,
            jitter_ns: 0,
        }
    }

    /// The smallest delay this model can produce.
    pub const fn min_ns(&self) -> u64 {
        self.latency_ns.saturating_sub(self.jitter_ns)
    }

    /// The largest delay this model can produce.
    pub const fn max_ns(&self) -> u64 {
        self.latency_ns + self.jitter_ns
    }
}

/// Draws delays from a [`Delay`] model with a seeded generator, so a run with
/// the same seed and the same triggers gives the same timeline.
#[derive(Clone, Debug)]
pub struct DelaySource {
    delay: Delay,
    rng: ChaCha8Rng,
}

impl DelaySource {
    /// A source for `delay`, reproducible from `seed`.
    pub fn new(delay: Delay, seed: u64) -> Self {
        Self {
            delay,
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// The model this source draws from.
    pub fn delay(&self) -> Delay {
        self.delay
    }

    /// The next delay in nanoseconds, in `[min_ns(), max_ns()]`.
    pub fn next_ns(&mut self) -> u64 {
        match self.delay.jitter_ns {
            0 => self.delay.latency_ns,
            _ => self
                .rng
                .random_range(self.delay.min_ns()..=self.delay.max_ns()),
        }
    }
}

/// A device's feedback output that follows its input after a [`Delay`]:
/// edges keep their order even where jitter would swap two close ones (a line
/// cannot fall before it rose). Shared by the projector's trigger-out and the
/// camera's exposure-active line.
#[derive(Clone, Debug)]
pub struct DelayedLine {
    delay: DelaySource,
    last_out_ns: u64,
}

impl DelayedLine {
    /// A line delayed by `delay`, its jitter reproducible from `seed`.
    pub fn new(delay: Delay, seed: u64) -> Self {
        Self {
            delay: DelaySource::new(delay, seed),
            last_out_ns: 0,
        }
    }

    /// The output edge for an input edge to `level` at `at_ns`.
    pub fn mirror(&mut self, level: protocol::Level, at_ns: u64) -> super::LineEdge {
        let out_ns = (at_ns + self.delay.next_ns()).max(self.last_out_ns + 1);
        self.last_out_ns = out_ns;
        super::LineEdge {
            level,
            at_ns: out_ns,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn fixed_delay_never_varies() {
        let mut source = DelaySource::new(Delay::fixed(1_500), 7);
        assert!((0..100).all(|_| source.next_ns() == 1_500));
    }

    #[test]
    fn same_seed_same_sequence_other_seed_other_sequence() {
        let delay = Delay {
            latency_ns: 100,
            jitter_ns: 1_000,
        };
        let draw = |seed| {
            let mut s = DelaySource::new(delay, seed);
            (0..32).map(|_| s.next_ns()).collect::<Vec<_>>()
        };
        assert_eq!(draw(1), draw(1));
        assert_ne!(draw(1), draw(2));
    }

    #[test]
    fn jitter_spreads_over_the_whole_range_either_side() {
        let delay = Delay {
            latency_ns: 5,
            jitter_ns: 4,
        };
        let mut source = DelaySource::new(delay, 3);
        let seen: std::collections::BTreeSet<u64> = (0..1_000).map(|_| source.next_ns()).collect();
        assert_eq!(seen, (1..=9).collect());
    }

    proptest! {
        #[test]
        fn delays_stay_within_bounds(latency_ns in 0u64..1_000_000, jitter_ns in 0u64..1_000_000, seed: u64) {
            let delay = Delay { latency_ns, jitter_ns };
            let mut source = DelaySource::new(delay, seed);
            for _ in 0..16 {
                let d = source.next_ns();
                prop_assert!(d >= delay.min_ns() && d <= delay.max_ns());
            }
        }
    }
}
