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
//! - [`super::genicam::aravis_camera::GenicamCameras`] (cargo feature
//!   `genicam`): GenICam cameras (GigE Vision, USB3 Vision) through Aravis,
//!   hardware-triggered from the sync board's line.
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
    /// The same frames as [`FrameSource::take_frames`], each as its red,
    /// green and blue planes, for colour cameras (the high-speed mode); a
    /// source of grey frames answers [`RigError::NotColour`].
    fn take_colour_frames(&mut self, head: usize) -> Result<Vec<[Raster<f32>; 3]>, RigError> {
        Err(RigError::NotColour { head })
    }
}

/// A boxed source is a source: the CLI picks the cameras at run time.
impl<T: FrameSource + ?Sized> FrameSource for Box<T> {
    fn image_size_px(&self, head: usize) -> Result<(u32, u32), RigError> {
        (**self).image_size_px(head)
    }

    fn arm(&mut self, frames_per_head: &[usize]) -> Result<(), RigError> {
        (**self).arm(frames_per_head)
    }

    fn take_frames(&mut self, head: usize) -> Result<Vec<Raster<f32>>, RigError> {
        (**self).take_frames(head)
    }

    fn take_colour_frames(&mut self, head: usize) -> Result<Vec<[Raster<f32>; 3]>, RigError> {
        (**self).take_colour_frames(head)
    }
}
