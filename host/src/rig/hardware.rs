//! The rig of real devices: the sync board over a serial port
//! ([`SerialBoard`]), DMD pattern sets handed to the DMD vendor's GUI as
//! files ([`FolderProjector`], PLACEHOLDER: no DMD driver), and camera
//! frames from a [`FrameSource`] (today [`FolderCamera`]: the folder the
//! camera vendor's software writes; a GenICam backend slots in there, see
//! [`super::camera_source`]).
//!
//! Before each plan the frame source is armed with the frame count each
//! head's camera will be triggered for, so only frames of that run count.

use protocol::ScanPlan;

use super::camera_source::FrameSource;
use super::folder_camera::FolderCamera;
use super::folder_projector::FolderProjector;
use super::serial_board::SerialBoard;
use super::{frames_per_head, Board, Camera, Projector, RigError};
use crate::board::ScanOutcome;
use crate::raster::Raster;

/// Board + projectors + cameras of a real rig.
pub struct HardwareRig<S: FrameSource = FolderCamera> {
    board: SerialBoard,
    projector: FolderProjector,
    cameras: S,
    heads: usize,
}

impl<S: FrameSource> HardwareRig<S> {
    /// A rig of `heads` heads from its three parts.
    pub fn new(board: SerialBoard, projector: FolderProjector, cameras: S, heads: usize) -> Self {
        HardwareRig {
            board,
            projector,
            cameras,
            heads,
        }
    }
}

impl<S: FrameSource> Board for HardwareRig<S> {
    fn run_plan(&mut self, plan: &ScanPlan) -> Result<ScanOutcome, RigError> {
        self.cameras.arm(&frames_per_head(plan, self.heads))?;
        self.board.run_plan(plan)
    }
}

impl<S: FrameSource> Projector for HardwareRig<S> {
    fn dmd_size_px(&self, head: usize) -> Result<(u32, u32), RigError> {
        self.projector.dmd_size_px(head)
    }

    fn load_sequence(&mut self, head: usize, patterns: &[Raster<f32>]) -> Result<(), RigError> {
        self.projector.load_sequence(head, patterns)
    }

    fn load_coloured_sequence(
        &mut self,
        head: usize,
        patterns: &[Raster<f32>],
        leds: &[super::Led],
    ) -> Result<(), RigError> {
        self.projector.load_coloured_sequence(head, patterns, leds)
    }
}

impl<S: FrameSource> Camera for HardwareRig<S> {
    fn image_size_px(&self, head: usize) -> Result<(u32, u32), RigError> {
        self.cameras.image_size_px(head)
    }

    fn take_frames(&mut self, head: usize) -> Result<Vec<Raster<f32>>, RigError> {
        self.cameras.take_frames(head)
    }
}
