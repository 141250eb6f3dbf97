//! Pixels that straddle a step of the adapted level map. A camera pixel
//! integrates a few DMD pixels (its footprint, blurred by the lenses); where
//! the projected level changes inside them, the fringe it records is the
//! sum of shifted sinusoids of different amplitude and its phase is bent,
//! by far more than the noise predicts. Reflectivity edges (the bands of a
//! machined part) are where the levels step, and where the mapping placed
//! them a pixel off the true edge the bias is largest. Such pixels are
//! marked unreliable after the adapted scan rather than reported.

use nalgebra::Point3;

use super::mapping::is_mapped;
use crate::calibration::PinholeModel;
use crate::raster::Raster;
use crate::reconstruct::PixelMaps;
use crate::unwrap::PixelStatus;

/// Marks every valid pixel of `maps` whose point, projected into
/// `projector`, has a level in `levels` (the adapted DMD map) that varies
/// by more than `max_ratio` (largest over smallest) within `radius_px` DMD
/// pixels; returns how many it marked.
pub fn mark_level_steps(
    maps: &mut PixelMaps,
    levels: &Raster<f32>,
    projector: &PinholeModel,
    radius_px: usize,
    max_ratio: f32,
) -> usize {
    let (w, h) = levels.size();
    let r = radius_px as isize;
    let mut marked = 0;
    for i in 0..maps.len() {
        if maps.status[i] != PixelStatus::Valid {
            continue;
        }
        let p = Point3::new(
            f64::from(maps.point_m[0][i]),
            f64::from(maps.point_m[1][i]),
            f64::from(maps.point_m[2][i]),
        );
        let Some(q) = projector.project(&p) else {
            continue;
        };
        let q = [q.x as f32, q.y as f32];
        if !is_mapped(&q) {
            continue;
        }
        let (cx, cy) = (q[0].round() as isize, q[1].round() as isize);
        let (mut lo, mut hi) = (f32::INFINITY, 0.0f32);
        for y in (cy - r).max(0)..=(cy + r).min(h as isize - 1) {
            for x in (cx - r).max(0)..=(cx + r).min(w as isize - 1) {
                let l = levels.data[y as usize * w + x as usize];
                lo = lo.min(l);
                hi = hi.max(l);
            }
        }
        if hi > lo * max_ratio {
            maps.mark_unreliable(i);
            marked += 1;
        }
    }
    marked
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_over_a_level_step_are_marked_and_the_rest_kept() {
        // A projector looking down +z at points on z = 1: DMD column u sees
        // x = (u - cx) / f.
        let projector = PinholeModel::ideal(40, 20, 100.0);
        let mut levels = Raster::filled(40, 20, 1.0f32);
        for y in 0..20 {
            for x in 20..40 {
                levels.data[y * 40 + x] = 0.3;
            }
        }
        let us = [5.0f32, 18.0, 19.5, 21.0, 30.0];
        let n = us.len();
        let mut maps = PixelMaps {
            width: n,
            height: 1,
            status: vec![PixelStatus::Valid; n],
            phase_u: vec![0.0; n],
            point_m: [
                us.iter().map(|u| (u - 19.5) / 100.0).collect(),
                vec![0.0; n],
                vec![1.0; n],
            ],
            depth_m: vec![1.0; n],
            sigma_m: vec![1e-5; n],
            modulation: vec![0.2; n],
            background: vec![0.2; n],
        };
        let marked = mark_level_steps(&mut maps, &levels, &projector, 2, 1.5);
        assert_eq!(marked, 3);
        let valid: Vec<bool> = maps
            .status
            .iter()
            .map(|&s| s == PixelStatus::Valid)
            .collect();
        assert_eq!(valid, [true, false, false, false, true]);
        assert!(maps.depth_m[1].is_nan() && maps.depth_m[0] == 1.0);
    }
}
