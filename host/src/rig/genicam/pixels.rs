//! A GenICam buffer's bytes to a frame in [0, 1]: the pixel formats a
//! fringe scanner uses (monochrome, 8 to 16 bits, unpacked little-endian;
//! and for the high-speed colour mode RGB8, BGR8 and Bayer 8/12/16).
//!
//! The buffer comes from the camera over the network, so every size is
//! checked against the declared width, height and format before a byte is
//! read: a short, long or mislabelled buffer is an error, never a panic.

use crate::raster::Raster;
use crate::rig::bayer::{demosaic_bilinear, Cfa};

/// The pixel formats slscan accepts from a camera (PFNC names).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PixelFormat {
    /// 8 bits per pixel.
    Mono8,
    /// 10 bits in the low bits of a little-endian u16.
    Mono10,
    /// 12 bits in the low bits of a little-endian u16.
    Mono12,
    /// 14 bits in the low bits of a little-endian u16.
    Mono14,
    /// 16 bits, little-endian.
    Mono16,
    /// 8-bit red, green, blue per pixel.
    Rgb8,
    /// 8-bit blue, green, red per pixel.
    Bgr8,
    /// A raw 8-bit Bayer mosaic.
    Bayer8(Cfa),
    /// A raw Bayer mosaic, 12 bits in the low bits of a little-endian u16.
    Bayer12(Cfa),
    /// A raw 16-bit little-endian Bayer mosaic.
    Bayer16(Cfa),
}

/// Each format with its PFNC name and 32-bit code.
const TABLE: [(PixelFormat, &str, u32); 19] = [
    (PixelFormat::Mono8, "Mono8", 0x0108_0001),
    (PixelFormat::Mono10, "Mono10", 0x0110_0003),
    (PixelFormat::Mono12, "Mono12", 0x0110_0005),
    (PixelFormat::Mono14, "Mono14", 0x0110_0025),
    (PixelFormat::Mono16, "Mono16", 0x0110_0007),
    (PixelFormat::Rgb8, "RGB8", 0x0218_0014),
    (PixelFormat::Bgr8, "BGR8", 0x0218_0015),
    (PixelFormat::Bayer8(Cfa::Gr), "BayerGR8", 0x0108_0008),
    (PixelFormat::Bayer8(Cfa::Rg), "BayerRG8", 0x0108_0009),
    (PixelFormat::Bayer8(Cfa::Gb), "BayerGB8", 0x0108_000A),
    (PixelFormat::Bayer8(Cfa::Bg), "BayerBG8", 0x0108_000B),
    (PixelFormat::Bayer12(Cfa::Gr), "BayerGR12", 0x0110_0010),
    (PixelFormat::Bayer12(Cfa::Rg), "BayerRG12", 0x0110_0011),
    (PixelFormat::Bayer12(Cfa::Gb), "BayerGB12", 0x0110_0012),
    (PixelFormat::Bayer12(Cfa::Bg), "BayerBG12", 0x0110_0013),
    (PixelFormat::Bayer16(Cfa::Gr), "BayerGR16", 0x0110_002E),
    (PixelFormat::Bayer16(Cfa::Rg), "BayerRG16", 0x0110_002F),
    (PixelFormat::Bayer16(Cfa::Gb), "BayerGB16", 0x0110_0030),
    (PixelFormat::Bayer16(Cfa::Bg), "BayerBG16", 0x0110_0031),
];

impl PixelFormat {
    /// Every accepted format, for messages and option parsing.
    pub const ALL: [PixelFormat; 19] = {
        let mut all = [PixelFormat::Mono8; 19];
        let mut i = 0;
        while i < TABLE.len() {
            all[i] = TABLE[i].0;
            i += 1;
        }
        all
    };

    fn entry(self) -> &'static (PixelFormat, &'static str, u32) {
        TABLE
            .iter()
            .find(|e| e.0 == self)
            .expect("every format is in the table")
    }

    /// The PFNC name the camera's `PixelFormat` feature uses.
    pub fn name(self) -> &'static str {
        self.entry().1
    }

    /// The format of a PFNC name (case as the standard writes it).
    pub fn from_name(name: &str) -> Option<PixelFormat> {
        TABLE.iter().find(|e| e.1 == name).map(|e| e.0)
    }

    /// The format of a PFNC 32-bit code, as a buffer reports it.
    pub fn from_pfnc(code: u32) -> Option<PixelFormat> {
        TABLE.iter().find(|e| e.2 == code).map(|e| e.0)
    }

    /// Significant bits per sample.
    pub fn bits(self) -> u8 {
        match self {
            PixelFormat::Mono8 | PixelFormat::Rgb8 | PixelFormat::Bgr8 | PixelFormat::Bayer8(_) => {
                8
            }
            PixelFormat::Mono10 => 10,
            PixelFormat::Mono12 | PixelFormat::Bayer12(_) => 12,
            PixelFormat::Mono14 => 14,
            PixelFormat::Mono16 | PixelFormat::Bayer16(_) => 16,
        }
    }

    /// Whether frames of this format carry colour (R, G and B planes).
    pub fn is_colour(self) -> bool {
        matches!(
            self,
            PixelFormat::Rgb8
                | PixelFormat::Bgr8
                | PixelFormat::Bayer8(_)
                | PixelFormat::Bayer12(_)
                | PixelFormat::Bayer16(_)
        )
    }

    /// Samples each pixel has in the buffer (3 for RGB8 / BGR8).
    fn samples_per_pixel(self) -> usize {
        if matches!(self, PixelFormat::Rgb8 | PixelFormat::Bgr8) {
            3
        } else {
            1
        }
    }

    /// Bytes each pixel takes in the buffer.
    pub fn bytes_per_pixel(self) -> usize {
        let per_sample = if self.bits() == 8 { 1 } else { 2 };
        per_sample * self.samples_per_pixel()
    }
}

/// Why a buffer is not a frame.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PixelError {
    /// Width or height zero, or their product overflows.
    #[error("buffer declares a {width}x{height} image")]
    BadSize {
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
    },
    /// Fewer bytes than width x height x bytes per pixel.
    #[error("{format:?} {width}x{height} needs {needed} bytes, the buffer holds {got}")]
    Short {
        /// The format.
        format: PixelFormat,
        /// Width.
        width: u32,
        /// Height.
        height: u32,
        /// Bytes needed.
        needed: usize,
        /// Bytes received.
        got: usize,
    },
    /// A value above the format's bit depth (a Mono12 pixel of 4096 or
    /// more): the camera sends another format than it claims.
    #[error("{format:?} pixel {index} holds {value}, above the format's {bits}-bit range")]
    OutOfRange {
        /// The format.
        format: PixelFormat,
        /// Pixel index (row-major).
        index: usize,
        /// Raw value.
        value: u16,
        /// The format's bits.
        bits: u8,
    },
    /// A Bayer mosaic one pixel wide or high holds no sample of some colour
    /// (found by fuzzing: its grey frame came out NaN).
    #[error("a {format:?} mosaic of {width}x{height} lacks a colour: a Bayer frame needs at least 2x2 pixels")]
    MosaicTooSmall {
        /// The format.
        format: PixelFormat,
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// A colour frame was asked of a monochrome format.
    #[error("{format:?} is a monochrome format; the high-speed mode needs a colour one (RGB8, BGR8 or a Bayer format)")]
    NotColour {
        /// The format.
        format: PixelFormat,
    },
}

/// The frame in `bytes`, `width` x `height` pixels of `format`, values
/// divided by the format's full scale (2^bits - 1). A colour format gives
/// the mean of its R, G and B planes (as the simulated camera reads a colour
/// sensor as grey). Bytes after the image (chunk data, padding) are ignored.
pub fn decode_frame(
    format: PixelFormat,
    width: u32,
    height: u32,
    bytes: &[u8],
) -> Result<Raster<f32>, PixelError> {
    if !format.is_colour() {
        let data = samples(format, width, height, bytes)?;
        return Ok(raster(width, height, data));
    }
    let [r, g, b] = decode_colour_frame(format, width, height, bytes)?;
    let data = r
        .data
        .iter()
        .zip(&g.data)
        .zip(&b.data)
        .map(|((r, g), b)| (r + g + b) / 3.0)
        .collect();
    Ok(raster(width, height, data))
}

/// The red, green and blue planes of a colour frame (RGB8, BGR8, or a Bayer
/// mosaic interpolated bilinearly), values as [`decode_frame`]'s; a
/// monochrome format is [`PixelError::NotColour`].
pub fn decode_colour_frame(
    format: PixelFormat,
    width: u32,
    height: u32,
    bytes: &[u8],
) -> Result<[Raster<f32>; 3], PixelError> {
    if !format.is_colour() {
        return Err(PixelError::NotColour { format });
    }
    let values = samples(format, width, height, bytes)?;
    match format {
        PixelFormat::Rgb8 | PixelFormat::Bgr8 => {
            let plane = |c: usize| {
                let data = values.iter().skip(c).step_by(3).copied().collect();
                raster(width, height, data)
            };
            let (r, b) = if format == PixelFormat::Rgb8 {
                (0, 2)
            } else {
                (2, 0)
            };
            Ok([plane(r), plane(1), plane(b)])
        }
        PixelFormat::Bayer8(cfa) | PixelFormat::Bayer12(cfa) | PixelFormat::Bayer16(cfa) => {
            if width < 2 || height < 2 {
                return Err(PixelError::MosaicTooSmall {
                    format,
                    width,
                    height,
                });
            }
            Ok(demosaic_bilinear(&raster(width, height, values), cfa))
        }
        _ => unreachable!("monochrome formats returned above"),
    }
}

/// A `width` x `height` raster of `data`, whose length [`samples`] checked.
fn raster(width: u32, height: u32, data: Vec<f32>) -> Raster<f32> {
    Raster::from_vec(width as usize, height as usize, data)
        .expect("data holds width x height values")
}

/// The buffer's samples (width x height x samples per pixel) scaled to
/// [0, 1], every size and value checked.
fn samples(
    format: PixelFormat,
    width: u32,
    height: u32,
    bytes: &[u8],
) -> Result<Vec<f32>, PixelError> {
    let values = (width as usize)
        .checked_mul(height as usize)
        .filter(|&n| n > 0)
        .and_then(|n| n.checked_mul(format.samples_per_pixel()))
        .ok_or(PixelError::BadSize { width, height })?;
    let needed = (width as usize * height as usize)
        .checked_mul(format.bytes_per_pixel())
        .ok_or(PixelError::BadSize { width, height })?;
    if bytes.len() < needed {
        return Err(PixelError::Short {
            format,
            width,
            height,
            needed,
            got: bytes.len(),
        });
    }
    let bits = format.bits();
    let full_scale = ((1u32 << bits) - 1) as f32;
    if bits == 8 {
        return Ok(bytes[..values]
            .iter()
            .map(|&b| b as f32 / full_scale)
            .collect());
    }
    let limit = ((1u32 << bits) - 1) as u16;
    let mut out = Vec::with_capacity(values);
    for (index, pair) in bytes[..needed].chunks_exact(2).enumerate() {
        let value = u16::from_le_bytes([pair[0], pair[1]]);
        if value > limit {
            return Err(PixelError::OutOfRange {
                format,
                index,
                value,
                bits,
            });
        }
        out.push(value as f32 / full_scale);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mono8_scales_by_255() {
        let frame = decode_frame(PixelFormat::Mono8, 2, 1, &[0, 255]).unwrap();
        assert_eq!(frame.data, vec![0.0, 1.0]);
    }

    #[test]
    fn mono12_reads_little_endian_and_scales_by_4095() {
        // 4095 = 0x0FFF, 2048 = 0x0800.
        let frame = decode_frame(PixelFormat::Mono12, 2, 1, &[0xFF, 0x0F, 0x00, 0x08]).unwrap();
        assert_eq!(frame.data[0], 1.0);
        assert!((frame.data[1] - 2048.0 / 4095.0).abs() < 1e-7);
    }

    #[test]
    fn a_value_over_the_bit_depth_is_refused() {
        let err = decode_frame(PixelFormat::Mono12, 1, 1, &[0x00, 0x10]).unwrap_err();
        assert!(matches!(
            err,
            PixelError::OutOfRange {
                value: 4096,
                bits: 12,
                ..
            }
        ));
    }

    #[test]
    fn a_short_buffer_is_refused_with_both_sizes() {
        let err = decode_frame(PixelFormat::Mono16, 4, 4, &[0; 31]).unwrap_err();
        assert_eq!(
            err,
            PixelError::Short {
                format: PixelFormat::Mono16,
                width: 4,
                height: 4,
                needed: 32,
                got: 31
            }
        );
    }

    #[test]
    fn zero_and_overflowing_sizes_are_refused() {
        assert!(matches!(
            decode_frame(PixelFormat::Mono8, 0, 5, &[]),
            Err(PixelError::BadSize { .. })
        ));
        assert!(decode_frame(PixelFormat::Mono16, u32::MAX, u32::MAX, &[0; 8]).is_err());
    }

    #[test]
    fn names_and_pfnc_codes_round_trip() {
        for f in PixelFormat::ALL {
            assert_eq!(PixelFormat::from_name(f.name()), Some(f));
        }
        assert_eq!(
            PixelFormat::from_pfnc(0x0108_0001),
            Some(PixelFormat::Mono8)
        );
        assert_eq!(
            PixelFormat::from_pfnc(0x0110_0007),
            Some(PixelFormat::Mono16)
        );
        assert_eq!(PixelFormat::from_pfnc(0x0218_0014), Some(PixelFormat::Rgb8));
        assert_eq!(
            PixelFormat::from_pfnc(0x0108_0009),
            Some(PixelFormat::Bayer8(Cfa::Rg))
        );
        assert_eq!(PixelFormat::from_pfnc(0x0218_0016), None); // RGBa8
        let codes: std::collections::HashSet<u32> = TABLE.iter().map(|e| e.2).collect();
        assert_eq!(codes.len(), TABLE.len());
    }

    #[test]
    fn rgb8_and_bgr8_give_their_planes_in_r_g_b_order() {
        let bytes = [255, 0, 51, 0, 102, 255];
        let [r, g, b] = decode_colour_frame(PixelFormat::Rgb8, 2, 1, &bytes).unwrap();
        assert_eq!(
            (r.data, g.data, b.data),
            (vec![1.0, 0.0], vec![0.0, 0.4], vec![0.2, 1.0])
        );
        let [r, _, b] = decode_colour_frame(PixelFormat::Bgr8, 2, 1, &bytes).unwrap();
        assert_eq!((r.data, b.data), (vec![0.2, 1.0], vec![1.0, 0.0]));
        // Read as grey: the planes' mean.
        let grey = decode_frame(PixelFormat::Rgb8, 2, 1, &bytes).unwrap();
        assert!((grey.data[0] - 0.4).abs() < 1e-6, "{:?}", grey.data);
        assert!(matches!(
            decode_colour_frame(PixelFormat::Rgb8, 2, 1, &bytes[..5]),
            Err(PixelError::Short { needed: 6, .. })
        ));
    }

    #[test]
    fn a_flat_bayer_mosaic_gives_flat_planes() {
        // RGGB, 4x4: R = 200, G = 100, B = 50 (12 bits).
        let mut bytes = Vec::new();
        for y in 0..4 {
            for x in 0..4 {
                let v: u16 = match (y % 2, x % 2) {
                    (0, 0) => 200,
                    (1, 1) => 50,
                    _ => 100,
                };
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
        let planes = decode_colour_frame(PixelFormat::Bayer12(Cfa::Rg), 4, 4, &bytes).unwrap();
        for (plane, v) in planes.iter().zip([200.0, 100.0, 50.0]) {
            assert!(plane.data.iter().all(|p| (p * 4095.0 - v).abs() < 1e-3));
        }
    }

    #[test]
    fn a_bayer_mosaic_one_pixel_wide_or_high_is_refused_as_grey_and_colour() {
        let format = PixelFormat::Bayer8(Cfa::Rg);
        for (w, h) in [(4, 1), (1, 4)] {
            let bytes = [100u8; 4];
            for err in [
                decode_frame(format, w, h, &bytes).unwrap_err(),
                decode_colour_frame(format, w, h, &bytes).unwrap_err(),
            ] {
                assert!(matches!(err, PixelError::MosaicTooSmall { .. }), "{err}");
            }
        }
        let frame = decode_frame(format, 2, 2, &[100u8; 4]).unwrap();
        assert!(frame.data.iter().all(|v| (0.0..=1.0).contains(v)));
    }

    #[test]
    fn a_monochrome_format_has_no_colour_frame() {
        assert_eq!(
            decode_colour_frame(PixelFormat::Mono8, 1, 1, &[0]).unwrap_err(),
            PixelError::NotColour {
                format: PixelFormat::Mono8
            }
        );
    }
}
