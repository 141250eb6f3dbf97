//! What can be wrong with an OpenCV calibration file on import (see `import`).

use std::path::PathBuf;

use super::storage::StorageError;
use crate::calibration::RigFileError;

/// What can be wrong with an OpenCV calibration file.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The text is not a FileStorage file this reader understands.
    #[error(transparent)]
    Storage(#[from] StorageError),
    /// No layout's keys are there.
    #[error("no OpenCV calibration in the file (keys found: {found}); expected M1 D1 M4 D4 Rlp Tlp, M1 D1 M2 D2 R T, R1 R2 P1 P2 Q or camera_matrix distortion_coefficients")]
    NoCalibration {
        /// The keys the file has.
        found: String,
    },
    /// The closest layout lacks a key.
    #[error("missing key `{key}`: a {layout} file needs {needs}")]
    MissingKey {
        /// The key.
        key: &'static str,
        /// The layout.
        layout: &'static str,
        /// All its keys.
        needs: &'static str,
    },
    /// A key holds something else than a matrix.
    #[error("`{key}` (line {line}) is not a matrix")]
    NotAMatrix {
        /// The key.
        key: String,
        /// Its line.
        line: usize,
    },
    /// A matrix has the wrong shape.
    #[error("`{key}` (line {line}) is {rows}x{cols}, expected {expected}")]
    WrongSize {
        /// The key.
        key: String,
        /// Its line.
        line: usize,
        /// Rows found.
        rows: usize,
        /// Columns found.
        cols: usize,
        /// The shapes accepted.
        expected: &'static str,
    },
    /// A value is NaN or infinite.
    #[error("`{key}` (line {line}) element {index} is {value}, not a finite number")]
    NonFinite {
        /// The key.
        key: String,
        /// Its line.
        line: usize,
        /// Row-major index.
        index: usize,
        /// The value.
        value: f64,
    },
    /// A camera matrix is not `[fx 0 cx; 0 fy cy; 0 0 1]` with `fx, fy > 0`.
    #[error("`{key}` is not a camera matrix [fx 0 cx; 0 fy cy; 0 0 1] with fx, fy > 0: {problem}")]
    BadCameraMatrix {
        /// The key.
        key: String,
        /// What is wrong.
        problem: &'static str,
    },
    /// Distortion terms we do not model are nonzero.
    #[error("`{key}` has nonzero {terms:?}: only k1 k2 p1 p2 k3 are modelled (recalibrate without CALIB_RATIONAL_MODEL / THIN_PRISM / TILTED)")]
    UnmodelledDistortion {
        /// The key.
        key: String,
        /// The nonzero terms' names.
        terms: Vec<&'static str>,
    },
    /// A rotation is not orthonormal with determinant +1.
    #[error("`{key}` is not a proper rotation (defect {defect:.3e} > 1e-6)")]
    NotARotation {
        /// The key.
        key: String,
        /// `max|R^T R - I| + |det R - 1|`.
        defect: f64,
    },
    /// The principal rays meet behind a device.
    #[error("`{r_key}`, `{t_key}` look inverted: the optical axes meet {s1_m:.3} m along device 1's axis and {s2_m:.3} m along device 2's, behind a device; OpenCV's R, T map device 1 into device 2 (X2 = R X1 + T), this file's seem to map device 2 into device 1 (or only one of R, T is inverted). If the file is otherwise right, import it with --invert-extrinsics")]
    InvertedExtrinsics {
        /// The rotation's key.
        r_key: &'static str,
        /// The translation's key.
        t_key: &'static str,
        /// Closest point along device 1's principal ray, metres.
        s1_m: f64,
        /// Closest point along device 2's principal ray, metres.
        s2_m: f64,
    },
    /// No image size for a device.
    #[error(
        "no image size for the {device}: the file has none of {keys}; give it with {flag} WxH"
    )]
    NoImageSize {
        /// `camera` or `projector`.
        device: &'static str,
        /// The keys looked for.
        keys: &'static str,
        /// The CLI option.
        flag: &'static str,
    },
    /// The file's image size and the caller's differ.
    #[error(
        "the {device} size is {file_w}x{file_h} in the file but {given_w}x{given_h} was given"
    )]
    SizeConflict {
        /// `camera` or `projector`.
        device: &'static str,
        /// Width in the file.
        file_w: u32,
        /// Height in the file.
        file_h: u32,
        /// Width given.
        given_w: u32,
        /// Height given.
        given_h: u32,
    },
    /// An image size in the file is not two positive integers.
    #[error("`{key}` (line {line}) is not an image size (two integers in 1..=65536)")]
    BadImageSize {
        /// The key.
        key: String,
        /// Its line.
        line: usize,
    },
    /// A single-camera file cannot make a rig on its own.
    #[error("the file holds one camera only (camera_matrix, distortion_coefficients): a rig needs a projector or a second camera")]
    CameraOnly,
    /// The imported devices fail the rig file's checks.
    #[error(transparent)]
    Rig(#[from] RigFileError),
}
