//! GenICam cameras (GigE Vision, USB3 Vision) as a [`super::camera_source::FrameSource`]:
//! each head's camera opened by id, set to hardware trigger from the sync
//! board's line, streaming into a pool of buffers; after each plan, exactly
//! one complete frame per trigger, in order, with its time stamps, or a
//! typed error naming the frame.
//!
//! - [`pixels`]: a buffer's bytes to a frame in [0, 1] (Mono8..Mono16),
//!   every size checked (the bytes come over the network).
//! - [`ledger`]: the arrivals of one plan against its triggers: incomplete
//!   frames (lost packets that resends did not recover), gaps in the block
//!   ids (triggers without a frame), too few by the time-out, too many.
//! - `aravis_camera` (cargo feature `genicam`, Debian `libaravis-dev`):
//!   the devices through Aravis 0.8, the reference open GenICam stack.
//!
//! The first two are plain code, built and tested without Aravis.

pub mod ledger;
pub mod pixels;

#[cfg(feature = "genicam")]
pub mod aravis_camera;

use std::time::Duration;

pub use ledger::{Arrival, ArrivalStatus, LedgerError};
pub use pixels::{PixelError, PixelFormat};

/// How each camera is set up for a scan.
#[derive(Clone, Debug, PartialEq)]
pub struct GenicamSettings {
    /// Pixel format (the camera must offer it).
    pub pixel_format: PixelFormat,
    /// Exposure time in us; `None` leaves the camera's.
    pub exposure_us: Option<f64>,
    /// Analogue gain in the camera's unit (usually dB); `None` leaves the
    /// camera's. Auto gain and auto exposure are switched off either way:
    /// they would change the fringe levels between patterns.
    pub gain: Option<f64>,
    /// Region of interest (x, y, width, height); `None`: the whole sensor.
    pub roi: Option<(u32, u32, u32, u32)>,
    /// `TriggerSource`: the input line the sync board drives (`Line0`), or
    /// `Software` (tests, a bench without a board).
    pub trigger_source: String,
    /// `TriggerActivation` (`RisingEdge`, as the board's edges are written).
    pub trigger_activation: String,
    /// Buffers in the stream's pool: at least a whole plan's frames, so
    /// none is dropped while the host waits for the board.
    pub buffers: usize,
    /// Longest wait for the next frame after the plan ran.
    pub frame_timeout: Duration,
    /// Ask the camera to resend lost packets (GigE Vision).
    pub packet_resend: bool,
}

impl Default for GenicamSettings {
    fn default() -> Self {
        GenicamSettings {
            pixel_format: PixelFormat::Mono8,
            exposure_us: None,
            gain: None,
            roi: None,
            trigger_source: "Line0".into(),
            trigger_activation: "RisingEdge".into(),
            buffers: 64,
            frame_timeout: Duration::from_secs(2),
            packet_resend: true,
        }
    }
}

/// A camera found on the networks and buses Aravis searches.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CameraInfo {
    /// The id to open it by (`Vendor-Model-Serial` for GigE Vision).
    pub id: String,
    /// Vendor name.
    pub vendor: String,
    /// Model name.
    pub model: String,
    /// `GigEVision`, `USB3Vision` or `Fake`.
    pub protocol: String,
    /// Network address or USB path.
    pub address: String,
}

/// Packet and buffer counters of one camera's stream since it was opened.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamCounters {
    /// Buffers completed whole.
    pub completed: u64,
    /// Buffers that failed (missing packets, time-outs, ...).
    pub failures: u64,
    /// Packets the camera resent on request.
    pub resent_packets: u64,
    /// Packets never received.
    pub missing_packets: u64,
    /// Resend requests sent.
    pub resend_requests: u64,
}

impl StreamCounters {
    /// What happened between `earlier` and `self`.
    pub fn since(&self, earlier: &StreamCounters) -> StreamCounters {
        StreamCounters {
            completed: self.completed.saturating_sub(earlier.completed),
            failures: self.failures.saturating_sub(earlier.failures),
            resent_packets: self.resent_packets.saturating_sub(earlier.resent_packets),
            missing_packets: self.missing_packets.saturating_sub(earlier.missing_packets),
            resend_requests: self.resend_requests.saturating_sub(earlier.resend_requests),
        }
    }
}

/// What can go wrong with a GenICam camera.
#[derive(Debug, thiserror::Error)]
pub enum GenicamError {
    /// No camera answers to this id.
    #[error("no GenICam camera {id:?} (found: {found:?})")]
    NotFound {
        /// The id asked for.
        id: String,
        /// Ids of the cameras found.
        found: Vec<String>,
    },
    /// The camera or Aravis refused a step (open, a feature, the stream).
    #[error("camera {id}: {step}: {message}")]
    Device {
        /// The camera.
        id: String,
        /// What was being done (`PixelFormat = Mono16`, `open`, ...).
        step: String,
        /// Aravis's message.
        message: String,
    },
    /// The camera does not offer a pixel format slscan reads.
    #[error("camera {id}: pixel format {format} is not one slscan reads ({accepted})")]
    PixelFormat {
        /// The camera.
        id: String,
        /// What it sends (PFNC code or name).
        format: String,
        /// The accepted formats.
        accepted: String,
    },
    /// The frames of a plan do not match its triggers.
    #[error("camera {id}: {source} (waited {waited_ms} ms; stream: {counters:?})")]
    Frames {
        /// The camera.
        id: String,
        /// Time spent waiting for this plan's frames, ms.
        waited_ms: u64,
        /// The stream's counters over this plan.
        counters: StreamCounters,
        /// Which frame, and how.
        source: LedgerError,
    },
    /// A frame's bytes are not an image of the declared size and format.
    #[error("camera {id}: frame {index}: {source}")]
    Pixels {
        /// The camera.
        id: String,
        /// Position in trigger order.
        index: usize,
        /// The decoder's error.
        source: PixelError,
    },
    /// The build has no Aravis (cargo feature `genicam`).
    #[error("GenICam cameras need Aravis: this slscan was built without the `genicam` feature (cargo build --release -p slscan --features genicam; Debian: apt install libaravis-dev)")]
    NotBuilt,
}
