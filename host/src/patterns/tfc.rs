//! Seed 001's triple-frequency colour-multiplexed (TFCMFPP) patterns.
//!
//! M = 8 directions `theta_n = (-1)^(n+1) (n/2 - ((-1)^n + 1)/4) theta_0` (eq. 3,
//! n = 1..8: +-9, +-27, +-45, +-63 degrees for theta_0 = 18); each direction carries three
//! frequencies on R, G, B (eq. 2):
//! `I = a + b cos(2 pi x cos(theta_n) / lambda_x + 2 pi y sin(theta_n) / lambda_y)`
//! with `lambda_x` R/B/G = 23/21/18 and `lambda_y` R/B/G = 18/15/13 pixels.

use crate::raster::Raster;

/// Periods and angle of a TFC pattern family.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TfcSpec {
    /// Number of directions M.
    pub directions: u32,
    /// Angular step theta_0, degrees.
    pub theta0_deg: f64,
    /// `lambda_x` for R, G, B, pixels.
    pub periods_x_px: [f64; 3],
    /// `lambda_y` for R, G, B, pixels.
    pub periods_y_px: [f64; 3],
    /// Background a.
    pub background: f32,
    /// Amplitude b.
    pub amplitude: f32,
}

impl TfcSpec {
    /// The values of seed 001 (R/G/B: lambda_x 23/18/21, lambda_y 18/13/15).
    pub fn seed001() -> Self {
        Self {
            directions: 8,
            theta0_deg: 18.0,
            periods_x_px: [23.0, 18.0, 21.0],
            periods_y_px: [18.0, 13.0, 15.0],
            background: 0.5,
            amplitude: 0.5,
        }
    }
}

/// `theta_n` of eq. 3 in degrees, `n` from 1.
pub fn theta_deg(n: u32, theta0_deg: f64) -> f64 {
    let sign = if !n.is_multiple_of(2) { 1.0 } else { -1.0 }; // (-1)^(n+1)
    let even = if n.is_multiple_of(2) { 1.0 } else { 0.0 }; // ((-1)^n + 1) / 2
    sign * (f64::from(n) / 2.0 - even / 2.0) * theta0_deg
}

/// Phase of direction `n` (from 1) and channel `c` (0 = R, 1 = G, 2 = B) at a pixel.
pub fn tfc_phase(spec: &TfcSpec, n: u32, channel: usize, x: f64, y: f64) -> f64 {
    let t = theta_deg(n, spec.theta0_deg).to_radians();
    std::f64::consts::TAU
        * (x * t.cos() / spec.periods_x_px[channel] + y * t.sin() / spec.periods_y_px[channel])
}

/// The M RGB patterns (channel order R, G, B).
pub fn tfc_patterns(spec: &TfcSpec, width_px: u32, height_px: u32) -> Vec<Raster<[f32; 3]>> {
    (1..=spec.directions)
        .map(|n| {
            Raster::from_fn(width_px as usize, height_px as usize, |x, y| {
                [0, 1, 2].map(|c| {
                    let p = tfc_phase(spec, n, c, x as f64, y as f64);
                    spec.background + spec.amplitude * p.cos() as f32
                })
            })
        })
        .collect()
}

/// One channel of each pattern as its own grey frame, in projection order
/// (m = 3n - 2, 3n - 1, 3n for R, G, B): the 3M frames a DMD shows in binary mode.
pub fn tfc_channel_frames(patterns: &[Raster<[f32; 3]>]) -> Vec<Raster<f32>> {
    patterns
        .iter()
        .flat_map(|p| {
            (0..3).map(move |c| Raster {
                width: p.width,
                height: p.height,
                data: p.data.iter().map(|v| v[c]).collect(),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eq3_angles() {
        let angles: Vec<f64> = (1..=8).map(|n| theta_deg(n, 18.0)).collect();
        assert_eq!(
            angles,
            vec![9.0, -9.0, 27.0, -27.0, 45.0, -45.0, 63.0, -63.0]
        );
    }

    #[test]
    fn patterns_have_the_stated_periods() {
        let spec = TfcSpec::seed001();
        let pats = tfc_patterns(&spec, 64, 48);
        assert_eq!(pats.len(), 8);
        assert_eq!(tfc_channel_frames(&pats).len(), 24);
        // Moving lambda_x / cos(theta) along x returns the same value (one full cycle).
        let t = theta_deg(1, 18.0).to_radians();
        let dx = spec.periods_x_px[0] / t.cos();
        let a = tfc_phase(&spec, 1, 0, 3.0, 5.0);
        let b = tfc_phase(&spec, 1, 0, 3.0 + dx, 5.0);
        assert!((b - a - std::f64::consts::TAU).abs() < 1e-9);
    }
}
