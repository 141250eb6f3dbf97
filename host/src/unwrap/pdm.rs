//! Projection distance minimisation (PDM): number-theoretic temporal unwrapping.
//!
//! For integer periods whose least common multiple covers the field (seed 001 eq. 4:
//! `LCM(23, 21, 18) = 2898 >= 912`), the wrapped phases of all periods pin down `u`.
//! Every candidate order `k_0` of the finest period gives `u_0`; each other period takes
//! the order nearest to it; the candidate whose per-period positions agree best (least
//! squares distance in cycles, each period weighted by its phase noise) wins. This is the
//! exhaustive form of Petković et al.'s projection onto the line of consistent phases.
//!
//! A pixel is unreliable when its best candidate's RMS disagreement exceeds half of the
//! *separation* of the period set: the smallest disagreement any wrong candidate has
//! without noise, computed once in [`Pdm::new`].

use rayon::prelude::*;

use super::{same_size, AbsolutePhase, PixelStatus, UnwrapError};
use crate::raster::Raster;

/// Largest number of periods.
pub const MAX_PERIODS: usize = 8;

/// A PDM unwrapper for one period set and field.
#[derive(Clone, Debug, PartialEq)]
pub struct Pdm {
    periods_px: Vec<f64>,
    range_px: f64,
    separation_cycles: f64,
    max_rms_cycles: f64,
}

/// Outcome of the candidate search at one pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PdmCandidate {
    /// Fringe order of the finest period.
    pub order: i32,
    /// RMS disagreement of the best candidate, cycles.
    pub rms_cycles: f64,
    /// RMS disagreement of the runner-up, cycles.
    pub runner_up_rms_cycles: f64,
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

impl Pdm {
    /// Sets up for integer `periods_px` (finest first: the result is the absolute phase
    /// of `periods_px[0]`) over a field of `range_px` pixels.
    pub fn new(periods_px: &[u32], range_px: f64) -> Result<Self, UnwrapError> {
        let k = periods_px.len();
        if !(2..=MAX_PERIODS).contains(&k) {
            return Err(UnwrapError::NotEnoughInputs {
                method: "pdm",
                got: k,
                need: 2,
            });
        }
        let as_f64: Vec<f64> = periods_px.iter().map(|&p| f64::from(p)).collect();
        let distinct = (0..k).all(|i| (i + 1..k).all(|j| periods_px[i] != periods_px[j]));
        if periods_px.contains(&0) || !distinct {
            return Err(UnwrapError::BadPeriods { periods_px: as_f64 });
        }
        let lcm = periods_px
            .iter()
            .fold(1u64, |acc, &p| acc / gcd(acc, u64::from(p)) * u64::from(p));
        if (lcm as f64) < range_px {
            return Err(UnwrapError::RangeTooShort {
                periods_px: as_f64,
                unambiguous_px: lcm as f64,
                range_px,
            });
        }
        let mut pdm = Self {
            periods_px: as_f64,
            range_px,
            separation_cycles: 0.0,
            max_rms_cycles: f64::INFINITY,
        };
        // Separation: scan the field noise-free, keep the closest runner-up.
        let tau = std::f64::consts::TAU;
        let mut separation = f64::INFINITY;
        let mut u = 0.0;
        while u < range_px {
            let w: Vec<f32> = pdm
                .periods_px
                .iter()
                .map(|p| crate::phase::wrap_pi((tau * u / p) as f32))
                .collect();
            separation = separation.min(pdm.search(&w).runner_up_rms_cycles);
            u += 0.5;
        }
        pdm.separation_cycles = separation;
        pdm.max_rms_cycles = separation / 2.0;
        Ok(pdm)
    }

    /// Smallest noise-free RMS disagreement of a wrong candidate, cycles.
    pub fn separation_cycles(&self) -> f64 {
        self.separation_cycles
    }

    /// Largest wrapped-phase noise (radians, same on every period) at which a wrong
    /// order stays `order_sigmas` standard deviations away: half the separation, as a
    /// distance over all periods, over `order_sigmas`. Pixels noisier than this (low
    /// modulation) must be masked by the caller: like heterodyne's, a miscount can pass
    /// the consistency check.
    pub fn max_phase_sigma_rad(&self, order_sigmas: f64) -> f64 {
        let n = self.periods_px.len() as f64;
        std::f64::consts::TAU * self.separation_cycles * n.sqrt() / 2.0 / order_sigmas
    }

    /// Searches all orders of the finest period for one pixel's wrapped phases.
    pub fn search(&self, wrapped: &[f32]) -> PdmCandidate {
        let tau = std::f64::consts::TAU;
        let p0 = self.periods_px[0];
        let frac0 = f64::from(wrapped[0]) / tau;
        let k_max = (self.range_px / p0).ceil() as i32 + 1;
        let weights: Vec<f64> = self.periods_px.iter().map(|p| 1.0 / (p * p)).collect();
        let weight_sum: f64 = weights.iter().sum();
        let mut best = (i32::MIN, f64::INFINITY);
        let mut second = f64::INFINITY;
        for k0 in -1..=k_max {
            let u0 = (frac0 + f64::from(k0)) * p0;
            if u0 < -0.5 * p0 || u0 > self.range_px + 0.5 * p0 {
                continue;
            }
            let mut positions = [0.0f64; MAX_PERIODS];
            positions[0] = u0;
            for (i, p) in self.periods_px.iter().enumerate().skip(1) {
                let frac = f64::from(wrapped[i]) / tau;
                let ki = (u0 / p - frac).round();
                positions[i] = (frac + ki) * p;
            }
            let n = self.periods_px.len();
            let mean = (0..n).map(|i| positions[i] * weights[i]).sum::<f64>() / weight_sum;
            let cost = (0..n)
                .map(|i| ((positions[i] - mean) / self.periods_px[i]).powi(2))
                .sum::<f64>()
                / n as f64;
            if cost < best.1 {
                second = best.1;
                best = (k0, cost);
            } else if cost < second {
                second = cost;
            }
        }
        PdmCandidate {
            order: best.0,
            rms_cycles: best.1.sqrt(),
            runner_up_rms_cycles: second.sqrt(),
        }
    }

    /// Absolute phase of the finest period at one pixel; `None` when unreliable.
    pub fn unwrap_pixel(&self, wrapped: &[f32]) -> Option<f32> {
        let c = self.search(wrapped);
        (c.rms_cycles <= self.max_rms_cycles)
            .then(|| wrapped[0] + std::f32::consts::TAU * c.order as f32)
    }

    /// Unwraps whole maps (same order as the periods); pixels outside `mask` are masked.
    pub fn unwrap(
        &self,
        wrapped: &[&Raster<f32>],
        mask: Option<&Raster<bool>>,
    ) -> Result<AbsolutePhase, UnwrapError> {
        if wrapped.len() != self.periods_px.len() {
            return Err(UnwrapError::WrongInputCount {
                method: "pdm",
                expected: self.periods_px.len(),
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
        let results: Vec<(f32, PixelStatus)> = (0..width * height)
            .into_par_iter()
            .map(|i| {
                if mask.is_some_and(|m| !m.data[i]) {
                    return (f32::NAN, PixelStatus::Masked);
                }
                let mut w = [0.0f32; MAX_PERIODS];
                for (slot, map) in w.iter_mut().zip(wrapped) {
                    *slot = map.data[i];
                }
                match self.unwrap_pixel(&w) {
                    Some(v) => (v, PixelStatus::Valid),
                    None => (f32::NAN, PixelStatus::Unreliable),
                }
            })
            .collect();
        let (phase, status): (Vec<f32>, Vec<PixelStatus>) = results.into_iter().unzip();
        Ok(AbsolutePhase {
            phase: Raster {
                width,
                height,
                data: phase,
            },
            status: Raster {
                width,
                height,
                data: status,
            },
            period_px: self.periods_px[0],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::wrap_pi;
    use std::f64::consts::TAU;

    fn wrapped_at(periods: &[u32], u: f64) -> Vec<f32> {
        periods
            .iter()
            .map(|&p| wrap_pi((TAU * u / f64::from(p)) as f32))
            .collect()
    }

    #[test]
    fn seed_001_periods_unwrap_the_whole_dmd() {
        // Finest first: x periods 18/21/23 over 912 columns, y periods 13/15/18 over 1140 rows.
        for (periods, range) in [([18u32, 21, 23], 912.0), ([13, 15, 18], 1140.0)] {
            let pdm = Pdm::new(&periods, range).unwrap();
            // 18/21/23: u and u + 252 differ by one pixel on the 23 px period only, so a wrong
            // order sits just 0.0216 cycles RMS away; 13/15/18 is similar. Both positive.
            assert!(
                pdm.separation_cycles() > 0.015,
                "{}",
                pdm.separation_cycles()
            );
            let mut u = 0.0;
            while u < range - 0.5 {
                let got = pdm
                    .unwrap_pixel(&wrapped_at(&periods, u))
                    .expect("reliable");
                let want = (TAU * u / f64::from(periods[0])) as f32;
                assert!((got - want).abs() < 1e-3 * want.abs().max(1.0), "u={u}");
                u += 0.7;
            }
        }
    }

    #[test]
    fn inconsistent_phases_are_flagged() {
        let pdm = Pdm::new(&[18, 21, 23], 912.0).unwrap();
        let mut w = wrapped_at(&[18, 21, 23], 300.0);
        w[2] = wrap_pi(w[2] + 2.0);
        assert_eq!(pdm.unwrap_pixel(&w), None);
    }

    #[test]
    fn lcm_must_cover_the_field() {
        assert!(matches!(
            Pdm::new(&[6, 9], 100.0),
            Err(UnwrapError::RangeTooShort { unambiguous_px, .. }) if unambiguous_px == 18.0
        ));
        assert!(matches!(
            Pdm::new(&[6, 6], 10.0),
            Err(UnwrapError::BadPeriods { .. })
        ));
    }
}
