//! Gray code + phase unwrapping, and seed 004's pixel-shift fine matching.
//!
//! Projector column `c` (integer) belongs to Gray block `g = floor(c / block_px)`; the
//! patterns ([`crate::patterns::gray_code`]) show bit `b` of `gray(g)` MSB first. Decoding
//! thresholds each captured bit (against a per-pixel threshold or the inverse pattern) and
//! marks pixels whose contrast is too small to read. Unwrapping rounds the phase's order to
//! the block centre: `k = round((2 pi u_g / P - phi) / 2 pi)`, which tolerates a misread at
//! block edges as long as blocks are at most half a period wide.

use super::{same_size, AbsolutePhase, PixelStatus, UnwrapError};
use crate::raster::Raster;

/// Reflected binary code of `n`.
pub fn binary_to_gray(n: u32) -> u32 {
    n ^ (n >> 1)
}

/// Inverse of [`binary_to_gray`].
pub fn gray_to_binary(mut g: u32) -> u32 {
    let mut mask = g >> 1;
    while mask != 0 {
        g ^= mask;
        mask >>= 1;
    }
    g
}

/// Decoded Gray block index per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct GrayDecoded {
    /// Block index (binary, already converted from Gray); 0 where not valid.
    pub block: Raster<u32>,
    /// [`PixelStatus::Valid`], or [`PixelStatus::Unreliable`] where a bit's contrast was
    /// below the floor, or [`PixelStatus::Masked`].
    pub status: Raster<PixelStatus>,
}

/// Decodes Gray bit frames (MSB first) against a per-pixel threshold (for example the
/// phase-shift background A, or the mean of white and black floods).
pub fn decode_with_threshold(
    bits: &[&Raster<f32>],
    threshold: &Raster<f32>,
    min_contrast: f32,
) -> Result<GrayDecoded, UnwrapError> {
    decode(
        bits,
        min_contrast,
        |_, i| threshold.data[i],
        Some(threshold),
    )
}

/// Decodes Gray bit frames (MSB first) against their inverse frames (more robust: each
/// bit compares two captures of the same surface).
pub fn decode_with_inverse(
    bits: &[&Raster<f32>],
    inverse: &[&Raster<f32>],
    min_contrast: f32,
) -> Result<GrayDecoded, UnwrapError> {
    if inverse.len() != bits.len() {
        return Err(UnwrapError::WrongInputCount {
            method: "gray code inverse",
            expected: bits.len(),
            got: inverse.len(),
        });
    }
    let mut all: Vec<&Raster<f32>> = bits.to_vec();
    all.extend_from_slice(inverse);
    same_size(&all)?;
    decode(bits, min_contrast, |b, i| inverse[b].data[i], None)
}

fn decode(
    bits: &[&Raster<f32>],
    min_contrast: f32,
    reference: impl Fn(usize, usize) -> f32,
    extra: Option<&Raster<f32>>,
) -> Result<GrayDecoded, UnwrapError> {
    if bits.is_empty() || bits.len() > 31 {
        return Err(UnwrapError::NotEnoughInputs {
            method: "gray code",
            got: bits.len(),
            need: 1,
        });
    }
    let mut all: Vec<&Raster<f32>> = bits.to_vec();
    all.extend(extra);
    let (width, height) = same_size(&all)?;
    let mut block = Raster::filled(width, height, 0u32);
    let mut status = Raster::filled(width, height, PixelStatus::Valid);
    for i in 0..width * height {
        let mut gray = 0u32;
        for (b, frame) in bits.iter().enumerate() {
            let d = frame.data[i] - reference(b, i);
            if d.abs() < min_contrast || !d.is_finite() {
                status.data[i] = PixelStatus::Unreliable;
            }
            gray = (gray << 1) | u32::from(d > 0.0);
        }
        if status.data[i] == PixelStatus::Valid {
            block.data[i] = gray_to_binary(gray);
        }
    }
    Ok(GrayDecoded { block, status })
}

/// Unwraps a wrapped phase of period `period_px` with decoded Gray blocks of `block_px`.
pub fn unwrap_with_blocks(
    wrapped: &Raster<f32>,
    decoded: &GrayDecoded,
    block_px: f64,
    period_px: f64,
    mask: Option<&Raster<bool>>,
) -> Result<AbsolutePhase, UnwrapError> {
    if !(block_px > 0.0 && period_px > 0.0) || block_px > period_px / 2.0 {
        return Err(UnwrapError::BlockTooWide {
            block_px,
            period_px,
        });
    }
    let (width, height) = wrapped.size();
    for (index, got) in [(1, decoded.block.size())]
        .into_iter()
        .chain(mask.map(|m| (2, m.size())))
    {
        if got != (width, height) {
            return Err(UnwrapError::SizeMismatch {
                index,
                expected: (width, height),
                got,
            });
        }
    }
    let tau = std::f32::consts::TAU;
    // A correct block is off by at most half a block; allow a quarter period on top.
    let max_residual = (std::f32::consts::PI * (block_px / period_px) as f32
        + std::f32::consts::FRAC_PI_4)
        .min(0.95 * std::f32::consts::PI);
    let mut phase = Raster::filled(width, height, f32::NAN);
    let mut status = decoded.status.clone();
    for i in 0..width * height {
        if mask.is_some_and(|m| !m.data[i]) {
            status.data[i] = PixelStatus::Masked;
        }
        if status.data[i] != PixelStatus::Valid {
            continue;
        }
        let u_block = f64::from(decoded.block.data[i]) * block_px + (block_px - 1.0) / 2.0;
        let estimate = (std::f64::consts::TAU * u_block / period_px) as f32;
        match super::fringe_order(estimate, wrapped.data[i], max_residual) {
            Some(k) => phase.data[i] = wrapped.data[i] + tau * k,
            None => status.data[i] = PixelStatus::Unreliable,
        }
    }
    Ok(AbsolutePhase {
        phase,
        status,
        period_px,
    })
}

/// Seed 004's fine matching: with the Gray patterns shifted by `s = 1 .. block_px - 1`
/// pixels (decoded into `shifted[s - 1]`), the offset inside the block is the first shift
/// whose block index differs from the unshifted one, minus one (`block_px - 1` when none
/// differs). Returns the full projector coordinate `block * block_px + offset`.
pub fn fine_coordinate(
    coarse: &GrayDecoded,
    shifted: &[&GrayDecoded],
    block_px: u32,
) -> Result<GrayDecoded, UnwrapError> {
    if shifted.len() + 1 != block_px as usize {
        return Err(UnwrapError::WrongInputCount {
            method: "gray fine shifts",
            expected: block_px.saturating_sub(1) as usize,
            got: shifted.len(),
        });
    }
    let mut maps = vec![&coarse.block];
    maps.extend(shifted.iter().map(|s| &s.block));
    same_size(&maps)?;
    let mut out = coarse.clone();
    for i in 0..out.block.data.len() {
        if out.status.data[i] != PixelStatus::Valid {
            continue;
        }
        if shifted
            .iter()
            .any(|s| s.status.data[i] != PixelStatus::Valid)
        {
            out.status.data[i] = PixelStatus::Unreliable;
            continue;
        }
        let g = coarse.block.data[i];
        let first_change = shifted
            .iter()
            .position(|s| s.block.data[i] != g)
            .map_or(block_px - 1, |p| p as u32);
        out.block.data[i] = g * block_px + first_change;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::patterns::gray_code::{gray_code_bits, GrayAxis};

    #[test]
    fn gray_round_trip() {
        for n in 0..5000 {
            assert_eq!(gray_to_binary(binary_to_gray(n)), n);
            assert_eq!((binary_to_gray(n) ^ binary_to_gray(n + 1)).count_ones(), 1);
        }
    }

    #[test]
    fn decodes_columns_and_unwraps_phase() {
        // A camera that sees projector column c = x exactly.
        let (w, h, block, period) = (128usize, 2usize, 8u32, 16.0f64);
        let bits = gray_code_bits(w as u32, h as u32, block, 0, GrayAxis::Columns);
        let frames: Vec<&Raster<f32>> = bits.iter().collect();
        let inverse: Vec<Raster<f32>> = bits
            .iter()
            .map(|f| Raster {
                data: f.data.iter().map(|v| 1.0 - v).collect(),
                ..f.clone()
            })
            .collect();
        let inv: Vec<&Raster<f32>> = inverse.iter().collect();
        let decoded = decode_with_inverse(&frames, &inv, 0.2).unwrap();
        let wrapped = Raster::from_fn(w, h, |x, _| {
            crate::phase::wrap_pi((std::f64::consts::TAU * x as f64 / period) as f32)
        });
        let abs = unwrap_with_blocks(&wrapped, &decoded, f64::from(block), period, None).unwrap();
        assert_eq!(abs.count(PixelStatus::Valid), w * h);
        for x in 0..w {
            assert!((abs.projector_coordinate(x, 1).unwrap() - x as f64).abs() < 1e-3);
        }
    }

    #[test]
    fn low_contrast_bits_are_unreliable() {
        let bit = Raster::from_fn(4, 1, |x, _| if x == 2 { 0.51 } else { 0.9 });
        let thr = Raster::filled(4, 1, 0.5f32);
        let d = decode_with_threshold(&[&bit], &thr, 0.05).unwrap();
        assert_eq!(d.status.data[2], PixelStatus::Unreliable);
        assert_eq!(d.status.data[0], PixelStatus::Valid);
    }

    #[test]
    fn seed_004_fine_shifts_recover_every_column() {
        let (w, block) = (64u32, 4u32);
        let decode_shift = |shift: u32| {
            let bits = gray_code_bits(w, 1, block, shift, GrayAxis::Columns);
            let frames: Vec<&Raster<f32>> = bits.iter().collect();
            decode_with_threshold(&frames, &Raster::filled(w as usize, 1, 0.5), 0.1).unwrap()
        };
        let coarse = decode_shift(0);
        let shifted: Vec<GrayDecoded> = (1..block).map(decode_shift).collect();
        let refs: Vec<&GrayDecoded> = shifted.iter().collect();
        let fine = fine_coordinate(&coarse, &refs, block).unwrap();
        // The shifts are cyclic, so even the first block's columns resolve.
        for c in 0..w {
            assert_eq!(fine.block.data[c as usize], c, "column {c}");
        }
    }

    #[test]
    fn wide_blocks_are_refused() {
        let d = GrayDecoded {
            block: Raster::filled(1, 1, 0),
            status: Raster::filled(1, 1, PixelStatus::Valid),
        };
        let w = Raster::filled(1, 1, 0.0f32);
        assert!(matches!(
            unwrap_with_blocks(&w, &d, 16.0, 16.0, None),
            Err(UnwrapError::BlockTooWide { .. })
        ));
    }
}
