//! Each camera pixel's response to projected light, from uniform floods
//! (seed 003, eq. 6-12): `I = b1 L + b2` at the exposure the floods were
//! taken with, where `L` in [0, 1] is the projected grey level, `b1` the
//! pixel's gain (surface reflectivity x sensor sensitivity x exposure) and
//! `b2` what it sees with the projector dark (ambient light and light from
//! other surface patches). Both by least squares over the floods that did
//! not saturate at that pixel.

use super::AdaptiveError;
use crate::raster::Raster;

/// How far a pixel's fit got.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResponseStatus {
    /// `b1` and `b2` are fitted.
    Fitted,
    /// Fewer than two distinct levels stayed under saturation: the surface
    /// saturates even at the lowest projected levels.
    SaturatesAtLowest,
    /// A flood sample is NaN or infinite.
    BadSample,
}

/// Per camera pixel `b1`, `b2` (frame units at the floods' exposure; NaN
/// unless fitted) and how the fit went.
#[derive(Clone, Debug, PartialEq)]
pub struct Response {
    /// Gain `b1`: frame units per unit of projected level.
    pub gain: Raster<f32>,
    /// Offset `b2`: frame units with the projector dark.
    pub offset: Raster<f32>,
    /// Per pixel: fitted, or why not.
    pub status: Raster<ResponseStatus>,
}

impl Response {
    /// Pixels with a status.
    pub fn count(&self, status: ResponseStatus) -> usize {
        self.status.data.iter().filter(|&&s| s == status).count()
    }
}

/// Checks floods against their levels: as many images as levels, at least
/// two distinct levels in [0, 1], every image the size of the first.
/// Returns `(width, height)`.
pub fn check_floods(
    floods: &[&Raster<f32>],
    levels: &[f32],
) -> Result<(usize, usize), AdaptiveError> {
    if floods.len() != levels.len() {
        return Err(AdaptiveError::FloodCount {
            got: floods.len(),
            levels: levels.len(),
        });
    }
    let in_range = levels.iter().all(|l| (0.0..=1.0).contains(l));
    let distinct = levels
        .iter()
        .any(|&l| levels.iter().any(|&m| (l - m).abs() > 1e-6));
    if !in_range || !distinct {
        return Err(AdaptiveError::FloodLevels {
            levels: levels.to_vec(),
        });
    }
    let expected = floods[0].size();
    for (index, f) in floods.iter().enumerate() {
        if f.size() != expected || f.data.len() != expected.0 * expected.1 {
            return Err(AdaptiveError::FloodSize {
                index,
                expected,
                got: f.size(),
            });
        }
    }
    Ok(expected)
}

/// Fits `b1`, `b2` per pixel over the floods whose sample is below
/// `saturation` (frame units): the closed-form 2x2 normal equations of
/// seed 003's eq. 12, with the samples that clipped left out.
pub fn fit_response(
    floods: &[&Raster<f32>],
    levels: &[f32],
    saturation: f32,
) -> Result<Response, AdaptiveError> {
    let (width, height) = check_floods(floods, levels)?;
    let n = width * height;
    let mut gain = vec![f32::NAN; n];
    let mut offset = vec![f32::NAN; n];
    let mut status = vec![ResponseStatus::Fitted; n];
    for i in 0..n {
        let (mut s, mut sl, mut sll, mut si, mut sli) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
        let mut bad = false;
        for (f, &l) in floods.iter().zip(levels) {
            let v = f.data[i];
            if !v.is_finite() {
                bad = true;
                break;
            }
            if v >= saturation {
                continue;
            }
            let (l, v) = (f64::from(l), f64::from(v));
            s += 1.0;
            sl += l;
            sll += l * l;
            si += v;
            sli += l * v;
        }
        if bad {
            status[i] = ResponseStatus::BadSample;
            continue;
        }
        // Determinant of the normal equations: n * sum(l^2) - sum(l)^2 is
        // zero unless two distinct levels stayed unsaturated.
        let det = s * sll - sl * sl;
        if s < 2.0 || det <= 1e-9 * s * s {
            status[i] = ResponseStatus::SaturatesAtLowest;
            continue;
        }
        let b1 = (s * sli - sl * si) / det;
        gain[i] = b1 as f32;
        offset[i] = ((si - b1 * sl) / s) as f32;
    }
    Ok(Response {
        gain: Raster::from_vec(width, height, gain).expect("sized"),
        offset: Raster::from_vec(width, height, offset).expect("sized"),
        status: Raster::from_vec(width, height, status).expect("sized"),
    })
}

/// The projected level that puts a pixel of gain `b1` and offset `b2` (at
/// exposure scale 1) at `target` frame units when the exposure is
/// `scale` times: `L = (target / scale - b2) / b1` (seed 003, eq. 15),
/// at most 1 (a dark pixel gets the projector's full level). `None` when
/// even `min_level` would exceed the target (the pixel cannot be held
/// under saturation at this exposure).
pub fn optimal_level(b1: f32, b2: f32, scale: f32, target: f32, min_level: f32) -> Option<f32> {
    let budget = target / scale - b2;
    if b1 <= 0.0 {
        return (budget >= 0.0).then_some(1.0);
    }
    let level = (budget / b1).min(1.0);
    (level >= min_level).then_some(level)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn floods_of(levels: &[f32], b1: &[f32], b2: &[f32]) -> Vec<Raster<f32>> {
        levels
            .iter()
            .map(|&l| {
                Raster::from_vec(
                    b1.len(),
                    1,
                    b1.iter()
                        .zip(b2)
                        .map(|(g, o)| (g * l + o).min(1.0))
                        .collect(),
                )
                .unwrap()
            })
            .collect()
    }

    #[test]
    fn fit_recovers_gain_and_offset_leaving_out_clipped_floods() {
        let levels: Vec<f32> = (0..7).map(|i| i as f32 / 6.0).collect();
        // A dim pixel, a bright one that clips from level 3/6 on, and one
        // that clips from the first lit level.
        let (b1, b2) = ([0.2f32, 1.9, 8.0], [0.03f32, 0.05, 0.04]);
        let floods = floods_of(&levels, &b1, &b2);
        let refs: Vec<&Raster<f32>> = floods.iter().collect();
        let r = fit_response(&refs, &levels, 0.995).unwrap();
        for i in 0..2 {
            assert_eq!(r.status.data[i], ResponseStatus::Fitted);
            assert!((r.gain.data[i] - b1[i]).abs() < 1e-5, "{i}: {:?}", r.gain);
            assert!((r.offset.data[i] - b2[i]).abs() < 1e-5);
        }
        assert_eq!(r.status.data[2], ResponseStatus::SaturatesAtLowest);
        assert!(r.gain.data[2].is_nan());
        assert_eq!(r.count(ResponseStatus::SaturatesAtLowest), 1);
    }

    #[test]
    fn bad_floods_are_refused_and_nan_samples_marked() {
        let levels = [0.0f32, 0.5, 1.0];
        let floods = floods_of(&levels, &[0.5, 0.5], &[0.0, 0.0]);
        let refs: Vec<&Raster<f32>> = floods.iter().collect();
        assert!(matches!(
            fit_response(&refs[..2], &levels, 0.99),
            Err(AdaptiveError::FloodCount { got: 2, levels: 3 })
        ));
        assert!(matches!(
            fit_response(&refs, &[0.5, 0.5, 0.5], 0.99),
            Err(AdaptiveError::FloodLevels { .. })
        ));
        assert!(matches!(
            fit_response(&refs, &[0.0, 0.5, 1.5], 0.99),
            Err(AdaptiveError::FloodLevels { .. })
        ));
        let small = Raster::filled(1, 1, 0.1f32);
        let mixed = [refs[0], refs[1], &small];
        assert!(matches!(
            fit_response(&mixed, &levels, 0.99),
            Err(AdaptiveError::FloodSize { index: 2, .. })
        ));
        let mut nan = floods.clone();
        nan[1].data[0] = f32::NAN;
        let refs: Vec<&Raster<f32>> = nan.iter().collect();
        let r = fit_response(&refs, &levels, 0.99).unwrap();
        assert_eq!(r.status.data[0], ResponseStatus::BadSample);
        assert_eq!(r.status.data[1], ResponseStatus::Fitted);
    }

    #[test]
    fn optimal_level_holds_the_target_or_says_it_cannot() {
        // 0.1 + 2 L = 0.9 -> L = 0.4 at scale 1.
        assert!((optimal_level(2.0, 0.1, 1.0, 0.9, 0.05).unwrap() - 0.4).abs() < 1e-6);
        // Twice the exposure: 2 (0.1 + 2 L) = 0.9 -> L = 0.175.
        assert!((optimal_level(2.0, 0.1, 2.0, 0.9, 0.05).unwrap() - 0.175).abs() < 1e-6);
        // Dark pixels get the full level.
        assert_eq!(optimal_level(0.1, 0.0, 1.0, 0.9, 0.05), Some(1.0));
        // A highlight that would need less than the lowest usable level.
        assert_eq!(optimal_level(40.0, 0.1, 1.0, 0.9, 0.05), None);
        // Ambient alone saturates.
        assert_eq!(optimal_level(0.0, 1.0, 1.0, 0.9, 0.05), None);
    }
}
