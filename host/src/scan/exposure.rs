//! How a head's fringes are exposed, and what the exposure left: in the
//! sequential mode saturated pixels are masked (a clipped sample bends the
//! decoded phase, so a pixel with one is never reconstructed), a multi-exposure capture's fringe sets
//! are reconstructed one by one and each pixel taken from its best set, and
//! the figures say how many pixels saturated or fell below the modulation
//! floor.

use crate::adaptive::exposure::ExposureChoice;
use crate::adaptive::hdr::{HdrParams, HdrStats};
use crate::raster::Raster;
use crate::reconstruct::{ReconstructError, Reconstruction, Reconstructor};
use crate::unwrap::PixelStatus;

/// How each head's fringes are exposed.
#[derive(Clone, Debug, PartialEq)]
pub enum Exposures {
    /// One fringe set at the standard exposure.
    Single,
    /// One fringe set per head at an exposure chosen for that head from
    /// one white flood at the standard exposure ([`auto_exposure_scale`]):
    /// what a scanner's auto exposure does, so a dim or steep view is not
    /// left under the fringe-order noise floor, nor a bright one clipped.
    Auto(AutoExposure),
    /// The fringe set at each of these exposure scales (units of the
    /// standard exposure), each pixel taken from the set where it decoded
    /// with the largest modulation without saturating: the usual
    /// multi-exposure high-dynamic-range scan.
    Multi(Vec<f64>),
    /// Adaptive projection (seed 003): grey floods and one full-intensity
    /// fringe set, then fringes whose level is chosen per projector pixel,
    /// at an exposure chosen for the view ([`crate::adaptive`]).
    AdaptiveHdr(HdrParams),
    /// Adaptive colour and intensity projection (seed 004): five floods,
    /// Gray-code matching, then 3-step fringes whose colour and level are
    /// chosen per projector pixel, at an exposure chosen for the view.
    AdaptiveColour(crate::adaptive::colour::ColourParams),
}

impl Exposures {
    /// For reports: `single`, `multi-exposure`, `adaptive-hdr` or
    /// `adaptive-colour`.
    pub fn name(&self) -> &'static str {
        match self {
            Exposures::Single => "single",
            Exposures::Auto(_) => "auto",
            Exposures::Multi(_) => "multi-exposure",
            Exposures::AdaptiveHdr(_) => "adaptive-hdr",
            Exposures::AdaptiveColour(_) => "adaptive-colour",
        }
    }

    /// Whether this is one of the adaptive kinds.
    pub fn is_adaptive(&self) -> bool {
        matches!(
            self,
            Exposures::AdaptiveHdr(_) | Exposures::AdaptiveColour(_)
        )
    }
}

/// How [`Exposures::Auto`] chooses a head's exposure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutoExposure {
    /// Frame value (full scale 1) the chosen percentile of the lit pixels
    /// of the white flood should reach: the fringes' peaks are the flood's
    /// level, so this leaves that share of headroom under saturation.
    pub target: f32,
    /// Share of the lit pixels allowed above `target` (their brightest
    /// `1 - percentile` may saturate and be masked: specular glints should
    /// not darken the whole view).
    pub percentile: f64,
    /// Flood value under which a pixel counts as unlit (shadow, off the
    /// projector's field): a few times the camera's noise.
    pub min_lit: f32,
}

impl Default for AutoExposure {
    /// 0.85 of full scale at the 99.5th percentile of pixels above 0.02.
    fn default() -> Self {
        Self {
            target: 0.85,
            percentile: 0.995,
            min_lit: 0.02,
        }
    }
}

impl AutoExposure {
    /// A target in (0, 1], a percentile in (0, 1] and an unlit level in
    /// [0, target).
    pub fn validate(&self) -> Result<(), String> {
        let ok = self.target > 0.0
            && self.target <= 1.0
            && self.percentile > 0.0
            && self.percentile <= 1.0
            && self.min_lit >= 0.0
            && self.min_lit < self.target;
        if ok {
            Ok(())
        } else {
            Err(format!(
                "auto exposure needs a target in (0, 1], a percentile in (0, 1] and an unlit \
                 level in [0, target): got {self:?}"
            ))
        }
    }
}

/// The exposure scale (standard exposures) that brings `rule.percentile`
/// of the lit pixels of `white` (a full-white flood at the standard
/// exposure) to `rule.target`, within `range`. A view with no lit pixel
/// keeps the standard exposure. Where the flood itself saturated, the
/// percentile is only a lower bound of the light, so the scale is an upper
/// bound: the fringes may still clip there (and are masked).
pub fn auto_exposure_scale(white: &Raster<f32>, rule: &AutoExposure, range: (f64, f64)) -> f64 {
    let mut lit: Vec<f32> = white
        .data
        .iter()
        .copied()
        .filter(|v| v.is_finite() && *v >= rule.min_lit)
        .collect();
    if lit.is_empty() {
        return 1.0_f64.clamp(range.0, range.1);
    }
    let rank = ((lit.len() - 1) as f64 * rule.percentile).round() as usize;
    let (_, level, _) = lit.select_nth_unstable_by(rank, f32::total_cmp);
    (f64::from(rule.target) / f64::from(*level)).clamp(range.0, range.1)
}

/// What a head's exposure left, in camera pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct ExposureFigures {
    /// Camera images the head took (preliminaries included).
    pub images: usize,
    /// Exposure scale of each fringe set reconstructed.
    pub scales: Vec<f64>,
    /// Pixels with a saturated sample in every fringe set (masked in the
    /// sequential mode; in the simultaneous modes, where the overlap sees
    /// both projectors, the separation takes the frames as they are).
    pub saturated_px: usize,
    /// Pixels below the modulation floor (saturated pixels not counted).
    pub below_floor_px: usize,
    /// Camera pixels.
    pub pixels: usize,
    /// Adaptive projection: what it found and chose.
    pub adaptive: Option<AdaptiveFigures>,
}

/// What the adaptive capture measured before it adapted, and chose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptiveFigures {
    /// The adapted fringes' exposure.
    pub exposure: ExposureChoice,
    /// The adaptation's pixel counts.
    pub stats: HdrStats,
    /// Pixels saturated in the full-intensity fringe set.
    pub before_saturated_px: usize,
    /// Pixels below the modulation floor in it (saturated ones not counted).
    pub before_below_floor_px: usize,
    /// Pixels of the adapted scan marked unreliable for straddling a step
    /// of the DMD level map.
    pub level_step_px: usize,
}

/// Warns when a head lost more than 0.1 % of its pixels to saturation, and
/// when adaptive projection met pixels it could not hold or place.
pub fn warn(
    head: &str,
    saturated: &[bool],
    adaptive: Option<&HdrStats>,
    warnings: &mut Vec<String>,
) {
    let lost = saturated.iter().filter(|&&s| s).count();
    if lost * 1000 > saturated.len() {
        warnings.push(format!(
            "head {head}: {lost} pixels ({:.2} %) saturated in the fringes and are masked{}",
            100.0 * lost as f64 / saturated.len() as f64,
            if adaptive.is_some() {
                ""
            } else {
                "; --adaptive hdr or --exposures recover them"
            }
        ));
    }
    if let Some(a) = adaptive {
        if a.saturates_at_lowest_px > 0 || a.cannot_hold_px > 0 {
            warnings.push(format!(
                "head {head}: adaptive projection: {} pixels saturate even at the lowest lit flood and {} cannot be held under the target at the chosen exposure; they get the lowest usable level and are masked where they still saturate (a shorter standard exposure or a lower projector power would hold them)",
                a.saturates_at_lowest_px, a.cannot_hold_px
            ));
        }
        if a.unmapped_px > 0 {
            warnings.push(format!(
                "head {head}: adaptive projection could not place {} of the {} pixels to lower on the projector (no phase and no usable homography around them); their projector area stays at full level",
                a.unmapped_px, a.lowered_px
            ));
        }
    }
}

/// Pixels with a sample at or above `level` in any of `frames` (a NaN
/// sample counts too: it cannot be decoded either).
pub fn saturated_pixels(frames: &[Raster<f32>], level: f32) -> Vec<bool> {
    let n = frames.first().map_or(0, |f| f.data.len());
    let mut out = vec![false; n];
    for f in frames {
        for (o, &v) in out.iter_mut().zip(&f.data) {
            *o |= v >= level || v.is_nan();
        }
    }
    out
}

/// The modulation a pixel needs to be reconstructed: the configured floor,
/// or the one under which its fringe orders are too noisy to count,
/// whichever is higher.
pub fn modulation_floor(rc: &Reconstructor) -> f32 {
    rc.config().min_modulation.max(rc.min_reliable_modulation())
}

/// Pixels whose modulation is under `floor` and that are not in `saturated`.
pub fn below_floor(recon: &Reconstruction, floor: f32, saturated: &[bool]) -> usize {
    recon
        .pixels
        .modulation
        .iter()
        .zip(saturated)
        .filter(|(&m, &s)| !s && (m.is_nan() || m < floor))
        .count()
}

/// One head's fringe sets reconstructed: with `mask`, each set's pixels
/// that saturated in its `raw` frames are masked (frames zeroed there);
/// each set is reconstructed, and with several sets each pixel taken from
/// the set where it is valid with the largest modulation. Returns the
/// result and, per pixel, whether it saturated in every set.
pub fn reconstruct_sets(
    rc: &Reconstructor,
    raw_sets: &[&[Raster<f32>]],
    frame_sets: &mut [&mut [Raster<f32>]],
    saturation: f32,
    mask: bool,
) -> Result<(Reconstruction, Vec<bool>), ReconstructError> {
    if frame_sets.is_empty() {
        // No frames at all: the reconstruction says how many it needed.
        return rc.reconstruct::<f32>(&[], None).map(|r| (r, Vec::new()));
    }
    let mut recons = Vec::with_capacity(frame_sets.len());
    let mut always_saturated: Option<Vec<bool>> = None;
    for (raw, frames) in raw_sets.iter().zip(frame_sets.iter_mut()) {
        let saturated = saturated_pixels(raw, saturation);
        if mask {
            crate::dealias::mask_pixels(frames, &saturated);
        }
        let refs: Vec<&Raster<f32>> = frames.iter().collect();
        recons.push(rc.reconstruct(&refs, None)?);
        always_saturated = Some(match always_saturated {
            None => saturated,
            Some(all) => all.iter().zip(&saturated).map(|(a, b)| *a && *b).collect(),
        });
    }
    let always_saturated = always_saturated.unwrap_or_default();
    if recons.len() == 1 {
        return Ok((recons.pop().expect("one"), always_saturated));
    }
    Ok((merge_best(rc, recons), always_saturated))
}

/// Per pixel, the valid result with the largest modulation among `recons`
/// (the first one's values where none is valid); the cloud rebuilt.
fn merge_best(rc: &Reconstructor, mut recons: Vec<Reconstruction>) -> Reconstruction {
    let mut maps = std::mem::take(&mut recons[0].pixels);
    for other in &recons[1..] {
        for i in 0..maps.len() {
            let theirs = other.pixels.status[i] == PixelStatus::Valid;
            let ours = maps.status[i] == PixelStatus::Valid;
            if theirs && (!ours || other.pixels.modulation[i] > maps.modulation[i]) {
                maps.copy_pixel(&other.pixels, i);
            }
        }
    }
    rc.from_maps(maps)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::PinholeModel;
    use crate::reconstruct::ReconstructConfig;

    #[test]
    fn auto_exposure_brings_the_bright_lit_pixels_to_the_target() {
        let rule = AutoExposure::default();
        let range = (1.0 / 32.0, 8.0);
        // 1000 lit pixels at 0.1..0.5 and 1000 unlit at 0.01: the 99.5th
        // percentile of the lit ones is 0.498, so 0.85 / 0.498.
        let mut data: Vec<f32> = (0..1000).map(|i| 0.1 + 0.4 * i as f32 / 999.0).collect();
        data.extend(std::iter::repeat_n(0.01, 1000));
        let white = Raster {
            width: 100,
            height: 20,
            data,
        };
        let scale = auto_exposure_scale(&white, &rule, range);
        assert!((scale - 0.85 / 0.498).abs() < 0.01, "{scale}");
        // A few glints do not darken the view; a bright view is shortened.
        let mut glints = white.clone();
        glints.data[..4].fill(1.0);
        assert!((auto_exposure_scale(&glints, &rule, range) - scale).abs() < 0.01);
        let bright = Raster::filled(10, 10, 0.97_f32);
        assert!((auto_exposure_scale(&bright, &rule, range) - 0.85 / 0.97).abs() < 1e-6);
        // A dark view stops at the plan's longest exposure; no light (or
        // only NaN) keeps the standard one.
        assert_eq!(
            auto_exposure_scale(&Raster::filled(10, 10, 0.05_f32), &rule, range),
            8.0
        );
        assert_eq!(
            auto_exposure_scale(&Raster::filled(10, 10, 0.0_f32), &rule, range),
            1.0
        );
        assert_eq!(
            auto_exposure_scale(&Raster::filled(4, 4, f32::NAN), &rule, range),
            1.0
        );
        // Settings out of range are refused.
        assert!(rule.validate().is_ok());
        for bad in [
            AutoExposure {
                target: 0.0,
                ..rule
            },
            AutoExposure {
                target: 1.5,
                ..rule
            },
            AutoExposure {
                percentile: 0.0,
                ..rule
            },
            AutoExposure {
                min_lit: 0.9,
                ..rule
            },
            AutoExposure {
                target: f32::NAN,
                ..rule
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }

    #[test]
    fn lost_pixels_and_unholdable_surfaces_are_warned_about() {
        let mut warnings = Vec::new();
        // 1 in 1000 saturated: quiet; 2 in 1000: a warning that names the fix.
        let mut saturated = vec![false; 1000];
        saturated[0] = true;
        warn("A", &saturated, None, &mut warnings);
        assert!(warnings.is_empty());
        saturated[1] = true;
        warn("A", &saturated, None, &mut warnings);
        assert_eq!(warnings.len(), 1);
        assert!(warnings[0].contains("--adaptive hdr"), "{warnings:?}");
        // Adaptive: pixels saturating at the lowest flood, and unplaced ones.
        let stats = HdrStats {
            saturates_at_lowest_px: 3,
            lowered_px: 10,
            unmapped_px: 2,
            ..HdrStats::default()
        };
        warnings.clear();
        warn("B", &[false; 10], Some(&stats), &mut warnings);
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(warnings[0].contains("3 pixels saturate even at the lowest lit flood"));
        assert!(warnings[1].contains("could not place 2 of the 10"));
    }

    #[test]
    fn saturated_and_nan_pixels_are_found() {
        let a = Raster::from_vec(3, 1, vec![0.2, 0.999, 0.5]).unwrap();
        let b = Raster::from_vec(3, 1, vec![0.3, 0.1, f32::NAN]).unwrap();
        assert_eq!(saturated_pixels(&[a, b], 0.995), [false, true, true]);
        assert!(saturated_pixels(&[], 0.995).is_empty());
    }

    #[test]
    fn each_pixel_comes_from_its_best_unsaturated_exposure() {
        let (camera, projector) = crate::synth::stereo_rig(
            PinholeModel::ideal(64, 48, 160.0),
            PinholeModel::ideal(228, 285, 450.0),
            0.15,
            0.5,
        );
        let periods = [9.0, 10.0, 11.0];
        let truth = crate::synth::trace(&crate::synth::two_spheres(0.5, 0.6), &camera, &projector);
        let render = |gain: f32| {
            let light = crate::synth::Lighting {
                ambient: 0.02,
                gain,
                noise_sigma: 0.002,
            };
            crate::synth::render_fringe_set(&truth, &periods, 4, true, &light, 3)
                .into_iter()
                .map(|mut f| {
                    f.data.iter_mut().for_each(|v| *v = v.min(1.0));
                    f
                })
                .collect::<Vec<_>>()
        };
        let mut config = ReconstructConfig::new(periods.to_vec());
        config.noise_sigma = 0.002;
        let rc = Reconstructor::new(&camera, &projector, config).unwrap();
        // Long exposure: the brightest parts clip; short: nothing clips but
        // everything is 4x dimmer.
        let (long, short) = (render(1.6), render(0.4));
        let raw = [long.clone(), short.clone()];
        let alone: Vec<Reconstruction> = raw
            .iter()
            .map(|set| {
                let mut frames = set.clone();
                let mut sets: Vec<&mut [Raster<f32>]> = vec![&mut frames];
                reconstruct_sets(&rc, &[set.as_slice()], &mut sets, 0.995, true)
                    .unwrap()
                    .0
            })
            .collect();
        let (mut l, mut s) = (long, short);
        let mut sets: Vec<&mut [Raster<f32>]> = vec![&mut l, &mut s];
        let raw_refs: Vec<&[Raster<f32>]> = raw.iter().map(|r| r.as_slice()).collect();
        let (out, saturated) = reconstruct_sets(&rc, &raw_refs, &mut sets, 0.995, true).unwrap();
        let clipped_long = saturated_pixels(&raw[0], 0.995);
        assert!(clipped_long.iter().filter(|&&c| c).count() > 50);
        // Nothing clips in the short set, so nothing is lost in both.
        assert!(saturated.iter().all(|&s| !s));
        let valid = |r: &Reconstruction, i: usize| r.pixels.status[i] == PixelStatus::Valid;
        let n = out.pixels.len();
        for (i, &clipped) in clipped_long.iter().enumerate() {
            if clipped {
                assert!(!valid(&alone[0], i), "pixel {i} clipped yet valid");
            }
            // The merge keeps every pixel either set decoded, from the one
            // with the larger modulation.
            assert_eq!(valid(&out, i), valid(&alone[0], i) || valid(&alone[1], i));
            if valid(&out, i) {
                let best = (0..2)
                    .filter(|&k| valid(&alone[k], i))
                    .map(|k| alone[k].pixels.modulation[i])
                    .fold(0.0, f32::max);
                assert_eq!(out.pixels.modulation[i], best);
            }
        }
        let count = |r: &Reconstruction| (0..n).filter(|&i| valid(r, i)).count();
        assert!(count(&out) > count(&alone[0]));
        assert_eq!(out.cloud.len(), count(&out));
    }
}
