//! Phase maps on disk as `.npy` (DESIGN: float arrays go to .npy): 2-D,
//! C order, little-endian f32 or f64, NaN where there is no phase.
//!
//! Reading and writing go through [`crate::io::npy`].

use std::path::{Path, PathBuf};

use super::board::GrayImage;
use crate::io::npy::{decode_npy_2d, encode_npy_f32_rows, Dtype, NpyError};
use crate::io::write_atomically;

/// Errors of phase-map files.
#[derive(Debug, thiserror::Error)]
pub enum PhaseFileError {
    /// Reading or writing failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not an .npy file.
    #[error("{path}: not a NumPy .npy file")]
    NotNpy {
        /// The file.
        path: PathBuf,
    },
    /// The array is not a 2-D little-endian float array in C order.
    #[error("{path}: need a 2-D C-order '<f4' or '<f8' array, found {header:?}")]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// The header dictionary as written.
        header: String,
    },
    /// The data is shorter than the shape says.
    #[error("{path}: shape {height}x{width} needs {expected} bytes of data, file has {got}")]
    Truncated {
        /// The file.
        path: PathBuf,
        /// Rows.
        height: usize,
        /// Columns.
        width: usize,
        /// Bytes expected.
        expected: usize,
        /// Bytes present.
        got: usize,
    },
}

/// Reads a phase map (radians, NaN = none) from an .npy file: a 2-D
/// float array (`<f4` or `<f8`).
pub fn read_phase_map(path: &Path) -> Result<GrayImage, PhaseFileError> {
    let bytes = std::fs::read(path).map_err(|source| PhaseFileError::Io {
        path: path.to_owned(),
        source,
    })?;
    let path = path.to_owned();
    let array = decode_npy_2d(&bytes).map_err(|e| match e {
        NpyError::NotNpy => PhaseFileError::NotNpy { path: path.clone() },
        NpyError::Unsupported { header } => PhaseFileError::Unsupported {
            path: path.clone(),
            header,
        },
        NpyError::Truncated {
            height,
            width,
            expected,
            got,
        } => PhaseFileError::Truncated {
            path: path.clone(),
            height,
            width,
            expected,
            got,
        },
    })?;
    let unsupported = || PhaseFileError::Unsupported {
        path: path.clone(),
        header: format!("{:?} array", array.dtype),
    };
    if !matches!(array.dtype, Dtype::F32 | Dtype::F64) {
        return Err(unsupported());
    }
    let v = array.values;
    let (Ok(w), Ok(h)) = (u32::try_from(v.width), u32::try_from(v.height)) else {
        return Err(unsupported());
    };
    GrayImage::from_raw(w, h, v.data).ok_or_else(unsupported)
}

/// Writes a phase map as a 2-D '<f4' .npy file (temp file, then rename).
pub fn write_phase_map(path: &Path, map: &GrayImage) -> Result<(), PhaseFileError> {
    let bytes = encode_npy_f32_rows(map.width() as usize, map.height() as usize, map.as_raw());
    write_atomically(path, |w| w.write_all(&bytes)).map_err(|source| PhaseFileError::Io {
        path: path.to_owned(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("slscan-phase-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    #[test]
    fn round_trip_keeps_values_and_nan() {
        let map = GrayImage::from_fn(5, 3, |x, y| {
            image::Luma([if x == 2 && y == 1 {
                f32::NAN
            } else {
                x as f32 * 0.5 - y as f32
            }])
        });
        let path = temp("rt.npy");
        write_phase_map(&path, &map).unwrap();
        let back = read_phase_map(&path).unwrap();
        assert_eq!(back.dimensions(), (5, 3));
        for (a, b) in map.as_raw().iter().zip(back.as_raw()) {
            assert!(a == b || (a.is_nan() && b.is_nan()));
        }
        std::fs::remove_file(path).unwrap();
    }

    #[test]
    fn reads_f64_and_rejects_bad_files() {
        let mut header = "{'descr': '<f8', 'fortran_order': False, 'shape': (1, 2), }".to_string();
        while !(10 + header.len() + 1).is_multiple_of(64) {
            header.push(' ');
        }
        header.push('\n');
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
        bytes.extend_from_slice(header.as_bytes());
        bytes.extend_from_slice(&1.5f64.to_le_bytes());
        bytes.extend_from_slice(&(-2.0f64).to_le_bytes());
        let path = temp("f8.npy");
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(read_phase_map(&path).unwrap().as_raw(), &vec![1.5f32, -2.0]);
        bytes.truncate(bytes.len() - 3);
        std::fs::write(&path, &bytes).unwrap();
        assert!(matches!(
            read_phase_map(&path),
            Err(PhaseFileError::Truncated { .. })
        ));
        std::fs::write(&path, b"not an npy").unwrap();
        assert!(matches!(
            read_phase_map(&path),
            Err(PhaseFileError::NotNpy { .. })
        ));
        let text = String::from_utf8_lossy(&bytes).replace("<f8", "<i4");
        std::fs::write(&path, text.as_bytes()).unwrap();
        assert!(read_phase_map(&path).is_err());
        std::fs::remove_file(path).unwrap();
    }
}
