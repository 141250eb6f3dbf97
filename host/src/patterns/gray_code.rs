//! Gray-code patterns: column or row codes over blocks, with seed 004's fine shifts.
//!
//! Column `c` belongs to block `g = floor(((c - shift) mod W) / block_px)` (the shift is
//! cyclic, as seed 004 "cycles the Gray coded images one row"); frame `b` is white where
//! bit `b` (MSB first) of `gray(g)` is set.

use crate::raster::Raster;
use crate::unwrap::gray_code::binary_to_gray;

/// Which projector coordinate the code encodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GrayAxis {
    /// Encodes the column (stripes are vertical).
    Columns,
    /// Encodes the row (stripes are horizontal).
    Rows,
}

/// Bits needed to give every block of `extent_px` its own code.
pub fn gray_bit_count(extent_px: u32, block_px: u32) -> u32 {
    let blocks = extent_px.div_ceil(block_px.max(1)).max(1);
    32 - (blocks - 1).leading_zeros()
}

/// The Gray frames (MSB first, 0.0 / 1.0) for a `width x height` projector.
pub fn gray_code_bits(
    width_px: u32,
    height_px: u32,
    block_px: u32,
    shift_px: u32,
    axis: GrayAxis,
) -> Vec<Raster<f32>> {
    let extent = match axis {
        GrayAxis::Columns => width_px,
        GrayAxis::Rows => height_px,
    };
    let block_px = block_px.max(1);
    let bits = gray_bit_count(extent, block_px);
    (0..bits)
        .map(|b| {
            let bit = bits - 1 - b;
            Raster::from_fn(width_px as usize, height_px as usize, |x, y| {
                let c = match axis {
                    GrayAxis::Columns => x as u32,
                    GrayAxis::Rows => y as u32,
                };
                let shifted = (c + extent - shift_px % extent) % extent;
                let g = binary_to_gray(shifted / block_px);
                ((g >> bit) & 1) as f32
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bit_counts() {
        assert_eq!(gray_bit_count(1024, 4), 8); // seed 004: 8 codes of 4x4 blocks
        assert_eq!(gray_bit_count(912, 1), 10);
        assert_eq!(gray_bit_count(1, 1), 0);
        assert_eq!(gray_bit_count(2, 1), 1);
    }

    #[test]
    fn adjacent_blocks_differ_in_one_frame() {
        let frames = gray_code_bits(64, 1, 4, 0, GrayAxis::Columns);
        for c in 0..63usize {
            let changes = frames.iter().filter(|f| f.data[c] != f.data[c + 1]).count();
            assert_eq!(changes, usize::from((c + 1) % 4 == 0), "column {c}");
        }
        let rows = gray_code_bits(2, 16, 2, 0, GrayAxis::Rows);
        assert_eq!(rows.len(), 3);
        assert_ne!(rows[2].at(0, 1), rows[2].at(0, 2));
    }
}
