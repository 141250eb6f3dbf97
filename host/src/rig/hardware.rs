//! Real devices: the sync board over a serial port, DMD pattern tables and
//! industrial cameras.
//!
//! PLACEHOLDER: only the board exists (the same serial client as the
//! simulator uses); no DMD (DLPC350 / DLPC900 I2C or USB) or camera (GenICam)
//! driver is written yet, so every call fails with a PLACEHOLDER error.

use protocol::ScanPlan;

use super::{Board, Camera, Projector, RigError};
use crate::board::ScanOutcome;
use crate::raster::Raster;

/// A rig of real devices (PLACEHOLDER: fails on every call).
#[derive(Debug, Default)]
pub struct HardwareRig;

const WHY: &str = "hardware rig: no DMD or camera driver yet; use --sim";

impl Board for HardwareRig {
    fn run_plan(&mut self, _plan: &ScanPlan) -> Result<ScanOutcome, RigError> {
        Err(RigError::Placeholder(WHY))
    }
}

impl Projector for HardwareRig {
    fn dmd_size_px(&self, _head: usize) -> Result<(u32, u32), RigError> {
        Err(RigError::Placeholder(WHY))
    }

    fn load_sequence(&mut self, _head: usize, _patterns: &[Raster<f32>]) -> Result<(), RigError> {
        Err(RigError::Placeholder(WHY))
    }
}

impl Camera for HardwareRig {
    fn image_size_px(&self, _head: usize) -> Result<(u32, u32), RigError> {
        Err(RigError::Placeholder(WHY))
    }

    fn take_frames(&mut self, _head: usize) -> Result<Vec<Raster<f32>>, RigError> {
        Err(RigError::Placeholder(WHY))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_call_says_placeholder() {
        let mut rig = HardwareRig;
        let err = rig.take_frames(0).unwrap_err().to_string();
        assert!(err.contains("PLACEHOLDER"), "{err}");
    }
}
