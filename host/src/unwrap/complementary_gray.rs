//! Complementary Gray-code unwrapping (Zhang et al. 2017; the SLMaster / OpenCV
//! `SinusCompleGrayCodePattern` family).
//!
//! A plain Gray code of one block per fringe period misreads its order at every period
//! edge, exactly where the wrapped phase jumps, so rounding cannot repair it. The
//! complementary code adds one finer bit: `n + 1` Gray bits over blocks of half a period
//! give `V2 = floor(2u / P)`, and from it two orders whose edges fall half a period
//! apart:
//!
//! ```text
//! k1 = V2 >> 1          = floor(u / P)          (changes at period edges, t = 0)
//! k2 = (V2 + 1) >> 1    = floor(u / P + 1/2)    (changes mid-period, t = 1/2)
//! ```
//!
//! With the DESIGN.md phase `phi = 2 pi u / P` wrapped into (-pi, pi] (the wrap falls at
//! `t = frac(u / P) = 1/2`), each pixel takes the order that is far from its own edges:
//!
//! | wrapped phase | where in the period | absolute phase |
//! |---|---|---|
//! | `|phi| < pi/2` | near a period edge (t < 1/4 or t > 3/4) | `phi + 2 pi k2` |
//! | `phi >= pi/2` | t in [1/4, 1/2) | `phi + 2 pi k1` |
//! | `phi < -pi/2` | t in [1/2, 3/4) | `phi + 2 pi (k1 + 1)` |
//!
//! so a code misread by one block at any code edge changes nothing. What it cannot
//! catch is a phase whose convention differs from the code's (origin, sign): see
//! [`crate::capture::checks`], which refuses such captures before this runs.

use std::f32::consts::{FRAC_PI_2, TAU};

use super::gray_code::GrayDecoded;
use super::{AbsolutePhase, PixelStatus, UnwrapError};
use crate::raster::Raster;

/// Unwraps `wrapped` (DESIGN.md convention, period `period_px`) with the complementary
/// code `decoded`: `n + 1` Gray bits whose finest block is half the period, so
/// `decoded.block = floor(2u / P)`. Pixels outside `mask` are masked; pixels the code
/// could not read keep its status.
pub fn unwrap_complementary(
    wrapped: &Raster<f32>,
    decoded: &GrayDecoded,
    period_px: f64,
    mask: Option<&Raster<bool>>,
) -> Result<AbsolutePhase, UnwrapError> {
    if !(period_px.is_finite() && period_px > 0.0) {
        return Err(UnwrapError::BadPeriods {
            periods_px: vec![period_px],
        });
    }
    let (width, height) = wrapped.size();
    for (index, got) in [(1, decoded.block.size()), (2, decoded.status.size())]
        .into_iter()
        .chain(mask.map(|m| (3, m.size())))
    {
        if got != (width, height) {
            return Err(UnwrapError::SizeMismatch {
                index,
                expected: (width, height),
                got,
            });
        }
    }
    let mut phase = Raster::filled(width, height, f32::NAN);
    let mut status = decoded.status.clone();
    for i in 0..width * height {
        if mask.is_some_and(|m| !m.data[i]) {
            status.data[i] = PixelStatus::Masked;
        }
        let phi = wrapped.data[i];
        if !phi.is_finite() && status.data[i] == PixelStatus::Valid {
            status.data[i] = PixelStatus::Unreliable;
        }
        if status.data[i] != PixelStatus::Valid {
            continue;
        }
        phase.data[i] = phi + TAU * order(phi, decoded.block.data[i]) as f32;
    }
    Ok(AbsolutePhase {
        phase,
        status,
        period_px,
    })
}

/// The fringe order of a pixel with wrapped phase `phi` and half-period block `v2`.
#[inline]
pub fn order(phi: f32, v2: u32) -> u32 {
    let k1 = v2 >> 1;
    let k2 = (v2 + 1) >> 1;
    if phi.abs() < FRAC_PI_2 {
        k2
    } else if phi >= FRAC_PI_2 {
        k1
    } else {
        k1 + 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::wrap_pi;

    fn decoded(blocks: Vec<u32>) -> GrayDecoded {
        let n = blocks.len();
        GrayDecoded {
            block: Raster::from_vec(n, 1, blocks).unwrap(),
            status: Raster::filled(n, 1, PixelStatus::Valid),
        }
    }

    #[test]
    fn every_column_unwraps_and_edge_misreads_change_nothing() {
        let (period, width) = (16.0f64, 256usize);
        let wrapped = Raster::from_fn(width, 1, |x, _| {
            wrap_pi((std::f64::consts::TAU * x as f64 / period) as f32)
        });
        let truth: Vec<u32> = (0..width)
            .map(|x| (2.0 * x as f64 / period).floor() as u32)
            .collect();
        // Misread every pixel within 1 px of a half-period edge into its neighbour's block.
        let misread: Vec<u32> = (0..width)
            .map(|x| {
                let half = period / 2.0;
                let t = x as f64 % half;
                if t < 1.0 && truth[x] > 0 {
                    truth[x] - 1
                } else if t >= half - 1.0 {
                    truth[x] + 1
                } else {
                    truth[x]
                }
            })
            .collect();
        for blocks in [truth, misread] {
            let abs = unwrap_complementary(&wrapped, &decoded(blocks), period, None).unwrap();
            for x in 0..width {
                let u = abs.projector_coordinate(x, 0).unwrap();
                assert!((u - x as f64).abs() < 1e-3, "column {x}: {u}");
            }
        }
    }

    #[test]
    fn unread_codes_and_masked_pixels_stay_out() {
        let wrapped = Raster::filled(3, 1, 0.5f32);
        let mut d = decoded(vec![0, 0, 0]);
        d.status.data[1] = PixelStatus::Unreliable;
        let mask = Raster::from_vec(3, 1, vec![true, true, false]).unwrap();
        let abs = unwrap_complementary(&wrapped, &d, 16.0, Some(&mask)).unwrap();
        assert_eq!(
            abs.status.data,
            vec![
                PixelStatus::Valid,
                PixelStatus::Unreliable,
                PixelStatus::Masked
            ]
        );
    }

    #[test]
    fn sizes_and_periods_are_checked() {
        let wrapped = Raster::filled(3, 1, 0.0f32);
        assert!(matches!(
            unwrap_complementary(&wrapped, &decoded(vec![0, 0]), 16.0, None),
            Err(UnwrapError::SizeMismatch { .. })
        ));
        assert!(matches!(
            unwrap_complementary(&wrapped, &decoded(vec![0, 0, 0]), f64::NAN, None),
            Err(UnwrapError::BadPeriods { .. })
        ));
    }
}
