//! A GenICam buffer's bytes to a frame in [0, 1]: the pixel formats a
//! fringe scanner uses (monochrome, 8 to 16 bits, unpacked little-endian).
//!
//! The buffer comes from the camera over the network, so every size is
//! checked against the declared width, height and format before a byte is
//! read: a short, long or mislabelled buffer is an error, never a panic.

use crate::raster::Raster;

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
}

impl PixelFormat {
    /// Every accepted format, for messages and option parsing.
    pub const ALL: [PixelFormat; 5] = [
        PixelFormat::Mono8,
        PixelFormat::Mono10,
        PixelFormat::Mono12,
        PixelFormat::Mono14,
        PixelFormat::Mono16,
    ];

    /// The PFNC name the camera's `PixelFormat` feature uses.
    pub fn name(self) -> &'static str {
        match self {
            PixelFormat::Mono8 => "Mono8",
            PixelFormat::Mono10 => "Mono10",
            PixelFormat::Mono12 => "Mono12",
            PixelFormat::Mono14 => "Mono14",
            PixelFormat::Mono16 => "Mono16",
        }
    }

    /// The format of a PFNC name (case as the standard writes it).
    pub fn from_name(name: &str) -> Option<PixelFormat> {
        PixelFormat::ALL.into_iter().find(|f| f.name() == name)
    }

    /// The format of a PFNC 32-bit code, as a buffer reports it.
    pub fn from_pfnc(code: u32) -> Option<PixelFormat> {
        match code {
            0x0108_0001 => Some(PixelFormat::Mono8),
            0x0110_0003 => Some(PixelFormat::Mono10),
            0x0110_0005 => Some(PixelFormat::Mono12),
            0x0110_0025 => Some(PixelFormat::Mono14),
            0x0110_0007 => Some(PixelFormat::Mono16),
            _ => None,
        }
    }

    /// Significant bits per pixel.
    pub fn bits(self) -> u8 {
        match self {
            PixelFormat::Mono8 => 8,
            PixelFormat::Mono10 => 10,
            PixelFormat::Mono12 => 12,
            PixelFormat::Mono14 => 14,
            PixelFormat::Mono16 => 16,
        }
    }

    /// Bytes each pixel takes in the buffer.
    pub fn bytes_per_pixel(self) -> usize {
        if self == PixelFormat::Mono8 {
            1
        } else {
            2
        }
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
}

/// The frame in `bytes`, `width` x `height` pixels of `format`, values
/// divided by the format's full scale (2^bits - 1). Bytes after the image
/// (chunk data, padding) are ignored.
pub fn decode_frame(
    format: PixelFormat,
    width: u32,
    height: u32,
    bytes: &[u8],
) -> Result<Raster<f32>, PixelError> {
    let pixels = (width as usize)
        .checked_mul(height as usize)
        .filter(|&n| n > 0)
        .ok_or(PixelError::BadSize { width, height })?;
    let needed = pixels
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
    let data = match format {
        PixelFormat::Mono8 => bytes[..pixels]
            .iter()
            .map(|&b| b as f32 / full_scale)
            .collect(),
        _ => {
            let limit = ((1u32 << bits) - 1) as u16;
            let mut out = Vec::with_capacity(pixels);
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
            out
        }
    };
    Ok(Raster::from_vec(width as usize, height as usize, data)
        .expect("data holds width x height values"))
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
        assert_eq!(PixelFormat::from_pfnc(0x0218_0014), None); // RGB8
    }
}
