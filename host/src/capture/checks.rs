//! Convention self-checks: a capture decoded with the wrong phase origin, sign, shift
//! direction or frame order is refused with its likely cause, instead of returning
//! points a half period (tens of millimetres) off.
//!
//! - Gray code + phase ([`half_period_share`]): each pixel's phase places it inside its
//!   period; its Gray block places it too. Right conventions agree to within half a
//!   block (edge misreads add a few pixels); a phase origin off by half a period, or a
//!   reversed sign, puts about half the pixels `3/8` of a period or more away.
//!   A phase that runs against the code (reversed sign or shift direction) can still
//!   land inside each block, mirrored, when its origin is also off by half a period, so
//!   [`direction_share`] compares the phase's direction with the code's across block
//!   edges.
//! - Heterodyne / PDM ([`wrong_order_share`]): the share of modulated pixels whose
//!   periods do not agree on one fringe order (the methods' residual votes). An origin
//!   off by half a period on every set leaves the beats intact but not the finest order;
//!   periods in the wrong frame order break every vote.
//! - Any method ([`outside_share`]): the share of decoded coordinates outside the
//!   projector; a reversed phase sign keeps heterodyne's votes consistent but mirrors
//!   the coordinates beyond the field.
//!
//! When a check fails, [`Alternative`]s (the same maps under another convention) are
//! tried, and the one that passes names the cause.

use super::ProjectorAxis;
use crate::raster::Raster;
use crate::unwrap::gray_code::GrayDecoded;
use crate::unwrap::PixelStatus;

/// A check as measured on a capture (kept for the report).
#[derive(Clone, Debug, PartialEq)]
pub struct CheckResult {
    /// The axis.
    pub axis: ProjectorAxis,
    /// What was measured.
    pub check: &'static str,
    /// Share of the pixels that fail it, 0..1.
    pub share: f64,
    /// Pixels it was measured on.
    pub pixels: usize,
    /// The limit, 0..1.
    pub limit: f64,
}

impl CheckResult {
    /// Whether the share is within the limit.
    pub fn passed(&self) -> bool {
        self.share <= self.limit
    }
}

/// Names of the checks.
pub const HALF_PERIOD: &str = "phase and Gray code disagree by about half a period";
/// See [`HALF_PERIOD`].
pub const DIRECTION: &str = "phase runs against the Gray code";
/// See [`HALF_PERIOD`].
pub const WRONG_ORDER: &str = "periods disagree on the fringe order";
/// See [`HALF_PERIOD`].
pub const OUTSIDE: &str = "decoded coordinates fall outside the projector";

/// Another convention to read the same wrapped phases with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Alternative {
    /// Every phase plus pi.
    HalfPeriodOrigin,
    /// Every phase negated.
    Reversed,
    /// Both.
    ReversedHalfPeriod,
    /// The periods' frames in the opposite order.
    PeriodOrderReversed,
}

impl Alternative {
    /// The alternatives for one wrapped phase (Gray code + phase).
    pub const SINGLE: [Alternative; 3] = [
        Alternative::HalfPeriodOrigin,
        Alternative::Reversed,
        Alternative::ReversedHalfPeriod,
    ];

    /// The alternatives for several periods (heterodyne, PDM).
    pub const MULTI: [Alternative; 4] = [
        Alternative::HalfPeriodOrigin,
        Alternative::Reversed,
        Alternative::ReversedHalfPeriod,
        Alternative::PeriodOrderReversed,
    ];

    /// The cause the alternative stands for, in words.
    pub fn cause(self) -> &'static str {
        match self {
            Alternative::HalfPeriodOrigin => {
                "the fringes' phase origin differs from the description's by half a period \
                 (e.g. phase 2 pi (u mod P)/P - pi against 2 pi u/P): set phase_offset_rad \
                 (-pi for SLMaster / OpenCV SinusCompleGrayCode) or use the family's preset"
            }
            Alternative::Reversed => {
                "the phase runs the other way: the fringe phase sign or the shift direction \
                 is reversed (set phase_sign or shift_sign to -1)"
            }
            Alternative::ReversedHalfPeriod => {
                "the phase runs the other way and its origin is off by half a period \
                 (set phase_sign or shift_sign to -1 and phase_offset_rad to pi)"
            }
            Alternative::PeriodOrderReversed => {
                "the periods' frames come in the other order (list periods_px in frame order)"
            }
        }
    }

    /// `phi` read under this alternative (one period; the order is handled by the
    /// caller).
    pub fn apply(self, phi: f32) -> f32 {
        let pi = std::f32::consts::PI;
        match self {
            Alternative::HalfPeriodOrigin => crate::phase::wrap_pi(phi + pi),
            Alternative::Reversed => crate::phase::wrap_pi(-phi),
            Alternative::ReversedHalfPeriod => crate::phase::wrap_pi(pi - phi),
            Alternative::PeriodOrderReversed => phi,
        }
    }
}

/// The cause named when no alternative passes.
pub const UNKNOWN_CAUSE: &str = "no single convention change explains it: the frames may be \
     out of order (fringe and Gray frames swapped, steps shuffled), or the capture is not \
     of the described family";

/// Gray + phase: the share of `pixels` (indices of pixels both decoded) whose phase
/// coordinate `u = phi P / 2 pi` lies more than 3/8 of a period from the centre of
/// their Gray block (modulo the period). `phi` is in the DESIGN.md convention.
pub fn half_period_share(
    phi: &Raster<f32>,
    code: &GrayDecoded,
    block_px: f64,
    period_px: f64,
    pixels: &[usize],
    alternative: Option<Alternative>,
) -> f64 {
    if pixels.is_empty() {
        return 0.0;
    }
    let p = period_px as f32;
    let far = 0.375 * p;
    let wrong = pixels
        .iter()
        .filter(|&&i| {
            let mut f = phi.data[i];
            if let Some(a) = alternative {
                f = a.apply(f);
            }
            let u = f * p / std::f32::consts::TAU;
            let centre = (f64::from(code.block.data[i]) * block_px + (block_px - 1.0) / 2.0) as f32;
            let d = u - centre;
            let wrapped = d - p * (d / p).round();
            wrapped.abs() > far
        })
        .count();
    wrong as f64 / pixels.len() as f64
}

/// Gray + phase: among pairs of read pixels two apart (along x and along y) in
/// adjacent Gray blocks, the share whose wrapped-phase difference has the other sign
/// than their block difference. `read[i]`: both phase and code read at pixel `i`.
/// Returns the share and the number of pairs.
pub fn direction_share(phi: &Raster<f32>, code: &GrayDecoded, read: &[bool]) -> (f64, usize) {
    const STEP: usize = 2;
    let (w, h) = phi.size();
    let (mut pairs, mut against) = (0usize, 0usize);
    let mut visit = |i: usize, j: usize| {
        if !(read[i] && read[j]) {
            return;
        }
        let dc = i64::from(code.block.data[j]) - i64::from(code.block.data[i]);
        let dp = crate::phase::wrap_pi(phi.data[j] - phi.data[i]);
        // Adjacent blocks only, and a smooth phase step: depth edges say nothing.
        if dc.abs() != 1 || dp.abs() > std::f32::consts::FRAC_PI_2 || dp == 0.0 {
            return;
        }
        pairs += 1;
        if (dc > 0) != (dp > 0.0) {
            against += 1;
        }
    };
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if x + STEP < w {
                visit(i, i + STEP);
            }
            if y + STEP < h {
                visit(i, i + STEP * w);
            }
        }
    }
    if pairs == 0 {
        (0.0, 0)
    } else {
        (against as f64 / pairs as f64, pairs)
    }
}

/// Heterodyne / PDM: the share of pixels inside `mask` that the method marked
/// unreliable (its order votes disagreed).
pub fn wrong_order_share(status: &Raster<PixelStatus>, mask: &Raster<bool>) -> (f64, usize) {
    let considered = mask.data.iter().filter(|&&m| m).count();
    if considered == 0 {
        return (0.0, 0);
    }
    let wrong = status
        .data
        .iter()
        .zip(&mask.data)
        .filter(|(s, m)| **m && **s == PixelStatus::Unreliable)
        .count();
    (wrong as f64 / considered as f64, considered)
}

/// Whether a coordinate lies on a projector of `extent` pixels (centres at integers),
/// with one pixel of margin.
pub fn inside(coord_px: f32, extent: u32) -> bool {
    (-1.5..=extent as f32 + 0.5).contains(&coord_px)
}

/// The share of `coords` (valid decoded coordinates) outside the projector.
pub fn outside_share(coords: impl Iterator<Item = f32>, extent: u32) -> (f64, usize) {
    let (mut n, mut out) = (0usize, 0usize);
    for c in coords {
        n += 1;
        if !inside(c, extent) {
            out += 1;
        }
    }
    if n == 0 {
        (0.0, 0)
    } else {
        (out as f64 / n as f64, n)
    }
}

/// At most `max` evenly spread entries of `pixels` (the alternatives are tried on a
/// sample: a convention error affects every pixel alike).
pub fn sample(pixels: &[usize], max: usize) -> Vec<usize> {
    if pixels.len() <= max {
        return pixels.to_vec();
    }
    let step = pixels.len() as f64 / max as f64;
    (0..max)
        .map(|k| pixels[(k as f64 * step) as usize])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::wrap_pi;

    /// A camera that sees projector column x; phase and code of period 32, block 16.
    fn maps(offset_rad: f32, sign: f32) -> (Raster<f32>, GrayDecoded, Vec<usize>) {
        let (w, p) = (512usize, 32.0f32);
        let phi = Raster::from_fn(w, 1, |x, _| {
            wrap_pi(sign * std::f32::consts::TAU * x as f32 / p + offset_rad)
        });
        let code = GrayDecoded {
            block: Raster::from_fn(w, 1, |x, _| (x / 16) as u32),
            status: Raster::filled(w, 1, PixelStatus::Valid),
        };
        (phi, code, (0..w).collect())
    }

    #[test]
    fn right_conventions_agree_and_wrong_ones_are_named() {
        let (phi, code, px) = maps(0.0, 1.0);
        let read = vec![true; px.len()];
        assert_eq!(half_period_share(&phi, &code, 16.0, 32.0, &px, None), 0.0);
        assert_eq!(direction_share(&phi, &code, &read).0, 0.0);
        let pi = std::f32::consts::PI;
        for (offset, sign, want) in [
            (-pi, 1.0, Alternative::HalfPeriodOrigin),
            (0.0, -1.0, Alternative::Reversed),
            (pi, -1.0, Alternative::ReversedHalfPeriod),
        ] {
            let (phi, code, px) = maps(offset, sign);
            let half = half_period_share(&phi, &code, 16.0, 32.0, &px, None);
            let (against, _) = direction_share(&phi, &code, &read);
            // Each wrong convention fails one check or the other.
            assert!(
                half > 0.3 || against > 0.9,
                "{offset} {sign}: {half} {against}"
            );
            assert_eq!(against > 0.5, sign < 0.0);
            let fixed: Vec<Alternative> = Alternative::SINGLE
                .into_iter()
                .filter(|&a| half_period_share(&phi, &code, 16.0, 32.0, &px, Some(a)) < 0.01)
                .filter(|&a| (a != Alternative::HalfPeriodOrigin) == (against > 0.5))
                .collect();
            assert_eq!(fixed, vec![want]);
        }
    }

    #[test]
    fn outside_and_order_shares_count_what_they_say() {
        let (share, n) = outside_share([0.0, 10.0, -5.0, 700.0].into_iter(), 640);
        assert_eq!((share, n), (0.5, 4));
        let status = Raster::from_vec(
            4,
            1,
            vec![
                PixelStatus::Valid,
                PixelStatus::Unreliable,
                PixelStatus::Unreliable,
                PixelStatus::Masked,
            ],
        )
        .unwrap();
        let mask = Raster::from_vec(4, 1, vec![true, true, false, false]).unwrap();
        assert_eq!(wrong_order_share(&status, &mask), (0.5, 2));
        assert_eq!(sample(&[1, 2, 3, 4], 2), vec![1, 3]);
    }
}
