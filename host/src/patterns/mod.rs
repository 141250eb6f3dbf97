//! Pattern generation (encode): what the projectors show.
//!
//! All patterns are `Raster<f32>` intensities in [0, 1] over the projector's pixels,
//! pixel centres at integer coordinates. Fringes follow the DESIGN.md convention
//! `I_n = A + B cos(2 pi u / P + delta_n)`, `delta_n = 2 pi n / N`, so that the decoder
//! in [`crate::phase`] returns `phi = 2 pi u / P` (wrapped).
//!
//! - [`phase_shift_set`], [`multi_frequency_set`]: N-step sets in x or y at any period;
//!   the seed period sets are constants here ([`SEED000_PERIODS_PX`], ...).
//! - [`gray_code`]: row/column Gray codes with seed 004's one-pixel shifts.
//! - [`tfc`]: seed 001's 8-direction RGB triple-frequency patterns.
//! - [`binary`]: 1-bit versions for DMD binary mode and bit-plane packing.

pub mod binary;
pub mod gray_code;
pub mod tfc;

pub use crate::phase::ftp::FringeAxis;
use crate::raster::Raster;

/// Seed 000: four periods, 4-step.
pub const SEED000_PERIODS_PX: [f64; 4] = [100.0, 110.0, 120.0, 130.0];
/// Seed 002: frequencies 1/59, 1/64, 1/70 per pixel.
pub const SEED002_PERIODS_PX: [f64; 3] = [59.0, 64.0, 70.0];

/// One N-step fringe set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FringeSpec {
    /// Pattern width, projector pixels.
    pub width_px: u32,
    /// Pattern height, projector pixels.
    pub height_px: u32,
    /// Fringe period along `axis`, projector pixels.
    pub period_px: f64,
    /// Number of phase steps N (>= 3).
    pub steps: usize,
    /// Along which axis the phase grows.
    pub axis: FringeAxis,
    /// Background A, in [0, 1].
    pub background: f32,
    /// Amplitude B; `A - B >= 0` and `A + B <= 1` keep the pattern displayable.
    pub amplitude: f32,
}

impl FringeSpec {
    /// Full-contrast fringes (`A = B = 0.5`).
    pub fn full_contrast(
        width_px: u32,
        height_px: u32,
        period_px: f64,
        steps: usize,
        axis: FringeAxis,
    ) -> Self {
        Self {
            width_px,
            height_px,
            period_px,
            steps,
            axis,
            background: 0.5,
            amplitude: 0.5,
        }
    }
}

/// The N frames of one fringe set, in shift order.
pub fn phase_shift_set(spec: &FringeSpec) -> Vec<Raster<f32>> {
    (0..spec.steps)
        .map(|n| {
            let delta = std::f64::consts::TAU * n as f64 / spec.steps as f64;
            Raster::from_fn(spec.width_px as usize, spec.height_px as usize, |x, y| {
                let u = match spec.axis {
                    FringeAxis::X => x,
                    FringeAxis::Y => y,
                } as f64;
                let phase = std::f64::consts::TAU * u / spec.period_px + delta;
                spec.background + spec.amplitude * phase.cos() as f32
            })
        })
        .collect()
}

/// Frames of several periods, period-major (all steps of `periods_px[0]`, then the next).
pub fn multi_frequency_set(spec: &FringeSpec, periods_px: &[f64]) -> Vec<Raster<f32>> {
    periods_px
        .iter()
        .flat_map(|&period_px| phase_shift_set(&FringeSpec { period_px, ..*spec }))
        .collect()
}

/// Seed 004's three pitches over `extent_px`: fringe counts `S + sqrt(S) + 1`, `S`,
/// `S - sqrt(S)` (S a perfect square), returned as periods, finest first. Their beat
/// spans exactly the extent.
pub fn three_pitch_periods_px(extent_px: f64, s: u32) -> [f64; 3] {
    let s = f64::from(s);
    let r = s.sqrt();
    [
        extent_px / (s + r + 1.0),
        extent_px / s,
        extent_px / (s - r),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::PhaseShift;

    #[test]
    fn decoding_a_generated_set_returns_the_projector_coordinate() {
        for axis in [FringeAxis::X, FringeAxis::Y] {
            let spec = FringeSpec::full_contrast(40, 30, 7.5, 5, axis);
            let frames = phase_shift_set(&spec);
            let refs: Vec<&Raster<f32>> = frames.iter().collect();
            let out = PhaseShift::new(5).unwrap().wrapped_phase(&refs).unwrap();
            for (x, y) in [(0, 0), (13, 7), (39, 29)] {
                let u = if axis == FringeAxis::X { x } else { y } as f32;
                let want = crate::phase::wrap_pi(std::f32::consts::TAU * u / 7.5);
                let got = *out.phase.at(x, y);
                assert!(
                    crate::phase::wrap_pi(got - want).abs() < 1e-4,
                    "{axis:?} {x} {y}"
                );
                assert!((out.modulation.at(x, y) - 0.5).abs() < 1e-4);
            }
        }
    }

    #[test]
    fn multi_frequency_order_and_ranges() {
        let spec = FringeSpec::full_contrast(16, 2, 10.0, 4, FringeAxis::X);
        let set = multi_frequency_set(&spec, &SEED000_PERIODS_PX);
        assert_eq!(set.len(), 16);
        assert!(set
            .iter()
            .all(|f| f.data.iter().all(|&v| (0.0..=1.0).contains(&v))));
        let p = three_pitch_periods_px(912.0, 64);
        let beat = |a: f64, b: f64| a * b / (b - a);
        assert!((beat(beat(p[0], p[1]), beat(p[1], p[2])).abs() - 912.0).abs() < 1e-6);
    }
}
