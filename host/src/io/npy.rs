//! 2-D arrays as NumPy `.npy`: written as version 1.0, little-endian, C
//! order (f32 maps, u8 status codes); read from versions 1-3 as u8, u16,
//! f32 or f64. A minimal codec of our own: no crate is needed for a 2-D
//! array, and the reader is fuzzed (`fuzz/fuzz_targets/npy_reader.rs`).

use std::path::Path;

use crate::raster::Raster;

/// What can be wrong with an `.npy` file's bytes.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NpyError {
    /// No NumPy magic, or a header that runs past the file.
    #[error("not a NumPy .npy file")]
    NotNpy,
    /// Not a 2-D C-order array of a supported type.
    #[error("need a 2-D C-order array of '|u1', '<u2', '<f4' or '<f8', header is {header:?}")]
    Unsupported {
        /// The header dictionary as written.
        header: String,
    },
    /// The data is shorter than the shape says (or the shape is absurd).
    #[error("shape {height}x{width} needs {expected} bytes of data, the file has {got}")]
    Truncated {
        /// Rows.
        height: usize,
        /// Columns.
        width: usize,
        /// Bytes the shape needs (saturating).
        expected: usize,
        /// Bytes present.
        got: usize,
    },
}

/// The element type of an array read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dtype {
    /// `|u1`.
    U8,
    /// `<u2`.
    U16,
    /// `<f4`.
    F32,
    /// `<f8` (read as f32).
    F64,
}

impl Dtype {
    fn size(self) -> usize {
        match self {
            Dtype::U8 => 1,
            Dtype::U16 => 2,
            Dtype::F32 => 4,
            Dtype::F64 => 8,
        }
    }
}

/// A 2-D array read from `.npy`, its values as f32 (integers exact).
#[derive(Clone, Debug, PartialEq)]
pub struct NpyArray {
    /// The file's element type.
    pub dtype: Dtype,
    /// The values, `(height, width)` as rows.
    pub values: Raster<f32>,
}

/// Value of `key` in the header dict, as the raw text after the colon.
fn header_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let at = header.find(&format!("'{key}'"))? + key.len() + 2;
    let rest = header
        .get(at..)?
        .trim_start()
        .strip_prefix(':')?
        .trim_start();
    Some(rest)
}

/// Decodes the bytes of a 2-D `.npy` file.
pub fn decode_npy_2d(bytes: &[u8]) -> Result<NpyArray, NpyError> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(NpyError::NotNpy);
    }
    let (header_len, start): (usize, usize) = match bytes[6] {
        1 => (usize::from(u16::from_le_bytes([bytes[8], bytes[9]])), 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        _ => return Err(NpyError::NotNpy),
    };
    let end = start.checked_add(header_len).ok_or(NpyError::NotNpy)?;
    let header_bytes = bytes.get(start..end).ok_or(NpyError::NotNpy)?;
    let header = String::from_utf8_lossy(header_bytes).into_owned();
    let unsupported = || NpyError::Unsupported {
        header: header.trim().to_owned(),
    };
    let descr = header_value(&header, "descr").ok_or_else(unsupported)?;
    let dtype = [
        ("'|u1'", Dtype::U8),
        ("'<u1'", Dtype::U8),
        ("'<u2'", Dtype::U16),
        ("'<f4'", Dtype::F32),
        ("'<f8'", Dtype::F64),
    ]
    .into_iter()
    .find(|(d, _)| descr.starts_with(d))
    .map(|(_, t)| t)
    .ok_or_else(unsupported)?;
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
    let data = &bytes[end..];
    let expected = height
        .checked_mul(width)
        .and_then(|n| n.checked_mul(dtype.size()));
    let Some(expected) = expected.filter(|&e| e <= data.len()) else {
        return Err(NpyError::Truncated {
            height,
            width,
            expected: expected.unwrap_or(usize::MAX),
            got: data.len(),
        });
    };
    let data = &data[..expected];
    let values: Vec<f32> = match dtype {
        Dtype::U8 => data.iter().map(|&b| f32::from(b)).collect(),
        Dtype::U16 => data
            .chunks_exact(2)
            .map(|c| f32::from(u16::from_le_bytes([c[0], c[1]])))
            .collect(),
        Dtype::F32 => data
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect(),
        Dtype::F64 => data
            .chunks_exact(8)
            .map(|c| {
                let mut b = [0u8; 8];
                b.copy_from_slice(c);
                f64::from_le_bytes(b) as f32
            })
            .collect(),
    };
    Ok(NpyArray {
        dtype,
        values: Raster {
            width,
            height,
            data: values,
        },
    })
}

/// Writes a raster of status codes (or any bytes) as a `(height, width)`
/// uint8 `.npy` file (temp file, then rename).
pub fn write_npy_u8(path: &Path, img: &Raster<u8>) -> std::io::Result<()> {
    let bytes = encode_npy("|u1", img.width, img.height, &img.data);
    super::write_atomically(path, |w| w.write_all(&bytes))
}

/// Writes a raster as a `(height, width)` float32 `.npy` file (temp file, then rename).
pub fn write_npy_f32(path: &Path, img: &Raster<f32>) -> std::io::Result<()> {
    let bytes = encode_npy_f32(img);
    super::write_atomically(path, |w| w.write_all(&bytes))
}

/// The bytes of a `(height, width)` float32 `.npy` file.
pub fn encode_npy_f32(img: &Raster<f32>) -> Vec<u8> {
    encode_npy_f32_rows(img.width, img.height, &img.data)
}

/// The bytes of a `(height, width)` float32 `.npy` file holding `data` in
/// row-major order (`data.len()` must be `width * height`).
pub fn encode_npy_f32_rows(width: usize, height: usize, data: &[f32]) -> Vec<u8> {
    debug_assert_eq!(data.len(), width * height);
    let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
    encode_npy("<f4", width, height, &bytes)
}

/// The bytes of a float64 `.npy` file of any `shape` holding `data` in C
/// order (`data.len()` must be the product of `shape`): point lists, 4x4
/// transforms and the like for numpy-side tools.
pub fn encode_npy_f64(shape: &[usize], data: &[f64]) -> Vec<u8> {
    debug_assert_eq!(data.len(), shape.iter().product::<usize>());
    let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
    encode_npy_shaped("<f8", shape, &bytes)
}

/// The bytes of a `(height, width)` `.npy` file of element type `descr`
/// whose little-endian element bytes are `data`.
fn encode_npy(descr: &str, width: usize, height: usize, data: &[u8]) -> Vec<u8> {
    encode_npy_shaped(descr, &[height, width], data)
}

/// The bytes of a `.npy` file of element type `descr` and `shape` whose
/// little-endian element bytes are `data`.
fn encode_npy_shaped(descr: &str, shape: &[usize], data: &[u8]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    // numpy writes a one-element tuple with a trailing comma.
    let tuple = match dims.len() {
        1 => format!("({},)", dims[0]),
        _ => format!("({})", dims.join(", ")),
    };
    let dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {tuple}, }}");
    // Magic (6) + version (2) + header length (2) + dict + padding + '\n' = multiple of 64.
    let unpadded = 10 + dict.len() + 1;
    let pad = (64 - unpadded % 64) % 64;
    let header_len = dict.len() + pad + 1;
    let mut out = Vec::with_capacity(10 + header_len + data.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header_len as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.extend(std::iter::repeat_n(b' ', pad));
    out.push(b'\n');
    out.extend_from_slice(data);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn float64_arrays_of_any_shape_have_numpy_headers() {
        let b = encode_npy_f64(&[2, 2, 3], &[0.5; 12]);
        let header_len = u16::from_le_bytes([b[8], b[9]]) as usize;
        assert_eq!((10 + header_len) % 64, 0);
        let header = std::str::from_utf8(&b[10..10 + header_len]).unwrap();
        assert!(header.contains("'descr': '<f8'") && header.contains("'shape': (2, 2, 3)"));
        assert_eq!(b.len(), 10 + header_len + 96);
        let one = encode_npy_f64(&[3], &[1.0, 2.0, 3.0]);
        assert!(std::str::from_utf8(&one[10..64])
            .unwrap()
            .contains("'shape': (3,)"));
    }

    #[test]
    fn header_is_aligned_and_data_follows() {
        let img = Raster::from_fn(3, 2, |x, y| (x + 3 * y) as f32);
        let b = encode_npy_f32(&img);
        let header_len = u16::from_le_bytes([b[8], b[9]]) as usize;
        assert_eq!((10 + header_len) % 64, 0);
        let header = std::str::from_utf8(&b[10..10 + header_len]).unwrap();
        assert!(header.contains("'shape': (2, 3)") && header.ends_with('\n'));
        let data = &b[10 + header_len..];
        assert_eq!(data.len(), 24);
        assert_eq!(f32::from_le_bytes(data[20..24].try_into().unwrap()), 5.0);
    }

    #[test]
    fn every_type_round_trips_and_bad_bytes_are_typed_errors() {
        let img = Raster::from_fn(3, 2, |x, y| (x + 3 * y) as f32 * 0.5);
        let back = decode_npy_2d(&encode_npy_f32(&img)).unwrap();
        assert_eq!((back.dtype, back.values.clone()), (Dtype::F32, img));
        let codes = Raster::from_fn(4, 1, |x, _| x as u8 * 60);
        let bytes = encode_npy("|u1", 4, 1, &codes.data);
        let back = decode_npy_2d(&bytes).unwrap();
        assert_eq!(back.dtype, Dtype::U8);
        assert_eq!(back.values.data, [0.0, 60.0, 120.0, 180.0]);
        let wide: Vec<u8> = [4095u16, 65535]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let back = decode_npy_2d(&encode_npy("<u2", 2, 1, &wide)).unwrap();
        assert_eq!(back.values.data, [4095.0, 65535.0]);
        let f8: Vec<u8> = [1.5f64, -2.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        assert_eq!(
            decode_npy_2d(&encode_npy("<f8", 1, 2, &f8))
                .unwrap()
                .values
                .data,
            [1.5, -2.0]
        );
        assert_eq!(decode_npy_2d(b"not an npy file"), Err(NpyError::NotNpy));
        let mut cut = encode_npy_f32(&Raster::filled(3, 3, 1.0));
        cut.truncate(cut.len() - 1);
        assert!(matches!(
            decode_npy_2d(&cut),
            Err(NpyError::Truncated { .. })
        ));
        // A shape whose byte count overflows is truncated, not a panic.
        let huge = encode_npy("<f4", usize::MAX / 2, 3, &[]);
        assert!(matches!(
            decode_npy_2d(&huge),
            Err(NpyError::Truncated { .. })
        ));
        let i4 = encode_npy("<i4", 1, 1, &[0; 4]);
        assert!(matches!(
            decode_npy_2d(&i4),
            Err(NpyError::Unsupported { .. })
        ));
        let three_d = String::from_utf8_lossy(&encode_npy_f32(&Raster::filled(1, 1, 0.0)))
            .replace("(1, 1)", "(1,1,1)");
        assert!(decode_npy_2d(three_d.as_bytes()).is_err());
    }
}
