//! FDD-Net (seed 001's third stage, compact for 2 cores) on tract: each
//! pattern's wrapped phase corrected by a network that sees every pattern's
//! demodulated baseband at once.
//!
//! The analytic demodulation low-passes each pattern's baseband with a
//! window narrow enough to keep its LED's seven other directions out; on a
//! small curved surface that window flattens the surface's own phase (the
//! `highspeed_error_sources` example). The 24 windows point different ways,
//! so together the 24 basebands keep more of the surface than any one; the
//! network reads them all and gives, per pattern, the numerator and
//! denominator of a correction in that pattern's baseband, from one trunk
//! into eight direction experts (one per fringe direction, its three LEDs'
//! patterns each).
//!
//! ```text
//! in  (72): per pattern m, cos and sin of its demodulated baseband phase
//!           (wrapped phase minus carrier phase), then per pattern its
//!           modulation over its LED's zero order per pattern (capped at 2)
//! out (48): per pattern m, numerator N_m and denominator D_m; the phase is
//!           wrapped phase + atan2(N_m, D_m)
//! ```

use std::path::Path;

use super::demux::{Demultiplexed, Demultiplexer};
use super::learned::{self, LearnedStage};
use super::set::PatternSet;
use super::HighSpeedError;
use crate::infer::tiles::{infer_tiled, Planes};
use crate::infer::{Model, ModelError};
use crate::phase::wrap_pi;

/// Patterns of the set the network is built for.
pub const PATTERNS: usize = 24;
/// Channels in: a baseband phase's cosine and sine, then a modulation ratio, per pattern.
pub const IN_CHANNELS: usize = 3 * PATTERNS;
/// Channels out: a numerator and a denominator per pattern.
pub const OUT_CHANNELS: usize = 2 * PATTERNS;
/// The largest modulation ratio fed in (a pixel's fringe as deep as its
/// zero order allows is 1; brighter glints are clipped).
const MAX_RATIO: f32 = 2.0;
/// Tiles overlap by this much (the network sees about 63 px).
const TILE_OVERLAP_PX: usize = 32;

/// The network's input planes for one demultiplexed exposure
/// ([`IN_CHANNELS`] planes, row-major, channel-major): 0 where a pattern
/// has no phase.
pub fn condition(demux: &Demultiplexer, set: &PatternSet, fringes: &Demultiplexed) -> Vec<f32> {
    let n = fringes.wrapped.first().map_or(0, Vec::len);
    let per_led = set.directions() as f32;
    let mut planes = vec![0.0f32; IN_CHANNELS * n];
    for (m, pattern) in set.patterns().iter().enumerate() {
        let carrier = demux.carrier(m);
        let zero = &fringes.zero_order[pattern.colour];
        let (trig, rest) = planes.split_at_mut(2 * PATTERNS * n);
        let (cos, sin) = trig[2 * m * n..(2 * m + 2) * n].split_at_mut(n);
        let ratio = &mut rest[m * n..(m + 1) * n];
        for i in 0..n {
            let base = fringes.wrapped[m][i] - carrier[i];
            if base.is_finite() {
                (sin[i], cos[i]) = base.sin_cos();
            }
            let r = fringes.modulation[m][i] * per_led / zero[i];
            ratio[i] = if r.is_finite() && zero[i] > 0.0 {
                r.clamp(0.0, MAX_RATIO)
            } else {
                0.0
            };
        }
    }
    planes
}

/// A loaded FDD-Net.
#[derive(Clone, Debug)]
pub struct FddNet {
    model: Model,
}

impl LearnedStage for FddNet {
    const NAME: &'static str = "FDD-Net";
    const TILE_OVERLAP_PX: usize = TILE_OVERLAP_PX;

    fn model(&self) -> &Model {
        &self.model
    }
}

impl FddNet {
    /// Loads `onnx` (and its metadata) and checks it was trained for `set`'s
    /// patterns (their DMD periods, in order) with this channel layout.
    pub fn load(onnx: &Path, set: &PatternSet) -> Result<Self, HighSpeedError> {
        if set.patterns().len() != PATTERNS {
            return Err(HighSpeedError::BadPatternSet {
                why: format!(
                    "FDD-Net takes a set of {PATTERNS} patterns, this one has {}",
                    set.patterns().len()
                ),
            });
        }
        Ok(Self {
            model: learned::load_stage(onnx, set, "FDD-Net", IN_CHANNELS, OUT_CHANNELS)?,
        })
    }

    /// Every pattern's wrapped phase corrected (radians in (-pi, pi]; NaN
    /// where the demultiplexer gave none).
    pub fn correct(
        &self,
        demux: &Demultiplexer,
        set: &PatternSet,
        fringes: &Demultiplexed,
        width: usize,
        height: usize,
    ) -> Result<Vec<Vec<f32>>, ModelError> {
        let plane = width * height;
        let data = condition(demux, set, fringes);
        let planes = Planes {
            data: &data,
            channels: IN_CHANNELS,
            width,
            height,
        };
        let tiled = infer_tiled(
            &planes,
            &vec![true; plane],
            self.model.meta.tile,
            Self::TILE_OVERLAP_PX,
            OUT_CHANNELS,
            |_, tile| self.model.run(&[tile]),
        )?;
        Ok((0..PATTERNS)
            .map(|m| {
                let num = &tiled.data[2 * m * plane..(2 * m + 1) * plane];
                let den = &tiled.data[(2 * m + 1) * plane..(2 * m + 2) * plane];
                fringes.wrapped[m]
                    .iter()
                    .zip(num.iter().zip(den))
                    .map(|(&a, (&y, &x))| wrap_pi(a + y.atan2(x)))
                    .collect()
            })
            .collect())
    }
}
