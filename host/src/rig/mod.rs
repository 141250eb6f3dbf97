//! The rig at the host's edge: the sync board, the projectors' pattern
//! sequences and the cameras' frames, behind three small traits, so that a
//! scan pipeline runs the same on hardware and on the simulator.
//!
//! ```text
//! scan --Projector::load_sequence--> DMD pattern table (one per head)
//!      --Board::run_plan----------> trigger edges (board clock)
//!      --Camera::take_frames------> one frame per camera trigger, in order
//! ```
//!
//! - `crate::sim::rig` (feature `sim`): hil-sim's board on a pseudo-terminal
//!   (the host's serial client talks to it) with cameras rendered by the
//!   digital twin from what the simulated DMDs displayed while each
//!   simulated shutter was open.
//! - [`hardware`]: the real sync board over a serial port ([`serial_board`]),
//!   cameras read from the folder the camera vendor's software writes
//!   ([`folder_camera`], behind the [`camera_source::FrameSource`] trait where
//!   a GenICam backend slots in later) and DMD pattern sets written as PNG
//!   files for the DMD vendor's GUI ([`folder_projector`]: PLACEHOLDER, no DMD
//!   driver uploads them), or DMD controllers driven over USB HID
//!   ([`dlpc`]: DLPC350, DLPC900).

pub mod bayer;
pub mod camera_source;
pub mod dlpc;
pub mod folder_camera;
pub mod folder_projector;
pub mod genicam;
pub mod hardware;
pub mod serial_board;

use std::path::PathBuf;

use protocol::ScanPlan;

use crate::board::{BoardError, ScanOutcome};
use crate::raster::Raster;

/// What can go wrong at the rig's edge.
#[derive(Debug, thiserror::Error)]
pub enum RigError {
    /// The board link failed or the board refused a request.
    #[error("sync board")]
    Board(#[from] BoardError),
    /// The board ran the plan but its own feedback check found deviations
    /// (late, missing or unexpected edges, patterns outside their exposure).
    #[error("scan not clean: {state:?}, {on_time}/{expected} feedback edges on time, {unexpected} unexpected, {out_of_window} patterns outside their exposure, {unchecked} unchecked")]
    NotClean {
        /// How the scan ended.
        state: protocol::ScanState,
        /// Feedback edges expected.
        expected: u32,
        /// Feedback edges on time.
        on_time: u32,
        /// Edges that matched nothing.
        unexpected: u32,
        /// Patterns lit outside their exposure.
        out_of_window: u32,
        /// Patterns the board could not check.
        unchecked: u32,
    },
    /// A camera took another number of frames than it was triggered for
    /// (a frame source that cannot name the missed triggers leaves
    /// `missed` empty).
    #[error("head {head}: camera took {got} frames for {expected} triggers (missed triggers: {missed:?})")]
    FrameCount {
        /// Head index (0 = A).
        head: usize,
        /// Triggers sent.
        expected: usize,
        /// Frames taken.
        got: usize,
        /// Trigger indices the camera reported missing.
        missed: Vec<u64>,
    },
    /// The projector showed another number of patterns than the plan triggers.
    #[error("head {head}: projector showed {got} patterns for {expected} triggers")]
    PatternCount {
        /// Head index.
        head: usize,
        /// Triggers sent.
        expected: usize,
        /// Patterns shown.
        got: usize,
    },
    /// A frame's exposure window (board clock) did not hold exactly the
    /// patterns the plan puts in it, each shown whole.
    #[error("head {head} frame {frame}: expected patterns {expected:?} shown whole, the exposure saw (pattern, ns) {seen:?}")]
    Sequencing {
        /// Head index.
        head: usize,
        /// Frame index.
        frame: usize,
        /// Pattern indices the plan puts in this exposure.
        expected: Vec<u32>,
        /// (pattern index, ns inside the window) of what was shown.
        seen: Vec<(u32, u64)>,
    },
    /// No such head on this rig.
    #[error("head {head} does not exist (the rig has {heads})")]
    NoSuchHead {
        /// Head asked for.
        head: usize,
        /// Heads present.
        heads: usize,
    },
    /// A pattern does not match the projector's DMD size.
    #[error("head {head}: pattern is {got:?} but the DMD is {expected:?} (width, height)")]
    PatternSize {
        /// Head index.
        head: usize,
        /// DMD size.
        expected: (u32, u32),
        /// Pattern size.
        got: (usize, usize),
    },
    /// A camera frame has another size than the camera's.
    #[error("head {head} frame {frame} ({path}): image is {got:?} but the camera is {expected:?} (width, height)")]
    FrameSize {
        /// Head index.
        head: usize,
        /// Frame index in trigger order.
        frame: usize,
        /// The frame's file.
        path: PathBuf,
        /// Camera size.
        expected: (u32, u32),
        /// Frame size.
        got: (usize, usize),
    },
    /// A camera frame could not be read or decoded (corrupt or truncated file).
    #[error("head {head} frame {frame}: {source}")]
    FrameDecode {
        /// Head index.
        head: usize,
        /// Frame index in trigger order.
        frame: usize,
        /// The decoder's error (names the file).
        source: crate::io::images::ImageError,
    },
    /// A frame holds values above the bit depth the user declared (a 16-bit
    /// file of a 12-bit camera must stay below 4096).
    #[error("head {head} frame {frame} ({path}): value {max_value} does not fit the declared {declared_bits}-bit depth (file is {file_bits}-bit)")]
    FrameBitDepth {
        /// Head index.
        head: usize,
        /// Frame index in trigger order.
        frame: usize,
        /// The frame's file.
        path: PathBuf,
        /// Bits per sample the file stores (8 or 16).
        file_bits: u8,
        /// Bits the user declared.
        declared_bits: u8,
        /// Largest raw value found.
        max_value: u32,
    },
    /// A folder of the rig (camera frames, DMD patterns) could not be
    /// listed, created or written.
    #[error("{path}: {source}")]
    Folder {
        /// The folder or file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Pre-loaded DMD patterns do not match what the scan would upload.
    #[error("head {head}: {path} holds {found} pattern images, the scan needs {expected}")]
    PatternsPreloaded {
        /// Head index.
        head: usize,
        /// The pattern folder.
        path: PathBuf,
        /// Patterns the scan shows.
        expected: usize,
        /// Pattern images found.
        found: usize,
    },
    /// A DMD pattern file could not be written, listed or read back.
    #[error("head {head}: pattern file: {source}")]
    PatternImage {
        /// Head index.
        head: usize,
        /// What failed (names the file).
        source: crate::io::images::ImageError,
    },
    /// Coloured patterns for a projector that lights every pattern white
    /// (or LEDs that do not pair with the patterns one to one).
    #[error(
        "head {head}: this projector cannot light patterns in colour (its patterns are white)"
    )]
    NoLedControl {
        /// Head index.
        head: usize,
    },
    /// A GenICam camera failed, or its frames do not match its triggers
    /// (lost packets, missing or extra frames, a time-out).
    #[error("head {head}: GenICam camera")]
    Genicam {
        /// Head index.
        head: usize,
        /// Which camera, step or frame.
        source: genicam::GenicamError,
    },
    /// A DMD controller refused the pattern set, or its link failed (the
    /// head then has no set loaded).
    #[error("head {head}: DMD controller")]
    Controller {
        /// Head index.
        head: usize,
        /// The driver's error.
        source: dlpc::DlpcError,
    },
    /// Colour frames asked of a camera that gives grey ones only (a mono
    /// sensor, or a back end that reads single-channel images): the
    /// multiplexed high-speed mode (seed 001) needs a colour camera.
    #[error("head {head}: the camera gives no colour frames (mono sensor or grey-only back end); seed 001's multiplexed mode needs a colour camera")]
    NotColour {
        /// Head index.
        head: usize,
    },
    /// A device back end failed in a way of its own (the simulator's pty or
    /// renderer, a vendor library).
    #[error("{what}")]
    Backend {
        /// Which back end, and what it was doing.
        what: String,
        /// Its error.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

/// The sync board: runs a plan to its end.
pub trait Board {
    /// Uploads, arms, starts and follows `plan`; fails unless the board's
    /// own feedback check found the scan clean.
    fn run_plan(&mut self, plan: &ScanPlan) -> Result<ScanOutcome, RigError>;
    /// The board's trigger and feedback lines as it reported them (`None`
    /// when it has not said): a scan of more heads than they drive is
    /// refused before any capture.
    fn limits(&self) -> Option<protocol::BoardLimits> {
        None
    }
}

/// The LEDs lighting a pattern: drive of the red, green and blue LED in
/// [0, 1] (a DLPC350 / DLPC900 pattern LUT selects them per pattern).
pub type Led = [f32; 3];

/// All three LEDs: a white pattern.
pub const WHITE: Led = [1.0; 3];

/// The DMD projectors: a pattern table per head, advanced by each trigger.
pub trait Projector {
    /// DMD size of head `head`'s projector (width, height).
    fn dmd_size_px(&self, head: usize) -> Result<(u32, u32), RigError>;
    /// Loads the patterns (values in [0, 1]) the triggers of head `head`
    /// step through, in trigger order, lit white.
    fn load_sequence(&mut self, head: usize, patterns: &[Raster<f32>]) -> Result<(), RigError>;
    /// Checks, before the board starts `plan`, that every head's projector
    /// can show what the plan's slots ask of the loaded sets (a DMD
    /// controller's exposure at the set's bit depth, its LUT); projectors
    /// without such limits accept every plan.
    fn check_plan(&self, _plan: &ScanPlan) -> Result<(), RigError> {
        Ok(())
    }
    /// Loads patterns each lit by its own LEDs (`leds[i]` lights
    /// `patterns[i]`). A projector without LED control takes white ones only.
    fn load_coloured_sequence(
        &mut self,
        head: usize,
        patterns: &[Raster<f32>],
        leds: &[Led],
    ) -> Result<(), RigError> {
        if leds.len() == patterns.len() && leds.iter().all(|l| *l == WHITE) {
            self.load_sequence(head, patterns)
        } else {
            Err(RigError::NoLedControl { head })
        }
    }
}

/// The triggered cameras.
pub trait Camera {
    /// Image size of head `head`'s camera (width, height).
    fn image_size_px(&self, head: usize) -> Result<(u32, u32), RigError>;
    /// The frames head `head`'s camera took during the last plan, one per
    /// trigger in trigger order (values in [0, 1]); fails when a trigger
    /// produced no frame.
    fn take_frames(&mut self, head: usize) -> Result<Vec<Raster<f32>>, RigError>;
    /// The same frames as [`Camera::take_frames`], each as its red, green
    /// and blue planes (same units, in that order), for cameras with a
    /// colour sensor; a camera without one answers [`RigError::NotColour`].
    fn take_colour_frames(&mut self, head: usize) -> Result<Vec<[Raster<f32>; 3]>, RigError> {
        Err(RigError::NotColour { head })
    }
}

/// Checks a coloured sequence before a projector takes it: every pattern
/// the DMD's size (`expected`), one LED setting per pattern.
pub fn check_sequence(
    head: usize,
    expected: (u32, u32),
    patterns: &[Raster<f32>],
    leds: &[Led],
) -> Result<(), RigError> {
    if let Some(p) = patterns
        .iter()
        .find(|p| p.size() != (expected.0 as usize, expected.1 as usize))
    {
        return Err(RigError::PatternSize {
            head,
            expected,
            got: p.size(),
        });
    }
    if leds.len() != patterns.len() {
        return Err(RigError::NoLedControl { head });
    }
    Ok(())
}

/// Camera triggers per head of one run of `plan` (cycle exposures of that
/// head times the repeat count), for heads `0..heads`.
pub fn frames_per_head(plan: &ScanPlan, heads: usize) -> Vec<usize> {
    slots_per_frame(plan, heads).iter().map(Vec::len).collect()
}

/// Per head, per camera trigger of one run of `plan`: how many patterns
/// that exposure holds.
pub fn slots_per_frame(plan: &ScanPlan, heads: usize) -> Vec<Vec<usize>> {
    (0..heads)
        .map(|h| {
            let one_cycle: Vec<usize> = plan
                .exposures()
                .filter(|e| e.entry.heads.contains(h))
                .map(|e| e.slots.len())
                .collect();
            one_cycle.repeat(plan.repeat_count as usize)
        })
        .collect()
}

/// Checks a finished scan's counters: clean, or [`RigError::NotClean`].
pub fn require_clean(outcome: &ScanOutcome) -> Result<(), RigError> {
    if outcome.is_clean() {
        return Ok(());
    }
    let r = &outcome.report;
    Err(RigError::NotClean {
        state: outcome.state,
        expected: r.expected,
        on_time: r.on_time,
        unexpected: r.unexpected,
        out_of_window: r.out_of_window,
        unchecked: r.patterns_unchecked,
    })
}
