//! Phase unwrapping: wrapped phase -> absolute phase, one method per file.
//!
//! | method | file | needs |
//! |---|---|---|
//! | multi-frequency heterodyne (2, 3, 4 ... periods) | [`heterodyne`] | beat of all periods >= field |
//! | projection distance minimisation (number-theoretic) | [`pdm`] | LCM of the periods >= field |
//! | Gray code + phase | [`gray_code`] | Gray blocks <= half a period |
//! | complementary Gray code + phase | [`complementary_gray`] | `n + 1` bits, finest block half a period |
//! | quality-guided spatial flood fill | [`quality_guided`] | one frequency, connected surface |
//!
//! [`temporal`] runs phase shifting and the heterodyne in one pass from the frames (the
//! pipeline's own row kernels).
//!
//! Every method returns an [`AbsolutePhase`]: the absolute phase `Phi = 2 pi u / P` of one
//! chosen period (projector coordinate `u`, pixel centres at integers) and a per-pixel
//! [`PixelStatus`]. Pixels a method cannot unwrap reliably are marked, never guessed.

pub mod complementary_gray;
pub mod gray_code;
pub mod heterodyne;
pub mod pdm;
pub mod quality_guided;
pub mod temporal;

use crate::raster::Raster;

/// How far a pixel got.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum PixelStatus {
    /// Absolute phase is trustworthy.
    Valid = 0,
    /// Masked before unwrapping (modulation too low, saturated, outside the mask).
    Masked = 1,
    /// The method's consistency check failed (rounding residual too large, codes unclear,
    /// two candidate orders too close): left out rather than guessed.
    Unreliable = 2,
    /// Spatial unwrapping never reached the pixel (separate region, below quality floor).
    Unreached = 3,
}

/// Absolute phase of one period with a status per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct AbsolutePhase {
    /// Absolute phase, radians (`2 pi u / period_px`); NaN where not [`PixelStatus::Valid`].
    pub phase: Raster<f32>,
    /// Status of each pixel.
    pub status: Raster<PixelStatus>,
    /// The period this phase belongs to, projector pixels.
    pub period_px: f64,
}

impl AbsolutePhase {
    /// Number of pixels with a given status.
    pub fn count(&self, status: PixelStatus) -> usize {
        self.status.data.iter().filter(|&&s| s == status).count()
    }

    /// Projector coordinate `u = Phi P / (2 pi)` at a pixel, if valid.
    pub fn projector_coordinate(&self, x: usize, y: usize) -> Option<f64> {
        (*self.status.at(x, y) == PixelStatus::Valid)
            .then(|| f64::from(*self.phase.at(x, y)) * self.period_px / std::f64::consts::TAU)
    }
}

/// What can be wrong with an unwrapping request.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum UnwrapError {
    /// A method got fewer inputs than it needs.
    #[error("{method} needs at least {need} wrapped phases / codes, got {got}")]
    NotEnoughInputs {
        /// The method.
        method: &'static str,
        /// Inputs given.
        got: usize,
        /// Inputs needed.
        need: usize,
    },
    /// Inputs do not match the configuration (count of periods vs phase maps).
    #[error("{method} was set up for {expected} inputs, got {got}")]
    WrongInputCount {
        /// The method.
        method: &'static str,
        /// Inputs configured.
        expected: usize,
        /// Inputs given.
        got: usize,
    },
    /// A period is not a positive finite number, or two periods are equal.
    #[error("bad periods {periods_px:?}: need positive, finite and pairwise different values")]
    BadPeriods {
        /// The periods given, projector pixels.
        periods_px: Vec<f64>,
    },
    /// The periods cannot resolve the field: their combined unambiguous range is too short.
    #[error("periods {periods_px:?} are unambiguous over {unambiguous_px:.1} px only, field is {range_px} px")]
    RangeTooShort {
        /// The periods, projector pixels.
        periods_px: Vec<f64>,
        /// Unambiguous range the periods give, pixels.
        unambiguous_px: f64,
        /// Field to cover, pixels.
        range_px: f64,
    },
    /// Maps have different sizes.
    #[error("map {index} is {got:?} but map 0 is {expected:?} (width, height)")]
    SizeMismatch {
        /// Index of the offending map.
        index: usize,
        /// Size of map 0.
        expected: (usize, usize),
        /// Size of the offending map.
        got: (usize, usize),
    },
    /// Gray-code blocks too wide for the period to correct edge errors.
    #[error("Gray block of {block_px} px must be at most half the period {period_px} px")]
    BlockTooWide {
        /// Finest Gray block, pixels.
        block_px: f64,
        /// Phase period, pixels.
        period_px: f64,
    },
}

/// Checks that all maps have the size of the first; returns `(width, height)`.
pub(crate) fn same_size<T>(maps: &[&Raster<T>]) -> Result<(usize, usize), UnwrapError> {
    let expected = maps.first().map(|m| m.size()).unwrap_or((0, 0));
    for (index, m) in maps.iter().enumerate() {
        if m.size() != expected || m.data.len() != expected.0 * expected.1 {
            return Err(UnwrapError::SizeMismatch {
                index,
                expected,
                got: m.size(),
            });
        }
    }
    Ok(expected)
}

/// Checks the inputs of a temporal unwrapper: one wrapped map per period, all of one
/// size, and a mask (if any) of that size too. Returns the common `(width, height)`.
pub(crate) fn check_temporal_inputs(
    method: &'static str,
    expected_maps: usize,
    wrapped: &[&Raster<f32>],
    mask: Option<&Raster<bool>>,
) -> Result<(usize, usize), UnwrapError> {
    if wrapped.len() != expected_maps {
        return Err(UnwrapError::WrongInputCount {
            method,
            expected: expected_maps,
            got: wrapped.len(),
        });
    }
    let (width, height) = same_size(wrapped)?;
    if let Some(m) = mask.filter(|m| m.size() != (width, height)) {
        return Err(UnwrapError::SizeMismatch {
            index: wrapped.len(),
            expected: (width, height),
            got: m.size(),
        });
    }
    Ok((width, height))
}

/// Rounds `(estimate - wrapped) / 2 pi` to the fringe order; `None` when the residual
/// exceeds `max_residual_rad` (the estimate is too far from any order to trust).
#[inline]
pub fn fringe_order(estimate_rad: f32, wrapped_rad: f32, max_residual_rad: f32) -> Option<f32> {
    let turns = (estimate_rad - wrapped_rad) * (1.0 / std::f32::consts::TAU);
    let k = round_fast(turns);
    let residual = (turns - k) * std::f32::consts::TAU;
    (residual.abs() <= max_residual_rad).then_some(k)
}

/// Round half away from zero, exactly as `f32::round` for every finite input, in plain
/// adds and selects. `f32::round`/`ceil` are libm calls on baseline x86-64 (no SSE4.1),
/// and a float-to-int cast is a scalar saturating conversion per lane that keeps the
/// loops from vectorising; these run for every pixel.
#[inline(always)]
pub fn round_fast(x: f32) -> f32 {
    let t = round_half_even(x);
    // Ties went to the even neighbour; send them away from zero.
    if (x - t).abs() == 0.5 {
        x + 0.5f32.copysign(x)
    } else {
        t
    }
}

/// `ceil`, exactly as `f32::ceil` for every finite input (see [`round_fast`]).
#[inline(always)]
pub fn ceil_fast(x: f32) -> f32 {
    let t = round_half_even(x);
    if t < x {
        t + 1.0
    } else {
        t
    }
}

/// Nearest integer, ties to even: adding and removing 2^23 leaves no fraction bits
/// (exact below 2^23; from there on every f32 is already an integer). NaN stays NaN.
#[inline(always)]
fn round_half_even(x: f32) -> f32 {
    const TWO_23: f32 = 8_388_608.0;
    let m = TWO_23.copysign(x);
    if x.abs() < TWO_23 {
        (x + m) - m
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_rounding_matches_std() {
        for i in -4000..4000 {
            let x = i as f32 * 0.173 + 0.0005;
            assert_eq!(round_fast(x), x.round(), "{x}");
            assert_eq!(ceil_fast(x), x.ceil(), "{x}");
        }
        assert_eq!(round_fast(2.5), 3.0);
        assert_eq!(round_fast(-2.5), -3.0);
        assert_eq!(round_fast(3.5), 4.0);
        assert_eq!(round_fast(0.49999997), 0.0);
        assert_eq!(ceil_fast(-0.5), 0.0);
        // Every tie, where an f32 has no fraction bits left, and the zeros (equal as
        // numbers; the sign of a zero result may differ from std's).
        let ties = (-300..300).map(|i| i as f32 + 0.5);
        for x in ties.chain([
            8_388_607.5f32,
            -8_388_607.5,
            8_388_609.0,
            3.0e9,
            -3.0e9,
            0.0,
            -0.0,
        ]) {
            assert_eq!(round_fast(x), x.round(), "{x}");
            assert_eq!(ceil_fast(x), x.ceil(), "{x}");
        }
        assert!(round_fast(f32::NAN).is_nan() && ceil_fast(f32::NAN).is_nan());
    }

    #[test]
    fn fringe_order_rounds_and_refuses() {
        let tau = std::f32::consts::TAU;
        assert_eq!(fringe_order(3.0 * tau + 0.1, 0.05, 1.0), Some(3.0));
        assert_eq!(fringe_order(-2.0 * tau, 0.3, 1.0), Some(-2.0));
        assert_eq!(fringe_order(3.0 * tau + 2.5, 0.0, 1.0), None);
    }
}
