//! The adapted fringe set: at each projector pixel the fringe swings from
//! `L_min` to that pixel's optimal level, so `A = (L_opt + L_min) / 2` and
//! `B = (L_opt - L_min) / 2` (seed 003, eq. 18-19), 8-bit as a DMD shows it.

use rayon::prelude::*;

use crate::raster::Raster;

/// Column fringes of `periods_px` x `steps` shifts (period-major, shifts
/// `2 pi n / N`, the DESIGN.md convention) whose pixel at `(u, v)` spans
/// `min_level ..= levels(u, v)`, quantised to 8 bits.
pub fn adapted_fringes(
    levels: &Raster<f32>,
    min_level: f32,
    periods_px: &[f64],
    steps: usize,
) -> Vec<Raster<f32>> {
    let (w, h) = levels.size();
    let frames: Vec<(f64, usize)> = periods_px
        .iter()
        .flat_map(|&p| (0..steps).map(move |n| (p, n)))
        .collect();
    frames
        .par_iter()
        .map(|&(period, n)| {
            let delta = std::f64::consts::TAU * n as f64 / steps as f64;
            // Column fringes: one profile per frame, scaled per pixel.
            let profile: Vec<f32> = (0..w)
                .map(|u| {
                    (0.5 + 0.5 * (std::f64::consts::TAU * u as f64 / period + delta).cos()) as f32
                })
                .collect();
            let mut data = Vec::with_capacity(w * h);
            for row in levels.data.chunks(w.max(1)) {
                data.extend(row.iter().zip(&profile).map(|(&l, &p)| {
                    let l = l.clamp(min_level, 1.0);
                    ((min_level + (l - min_level) * p) * 255.0).round() / 255.0
                }));
            }
            Raster {
                width: w,
                height: h,
                data,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::PhaseShift;

    #[test]
    fn adapted_fringes_keep_the_phase_and_span_the_level() {
        let mut levels = Raster::filled(64, 2, 1.0f32);
        levels.data[64..].iter_mut().for_each(|v| *v = 0.3);
        let f = adapted_fringes(&levels, 0.0, &[16.0, 20.0], 4);
        assert_eq!(f.len(), 8);
        let shift = PhaseShift::new(4).unwrap();
        for y in 0..2 {
            let top = if y == 0 { 1.0 } else { 0.3 };
            for u in [3usize, 17, 40] {
                let s: Vec<f32> = f[..4].iter().map(|r| *r.at(u, y)).collect();
                let max = s.iter().copied().fold(0.0, f32::max);
                assert!(max <= top + 0.5 / 255.0, "{max} > {top}");
                let (phi, _, _) = shift.decode(s.iter().copied());
                let want = std::f32::consts::TAU * u as f32 / 16.0;
                let d = (phi - want).rem_euclid(std::f32::consts::TAU);
                let d = d.min(std::f32::consts::TAU - d);
                // 8-bit levels over an amplitude of 0.15 move the phase by
                // at most a few hundredths of a radian.
                assert!(d < 0.05, "y {y} u {u}: {phi} vs {want}");
            }
        }
        assert!(f
            .iter()
            .flat_map(|r| &r.data)
            .all(|v| (v * 255.0).fract() == 0.0));
    }
}
