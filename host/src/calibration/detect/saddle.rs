//! Corner candidates: saddle points of the smoothed image.
//!
//! A checkerboard corner is an X-junction, where the image is a saddle: the
//! Hessian's determinant is strongly negative there and near zero along
//! straight edges and in flat squares. The response `max(0, -det H)` is
//! suppressed to local maxima; the grid stage sorts out clutter.

use nalgebra::Point2;

use super::filter::Plane;

/// A corner candidate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Position at pixel precision (refined later), pixels.
    pub position: Point2<f64>,
    /// Saddle response `-det H` of the smoothed image.
    pub response: f64,
}

/// `-det` of the Hessian of `plane` at every pixel, floored at 0.
pub fn saddle_response(plane: &Plane) -> Vec<f32> {
    let (w, h) = (plane.width, plane.height);
    let mut out = vec![0.0f32; w * h];
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let (xi, yi) = (x as isize, y as isize);
            let c = plane.at(xi, yi);
            let ixx = plane.at(xi + 1, yi) - 2.0 * c + plane.at(xi - 1, yi);
            let iyy = plane.at(xi, yi + 1) - 2.0 * c + plane.at(xi, yi - 1);
            let ixy = 0.25
                * (plane.at(xi + 1, yi + 1) - plane.at(xi + 1, yi - 1) - plane.at(xi - 1, yi + 1)
                    + plane.at(xi - 1, yi - 1));
            out[y * w + x] = (ixy * ixy - ixx * iyy).max(0.0);
        }
    }
    out
}

/// Local maxima of `response` within `radius_px`, above `min_fraction` of
/// the strongest, strongest first, at most `max_count`. Pixels closer than
/// `border_px` to the image edge are skipped.
pub fn local_maxima(
    response: &[f32],
    width: usize,
    height: usize,
    radius_px: usize,
    min_fraction: f32,
    border_px: usize,
    max_count: usize,
) -> Vec<Candidate> {
    let peak = response.iter().copied().fold(0.0f32, f32::max);
    if peak <= 0.0 {
        return Vec::new();
    }
    let threshold = peak * min_fraction;
    let r = radius_px as isize;
    let mut found = Vec::new();
    for y in border_px..height.saturating_sub(border_px) {
        for x in border_px..width.saturating_sub(border_px) {
            let v = response[y * width + x];
            if v < threshold {
                continue;
            }
            let mut is_max = true;
            'window: for dy in -r..=r {
                for dx in -r..=r {
                    let (xx, yy) = (x as isize + dx, y as isize + dy);
                    if (dx, dy) == (0, 0)
                        || xx < 0
                        || yy < 0
                        || xx >= width as isize
                        || yy >= height as isize
                    {
                        continue;
                    }
                    let o = response[yy as usize * width + xx as usize];
                    // Ties go to the first pixel in raster order.
                    if o > v || (o == v && (dy < 0 || (dy == 0 && dx < 0))) {
                        is_max = false;
                        break 'window;
                    }
                }
            }
            if is_max {
                found.push(Candidate {
                    position: Point2::new(x as f64, y as f64),
                    response: f64::from(v),
                });
            }
        }
    }
    found.sort_by(|a, b| b.response.total_cmp(&a.response));
    found.truncate(max_count);
    found
}

/// Whether the smoothed image around `p` alternates dark-light four times on
/// a circle of `radius_px`: true for an X-junction, false for the L-corners
/// where the outer squares meet the board margin (which are saddles too, of
/// a sixteenth of the strength) and for straight edges.
pub fn is_x_junction(plane: &Plane, p: &Point2<f64>, radius_px: f64) -> bool {
    const SAMPLES: usize = 24;
    let ring: Vec<f64> = (0..SAMPLES)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / SAMPLES as f64;
            plane.bilinear(p.x + radius_px * a.cos(), p.y + radius_px * a.sin())
        })
        .collect();
    let lo = ring.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = ring.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if hi - lo <= 1e-3 || (hi - lo).is_nan() {
        return false;
    }
    let mid = 0.5 * (lo + hi);
    let transitions = (0..SAMPLES)
        .filter(|&k| (ring[k] > mid) != (ring[(k + 1) % SAMPLES] > mid))
        .count();
    transitions == 4
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2x2 checker with its X-junction at (10, 12), slightly blurred.
    fn x_junction() -> Plane {
        let (w, h) = (24, 24);
        let data = (0..w * h)
            .map(|k| {
                let (x, y) = ((k % w) as f32 - 10.0, (k / w) as f32 - 12.0);
                let s = (x / 1.5).tanh() * (y / 1.5).tanh();
                0.5 + 0.4 * s
            })
            .collect();
        Plane {
            width: w,
            height: h,
            data,
        }
    }

    #[test]
    fn finds_the_x_junction() {
        let p = x_junction();
        let r = saddle_response(&p);
        let c = local_maxima(&r, p.width, p.height, 3, 0.2, 2, 10);
        assert_eq!(c.len(), 1, "{c:?}");
        assert_eq!(c[0].position, Point2::new(10.0, 12.0));
    }

    #[test]
    fn ring_test_tells_x_from_l_corners() {
        let p = x_junction();
        assert!(is_x_junction(&p, &Point2::new(10.0, 12.0), 5.0));
        let (w, h) = (24, 24);
        let data = (0..w * h)
            .map(|k| {
                let (x, y) = ((k % w) as f32 - 10.0, (k / w) as f32 - 12.0);
                if x < 0.0 && y < 0.0 {
                    0.1
                } else {
                    0.9
                }
            })
            .collect();
        let l = Plane {
            width: w,
            height: h,
            data,
        };
        assert!(!is_x_junction(&l, &Point2::new(10.0, 12.0), 5.0));
    }

    #[test]
    fn flat_image_has_no_candidates() {
        let p = Plane {
            width: 16,
            height: 16,
            data: vec![0.3; 256],
        };
        let r = saddle_response(&p);
        assert!(local_maxima(&r, 16, 16, 3, 0.2, 2, 10).is_empty());
    }
}
