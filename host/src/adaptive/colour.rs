//! Seed 004's adaptive colour and intensity projection, for coloured and
//! reflective parts seen by a mono camera. An RGB projector shows a colour
//! pattern as its red, green and blue planes one after another inside one
//! camera exposure (each plane lit by its own LED), so every preliminary
//! and adapted image here is three sub-frames.
//!
//! ```text
//! floods: grey 0, grey 100 of 255, red, green, blue (5 images)
//!   ──response──> offset b2 = I_0, gain per band g_c = I_c - I_0,
//!                 texture colour t_c = g_c / balance_c / max (normalised on white)
//! Gray codes of 4x4 blocks, columns and rows, each also shifted by 1..3 px
//!   ──matching──> (u, v) per camera pixel (seed 004's rough + pixel-shift fine match)
//! per pixel colour w (the texture colour, or white), gain b1 = sum w_c g_c
//!   ──exposure::choose_exposure / response::optimal_level──> exposure, level L
//! w_c L at (u, v) ──projector_map──> one level map per LED
//!   ──fringes──> 3-step x three-pitch fringes, each a red, green and blue plane
//! ```
//!
//! Seed 004 chooses the levels and the exposure with a genetic algorithm;
//! with one exposure for the view and a closed-form level per pixel the
//! problem is a one-dimensional search, done exhaustively
//! ([`super::exposure`]). For the colour it projects the surface's own
//! colour ([`ColourChoice::Texture`]); on a mono camera every LED adds
//! light to every surface, so white at the chosen level
//! ([`ColourChoice::White`]) gives each pixel at least as much modulation
//! under the same no-saturation limit: the two are measured side by side.

use super::exposure::{choose_exposure, ExposureChoice, ExposureRule};
use super::fringes::adapted_fringes;
use super::hdr::HdrStats;
use super::mapping::{is_mapped, UNMAPPED};
use super::projector_map::{footprint_px, projector_levels};
use super::response::{optimal_level, Response, ResponseStatus};
use super::AdaptiveError;
use crate::patterns::gray_code::{gray_code_bits, GrayAxis};
use crate::raster::Raster;
use crate::rig::Led;
use crate::unwrap::gray_code::{decode_with_threshold, fine_coordinate};
use crate::unwrap::PixelStatus;

/// The three LEDs, one per sub-frame of a colour image.
pub const PLANE_LEDS: [Led; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// Grey level of the second flood (seed 004: 100 of 255).
pub const GREY_FLOOD: f32 = 100.0 / 255.0;

/// Floods in capture order: grey 0, grey 100, red, green, blue; each as
/// the level of its (red, green, blue) planes.
pub const FLOODS: [[f32; 3]; 5] = [
    [0.0; 3],
    [GREY_FLOOD; 3],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
];

/// Which colour each projector pixel gets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourChoice {
    /// Seed 004: the surface's own colour (its texture, normalised on white).
    Texture,
    /// Every LED: on a mono camera the most modulation a level can give.
    White,
}

/// How to adapt.
#[derive(Clone, Debug, PartialEq)]
pub struct ColourParams {
    /// The projected colour.
    pub choice: ColourChoice,
    /// Gray-code block, projector pixels (seed 004: 4x4).
    pub block_px: u32,
    /// Smallest difference from the threshold a Gray bit is read at, frame units.
    pub min_contrast: f32,
    /// What a white board gives under the red, green and blue floods, over
    /// what it gives under white (measured once per rig; the colour texture
    /// is normalised by it).
    pub white_balance: [f32; 3],
    /// The exposure's rule (target, lowest usable level, range).
    pub rule: ExposureRule,
    /// What the optics leave of a full-swing fringe's modulation (measured
    /// once per rig; the HDR mode measures it per scan).
    pub fringe_contrast: f32,
    /// Frame value at and above which a flood sample counts as saturated.
    pub saturation: f32,
    /// Growth of the lowered areas on the DMD, projector pixels.
    pub grow_px: usize,
}

impl Default for ColourParams {
    /// The texture colour, 4 px blocks, bits read 0.01 of full scale off the
    /// threshold, the twin's LEDs balanced (a third of white each), the HDR
    /// mode's exposure rule, fringe contrast 0.8, saturation at 99.5 %,
    /// lowered areas grown by 3 px.
    fn default() -> Self {
        ColourParams {
            choice: ColourChoice::Texture,
            block_px: 4,
            min_contrast: 0.01,
            white_balance: [1.0 / 3.0; 3],
            rule: super::hdr::HdrParams::default().rule,
            fringe_contrast: 0.8,
            saturation: 0.995,
            grow_px: 3,
        }
    }
}

impl ColourParams {
    /// Refuses parameters outside their ranges.
    pub fn validate(&self) -> Result<(), AdaptiveError> {
        let rule = &self.rule;
        let checks: [(&'static str, f64, bool, &'static str); 6] = [
            (
                "block_px",
                f64::from(self.block_px),
                (2..=64).contains(&self.block_px),
                "2..=64",
            ),
            (
                "target",
                f64::from(rule.target),
                rule.target > 0.0 && rule.target < self.saturation,
                "(0, saturation)",
            ),
            (
                "min_level",
                f64::from(rule.min_level),
                rule.min_level > 0.0 && rule.min_level <= 1.0,
                "(0, 1]",
            ),
            (
                "fringe_contrast",
                f64::from(self.fringe_contrast),
                self.fringe_contrast > 0.0 && self.fringe_contrast <= 1.0,
                "(0, 1]",
            ),
            (
                "white_balance",
                f64::from(
                    self.white_balance
                        .iter()
                        .copied()
                        .fold(f32::INFINITY, f32::min),
                ),
                self.white_balance.iter().all(|b| *b > 0.0 && b.is_finite()),
                "> 0 per LED",
            ),
            (
                "exposure range",
                rule.range.0,
                rule.range.0 > 0.0 && rule.range.0 <= rule.range.1,
                "0 < shortest <= longest",
            ),
        ];
        for (name, value, ok, range) in checks {
            if !ok {
                return Err(AdaptiveError::Parameter { name, value, range });
            }
        }
        Ok(())
    }
}

/// One colour image as its three planes (red, green, blue levels).
pub type Planes = [Raster<f32>; 3];

/// The flood images' planes, in [`FLOODS`] order.
pub fn flood_planes(dmd_px: (u32, u32)) -> Vec<Planes> {
    let (w, h) = (dmd_px.0 as usize, dmd_px.1 as usize);
    FLOODS
        .iter()
        .map(|l| l.map(|v| Raster::filled(w, h, (v * 255.0).round() / 255.0)))
        .collect()
}

/// Seed 004's matching patterns: column Gray codes of `block_px` blocks
/// shifted by 0 .. block_px - 1 pixels, then row codes likewise (MSB first
/// within each), white (the same level on all three planes).
pub fn matching_patterns(dmd_px: (u32, u32), block_px: u32) -> Vec<Raster<f32>> {
    let mut out = Vec::new();
    for axis in [GrayAxis::Columns, GrayAxis::Rows] {
        for shift in 0..block_px {
            out.extend(gray_code_bits(dmd_px.0, dmd_px.1, block_px, shift, axis));
        }
    }
    out
}

/// Each camera pixel's projector `(u, v)` from the matching frames (in
/// [`matching_patterns`] order), each bit read against the pixel's own
/// threshold (halfway between its dark level and full white), for every
/// pixel that full white lights by at least `2 x min_contrast`
/// ([`UNMAPPED`] elsewhere). A bit is read even where it sits near the
/// threshold: a camera pixel coarser than the DMD straddles block edges,
/// and a Gray code misread at an edge lands in the neighbouring block, so
/// the match is off by at most one block there (4 px, inside the 3 px the
/// level map is grown by plus the pixel's own footprint).
pub fn decode_matching(
    frames: &[Raster<f32>],
    response: &ColourResponse,
    dmd_px: (u32, u32),
    params: &ColourParams,
) -> Result<Raster<[f32; 2]>, AdaptiveError> {
    let threshold = response.threshold();
    let block = params.block_px;
    let bits = [
        crate::patterns::gray_code::gray_bit_count(dmd_px.0, block) as usize,
        crate::patterns::gray_code::gray_bit_count(dmd_px.1, block) as usize,
    ];
    let need = (bits[0] + bits[1]) * block as usize;
    if frames.len() != need {
        return Err(AdaptiveError::MatchingCount {
            got: frames.len(),
            need,
        });
    }
    let mut coords = Vec::new();
    let mut start = 0;
    for n in bits {
        let mut decoded = Vec::new();
        for _ in 0..block {
            let set: Vec<&Raster<f32>> = frames[start..start + n].iter().collect();
            start += n;
            decoded.push(
                decode_with_threshold(&set, &threshold, 0.0)
                    .map_err(|_| mapping_size(&threshold, &frames[0]))?,
            );
        }
        let shifted: Vec<_> = decoded[1..].iter().collect();
        coords.push(
            fine_coordinate(&decoded[0], &shifted, block)
                .map_err(|_| mapping_size(&threshold, &frames[0]))?,
        );
    }
    let (w, h) = threshold.size();
    let data = (0..w * h)
        .map(|i| {
            let lit = response.white_gain.data[i] >= 2.0 * params.min_contrast;
            let ok = coords
                .iter()
                .all(|c| c.status.data[i] == PixelStatus::Valid);
            let (u, v) = (coords[0].block.data[i], coords[1].block.data[i]);
            if lit && ok && u < dmd_px.0 && v < dmd_px.1 {
                [u as f32, v as f32]
            } else {
                UNMAPPED
            }
        })
        .collect();
    Ok(Raster {
        width: w,
        height: h,
        data,
    })
}

fn mapping_size(threshold: &Raster<f32>, frame: &Raster<f32>) -> AdaptiveError {
    AdaptiveError::MappingSize {
        expected: threshold.size(),
        got: frame.size(),
    }
}

/// The surface's response to the floods (in [`FLOODS`] order): the dark
/// level, the gain of a full-level white pattern and the texture colour.
#[derive(Clone, Debug, PartialEq)]
pub struct ColourResponse {
    /// `I_0`, frame units.
    pub offset: Raster<f32>,
    /// Gain of each LED at full level, frame units (NaN where its flood saturated).
    pub band_gain: [Raster<f32>; 3],
    /// Gain of full white from the grey flood, frame units (NaN where it saturated).
    pub white_gain: Raster<f32>,
}

impl ColourResponse {
    /// Bit-reading threshold: halfway between dark and full white.
    pub fn threshold(&self) -> Raster<f32> {
        Raster {
            width: self.offset.width,
            height: self.offset.height,
            data: self
                .offset
                .data
                .iter()
                .zip(&self.white_gain.data)
                .map(|(&o, &g)| if g.is_finite() { o + 0.5 * g } else { o + 0.5 })
                .collect(),
        }
    }
}

/// Seed 004's eq. 9 and its colour floods: `I_0` is the offset, `(I_100 -
/// I_0) / (100 / 255)` the gain of full white, `I_c - I_0` the gain of LED
/// `c`; a saturated flood leaves its gain NaN.
pub fn colour_response(
    floods: &[Raster<f32>],
    saturation: f32,
) -> Result<ColourResponse, AdaptiveError> {
    let refs: Vec<&Raster<f32>> = floods.iter().collect();
    let levels: Vec<f32> = FLOODS.iter().map(|l| l[0].max(l[1]).max(l[2])).collect();
    super::response::check_floods(&refs, &levels)?;
    let gain = |k: usize, scale: f32| Raster {
        width: floods[0].width,
        height: floods[0].height,
        data: floods[k]
            .data
            .iter()
            .zip(&floods[0].data)
            .map(|(&i, &o)| {
                if i < saturation && o < saturation && i.is_finite() && o.is_finite() {
                    (i - o) / scale
                } else {
                    f32::NAN
                }
            })
            .collect(),
    };
    Ok(ColourResponse {
        offset: floods[0].clone(),
        band_gain: [gain(2, 1.0), gain(3, 1.0), gain(4, 1.0)],
        white_gain: gain(1, GREY_FLOOD),
    })
}

/// What [`adapt_colour`] chose and built.
#[derive(Clone, Debug, PartialEq)]
pub struct ColourAdaptation {
    /// The adapted fringes' exposure.
    pub exposure: ExposureChoice,
    /// Level per DMD pixel and LED (red, green, blue).
    pub projector_levels: Planes,
    /// The adapted fringes: per image its red, green and blue planes, in
    /// that order (3 planes x steps x periods).
    pub patterns: Vec<Raster<f32>>,
    /// Counts (`mapped_by_phase_px` counts pixels placed by the Gray match).
    pub stats: HdrStats,
}

/// Chooses each pixel's colour (`params.choice`), the exposure at which
/// the most pixels reach `floor`, each pixel's level, places colour x
/// level on the DMD through the matching `uv`, and builds 3-step fringes of
/// `periods_px` as colour planes.
pub fn adapt_colour(
    response: &ColourResponse,
    uv: &Raster<[f32; 2]>,
    dmd_px: (u32, u32),
    periods_px: &[f64],
    steps: usize,
    floor: f32,
    params: &ColourParams,
) -> Result<ColourAdaptation, AdaptiveError> {
    let (w, h) = response.offset.size();
    if uv.size() != (w, h) {
        return Err(AdaptiveError::MappingSize {
            expected: (w, h),
            got: uv.size(),
        });
    }
    let n = w * h;
    // Per pixel: colour weights and the gain they give.
    let mut weights = vec![[1.0f32; 3]; n];
    let mut gain = vec![f32::NAN; n];
    let mut status = vec![ResponseStatus::Fitted; n];
    for i in 0..n {
        let g = [0, 1, 2].map(|c| response.band_gain[c].data[i]);
        if g.iter().any(|v| !v.is_finite()) {
            status[i] = ResponseStatus::SaturatesAtLowest;
            continue;
        }
        let w = match params.choice {
            ColourChoice::White => [1.0; 3],
            ColourChoice::Texture => {
                let t = [0, 1, 2].map(|c| (g[c] / params.white_balance[c]).max(0.0));
                let top = t.iter().copied().fold(0.0f32, f32::max);
                if top > 0.0 {
                    t.map(|v| v / top)
                } else {
                    [1.0; 3]
                }
            }
        };
        weights[i] = w;
        gain[i] = (0..3).map(|c| w[c] * g[c].max(0.0)).sum();
    }
    let fit = Response {
        gain: Raster::from_vec(w, h, gain).expect("sized"),
        offset: response.offset.clone(),
        status: Raster::from_vec(w, h, status).expect("sized"),
    };
    let exposure = choose_exposure(&fit, &params.rule, floor, params.fringe_contrast);
    let scale = exposure.scale as f32;
    let rule = &params.rule;
    let mut stats = HdrStats {
        fitted_px: fit.count(ResponseStatus::Fitted),
        saturates_at_lowest_px: fit.count(ResponseStatus::SaturatesAtLowest),
        ..HdrStats::default()
    };
    let mut band_levels = [0, 1, 2].map(|_| vec![f32::NAN; n]);
    for i in 0..n {
        let level = match fit.status.data[i] {
            ResponseStatus::Fitted => {
                match optimal_level(
                    fit.gain.data[i],
                    fit.offset.data[i],
                    scale,
                    rule.target,
                    rule.min_level,
                ) {
                    Some(l) => l,
                    None => {
                        stats.cannot_hold_px += 1;
                        rule.min_level
                    }
                }
            }
            _ => rule.min_level,
        };
        let wanted = weights[i].map(|c| c * level);
        if wanted.iter().any(|&v| v < 1.0) {
            stats.lowered_px += 1;
            if is_mapped(&uv.data[i]) {
                stats.mapped_by_phase_px += 1;
                for c in 0..3 {
                    band_levels[c][i] = wanted[c];
                }
            } else {
                stats.unmapped_px += 1;
            }
        }
    }
    let footprint = footprint_px(uv);
    let projector_levels = band_levels.map(|levels| {
        let camera = Raster::from_vec(w, h, levels).expect("sized");
        // A band asked for 0 (a colour without it) stays dark; the level
        // map's floor is the lowest request.
        projector_levels(uv, &camera, dmd_px, footprint, params.grow_px)
    });
    let per_band: Vec<Vec<Raster<f32>>> = projector_levels
        .iter()
        .map(|levels| adapted_fringes(levels, 0.0, periods_px, steps))
        .collect();
    let mut patterns = Vec::with_capacity(3 * per_band[0].len());
    for k in 0..per_band[0].len() {
        for band in &per_band {
            patterns.push(band[k].clone());
        }
    }
    Ok(ColourAdaptation {
        exposure,
        projector_levels,
        patterns,
        stats,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matching_patterns_decode_to_each_projector_pixel() {
        let dmd = (40u32, 24u32);
        let params = ColourParams::default();
        let patterns = matching_patterns(dmd, params.block_px);
        // A camera that sees the DMD one to one, dark 0.1, white adds 0.6.
        let lit = |g: f32| ColourResponse {
            offset: Raster::filled(40, 24, 0.1f32),
            band_gain: [0, 1, 2].map(|_| Raster::filled(40, 24, g / 3.0)),
            white_gain: Raster::filled(40, 24, g),
        };
        let frames: Vec<Raster<f32>> = patterns
            .iter()
            .map(|p| Raster {
                width: 40,
                height: 24,
                data: p.data.iter().map(|v| 0.1 + 0.6 * v).collect(),
            })
            .collect();
        let uv = decode_matching(&frames, &lit(0.6), dmd, &params).unwrap();
        for y in 0..24 {
            for x in 0..40 {
                assert_eq!(*uv.at(x, y), [x as f32, y as f32], "({x}, {y})");
            }
        }
        // A pixel full white barely lights is not matched.
        let uv = decode_matching(&frames, &lit(0.01), dmd, &params).unwrap();
        assert!(uv.data.iter().all(|q| !is_mapped(q)));
        // A pixel straddling a column block edge (half of each neighbour's
        // light) lands within a block of its column.
        let mut blurred = frames.clone();
        for f in &mut blurred {
            let (a, b) = (f.data[7], f.data[8]);
            f.data[8] = 0.5 * (a + b);
        }
        let uv = decode_matching(&blurred, &lit(0.6), dmd, &params).unwrap();
        assert!((uv.data[8][0] - 8.0).abs() <= 4.0, "{:?}", uv.data[8]);
        assert!(matches!(
            decode_matching(&frames[1..], &lit(0.6), dmd, &params),
            Err(AdaptiveError::MatchingCount { got: 27, need: 28 })
        ));
    }

    #[test]
    fn texture_colour_follows_the_surface_and_white_gives_more_gain() {
        // One red pixel (0.5 red, 0.02 green / blue at full level) and one
        // white pixel, dark 0.05, seen one to one by the DMD.
        let px = |v: [f32; 2]| Raster::from_vec(2, 1, v.to_vec()).unwrap();
        let floods = vec![
            px([0.05, 0.05]),
            px([0.05 + GREY_FLOOD * 0.54, 0.05 + GREY_FLOOD * 0.9]),
            px([0.55, 0.35]),
            px([0.07, 0.35]),
            px([0.07, 0.35]),
        ];
        let response = colour_response(&floods, 0.995).unwrap();
        assert!((response.band_gain[0].data[0] - 0.5).abs() < 1e-5);
        assert!((response.white_gain.data[1] - 0.9).abs() < 1e-4);
        let uv = Raster::from_vec(2, 1, vec![[0.0, 0.0], [1.0, 0.0]]).unwrap();
        let mut params = ColourParams {
            grow_px: 0,
            ..ColourParams::default()
        };
        params.rule.range = (1.0, 1.0);
        let texture = adapt_colour(&response, &uv, (2, 1), &[2.0], 3, 0.0, &params).unwrap();
        // The red pixel gets red (and a little of the others): its gain
        // 0.5 + 2 x 0.04 x 0.02 holds the target without lowering; the
        // white pixel (gain 0.9 + 0.05) is lowered to 0.8 / 0.9.
        let red = texture.projector_levels.clone().map(|m| m.data[0]);
        assert_eq!(red[0], 1.0);
        assert!(red[1] < 0.05 && red[2] < 0.05, "{red:?}");
        let white = texture.projector_levels.clone().map(|m| m.data[1]);
        assert!(
            white
                .iter()
                .all(|&v| (v - white[0]).abs() < 1e-6 && v < 0.95),
            "{white:?}"
        );
        assert_eq!(texture.patterns.len(), 3 * 3);
        params.choice = ColourChoice::White;
        let white_choice = adapt_colour(&response, &uv, (2, 1), &[2.0], 3, 0.0, &params).unwrap();
        let red_white = white_choice.projector_levels.map(|m| m.data[0]);
        assert_eq!(red_white, [1.0; 3]);
    }
}
