//! Seed 001's 24 patterns as the decoder needs them: for each pattern its
//! LED, its fringe frequency on the DMD and its place in the projection order.

use super::HighSpeedError;
use crate::patterns::binary::{binarize, Binarize};
use crate::patterns::tfc::{theta_deg, TfcSpec};
use crate::raster::Raster;
use crate::rig::Led;

/// One pattern of the set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SetPattern {
    /// Place in the projection order (m - 1 of seed 001: 0..24).
    pub index: usize,
    /// Direction n, from 1.
    pub direction: u32,
    /// LED: 0 = R, 1 = G, 2 = B.
    pub colour: usize,
    /// Fringe frequency on the DMD, cycles per pixel along (u, v): the pattern's
    /// phase at DMD pixel (u, v) is `2 pi (f_u u + f_v v)`.
    pub frequency: [f64; 2],
}

/// The multiplexed set of one head: a [`TfcSpec`] on a DMD.
#[derive(Clone, Debug, PartialEq)]
pub struct PatternSet {
    spec: TfcSpec,
    dmd_px: (u32, u32),
    patterns: Vec<SetPattern>,
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

fn lcm(periods: &[f64; 3]) -> Option<u64> {
    periods.iter().try_fold(1u64, |acc, &p| {
        let p = (p.fract() == 0.0 && p >= 1.0).then_some(p as u64)?;
        Some(acc / gcd(acc, p) * p)
    })
}

impl PatternSet {
    /// Seed 001's set (theta_0 = 18 deg, lambda_x R/G/B 23/18/21, lambda_y 18/13/15)
    /// on a DMD of `dmd_px`.
    pub fn seed001(dmd_px: (u32, u32)) -> Result<Self, HighSpeedError> {
        Self::new(TfcSpec::seed001(), dmd_px)
    }

    /// A set on a DMD of `dmd_px`; refused unless eq. 4 holds (each axis' LCM of the
    /// three periods covers the DMD, so the three frequencies pin the position).
    pub fn new(spec: TfcSpec, dmd_px: (u32, u32)) -> Result<Self, HighSpeedError> {
        let covers =
            |periods: &[f64; 3], extent: u32| lcm(periods).is_some_and(|l| l >= u64::from(extent));
        if spec.directions == 0
            || !covers(&spec.periods_x_px, dmd_px.0)
            || !covers(&spec.periods_y_px, dmd_px.1)
        {
            return Err(HighSpeedError::BadPatternSet {
                why: format!(
                    "{} directions, periods x {:?} / y {:?} px: need integer periods whose LCM covers the {}x{} DMD (seed 001 eq. 4)",
                    spec.directions, spec.periods_x_px, spec.periods_y_px, dmd_px.0, dmd_px.1
                ),
            });
        }
        let patterns = (1..=spec.directions)
            .flat_map(|n| {
                let t = theta_deg(n, spec.theta0_deg).to_radians();
                (0..3).map(move |c| (n, c, t))
            })
            .enumerate()
            .map(|(index, (direction, colour, t))| SetPattern {
                index,
                direction,
                colour,
                frequency: [
                    t.cos() / spec.periods_x_px[colour],
                    t.sin() / spec.periods_y_px[colour],
                ],
            })
            .collect();
        Ok(Self {
            spec,
            dmd_px,
            patterns,
        })
    }

    /// The patterns in projection order.
    pub fn patterns(&self) -> &[SetPattern] {
        &self.patterns
    }

    /// The pattern family.
    pub fn spec(&self) -> &TfcSpec {
        &self.spec
    }

    /// The DMD the set is made for.
    pub fn dmd_px(&self) -> (u32, u32) {
        self.dmd_px
    }

    /// Number of directions M.
    pub fn directions(&self) -> usize {
        self.spec.directions as usize
    }

    /// The pattern of direction `n` (from 1) and `colour`.
    pub fn pattern(&self, n: u32, colour: usize) -> &SetPattern {
        &self.patterns[(n as usize - 1) * 3 + colour]
    }

    /// The grey sinusoidal fringes (0..1) the binary frames are cut from, in
    /// projection order: what a DMD would show if it could show grey at the
    /// set's rate (the twin can; the error-source ablations use them).
    pub fn grey_frames(&self) -> Vec<Raster<f32>> {
        let (w, h) = (self.dmd_px.0 as usize, self.dmd_px.1 as usize);
        self.patterns
            .iter()
            .map(|p| {
                Raster::from_fn(w, h, |u, v| {
                    (0.5 + 0.5 * Self::phase_at(p, u as f64, v as f64).cos()) as f32
                })
            })
            .collect()
    }

    /// The 1-bit DMD frames (0 or 1) in projection order: each grey fringe cut at
    /// one half (binary defocusing: the projector's defocus and the camera's pixels
    /// round the square wave; its odd harmonics lie far from every carrier).
    pub fn binary_frames(&self) -> Vec<Raster<f32>> {
        self.grey_frames()
            .iter()
            .map(|grey| {
                let bits = binarize(grey, Binarize::Threshold);
                Raster {
                    width: grey.width,
                    height: grey.height,
                    data: bits.data.iter().map(|&b| f32::from(u8::from(b))).collect(),
                }
            })
            .collect()
    }

    /// Each pattern's LED, in projection order.
    pub fn leds(&self) -> Vec<Led> {
        self.patterns
            .iter()
            .map(|p| {
                let mut led = [0.0; 3];
                led[p.colour] = 1.0;
                led
            })
            .collect()
    }

    /// The pattern's phase at DMD pixel (u, v), radians (pixel centres at integers,
    /// as [`crate::patterns::tfc::tfc_phase`]).
    pub fn phase_at(p: &SetPattern, u: f64, v: f64) -> f64 {
        std::f64::consts::TAU * (p.frequency[0] * u + p.frequency[1] * v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::patterns::tfc::tfc_phase;

    #[test]
    fn seed_set_matches_the_pattern_family() {
        let set = PatternSet::seed001((912, 1140)).unwrap();
        assert_eq!(set.patterns().len(), 24);
        for p in set.patterns() {
            let want = tfc_phase(set.spec(), p.direction, p.colour, 37.0, 91.0);
            assert!((PatternSet::phase_at(p, 37.0, 91.0) - want).abs() < 1e-9);
        }
        // Projection order: R, G, B of direction 1, then direction 2, ...
        assert_eq!(set.pattern(2, 1).index, 4);
        assert_eq!(set.leds()[5], [0.0, 0.0, 1.0]);
        let frames = set.binary_frames();
        assert_eq!(frames.len(), 24);
        assert!(frames[0].data.iter().all(|&v| v == 0.0 || v == 1.0));
        let mean = frames[0].data.iter().sum::<f32>() / frames[0].data.len() as f32;
        assert!((mean - 0.5).abs() < 0.02, "{mean}");
    }

    #[test]
    fn a_set_whose_periods_cannot_cover_the_dmd_is_refused() {
        let mut spec = TfcSpec::seed001();
        spec.periods_y_px = [12.0, 6.0, 4.0];
        let err = PatternSet::new(spec, (912, 1140)).unwrap_err();
        assert!(err.to_string().contains("eq. 4"), "{err}");
        let mut spec = TfcSpec::seed001();
        spec.periods_x_px = [23.5, 18.0, 21.0];
        assert!(PatternSet::new(spec, (912, 1140)).is_err());
    }
}
