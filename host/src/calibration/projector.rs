//! Projector calibration as an inverse camera (Zhang & Huang 2006): at each
//! board corner found by the camera, absolute phase in x and y tells which
//! projector pixel lit it, so the projector "sees" the board too and is
//! calibrated by the same Zhang + LM as a camera.
//!
//! Phase -> projector pixel: `u_p = phase_x * period_px / (2 pi)`,
//! `v_p = phase_y * period_px / (2 pi)` (pixel centres at integers, so
//! phase 0 is the centre of projector column / row 0). The corner's projector
//! pixel comes from a local homography fitted to the phase in a window
//! around it (Moreno & Taubin 2012): it averages phase noise and follows the
//! board's perspective, where reading the phase at one pixel would not.

use nalgebra::{Matrix3, Point2};

use super::board::GrayImage;
use super::bundle::{
    calibrate_camera, CalibrateError, CameraCalibration, CameraCalibrationOptions,
};
use super::homography::{apply_homography, fit_homography};
use super::zhang::PlanarView;

/// Absolute phase maps of one board view, radians; NaN where unknown.
#[derive(Debug, Clone, Copy)]
pub struct PhaseMaps<'a> {
    /// Phase of the vertical fringes (varies along projector x).
    pub phase_x: &'a GrayImage,
    /// Phase of the horizontal fringes (varies along projector y).
    pub phase_y: &'a GrayImage,
    /// Fringe period on the DMD, projector pixels.
    pub period_px: f64,
}

/// Errors of projector calibration.
#[derive(Debug, thiserror::Error)]
pub enum ProjectorError {
    /// The two phase maps differ in size.
    #[error("phase maps differ in size: x is {x_width}x{x_height}, y is {y_width}x{y_height}")]
    PhaseSizeMismatch {
        /// Width of the x map.
        x_width: u32,
        /// Height of the x map.
        x_height: u32,
        /// Width of the y map.
        y_width: u32,
        /// Height of the y map.
        y_height: u32,
    },
    /// The fringe period is not a positive number.
    #[error("fringe period {period_px} px is not positive")]
    BadPeriod {
        /// The period given.
        period_px: f64,
    },
    /// Too few corners of a view have valid phase around them.
    #[error("view {view}: only {valid} of {total} corners have valid phase (need >= {needed})")]
    TooFewPhaseCorners {
        /// Index of the view.
        view: usize,
        /// Corners with a projector pixel.
        valid: usize,
        /// Corners in the view.
        total: usize,
        /// Corners needed.
        needed: usize,
    },
    /// Views and phase maps differ in number.
    #[error("{views} corner views but {maps} phase map pairs")]
    CountMismatch {
        /// Corner views.
        views: usize,
        /// Phase map pairs.
        maps: usize,
    },
    /// The projector's own Zhang + LM failed.
    #[error("projector calibration: {0}")]
    Calibrate(#[from] CalibrateError),
}

/// Projector pixel of each camera corner, `None` where fewer than half the
/// window's pixels have phase or the local fit fails.
pub fn projector_points(
    corners_px: &[Point2<f64>],
    maps: &PhaseMaps<'_>,
    half_window_px: usize,
) -> Result<Vec<Option<Point2<f64>>>, ProjectorError> {
    let (xw, xh) = maps.phase_x.dimensions();
    let (yw, yh) = maps.phase_y.dimensions();
    if (xw, xh) != (yw, yh) {
        return Err(ProjectorError::PhaseSizeMismatch {
            x_width: xw,
            x_height: xh,
            y_width: yw,
            y_height: yh,
        });
    }
    if !(maps.period_px.is_finite() && maps.period_px > 0.0) {
        return Err(ProjectorError::BadPeriod {
            period_px: maps.period_px,
        });
    }
    let to_px = maps.period_px / std::f64::consts::TAU;
    let hw = half_window_px as i64;
    let window = ((2 * hw + 1) * (2 * hw + 1)) as usize;
    Ok(corners_px
        .iter()
        .map(|c| {
            let (cx, cy) = (c.x.round() as i64, c.y.round() as i64);
            let mut cam = Vec::with_capacity(window);
            let mut proj = Vec::with_capacity(window);
            for y in cy - hw..=cy + hw {
                for x in cx - hw..=cx + hw {
                    if x < 0 || y < 0 || x >= i64::from(xw) || y >= i64::from(xh) {
                        continue;
                    }
                    let px = maps.phase_x.get_pixel(x as u32, y as u32)[0];
                    let py = maps.phase_y.get_pixel(x as u32, y as u32)[0];
                    if px.is_finite() && py.is_finite() {
                        // Relative to the corner, so the fit is well scaled.
                        cam.push(Point2::new(x as f64 - c.x, y as f64 - c.y));
                        proj.push(Point2::new(f64::from(px) * to_px, f64::from(py) * to_px));
                    }
                }
            }
            let h = robust_homography(&cam, &proj, window.div_ceil(2))?;
            let p = apply_homography(&h, Point2::origin());
            (p.x.is_finite() && p.y.is_finite()).then_some(p)
        })
        .collect())
}

/// Inlier threshold, in robust standard deviations of the residuals.
const OUTLIER_SIGMAS: f64 = 3.5;
/// Smallest inlier threshold, projector pixels: noise-free maps have residuals of
/// rounding size, which must not turn into rejections.
const MIN_THRESHOLD_PX: f64 = 1e-3;
/// Most rounds of fit -> reject -> refit.
const MAX_ROUNDS: usize = 8;

/// Local homography `cam -> proj` that ignores samples off the fit: after each
/// least-squares fit, samples whose residual exceeds `OUTLIER_SIGMAS` robust standard
/// deviations (from the median residual) are set aside and the rest refitted, until the
/// inlier set no longer changes. A fringe-order error that slipped past the unwrapper
/// puts a sample a whole period off, and one such sample bends a plain least-squares
/// fit by a good fraction of a pixel. `None` with fewer than `min_inliers` inliers.
fn robust_homography(
    cam: &[Point2<f64>],
    proj: &[Point2<f64>],
    min_inliers: usize,
) -> Option<Matrix3<f64>> {
    let mut inliers: Vec<usize> = (0..cam.len()).collect();
    for round in 0..MAX_ROUNDS {
        if inliers.len() < min_inliers.max(4) {
            return None;
        }
        let from: Vec<Point2<f64>> = inliers.iter().map(|&i| cam[i]).collect();
        let to: Vec<Point2<f64>> = inliers.iter().map(|&i| proj[i]).collect();
        let h = fit_homography(&from, &to).ok()?;
        // Residuals of every sample, so that one set aside too early can come back.
        let residual: Vec<f64> = cam
            .iter()
            .zip(proj)
            .map(|(c, p)| (apply_homography(&h, *c) - p).norm())
            .collect();
        let mut of_inliers: Vec<f64> = inliers.iter().map(|&i| residual[i]).collect();
        of_inliers.sort_by(f64::total_cmp);
        // The norm of a 2-D Gaussian residual has median sqrt(2 ln 2) sigma = 1.1774 sigma.
        let sigma = of_inliers[of_inliers.len() / 2] / 1.1774;
        let threshold = (OUTLIER_SIGMAS * sigma).max(MIN_THRESHOLD_PX);
        let next: Vec<usize> = (0..cam.len())
            .filter(|&i| residual[i] <= threshold)
            .collect();
        if next == inliers || round + 1 == MAX_ROUNDS {
            return Some(h);
        }
        inliers = next;
    }
    None
}

/// Calibrates the projector from the camera's corners and the phase maps of
/// the same views. `board_m` lists the board corners in the order of each
/// `corners_px[v]`; `projector_size` is the DMD size in pixels.
pub fn calibrate_projector(
    board_m: &[Point2<f64>],
    corners_px: &[Vec<Point2<f64>>],
    maps: &[PhaseMaps<'_>],
    projector_size: (u32, u32),
    half_window_px: usize,
    options: &CameraCalibrationOptions,
) -> Result<(CameraCalibration, Vec<PlanarView>), ProjectorError> {
    if corners_px.len() != maps.len() {
        return Err(ProjectorError::CountMismatch {
            views: corners_px.len(),
            maps: maps.len(),
        });
    }
    let mut views = Vec::with_capacity(maps.len());
    for (view, (corners, m)) in corners_px.iter().zip(maps).enumerate() {
        let pts = projector_points(corners, m, half_window_px)?;
        let mut planar = PlanarView {
            board_m: Vec::new(),
            image_px: Vec::new(),
        };
        for (b, p) in board_m.iter().zip(&pts) {
            if let Some(p) = p {
                planar.board_m.push(*b);
                planar.image_px.push(*p);
            }
        }
        let needed = 6.max(board_m.len() / 2);
        if planar.board_m.len() < needed {
            return Err(ProjectorError::TooFewPhaseCorners {
                view,
                valid: planar.board_m.len(),
                total: board_m.len(),
                needed,
            });
        }
        views.push(planar);
    }
    let cal = calibrate_camera(&views, projector_size, options)?;
    Ok((cal, views))
}

/// Least-squares local homography without outlier rejection (the tests' reference).
#[cfg(test)]
fn plain_homography(cam: &[Point2<f64>], proj: &[Point2<f64>]) -> Option<Matrix3<f64>> {
    fit_homography(cam, proj).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: u32, h: u32, f: impl Fn(f64, f64) -> f64) -> GrayImage {
        GrayImage::from_fn(w, h, |x, y| {
            image::Luma([f(f64::from(x), f64::from(y)) as f32])
        })
    }

    #[test]
    fn reads_projector_pixel_through_local_homography() {
        // Projector pixel = affine map of the camera pixel; period 20 px.
        let tau = std::f64::consts::TAU;
        let px = ramp(64, 64, |x, y| tau * (2.0 * x + 0.3 * y + 5.0) / 20.0);
        let py = ramp(64, 64, |x, y| tau * (-0.2 * x + 1.8 * y + 7.0) / 20.0);
        let maps = PhaseMaps {
            phase_x: &px,
            phase_y: &py,
            period_px: 20.0,
        };
        let c = Point2::new(30.4, 25.7);
        let got = projector_points(&[c], &maps, 5).unwrap()[0].unwrap();
        let want = Point2::new(2.0 * c.x + 0.3 * c.y + 5.0, -0.2 * c.x + 1.8 * c.y + 7.0);
        assert!((got - want).norm() < 1e-3, "{got} vs {want}");
    }

    #[test]
    fn order_errors_in_the_window_do_not_move_the_projector_pixel() {
        // As above, with four samples one fringe period (20 px) off in x or y, as an
        // unwrapping order error leaves them.
        let tau = std::f64::consts::TAU;
        let truth_x = |x: f64, y: f64| 2.0 * x + 0.3 * y + 5.0;
        let truth_y = |x: f64, y: f64| -0.2 * x + 1.8 * y + 7.0;
        let spikes = [
            (28, 24, 20.0, 0.0),
            (33, 27, 20.0, 0.0),
            (31, 22, 0.0, 20.0),
        ];
        let spiked = |x: f64, y: f64, axis: usize| {
            spikes
                .iter()
                .find(|s| (f64::from(s.0), f64::from(s.1)) == (x, y))
                .map_or(0.0, |s| if axis == 0 { s.2 } else { s.3 })
        };
        let px = ramp(64, 64, |x, y| {
            tau * (truth_x(x, y) + spiked(x, y, 0)) / 20.0
        });
        let py = ramp(64, 64, |x, y| {
            tau * (truth_y(x, y) + spiked(x, y, 1)) / 20.0
        });
        let maps = PhaseMaps {
            phase_x: &px,
            phase_y: &py,
            period_px: 20.0,
        };
        let c = Point2::new(30.4, 25.7);
        let want = Point2::new(truth_x(c.x, c.y), truth_y(c.x, c.y));
        let got = projector_points(&[c], &maps, 5).unwrap()[0].unwrap();
        assert!((got - want).norm() < 1e-3, "{got} vs {want}");
        // The same window fitted without rejection is bent by the spikes.
        let (mut cam, mut proj) = (Vec::new(), Vec::new());
        for y in 21..=31 {
            for x in 25..=35 {
                let (xf, yf) = (f64::from(x), f64::from(y));
                cam.push(Point2::new(xf - c.x, yf - c.y));
                proj.push(Point2::new(
                    truth_x(xf, yf) + spiked(xf, yf, 0),
                    truth_y(xf, yf) + spiked(xf, yf, 1),
                ));
            }
        }
        let plain = apply_homography(&plain_homography(&cam, &proj).unwrap(), Point2::origin());
        assert!((plain - want).norm() > 0.05, "{plain} vs {want}");
    }

    #[test]
    fn missing_phase_and_bad_inputs() {
        let nan = ramp(32, 32, |_, _| f64::NAN);
        let maps = PhaseMaps {
            phase_x: &nan,
            phase_y: &nan,
            period_px: 20.0,
        };
        assert_eq!(
            projector_points(&[Point2::new(10.0, 10.0)], &maps, 3).unwrap(),
            vec![None]
        );
        let small = ramp(16, 32, |_, _| 0.0);
        let maps = PhaseMaps {
            phase_x: &nan,
            phase_y: &small,
            period_px: 20.0,
        };
        assert!(matches!(
            projector_points(&[], &maps, 3),
            Err(ProjectorError::PhaseSizeMismatch { .. })
        ));
        let maps = PhaseMaps {
            phase_x: &nan,
            phase_y: &nan,
            period_px: -1.0,
        };
        assert!(matches!(
            projector_points(&[], &maps, 3),
            Err(ProjectorError::BadPeriod { .. })
        ));
    }
}
