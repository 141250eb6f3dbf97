//! Files the twin writes: 8/16-bit PNG, float `.npy`, JSON; each written to
//! a temporary file in the same folder and renamed, so a failure never
//! leaves a half-written output.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::error::TwinError;

/// Writes `bytes` to `path` via a temporary file and a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), TwinError> {
    let tmp = temp_path(path);
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(TwinError::io(path))
}

fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

/// PNG sample depth.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PngDepth {
    /// 8 bits per sample.
    Eight,
    /// 16 bits per sample.
    Sixteen,
}

/// Writes a grey (1 channel) or RGB (3 channels) float image in [0, 1] as PNG;
/// values are clamped, NaN becomes 0.
pub fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    channels: usize,
    data: &[f32],
    depth: PngDepth,
) -> Result<(), TwinError> {
    use image::ImageEncoder;
    let color = match (channels, depth) {
        (1, PngDepth::Eight) => image::ExtendedColorType::L8,
        (1, PngDepth::Sixteen) => image::ExtendedColorType::L16,
        (3, PngDepth::Eight) => image::ExtendedColorType::Rgb8,
        (3, PngDepth::Sixteen) => image::ExtendedColorType::Rgb16,
        _ => {
            return Err(TwinError::BadParameter {
                name: "channels",
                value: channels as f64,
                why: "PNG output takes 1 or 3 channels",
            })
        }
    };
    let expected = width as usize * height as usize * channels;
    if data.len() != expected {
        return Err(TwinError::BadParameter {
            name: "image buffer length",
            value: data.len() as f64,
            why: "must be width * height * channels",
        });
    }
    let unit = |v: f32| {
        if v.is_finite() {
            v.clamp(0.0, 1.0)
        } else {
            0.0
        }
    };
    let raw: Vec<u8> = match depth {
        PngDepth::Eight => data
            .iter()
            .map(|&v| (unit(v) * 255.0).round() as u8)
            .collect(),
        // `ImageEncoder` takes 16-bit samples in native byte order (it swaps for PNG).
        PngDepth::Sixteen => data
            .iter()
            .flat_map(|&v| ((unit(v) * 65535.0).round() as u16).to_ne_bytes())
            .collect(),
    };
    let mut buf = Vec::new();
    image::codecs::png::PngEncoder::new(&mut buf)
        .write_image(&raw, width, height, color)
        .map_err(|source| TwinError::Png {
            path: path.to_path_buf(),
            source,
        })?;
    write_atomic(path, &buf)
}

/// Writes a little-endian f32 array of `shape` (row-major) as NumPy `.npy` v1.0.
pub fn write_npy(path: &Path, shape: &[usize], data: &[f32]) -> Result<(), TwinError> {
    let count: usize = shape.iter().product();
    if count != data.len() {
        return Err(TwinError::BadParameter {
            name: "npy data length",
            value: data.len() as f64,
            why: "must equal the product of the shape",
        });
    }
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape_txt = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape_txt}, }}");
    // Magic (6) + version (2) + length (2) + header + '\n' must be a multiple of 64.
    let total = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - total % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + 4 * data.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    write_atomic(path, &out)
}

/// Writes a JSON value, pretty-printed.
pub fn write_json(path: &Path, value: &serde_json::Value) -> Result<(), TwinError> {
    let text = serde_json::to_string_pretty(value).expect("a serde_json::Value always serialises");
    write_atomic(path, text.as_bytes())
}

/// Creates a folder (and parents).
pub fn create_dir(path: &Path) -> Result<(), TwinError> {
    std::fs::create_dir_all(path).map_err(TwinError::io(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmpdir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("twin-io-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn npy_header_is_aligned_and_data_follows() {
        let d = tmpdir("npy");
        let p = d.join("a.npy");
        write_npy(&p, &[2, 3], &[0.0, 1.0, 2.0, 3.0, 4.0, 5.0]).unwrap();
        let b = std::fs::read(&p).unwrap();
        let hl = u16::from_le_bytes([b[8], b[9]]) as usize;
        assert_eq!((10 + hl) % 64, 0);
        assert!(std::str::from_utf8(&b[10..10 + hl])
            .unwrap()
            .contains("'shape': (2, 3)"));
        assert_eq!(
            f32::from_le_bytes(b[10 + hl + 4..10 + hl + 8].try_into().unwrap()),
            1.0
        );
        assert!(write_npy(&p, &[2, 2], &[0.0]).is_err());
        std::fs::remove_dir_all(d).unwrap();
    }

    #[test]
    fn png_roundtrips_16_bit() {
        let d = tmpdir("png");
        let p = d.join("a.png");
        write_png(&p, 3, 1, 1, &[0.0, 1.0, 0.25], PngDepth::Sixteen).unwrap();
        let img = image::open(&p).unwrap().into_luma16();
        assert_eq!(img.as_raw(), &vec![0u16, 65535, 16384]);
        assert!(write_png(&d.join("b.png"), 2, 2, 1, &[0.0], PngDepth::Eight).is_err());
        assert!(!d.join("b.png").exists());
        std::fs::remove_dir_all(d).unwrap();
    }
}
