//! Phase maps on disk as `.npy` (DESIGN: float arrays go to .npy): 2-D,
//! C order, little-endian f32 or f64, NaN where there is no phase.
//!
//! A minimal reader of NumPy's format (versions 1-3) for the calibration
//! CLI (no crate is needed for a 2-D float array); writing uses
//! [`crate::io::npy`].

use std::path::{Path, PathBuf};

use super::board::GrayImage;
use crate::io::npy::encode_npy_f32_rows;
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
    #[error("{path}: need a 2-D C-order '<f4' or '<f8' array, header is {header:?}")]
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

/// Value of `key` in the header dict, as the raw text after the colon.
fn header_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let at = header.find(&format!("'{key}'"))? + key.len() + 2;
    let rest = header[at..].trim_start().strip_prefix(':')?.trim_start();
    Some(rest)
}

/// Reads a phase map (radians, NaN = none) from an .npy file.
pub fn read_phase_map(path: &Path) -> Result<GrayImage, PhaseFileError> {
    let bytes = std::fs::read(path).map_err(|source| PhaseFileError::Io {
        path: path.to_owned(),
        source,
    })?;
    let not_npy = || PhaseFileError::NotNpy {
        path: path.to_owned(),
    };
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(not_npy());
    }
    let (header_len, start) = match bytes[6] {
        1 => (usize::from(u16::from_le_bytes([bytes[8], bytes[9]])), 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        _ => return Err(not_npy()),
    };
    let header_bytes = bytes.get(start..start + header_len).ok_or_else(not_npy)?;
    let header = String::from_utf8_lossy(header_bytes).into_owned();
    let unsupported = || PhaseFileError::Unsupported {
        path: path.to_owned(),
        header: header.trim().to_owned(),
    };
    let descr = header_value(&header, "descr").ok_or_else(unsupported)?;
    let size = if descr.starts_with("'<f4'") {
        4
    } else if descr.starts_with("'<f8'") {
        8
    } else {
        return Err(unsupported());
    };
    let fortran = header_value(&header, "fortran_order").ok_or_else(unsupported)?;
    if !fortran.starts_with("False") {
        return Err(unsupported());
    }
    let shape = header_value(&header, "shape").ok_or_else(unsupported)?;
    let inner = shape
        .strip_prefix('(')
        .and_then(|s| s.split(')').next())
        .ok_or_else(unsupported)?;
    let dims: Vec<usize> = inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<usize>().map_err(|_| unsupported()))
        .collect::<Result<_, _>>()?;
    let [height, width] = dims[..] else {
        return Err(unsupported());
    };
    let data = &bytes[start + header_len..];
    let expected = height * width * size;
    if data.len() < expected || width > u32::MAX as usize || height > u32::MAX as usize {
        return Err(PhaseFileError::Truncated {
            path: path.to_owned(),
            height,
            width,
            expected,
            got: data.len(),
        });
    }
    let values: Vec<f32> = if size == 4 {
        data[..expected]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    } else {
        data[..expected]
            .chunks_exact(8)
            .map(|c| {
                let mut b = [0u8; 8];
                b.copy_from_slice(c);
                f64::from_le_bytes(b) as f32
            })
            .collect()
    };
    GrayImage::from_raw(width as u32, height as u32, values).ok_or_else(unsupported)
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
