//! The rig of real devices: the sync board over a serial port
//! ([`SerialBoard`]), DMD pattern sets uploaded by a [`Projector`]: a DLPC
//! controller driver ([`super::dlpc`], with the `hid` feature) or handed to
//! the DMD vendor's GUI as files ([`FolderProjector`], the default), and camera
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
pub struct HardwareRig<S: FrameSource = FolderCamera, P: Projector = FolderProjector> {
    board: SerialBoard,
    projector: P,
    cameras: S,
    heads: usize,
}

impl<S: FrameSource, P: Projector> HardwareRig<S, P> {
    /// A rig of `heads` heads from its three parts.
    pub fn new(board: SerialBoard, projector: P, cameras: S, heads: usize) -> Self {
        HardwareRig {
            board,
            projector,
            cameras,
            heads,
        }
    }
}

impl<S: FrameSource, P: Projector> Board for HardwareRig<S, P> {
    fn run_plan(&mut self, plan: &ScanPlan) -> Result<ScanOutcome, RigError> {
        self.projector.check_plan(plan)?;
        self.cameras.arm(&frames_per_head(plan, self.heads))?;
        self.board.run_plan(plan)
    }

    fn limits(&self) -> Option<protocol::BoardLimits> {
        self.board.limits()
    }
}

impl<S: FrameSource, P: Projector> Projector for HardwareRig<S, P> {
    fn dmd_size_px(&self, head: usize) -> Result<(u32, u32), RigError> {
        self.projector.dmd_size_px(head)
    }

    fn load_sequence(&mut self, head: usize, patterns: &[Raster<f32>]) -> Result<(), RigError> {
        self.projector.load_sequence(head, patterns)
    }

    fn check_plan(&self, plan: &ScanPlan) -> Result<(), RigError> {
        self.projector.check_plan(plan)
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

impl<S: FrameSource, P: Projector> Camera for HardwareRig<S, P> {
    fn image_size_px(&self, head: usize) -> Result<(u32, u32), RigError> {
        self.cameras.image_size_px(head)
    }

    fn take_frames(&mut self, head: usize) -> Result<Vec<Raster<f32>>, RigError> {
        self.cameras.take_frames(head)
    }

    fn take_colour_frames(&mut self, head: usize) -> Result<Vec<[Raster<f32>; 3]>, RigError> {
        self.cameras.take_colour_frames(head)
    }
}
