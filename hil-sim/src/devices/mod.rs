//! Simulated devices on the board's trigger lines: DMD projectors and
//! hardware-triggered cameras, each with configurable latency and jitter on
//! its feedback line (projector trigger-out, camera exposure-active).
//!
//! They are plain state machines on virtual nanoseconds: feed them the board's
//! output edges in time order and they answer with feedback edges, and keep a
//! log of what they displayed or exposed so a camera model can integrate
//! exactly what the DMDs showed during each exposure window.
//!
//! [`dlpc`] is the DMD controller behind a projector at the byte level: the
//! USB HID reports a host driver sends, the images and pattern LUT they
//! upload, what the DMD then shows.

pub mod camera;
pub mod delay;
pub mod dlpc;
pub mod projector;

pub use camera::{Camera, CameraConfig, Exposure, MissReason};
pub use delay::{Delay, DelaySource, DelayedLine};
pub use projector::{Displayed, Projector, ProjectorConfig};

/// An edge on a device's feedback line, in virtual nanoseconds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LineEdge {
    /// The level after the edge.
    pub level: protocol::Level,
    /// When it happened.
    pub at_ns: u64,
}

/// How long each displayed pattern overlapped the window `[start_ns, end_ns)`:
/// `(pattern_index, overlap_ns)` for every pattern with a non-empty overlap, in
/// display order. This is what a camera exposing over that window integrates.
pub fn patterns_in_window(displayed: &[Displayed], start_ns: u64, end_ns: u64) -> Vec<(u32, u64)> {
    displayed
        .iter()
        .filter_map(|d| {
            let from_ns = d.start_ns.max(start_ns);
            let to_ns = d.end_ns.min(end_ns);
            (to_ns > from_ns).then(|| (d.pattern_index, to_ns - from_ns))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shown(pattern_index: u32, start_ns: u64, end_ns: u64) -> Displayed {
        Displayed {
            pattern_index,
            trigger_ns: start_ns,
            start_ns,
            end_ns,
        }
    }

    #[test]
    fn window_overlaps_are_clipped_to_the_window() {
        let log = [shown(0, 0, 100), shown(1, 100, 200), shown(2, 250, 300)];
        assert_eq!(
            patterns_in_window(&log, 50, 260),
            vec![(0, 50), (1, 100), (2, 10)]
        );
        assert_eq!(patterns_in_window(&log, 200, 250), vec![]);
    }
}
