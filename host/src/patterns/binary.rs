//! 1-bit patterns for DMD binary mode and their packing into 24-bit bit-plane images.
//!
//! A DMD in pattern mode shows 1-bit planes at kHz rates; grey fringes become binary by
//! error diffusion (Floyd-Steinberg, serpentine scan, so the defocused projector
//! low-passes the dither back into a sinusoid) or by a plain threshold (binary
//! defocusing: a square wave whose odd harmonics the defocus attenuates).
//! The DLPC350 (LightCrafter 4500) takes 24 planes per RGB888 frame: planes 0-7 are the
//! green bits, 8-15 red, 16-23 blue (DLPC350 programmer's guide, pattern display).

use crate::raster::Raster;

/// How grey levels become bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Binarize {
    /// Floyd-Steinberg error diffusion, serpentine.
    ErrorDiffusion,
    /// `value >= 0.5` (binary defocusing).
    Threshold,
}

/// Turns a grey pattern in [0, 1] into a 1-bit pattern.
pub fn binarize(pattern: &Raster<f32>, method: Binarize) -> Raster<bool> {
    match method {
        Binarize::Threshold => Raster {
            width: pattern.width,
            height: pattern.height,
            data: pattern.data.iter().map(|&v| v >= 0.5).collect(),
        },
        Binarize::ErrorDiffusion => floyd_steinberg(pattern),
    }
}

fn floyd_steinberg(pattern: &Raster<f32>) -> Raster<bool> {
    let (w, h) = pattern.size();
    let mut err = pattern.data.clone();
    let mut out = Raster::filled(w, h, false);
    for y in 0..h {
        let forward = y % 2 == 0;
        for i in 0..w {
            let x = if forward { i } else { w - 1 - i };
            let idx = y * w + x;
            let on = err[idx] >= 0.5;
            out.data[idx] = on;
            let e = err[idx] - if on { 1.0 } else { 0.0 };
            let ahead = |d: isize| -> Option<usize> {
                let nx = x as isize + if forward { d } else { -d };
                (0..w as isize).contains(&nx).then_some(nx as usize)
            };
            if let Some(nx) = ahead(1) {
                err[y * w + nx] += e * 7.0 / 16.0;
            }
            if y + 1 < h {
                if let Some(nx) = ahead(-1) {
                    err[(y + 1) * w + nx] += e * 3.0 / 16.0;
                }
                err[(y + 1) * w + x] += e * 5.0 / 16.0;
                if let Some(nx) = ahead(1) {
                    err[(y + 1) * w + nx] += e * 1.0 / 16.0;
                }
            }
        }
    }
    out
}

/// What can be wrong with a bit-plane packing request.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PackError {
    /// Planes differ in size.
    #[error("plane {index} is {got:?}, plane 0 is {expected:?}")]
    SizeMismatch {
        /// Offending plane.
        index: usize,
        /// Size of plane 0.
        expected: (usize, usize),
        /// Its size.
        got: (usize, usize),
    },
}

/// Packs 1-bit planes, 24 per RGB888 image in DLPC350 order; the last image is padded
/// with dark planes.
pub fn pack_bit_planes(planes: &[Raster<bool>]) -> Result<Vec<Raster<[u8; 3]>>, PackError> {
    let Some(first) = planes.first() else {
        return Ok(Vec::new());
    };
    let expected = first.size();
    for (index, p) in planes.iter().enumerate() {
        if p.size() != expected {
            return Err(PackError::SizeMismatch {
                index,
                expected,
                got: p.size(),
            });
        }
    }
    Ok(planes
        .chunks(24)
        .map(|chunk| {
            let mut img = Raster::filled(expected.0, expected.1, [0u8; 3]);
            for (bit, plane) in chunk.iter().enumerate() {
                // planes 0-7 -> G (index 1), 8-15 -> R (index 0), 16-23 -> B (index 2)
                let channel = [1, 0, 2][bit / 8];
                let mask = 1u8 << (bit % 8);
                for (px, &on) in img.data.iter_mut().zip(&plane.data) {
                    if on {
                        px[channel] |= mask;
                    }
                }
            }
            img
        })
        .collect())
}

/// Inverse of [`pack_bit_planes`] for one image: its 24 planes.
pub fn unpack_bit_planes(image: &Raster<[u8; 3]>) -> Vec<Raster<bool>> {
    (0..24)
        .map(|bit| {
            let channel = [1, 0, 2][bit / 8];
            Raster {
                width: image.width,
                height: image.height,
                data: image
                    .data
                    .iter()
                    .map(|px| px[channel] >> (bit % 8) & 1 == 1)
                    .collect(),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_diffusion_keeps_local_mean() {
        let grey = Raster::from_fn(64, 64, |x, _| x as f32 / 63.0);
        let bits = binarize(&grey, Binarize::ErrorDiffusion);
        for band in 0..8 {
            let (mut on, mut want) = (0.0f32, 0.0f32);
            for y in 0..64 {
                for x in band * 8..band * 8 + 8 {
                    on += f32::from(u8::from(*bits.at(x, y)));
                    want += grey.at(x, y);
                }
            }
            assert!(
                (on - want).abs() / 512.0 < 0.03,
                "band {band}: {on} vs {want}"
            );
        }
    }

    #[test]
    fn bit_planes_round_trip() {
        let planes: Vec<Raster<bool>> = (0..30)
            .map(|k| Raster::from_fn(5, 3, |x, y| (x * 7 + y * 3 + k) % 4 == 0))
            .collect();
        let packed = pack_bit_planes(&planes).unwrap();
        assert_eq!(packed.len(), 2);
        let mut back = unpack_bit_planes(&packed[0]);
        back.extend(unpack_bit_planes(&packed[1]).into_iter().take(6));
        assert_eq!(back, planes);
        let odd = vec![Raster::filled(2, 2, true), Raster::filled(3, 2, true)];
        assert!(matches!(
            pack_bit_planes(&odd),
            Err(PackError::SizeMismatch { index: 1, .. })
        ));
    }
}
