//! Where camera frames come from on hardware: the [`FrameSource`] trait.
//!
//! The hardware rig ([`super::hardware::HardwareRig`]) asks its frame
//! source two things: "a plan that triggers `n[h]` frames of head `h` is
//! about to start" ([`FrameSource::arm`]) and, after the board ran it, "the
//! frames of head `h`, in trigger order" ([`FrameSource::take_frames`]).
//!
//! Implementations:
//! - [`super::folder_camera::FolderCamera`]: the camera vendor's software
//!   (Basler pylon Viewer, FLIR SpinView, IDS peak, ...) runs the cameras in
//!   hardware-trigger mode and saves one file per trigger into a folder;
//!   slscan reads them from there.
//!
//! # Extension point: a GenICam backend (not written)
//!
//! A direct camera driver goes here, as another `impl FrameSource`, e.g. a
//! `GenicamCamera` in `rig/genicam_camera.rs` on Aravis (the `aravis` crate,
//! GigE Vision and USB3 Vision) behind a cargo feature so the default build
//! needs no system library. Its job, mapped onto the trait:
//! - `new`: open each head's camera by serial number; set `TriggerMode=On`,
//!   `TriggerSource=Line0` (the sync board's trigger line),
//!   `TriggerActivation=RisingEdge`, `ExposureMode=TriggerWidth` or a fixed
//!   `ExposureTime` shorter than the plan's exposure, `PixelFormat=Mono12`
//!   or `Mono16`, and start acquisition with enough buffers for a whole scan.
//! - `arm`: flush buffers left from earlier scans; remember the counts.
//! - `take_frames`: pop buffers until `n[h]` arrived or a timeout; a gap in
//!   the GenICam block (frame) ids names the missed triggers in
//!   [`super::RigError::FrameCount`]'s `missed`; normalise by the pixel
//!   format's bit depth.
//!
//! Nothing else changes: the scan pipeline only sees [`super::Camera`].

use super::RigError;
use crate::raster::Raster;

/// A source of triggered camera frames, one camera per head.
pub trait FrameSource {
    /// Image size of head `head`'s camera (width, height), pixels.
    fn image_size_px(&self, head: usize) -> Result<(u32, u32), RigError>;
    /// Called just before the board starts a plan that triggers
    /// `frames_per_head[h]` frames of head `h`: frames that arrived before
    /// this call belong to no scan of ours.
    fn arm(&mut self, frames_per_head: &[usize]) -> Result<(), RigError>;
    /// After the plan ran: head `head`'s frames, one per trigger in trigger
    /// order, values in [0, 1]. Waits for them (the source's own timeout);
    /// fails with [`RigError::FrameCount`] when too few or too many came.
    fn take_frames(&mut self, head: usize) -> Result<Vec<Raster<f32>>, RigError>;
}
