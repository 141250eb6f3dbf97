//! A rig file given to a scan (`slscan calibrate ... --out FILE`, or any
//! rig file a user brings): read and checked against the scan (its head
//! count, each device's image size) before anything is captured.

use std::path::{Path, PathBuf};

use crate::calibration::{read_rig, PinholeModel, RigCalibration, RigFileError};

/// What can be wrong with the calibration a scan is given.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationFileError {
    /// The rig file is missing, unreadable or invalid (missing field, NaN, ...).
    #[error(transparent)]
    File(#[from] RigFileError),
    /// The rig file has another number of heads than the rig scanned.
    #[error("rig file {path}: {heads} head(s); the rig scanned has {expected}")]
    HeadCount {
        /// The file.
        path: PathBuf,
        /// Heads in it.
        heads: usize,
        /// Heads of the rig.
        expected: usize,
    },
    /// A device in the file was calibrated at another image size than the scan uses.
    #[error("rig file {path}: head {head} {device} is {file_px:?} px, the scan's {device} is {scan_px:?} px")]
    ImageSize {
        /// The file.
        path: PathBuf,
        /// Head name in the file.
        head: String,
        /// "camera" or "projector".
        device: &'static str,
        /// (width, height) in the file.
        file_px: (u32, u32),
        /// (width, height) the scan uses.
        scan_px: (u32, u32),
    },
}

/// Reads the rig file at `path` and checks it fits a scan of `heads` heads
/// with these camera and projector sizes.
pub fn read_checked(
    path: &Path,
    heads: usize,
    camera_px: (u32, u32),
    projector_px: (u32, u32),
) -> Result<RigCalibration, CalibrationFileError> {
    let rig = read_rig(path)?;
    if rig.heads.len() != heads {
        return Err(CalibrationFileError::HeadCount {
            path: path.to_owned(),
            heads: rig.heads.len(),
            expected: heads,
        });
    }
    for head in &rig.heads {
        let devices: [(&'static str, &PinholeModel, (u32, u32)); 2] = [
            ("camera", &head.camera, camera_px),
            ("projector", &head.projector, projector_px),
        ];
        for (device, model, scan_px) in devices {
            let file_px = (model.width_px, model.height_px);
            if file_px != scan_px {
                return Err(CalibrationFileError::ImageSize {
                    path: path.to_owned(),
                    head: head.name.clone(),
                    device,
                    file_px,
                    scan_px,
                });
            }
        }
    }
    Ok(rig)
}
