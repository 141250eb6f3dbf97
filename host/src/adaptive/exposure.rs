//! The exposure of the adapted scan. Seed 003 keeps it fixed and only
//! lowers the projector where the floods saturate; then the dark parts stay
//! as starved as in a plain scan. Here it is chosen from the floods' fit as
//! the one at which the most pixels will decode: a longer exposure lifts
//! dark parts over the modulation floor, but a highlight that needs less
//! than the projector's lowest usable level to stay under the target is
//! lost to saturation (seed 004 chooses its exposure too, by a genetic
//! algorithm; one exposure for the view is a one-dimensional search, done
//! exhaustively on a fine grid).

use rayon::prelude::*;

use super::response::{optimal_level, Response, ResponseStatus};

/// What decided the chosen exposure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExposureLimit {
    /// Inside the range: longer loses more highlights than it gains dark
    /// pixels, shorter the other way round.
    MostPixels,
    /// The longest exposure the plan allows (more would still gain).
    Longest,
    /// The shortest exposure the plan allows.
    Shortest,
    /// The range holds one exposure (seed 003's fixed exposure).
    Fixed,
}

impl ExposureLimit {
    /// For reports.
    pub fn name(self) -> &'static str {
        match self {
            ExposureLimit::MostPixels => "the most pixels over the modulation floor",
            ExposureLimit::Longest => "the longest exposure (more would still gain)",
            ExposureLimit::Shortest => "the shortest exposure",
            ExposureLimit::Fixed => "fixed",
        }
    }
}

/// How to choose the exposure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExposureRule {
    /// Frame units the brightest sample of a pixel should reach.
    pub target: f32,
    /// Lowest projected level that still gives usable fringes.
    pub min_level: f32,
    /// Pixels whose gain is below this see (almost) no projector light
    /// (shadow, outside the projector's field) and do not count.
    pub min_gain: f32,
    /// Allowed exposure scales (shortest, longest).
    pub range: (f64, f64),
    /// Candidate exposures, geometrically spaced over `range`.
    pub candidates: usize,
}

/// The chosen exposure scale, what decided it and what it predicts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExposureChoice {
    /// Exposure, in units of the floods' exposure.
    pub scale: f64,
    /// What decided it.
    pub limit: ExposureLimit,
    /// Share of the lit pixels predicted to decode at it.
    pub predicted_share: f64,
}

/// Most pixels looked at per candidate (a regular subsample beyond).
const MAX_SAMPLES: usize = 250_000;

/// Chooses the exposure scale at which the most lit pixels (gain at least
/// `min_gain`) are predicted to decode: each pixel's optimal level at that
/// exposure exists (it can be held under the target at `min_level` or
/// more) and its predicted modulation, `contrast x scale x b1 x L / 2`
/// (the fringe swings the light from 0 to `L`; `contrast` is what the
/// optics leave of it, measured on the full-intensity set), reaches
/// `floor`. Ties go to the shorter exposure. With no lit pixel, the
/// floods' exposure, as when no exposure decodes any. Pixels that saturate even at the lowest flood have no
/// fit and take no part (they are masked, with a warning).
pub fn choose_exposure(
    response: &Response,
    rule: &ExposureRule,
    floor: f32,
    contrast: f32,
) -> ExposureChoice {
    let stride = (response.gain.data.len() / MAX_SAMPLES).max(1);
    let lit: Vec<(f32, f32)> = response
        .gain
        .data
        .iter()
        .zip(&response.offset.data)
        .zip(&response.status.data)
        .step_by(stride)
        .filter(|((&b1, _), &s)| s == ResponseStatus::Fitted && b1 >= rule.min_gain)
        .map(|((&b1, &b2), _)| (b1, b2))
        .collect();
    let (shortest, longest) = rule.range;
    let n = rule.candidates.max(2);
    let ratio = (longest / shortest).powf(1.0 / (n - 1) as f64);
    let counts: Vec<(f64, usize)> = (0..n)
        .into_par_iter()
        .map(|k| {
            let scale = shortest * ratio.powi(k as i32);
            let s = scale as f32;
            let decoding = lit
                .iter()
                .filter(|&&(b1, b2)| {
                    optimal_level(b1, b2, s, rule.target, rule.min_level)
                        .is_some_and(|l| contrast * s * b1 * l * 0.5 >= floor)
                })
                .count();
            (scale, decoding)
        })
        .collect();
    // The first (shortest) of the best.
    let mut best = (shortest, 0usize);
    for &(scale, decoding) in &counts {
        if decoding > best.1 {
            best = (scale, decoding);
        }
    }
    let (mut scale, decoding) = best;
    if decoding == 0 {
        // No exposure decodes anything: keep the floods'.
        scale = 1.0f64.clamp(shortest, longest);
    }
    let limit = if shortest == longest {
        ExposureLimit::Fixed
    } else if decoding == 0 {
        ExposureLimit::MostPixels
    } else if scale >= longest * (1.0 - 1e-9) {
        ExposureLimit::Longest
    } else if scale <= shortest * (1.0 + 1e-9) {
        ExposureLimit::Shortest
    } else {
        ExposureLimit::MostPixels
    };
    ExposureChoice {
        scale,
        limit,
        predicted_share: decoding as f64 / lit.len().max(1) as f64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::Raster;

    fn response(pixels: &[(f32, f32)], saturating: usize) -> Response {
        let n = pixels.len() + saturating;
        let mut gain: Vec<f32> = pixels.iter().map(|p| p.0).collect();
        let mut offset: Vec<f32> = pixels.iter().map(|p| p.1).collect();
        let mut status = vec![ResponseStatus::Fitted; pixels.len()];
        gain.resize(n, f32::NAN);
        offset.resize(n, f32::NAN);
        status.resize(n, ResponseStatus::SaturatesAtLowest);
        Response {
            gain: Raster::from_vec(n, 1, gain).unwrap(),
            offset: Raster::from_vec(n, 1, offset).unwrap(),
            status: Raster::from_vec(n, 1, status).unwrap(),
        }
    }

    fn rule() -> ExposureRule {
        ExposureRule {
            target: 0.9,
            min_level: 0.1,
            min_gain: 0.01,
            range: (1.0 / 32.0, 8.0),
            candidates: 256,
        }
    }

    #[test]
    fn the_exposure_decoding_the_most_pixels_wins() {
        // Three dark pixels (b1 0.1: need scale >= 2 for modulation 0.1 at
        // full level) against one highlight (b1 4: held at level 0.1 up to
        // scale 2.25). Every scale in [2, 2.25] decodes all four.
        let r = response(&[(0.1, 0.0), (0.1, 0.0), (0.1, 0.0), (4.0, 0.0)], 0);
        let c = choose_exposure(&r, &rule(), 0.1, 1.0);
        assert_eq!(c.limit, ExposureLimit::MostPixels);
        assert!((2.0..=2.25).contains(&c.scale), "{c:?}");
        assert_eq!(c.predicted_share, 1.0);
        // Four highlights outvote three dark pixels: they are kept.
        let r = response(
            &[
                (0.1, 0.0),
                (0.1, 0.0),
                (0.1, 0.0),
                (40.0, 0.0),
                (40.0, 0.0),
                (40.0, 0.0),
                (40.0, 0.0),
            ],
            0,
        );
        let c = choose_exposure(&r, &rule(), 0.1, 1.0);
        assert!(c.scale <= 0.225, "{c:?}");
        assert!((c.predicted_share - 4.0 / 7.0).abs() < 1e-9);
        // A dark pixel that decodes only at the longest exposure.
        let c = choose_exposure(&response(&[(0.0251, 0.0)], 0), &rule(), 0.1, 1.0);
        assert_eq!(c.limit, ExposureLimit::Longest);
        assert_eq!(c.predicted_share, 1.0);
        // One too dark for any: the floods' exposure.
        let c = choose_exposure(&response(&[(0.02, 0.0)], 0), &rule(), 0.1, 1.0);
        assert_eq!((c.scale, c.predicted_share), (1.0, 0.0));
    }

    #[test]
    fn pixels_without_a_fit_or_light_do_not_choose() {
        // A pixel saturating at the lowest flood has no fit; the lit one
        // decodes from the shortest exposure at which its modulation
        // reaches the floor (0.4 x 0.5 x s >= 0.1: s >= 0.5).
        let c = choose_exposure(&response(&[(0.4, 0.0)], 1), &rule(), 0.1, 1.0);
        assert!((0.5..0.52).contains(&c.scale), "{c:?}");
        assert_eq!(c.predicted_share, 1.0);
        // Unlit pixels alone: the floods' exposure.
        let c = choose_exposure(&response(&[(0.001, 0.05)], 0), &rule(), 0.1, 1.0);
        assert_eq!(c.scale, 1.0);
    }
}
