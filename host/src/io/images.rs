//! Reading fringe images (8- or 16-bit PNG/TIFF, or NumPy `.npy` arrays of
//! u8, u16 or floats in [0, 1] -> f32 in [0, 1]) and writing pictures.
//!
//! A capture set is checked as a whole: all frames the same size and bit depth, none
//! missing, none saturated beyond a tolerated fraction, none empty (no signal).

use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageBuffer, Luma, Rgb};

use crate::raster::Raster;

/// What can be wrong with an image or a set of images.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The file could not be opened or decoded.
    #[error("image {path}: {source}")]
    Decode {
        /// The file.
        path: PathBuf,
        /// The decoder's error.
        source: image::ImageError,
    },
    /// An `.npy` frame could not be decoded.
    #[error("frame {path}: {source}")]
    Npy {
        /// The file.
        path: PathBuf,
        /// Why.
        source: super::npy::NpyError,
    },
    /// A float frame holds NaN or infinite values.
    #[error("frame {path}: {count} pixels are NaN or infinite")]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// How many.
        count: usize,
    },
    /// The pixel format is not 8/16-bit grey or RGB.
    #[error("image {path}: unsupported pixel format {format}")]
    UnsupportedFormat {
        /// The file.
        path: PathBuf,
        /// The format found.
        format: String,
    },
    /// A frame differs in size from the first frame of its set.
    #[error("image {path} is {got:?} but the set's first frame is {expected:?} (width, height)")]
    SizeMismatch {
        /// The file.
        path: PathBuf,
        /// Size of the first frame.
        expected: (usize, usize),
        /// Size of this frame.
        got: (usize, usize),
    },
    /// A frame has another bit depth than the first frame of its set.
    #[error("image {path} is {got}-bit but the set's first frame is {expected}-bit")]
    BitDepthMismatch {
        /// The file.
        path: PathBuf,
        /// Bits of the first frame.
        expected: u8,
        /// Bits of this frame.
        got: u8,
    },
    /// The set has another number of frames than expected.
    #[error("{dir}: expected {expected} frames, found {found}")]
    MissingFrames {
        /// The folder.
        dir: PathBuf,
        /// Frames the pattern set needs.
        expected: usize,
        /// Frames found.
        found: usize,
    },
    /// Too many pixels at full scale.
    #[error("image {path}: {fraction:.1}% of pixels saturated (limit {limit:.1}%)")]
    Saturated {
        /// The file.
        path: PathBuf,
        /// Saturated share, percent.
        fraction: f64,
        /// Tolerated share, percent.
        limit: f64,
    },
    /// The frame carries no signal (dark or flat).
    #[error("image {path}: no signal (min {min:.4}, max {max:.4})")]
    Empty {
        /// The file.
        path: PathBuf,
        /// Smallest value.
        min: f32,
        /// Largest value.
        max: f32,
    },
    /// A folder could not be listed or a file written.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
}

/// A loaded frame with its source bit depth.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Intensities in [0, 1] (RGB frames are reduced to luma).
    pub image: Raster<f32>,
    /// 8 or 16 (32 for a float `.npy` frame).
    pub bit_depth: u8,
}

/// Whether `path` names a NumPy array (by its extension).
fn is_npy(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
}

/// Loads a 2-D `.npy` frame: u8 / u16 scaled by their full scale, floats
/// taken as given (frame units, [0, 1]) and refused when not finite.
fn load_npy(path: &Path) -> Result<Frame, ImageError> {
    use super::npy::{decode_npy_2d, Dtype};
    let bytes = std::fs::read(path).map_err(|source| ImageError::Io {
        path: path.to_owned(),
        source,
    })?;
    let array = decode_npy_2d(&bytes).map_err(|source| ImageError::Npy {
        path: path.to_owned(),
        source,
    })?;
    let (scale, bit_depth) = match array.dtype {
        Dtype::U8 => (1.0 / 255.0, 8),
        Dtype::U16 => (1.0 / 65535.0, 16),
        Dtype::F32 | Dtype::F64 => (1.0, 32),
    };
    let mut image = array.values;
    let count = image.data.iter().filter(|v| !v.is_finite()).count();
    if count > 0 {
        return Err(ImageError::NonFinite {
            path: path.to_owned(),
            count,
        });
    }
    image.data.iter_mut().for_each(|v| *v *= scale);
    Ok(Frame { image, bit_depth })
}

/// 8-bit samples in [0, 1].
fn unit_8(raw: &[u8]) -> Vec<f32> {
    raw.iter().map(|&v| f32::from(v) / 255.0).collect()
}

/// 16-bit samples in [0, 1].
fn unit_16(raw: &[u16]) -> Vec<f32> {
    raw.iter().map(|&v| f32::from(v) / 65535.0).collect()
}

/// Loads one frame as f32 in [0, 1]: an 8- or 16-bit grey (or RGB, reduced
/// to luma) image, or a 2-D `.npy` array.
pub fn load_gray(path: &Path) -> Result<Frame, ImageError> {
    if is_npy(path) {
        return load_npy(path);
    }
    let img = image::open(path).map_err(|source| ImageError::Decode {
        path: path.to_owned(),
        source,
    })?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let (data, bit_depth): (Vec<f32>, u8) = match &img {
        DynamicImage::ImageLuma8(b) => (unit_8(b.as_raw()), 8),
        DynamicImage::ImageLuma16(b) => (unit_16(b.as_raw()), 16),
        DynamicImage::ImageRgb8(_) | DynamicImage::ImageRgba8(_) | DynamicImage::ImageLumaA8(_) => {
            (unit_8(img.to_luma8().as_raw()), 8)
        }
        DynamicImage::ImageRgb16(_)
        | DynamicImage::ImageRgba16(_)
        | DynamicImage::ImageLumaA16(_) => (unit_16(img.to_luma16().as_raw()), 16),
        other => {
            return Err(ImageError::UnsupportedFormat {
                path: path.to_owned(),
                format: format!("{:?}", other.color()),
            })
        }
    };
    Ok(Frame {
        image: Raster {
            width: w,
            height: h,
            data,
        },
        bit_depth,
    })
}

/// A loaded colour frame with its source bit depth.
#[derive(Clone, Debug, PartialEq)]
pub struct ColourFrame {
    /// Red, green and blue planes in [0, 1].
    pub planes: [Raster<f32>; 3],
    /// 8 or 16.
    pub bit_depth: u8,
}

/// Loads one colour frame (8- or 16-bit RGB or RGBA PNG/TIFF, alpha
/// ignored) as its R, G and B planes in [0, 1]; a grey image is
/// [`ImageError::UnsupportedFormat`]: reduced to one plane it lost the colours.
pub fn load_colour(path: &Path) -> Result<ColourFrame, ImageError> {
    let img = image::open(path).map_err(|source| ImageError::Decode {
        path: path.to_owned(),
        source,
    })?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let (samples, bit_depth): (Vec<f32>, u8) = match &img {
        DynamicImage::ImageRgb8(_) | DynamicImage::ImageRgba8(_) => {
            (unit_8(img.to_rgb8().as_raw()), 8)
        }
        DynamicImage::ImageRgb16(_) | DynamicImage::ImageRgba16(_) => {
            (unit_16(img.to_rgb16().as_raw()), 16)
        }
        other => {
            return Err(ImageError::UnsupportedFormat {
                path: path.to_owned(),
                format: format!(
                    "{:?} (a colour frame must be 8- or 16-bit RGB)",
                    other.color()
                ),
            })
        }
    };
    let planes = [0, 1, 2].map(|c| Raster {
        width: w,
        height: h,
        data: samples.iter().skip(c).step_by(3).copied().collect(),
    });
    Ok(ColourFrame { planes, bit_depth })
}

/// Limits for [`check_exposure`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExposureLimits {
    /// Values at or above this count as saturated (for example 248/255, seed 003).
    pub saturation_level: f32,
    /// Largest tolerated saturated share, percent.
    pub max_saturated_percent: f64,
    /// Smallest `max - min` that counts as signal.
    pub min_range: f32,
}

impl Default for ExposureLimits {
    fn default() -> Self {
        Self {
            saturation_level: 248.0 / 255.0,
            max_saturated_percent: 5.0,
            min_range: 0.02,
        }
    }
}

/// Rejects saturated or empty frames.
pub fn check_exposure(
    path: &Path,
    img: &Raster<f32>,
    limits: &ExposureLimits,
) -> Result<(), ImageError> {
    let (mut min, mut max, mut saturated) = (f32::INFINITY, f32::NEG_INFINITY, 0usize);
    for &v in &img.data {
        min = min.min(v);
        max = max.max(v);
        saturated += usize::from(v >= limits.saturation_level);
    }
    if img.is_empty() || max - min < limits.min_range {
        return Err(ImageError::Empty {
            path: path.to_owned(),
            min,
            max,
        });
    }
    let fraction = 100.0 * saturated as f64 / img.len() as f64;
    if fraction > limits.max_saturated_percent {
        return Err(ImageError::Saturated {
            path: path.to_owned(),
            fraction,
            limit: limits.max_saturated_percent,
        });
    }
    Ok(())
}

/// Loads a set of frames, checking sizes, bit depths and exposure. Frames are decoded
/// in parallel (decoding is most of the time); the checks then run in path order, so
/// an error names the first bad frame as a one-by-one load would.
pub fn load_set(
    paths: &[PathBuf],
    limits: &ExposureLimits,
) -> Result<Vec<Raster<f32>>, ImageError> {
    use rayon::prelude::*;
    // Per frame: the decoded frame and its exposure verdict, or why it did not decode.
    type Loaded = Result<(Frame, Result<(), ImageError>), ImageError>;
    let loaded: Vec<Loaded> = paths
        .par_iter()
        .map(|path| {
            let frame = load_gray(path)?;
            let exposure = check_exposure(path, &frame.image, limits);
            Ok((frame, exposure))
        })
        .collect();
    let mut out: Vec<Raster<f32>> = Vec::with_capacity(paths.len());
    let mut first: Option<((usize, usize), u8)> = None;
    for (path, loaded) in paths.iter().zip(loaded) {
        let (frame, exposure) = loaded?;
        let size = frame.image.size();
        match first {
            None => first = Some((size, frame.bit_depth)),
            Some((expected, _)) if expected != size => {
                return Err(ImageError::SizeMismatch {
                    path: path.clone(),
                    expected,
                    got: size,
                })
            }
            Some((_, bits)) if bits != frame.bit_depth => {
                return Err(ImageError::BitDepthMismatch {
                    path: path.clone(),
                    expected: bits,
                    got: frame.bit_depth,
                })
            }
            Some(_) => {}
        }
        exposure?;
        out.push(frame.image);
    }
    Ok(out)
}

/// The PNG/TIFF (and `.npy`) files of a folder, sorted by name.
pub fn list_images(dir: &Path) -> Result<Vec<PathBuf>, ImageError> {
    let io = |source| ImageError::Io {
        path: dir.to_owned(),
        source,
    };
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(io)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                matches!(
                    e.to_ascii_lowercase().as_str(),
                    "png" | "tif" | "tiff" | "npy"
                )
            })
        })
        .collect();
    paths.sort();
    Ok(paths)
}

/// Writes a [0, 1] raster as 8- or 16-bit grey PNG (values clamped), atomically.
pub fn save_gray_png(path: &Path, img: &Raster<f32>, sixteen_bit: bool) -> Result<(), ImageError> {
    let (w, h) = (img.width as u32, img.height as u32);
    let dynamic = if sixteen_bit {
        let data = img
            .data
            .iter()
            .map(|&v| (v.clamp(0.0, 1.0) * 65535.0).round() as u16)
            .collect();
        DynamicImage::ImageLuma16(ImageBuffer::<Luma<u16>, _>::from_raw(w, h, data).expect("sized"))
    } else {
        let data = img
            .data
            .iter()
            .map(|&v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
            .collect();
        DynamicImage::ImageLuma8(ImageBuffer::<Luma<u8>, _>::from_raw(w, h, data).expect("sized"))
    };
    save_png(path, &dynamic)
}

/// Writes an RGB8 raster as PNG, atomically.
pub fn save_rgb_png(path: &Path, img: &Raster<[u8; 3]>) -> Result<(), ImageError> {
    let bytes = encode_rgb_png(img).map_err(|source| ImageError::Decode {
        path: path.to_owned(),
        source,
    })?;
    save_bytes(path, &bytes)
}

/// An RGB8 raster as PNG file bytes (for writing, or embedding in a page).
pub fn encode_rgb_png(img: &Raster<[u8; 3]>) -> Result<Vec<u8>, image::ImageError> {
    let data = img.data.iter().flatten().copied().collect();
    let buf = ImageBuffer::<Rgb<u8>, _>::from_raw(img.width as u32, img.height as u32, data)
        .expect("sized");
    encode_png(&DynamicImage::ImageRgb8(buf))
}

fn encode_png(img: &DynamicImage) -> Result<Vec<u8>, image::ImageError> {
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )?;
    Ok(bytes)
}

/// Writes encoded file bytes (a PNG) atomically.
pub fn save_bytes(path: &Path, bytes: &[u8]) -> Result<(), ImageError> {
    super::write_atomically(path, |w| w.write_all(bytes)).map_err(|source| ImageError::Io {
        path: path.to_owned(),
        source,
    })
}

fn save_png(path: &Path, img: &DynamicImage) -> Result<(), ImageError> {
    let bytes = encode_png(img).map_err(|source| ImageError::Decode {
        path: path.to_owned(),
        source,
    })?;
    save_bytes(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("slscan-img-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn eight_and_sixteen_bit_round_trip_and_mismatch() {
        let dir = tmp("rt");
        let img = Raster::from_fn(16, 8, |x, y| (x + y) as f32 / 30.0 + 0.05);
        save_gray_png(&dir.join("a.png"), &img, false).unwrap();
        save_gray_png(&dir.join("b.png"), &img, true).unwrap();
        let a = load_gray(&dir.join("a.png")).unwrap();
        let b = load_gray(&dir.join("b.png")).unwrap();
        assert_eq!((a.bit_depth, b.bit_depth), (8, 16));
        for i in 0..img.len() {
            assert!((a.image.data[i] - img.data[i]).abs() <= 0.5 / 255.0 + 1e-6);
            assert!((b.image.data[i] - img.data[i]).abs() <= 0.5 / 65535.0 + 1e-6);
        }
        let limits = ExposureLimits::default();
        let err = load_set(&[dir.join("a.png"), dir.join("b.png")], &limits).unwrap_err();
        assert!(matches!(
            err,
            ImageError::BitDepthMismatch {
                expected: 8,
                got: 16,
                ..
            }
        ));
        save_gray_png(
            &dir.join("c.png"),
            &Raster::from_fn(8, 8, |x, _| x as f32 / 8.0),
            false,
        )
        .unwrap();
        let err = load_set(&[dir.join("a.png"), dir.join("c.png")], &limits).unwrap_err();
        assert!(matches!(err, ImageError::SizeMismatch { .. }));
        assert_eq!(list_images(&dir).unwrap().len(), 3);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn npy_frames_load_scaled_and_bad_ones_are_named() {
        let dir = tmp("npy");
        let img = Raster::from_fn(16, 8, |x, y| (x + y) as f32 / 30.0 + 0.05);
        crate::io::npy::write_npy_f32(&dir.join("f.npy"), &img).unwrap();
        let f = load_gray(&dir.join("f.npy")).unwrap();
        assert_eq!((f.bit_depth, f.image), (32, img.clone()));
        let codes = Raster::from_fn(16, 8, |x, _| x as u8 * 10);
        crate::io::npy::write_npy_u8(&dir.join("u.npy"), &codes).unwrap();
        let u = load_gray(&dir.join("u.npy")).unwrap();
        assert_eq!(u.bit_depth, 8);
        assert!((u.image.data[15] - 150.0 / 255.0).abs() < 1e-6);
        let mut nan = img;
        nan.data[3] = f32::NAN;
        crate::io::npy::write_npy_f32(&dir.join("nan.npy"), &nan).unwrap();
        let err = load_gray(&dir.join("nan.npy")).unwrap_err();
        assert!(
            matches!(err, ImageError::NonFinite { count: 1, .. }),
            "{err}"
        );
        std::fs::write(dir.join("bad.npy"), b"garbage").unwrap();
        let err = load_gray(&dir.join("bad.npy")).unwrap_err();
        assert!(err.to_string().contains("bad.npy") && err.to_string().contains("not a NumPy"));
        assert_eq!(list_images(&dir).unwrap().len(), 4);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn saturated_empty_and_missing_files() {
        let p = Path::new("x.png");
        let limits = ExposureLimits::default();
        let flat = Raster::filled(10, 10, 0.3f32);
        assert!(matches!(
            check_exposure(p, &flat, &limits),
            Err(ImageError::Empty { .. })
        ));
        let sat = Raster::from_fn(10, 10, |x, _| if x < 5 { 1.0 } else { 0.2 });
        assert!(matches!(
            check_exposure(p, &sat, &limits),
            Err(ImageError::Saturated { .. })
        ));
        let ok = Raster::from_fn(10, 10, |x, _| x as f32 / 20.0);
        assert!(check_exposure(p, &ok, &limits).is_ok());
        assert!(matches!(
            load_gray(Path::new("/nonexistent/x.png")),
            Err(ImageError::Decode { .. })
        ));
    }
}
