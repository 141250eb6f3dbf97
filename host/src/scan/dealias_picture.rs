//! What the simultaneous mode's de-aliasing did to one camera's frames, for
//! the pictures and the report: the first period's fringe frames as
//! captured (aliased where both projectors light the pixel) and as
//! de-aliased, beside the same frames of the own projector alone where the
//! simulator can render them, and the separated pixels' error against those.
//!
//! A de-aliaser recovers the own fringe's phase and modulation; the scan
//! re-centres every written pixel on its observed mean (both projectors'
//! light), so the error is taken on the fringe alone, each frame less its
//! pixel's mean over the period's steps (as `--example dealias_eval` scores
//! it over all periods).

use crate::raster::Raster;

/// One camera's first period of fringe frames before and after de-aliasing.
#[derive(Clone, Debug, PartialEq)]
pub struct DealiasSample {
    /// As captured, one frame per phase step.
    pub aliased: Vec<Raster<f32>>,
    /// As de-aliased: the own projector's fringe where the overlap was
    /// separated, 0 where it was masked.
    pub separated: Vec<Raster<f32>>,
    /// Pixels the flat fields show lit by both projectors.
    pub overlap: Vec<bool>,
    /// The same frames of the own projector alone, noise-free (the
    /// simulator's; `None` on hardware).
    pub reference: Option<Vec<Raster<f32>>>,
}

impl DealiasSample {
    /// The first de-aliased frame's fringe less the reference's, `|(s_0 -
    /// mean s) - (r_0 - mean r)|`, on the overlap pixels that were
    /// separated (masked ones are 0 in every step), NaN elsewhere; `None`
    /// without a reference of the same frames and size.
    pub fn error(&self) -> Option<Raster<f32>> {
        let reference = self.reference.as_ref()?;
        let first = reference.first()?;
        let pixels = first.data.len();
        let same = reference.len() == self.separated.len()
            && self.overlap.len() == pixels
            && reference
                .iter()
                .chain(&self.separated)
                .all(|f| f.size() == first.size());
        if !same {
            return None;
        }
        let mean = |frames: &[Raster<f32>], i: usize| {
            frames.iter().map(|f| f.data[i]).sum::<f32>() / frames.len() as f32
        };
        let data = (0..pixels)
            .map(|i| {
                let s0 = self.separated[0].data[i];
                let masked = self.separated.iter().all(|f| f.data[i] == 0.0);
                if !self.overlap[i] || masked || !s0.is_finite() {
                    return f32::NAN;
                }
                let fringe = s0 - mean(&self.separated, i);
                let truth = reference[0].data[i] - mean(reference, i);
                (fringe - truth).abs()
            })
            .collect();
        Some(Raster {
            width: first.width,
            height: first.height,
            data,
        })
    }

    /// RMS of [`Self::error`] over its pixels, on the 8-bit scale of seed
    /// 000's figures (full scale 255); `None` without a reference or a
    /// separated pixel.
    pub fn error_rms_8bit(&self) -> Option<f64> {
        let error = self.error()?;
        let (sum, n) = error
            .data
            .iter()
            .filter(|e| e.is_finite())
            .fold((0.0f64, 0usize), |(s, n), &e| {
                (s + f64::from(e * 255.0).powi(2), n + 1)
            });
        (n > 0).then(|| (sum / n as f64).sqrt())
    }
}

/// The picture file of head `tag`'s de-aliasing.
pub fn picture_file(tag: &str) -> String {
    format!("dealias_{tag}.png")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two steps of 4 pixels each.
    fn frames(steps: [[f32; 4]; 2]) -> Vec<Raster<f32>> {
        steps
            .iter()
            .map(|d| Raster {
                width: 4,
                height: 1,
                data: d.to_vec(),
            })
            .collect()
    }

    #[test]
    fn the_error_is_the_fringe_of_separated_overlap_pixels_only() {
        let sample = DealiasSample {
            aliased: frames([[0.9; 4]; 2]),
            // Pixel 0: the reference's fringe (+-0.1) on another mean and
            // 2/255 off; pixel 1 masked (0 in every step); pixel 2 exact;
            // pixel 3 outside the overlap.
            separated: frames([
                [0.6 + 2.0 / 255.0, 0.0, 0.35, 0.7],
                [0.4 - 2.0 / 255.0, 0.0, 0.25, 0.1],
            ]),
            overlap: vec![true, true, true, false],
            reference: Some(frames([[0.3, 0.4, 0.35, 0.1], [0.1, 0.4, 0.25, 0.1]])),
        };
        let e = sample.error().unwrap();
        assert!((e.data[0] - 2.0 / 255.0).abs() < 1e-6, "{:?}", e.data);
        assert!(e.data[1].is_nan() && e.data[3].is_nan());
        assert!(e.data[2].abs() < 1e-7);
        // RMS of 2 and 0 on the 8-bit scale.
        assert!((sample.error_rms_8bit().unwrap() - 2f64.sqrt()).abs() < 1e-3);
        let no_reference = DealiasSample {
            reference: None,
            ..sample.clone()
        };
        assert_eq!(no_reference.error_rms_8bit(), None);
        let wrong_size = DealiasSample {
            reference: Some(vec![Raster::filled(2, 2, 0.0); 2]),
            ..sample
        };
        assert!(wrong_size.error().is_none());
    }
}
