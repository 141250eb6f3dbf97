//! Which camera pixels both projectors light, measured from three
//! flat-field exposures that every camera takes: both projectors dark,
//! projector A alone full on, projector B alone full on.
//!
//! A pixel counts as lit by a projector when that projector's flat field
//! raises it above the dark frame by more than [`AliasParams::relative`]
//! of the pixel's own brighter flat-field signal (so a dim surface is
//! judged against its own albedo) and by more than
//! [`AliasParams::floor`] (full-scale units, so sensor noise on a pixel
//! neither lights cannot count). Pixels lit by both are aliased in the
//! simultaneous mode: their fringes are the sum of two unrelated phases;
//! pixels lit by the other head's projector alone show fringes a camera
//! would decode with the wrong projector. Both are masked.

use crate::raster::Raster;

/// Thresholds of [`unusable_mask`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AliasParams {
    /// Least share of the pixel's brighter flat-field signal (above dark)
    /// the weaker projector must add to count as lighting it. 0.05: the
    /// other head's fringes at 5 % of the own modulation shift the phase
    /// by up to 0.05 rad, several times the noise-limited phase error.
    pub relative: f32,
    /// Least signal above dark, full-scale units (about 40 sigma of the
    /// 12-bit twin sensor's read noise, 5 sigma of shot noise at 5 %).
    pub floor: f32,
    /// Grow the mask by this many pixels (square), for the blurred light
    /// edge just under the threshold.
    pub grow_px: usize,
}

impl Default for AliasParams {
    fn default() -> Self {
        AliasParams {
            relative: 0.05,
            floor: 0.01,
            grow_px: 1,
        }
    }
}

/// The flat-field frames of one camera.
#[derive(Clone, Debug)]
pub struct FlatFields {
    /// Both projectors dark.
    pub dark: Raster<f32>,
    /// Projector A full on, B dark.
    pub lit_a: Raster<f32>,
    /// Projector B full on, A dark.
    pub lit_b: Raster<f32>,
}

impl FlatFields {
    /// (own projector on, other projector on) for head `own`'s camera.
    pub fn own_other(&self, own: usize) -> (&Raster<f32>, &Raster<f32>) {
        if own == 0 {
            (&self.lit_a, &self.lit_b)
        } else {
            (&self.lit_b, &self.lit_a)
        }
    }
}

/// Which pixels each projector lights, by the flat fields.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Lighting {
    /// Lit by projector A.
    pub lit_a: Vec<bool>,
    /// Lit by projector B.
    pub lit_b: Vec<bool>,
}

impl Lighting {
    /// Lit by both: the aliased overlap.
    pub fn both(&self) -> Vec<bool> {
        self.lit_a
            .iter()
            .zip(&self.lit_b)
            .map(|(&a, &b)| a && b)
            .collect()
    }
}

impl Lighting {
    /// The pixels head `own`'s projector lights.
    pub fn lit_by(&self, own: usize) -> &[bool] {
        if own == 0 {
            &self.lit_a
        } else {
            &self.lit_b
        }
    }
}

/// Each projector's lit pixels (before growing).
pub fn lighting(flat: &FlatFields, params: &AliasParams) -> Lighting {
    let (lit_a, lit_b) = flat
        .dark
        .data
        .iter()
        .zip(&flat.lit_a.data)
        .zip(&flat.lit_b.data)
        .map(|((&d, &a), &b)| {
            let (sa, sb) = (a - d, b - d);
            let threshold = (params.relative * sa.max(sb)).max(params.floor);
            // NaN signals compare false: a broken pixel lights nothing.
            (sa > threshold, sb > threshold)
        })
        .unzip();
    Lighting { lit_a, lit_b }
}

/// The pixels of head `head`'s camera (0 = A) that must be masked in the
/// simultaneous mode: every pixel the *other* head's projector lights,
/// grown by [`AliasParams::grow_px`]. That is the aliased overlap (lit by
/// both) and also the pixels lit by the other projector alone, whose
/// fringes the camera would decode with the wrong projector's geometry.
pub fn unusable_mask(flat: &FlatFields, head: usize, params: &AliasParams) -> Vec<bool> {
    camera_lighting(flat, head, params).unusable
}

/// One camera's lighting by the flat fields and its [`unusable_mask`],
/// from one pass over the flat fields.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CameraLighting {
    /// Which pixels each projector lights.
    pub lit: Lighting,
    /// Every pixel the other head's projector lights, grown.
    pub unusable: Vec<bool>,
}

/// [`lighting`] and [`unusable_mask`] of head `head`'s camera together.
pub fn camera_lighting(flat: &FlatFields, head: usize, params: &AliasParams) -> CameraLighting {
    let lit = lighting(flat, params);
    let other = lit.lit_by(1 - head);
    let unusable = dilate(other, flat.dark.width, flat.dark.height, params.grow_px);
    CameraLighting { lit, unusable }
}

/// How a measured mask agrees with a true one.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MaskAgreement {
    /// Pixels in the measured mask.
    pub measured: usize,
    /// Pixels in the true mask.
    pub truth: usize,
    /// |measured AND truth| / |measured OR truth| (1 when both are empty).
    pub iou: f64,
    /// Share of the true pixels the measured mask holds (1 when none).
    pub recall: f64,
}

/// Agreement of `measured` with `truth` (same length).
pub fn agreement(measured: &[bool], truth: &[bool]) -> MaskAgreement {
    let (mut both, mut either) = (0usize, 0usize);
    for (&m, &t) in measured.iter().zip(truth) {
        both += usize::from(m && t);
        either += usize::from(m || t);
    }
    let count = |v: &[bool]| v.iter().filter(|&&b| b).count();
    let truth_n = count(truth);
    MaskAgreement {
        measured: count(measured),
        truth: truth_n,
        iou: if either == 0 {
            1.0
        } else {
            both as f64 / either as f64
        },
        recall: if truth_n == 0 {
            1.0
        } else {
            both as f64 / truth_n as f64
        },
    }
}

/// `mask` grown by `radius` pixels (square neighbourhood).
pub(crate) fn dilate(mask: &[bool], width: usize, height: usize, radius: usize) -> Vec<bool> {
    if radius == 0 {
        return mask.to_vec();
    }
    let mut out = vec![false; mask.len()];
    for y in 0..height {
        for x in 0..width {
            if !mask[y * width + x] {
                continue;
            }
            for yy in y.saturating_sub(radius)..(y + radius + 1).min(height) {
                for xx in x.saturating_sub(radius)..(x + radius + 1).min(width) {
                    out[yy * width + xx] = true;
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raster(values: &[f32]) -> Raster<f32> {
        Raster {
            width: values.len(),
            height: 1,
            data: values.to_vec(),
        }
    }

    #[test]
    fn only_pixels_both_projectors_raise_are_aliased() {
        // Pixels: both lit, A only, B only, neither (noise), dim surface lit
        // by both, B adding 2 % of A (below the 5 % share), broken (NaN).
        let flat = FlatFields {
            dark: raster(&[0.02, 0.02, 0.02, 0.02, 0.02, 0.02, f32::NAN]),
            lit_a: raster(&[0.6, 0.6, 0.021, 0.025, 0.05, 0.62, 0.5]),
            lit_b: raster(&[0.4, 0.021, 0.5, 0.024, 0.045, 0.032, 0.5]),
        };
        let params = AliasParams {
            grow_px: 0,
            ..AliasParams::default()
        };
        let l = lighting(&flat, &params);
        assert_eq!(l.both(), [true, false, false, false, true, false, false]);
        assert_eq!(l.lit_b, [true, false, true, false, true, false, false]);
        // Camera A must drop what B lights, camera B what A lights.
        assert_eq!(unusable_mask(&flat, 0, &params), l.lit_b);
        assert_eq!(unusable_mask(&flat, 1, &params), l.lit_a);
    }

    #[test]
    fn growing_reaches_the_neighbours_and_agreement_counts_right() {
        let flat = FlatFields {
            dark: raster(&[0.0; 5]),
            lit_a: raster(&[0.5; 5]),
            lit_b: raster(&[0.0, 0.0, 0.5, 0.0, 0.0]),
        };
        let grown = unusable_mask(&flat, 0, &AliasParams::default());
        assert_eq!(grown, [false, true, true, true, false]);
        let truth = [false, false, true, true, true];
        let a = agreement(&grown, &truth);
        assert_eq!((a.measured, a.truth), (3, 3));
        assert!((a.iou - 2.0 / 4.0).abs() < 1e-12);
        assert!((a.recall - 2.0 / 3.0).abs() < 1e-12);
        assert_eq!(agreement(&[false], &[false]).iou, 1.0);
    }
}
