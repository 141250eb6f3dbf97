//! Float arrays as NumPy `.npy` (version 1.0, little-endian f32, C order).

use std::path::Path;

use crate::raster::Raster;

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
    let dict =
        format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({height}, {width}), }}");
    // Magic (6) + version (2) + header length (2) + dict + padding + '\n' = multiple of 64.
    let unpadded = 10 + dict.len() + 1;
    let pad = (64 - unpadded % 64) % 64;
    let header_len = dict.len() + pad + 1;
    let mut out = Vec::with_capacity(10 + header_len + 4 * data.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header_len as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.extend(std::iter::repeat_n(b' ', pad));
    out.push(b'\n');
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
