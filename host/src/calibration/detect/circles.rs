//! Symmetric circle-grid detection.
//!
//! ```text
//! image --local background (wide blur)--> dark mask --components--> blobs
//!   --shape test (area vs second moments)--> ellipses
//!   --coverage-weighted centroid--> sub-pixel centres --grid.rs--> board order
//! ```
//!
//! The centre is the centroid of each pixel's dark coverage, `(bg - I) /
//! (bg - dark)` clamped to [0, 1], which is exact for anti-aliased ellipses.
//! It is the centre of the *imaged ellipse*: under perspective that differs
//! from the image of the circle's centre by a small amount that grows with
//! circle size and tilt (measured in `tests/calibration.rs`), the known
//! limit of circle targets.

use std::collections::VecDeque;

use nalgebra::{Matrix2, Point2};

use super::filter::{gaussian_blur, wide_blur, Plane};
use super::{check_image, grid, plane_of, DetectError};
use crate::calibration::board::{CircleGrid, GrayImage};
use crate::raster::neighbours4;

/// Pixels of each 4-connected component of `mask` (components touching the
/// image border are dropped: a cut circle has a wrong centre).
fn components(mask: &[bool], w: usize, h: usize) -> Vec<Vec<usize>> {
    let mut seen = vec![false; mask.len()];
    let mut out = Vec::new();
    for start in 0..mask.len() {
        if !mask[start] || seen[start] {
            continue;
        }
        let mut pixels = Vec::new();
        let mut touches_border = false;
        let mut queue = VecDeque::from([start]);
        seen[start] = true;
        while let Some(k) = queue.pop_front() {
            pixels.push(k);
            let neighbours = neighbours4(k, w, h);
            // A pixel on the border is one with a neighbour missing.
            touches_border |= neighbours.contains(&None);
            let visit = |n: usize| {
                if mask[n] && !seen[n] {
                    seen[n] = true;
                    queue.push_back(n);
                }
            };
            neighbours.into_iter().flatten().for_each(visit);
        }
        if !touches_border {
            out.push(pixels);
        }
    }
    out
}

/// Shape test and sub-pixel centre of one component.
fn blob_centre(pixels: &[usize], raw: &Plane, background: &Plane) -> Option<Point2<f64>> {
    let w = raw.width;
    let n = pixels.len() as f64;
    if pixels.len() < 12 {
        return None;
    }
    let (mut sx, mut sy) = (0.0, 0.0);
    for &k in pixels {
        sx += (k % w) as f64;
        sy += (k / w) as f64;
    }
    let (mx, my) = (sx / n, sy / n);
    let mut cov = Matrix2::zeros();
    for &k in pixels {
        let (dx, dy) = ((k % w) as f64 - mx, (k / w) as f64 - my);
        cov += Matrix2::new(dx * dx, dx * dy, dx * dy, dy * dy);
    }
    cov /= n;
    let eig = cov.symmetric_eigen();
    let (l1, l2) = (eig.eigenvalues.max(), eig.eigenvalues.min().max(1e-12));
    // A filled ellipse of semi-axes a, b has variances a^2/4, b^2/4.
    let (a, b) = (2.0 * l1.sqrt(), 2.0 * l2.sqrt());
    let fill = n / (std::f64::consts::PI * a * b);
    if !(0.8..=1.2).contains(&fill) || a / b > 4.0 {
        return None;
    }
    // Darkest level inside, for the coverage weights.
    let dark = pixels
        .iter()
        .map(|&k| f64::from(raw.data[k]))
        .fold(f64::INFINITY, f64::min);
    let reach = a + 2.5;
    let (x0, x1) = ((mx - reach).floor() as isize, (mx + reach).ceil() as isize);
    let (y0, y1) = ((my - reach).floor() as isize, (my + reach).ceil() as isize);
    let (mut wsum, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (fx, fy) = (x as f64 - mx, y as f64 - my);
            if fx * fx + fy * fy > reach * reach {
                continue;
            }
            let bg = f64::from(background.at(x, y));
            let depth = bg - dark;
            if depth <= 1e-6 {
                continue;
            }
            let coverage = ((bg - f64::from(raw.at(x, y))) / depth).clamp(0.0, 1.0);
            wsum += coverage;
            cx += coverage * x as f64;
            cy += coverage * y as f64;
        }
    }
    (wsum > 0.0).then(|| Point2::new(cx / wsum, cy / wsum))
}

/// Finds the circle centres of `grid`, in board order (row by row).
pub fn detect_circle_grid(
    image: &GrayImage,
    grid_spec: &CircleGrid,
) -> Result<Vec<Point2<f64>>, DetectError> {
    if grid_spec.cols < 2 || grid_spec.rows < 2 {
        return Err(DetectError::BadBoard {
            cols: grid_spec.cols,
            rows: grid_spec.rows,
        });
    }
    check_image(image)?;
    let raw = plane_of(image);
    let (w, h) = (raw.width, raw.height);
    let smooth = gaussian_blur(&raw, 1.0);
    // The plate's local brightness: wide enough to ignore one circle, narrow
    // enough to follow vignetting. Circles lower it a little; the threshold
    // sits halfway down, so that does not matter.
    let sigma_bg = (w.max(h) as f64 / 25.0).max(4.0);
    let local = wide_blur(&raw, sigma_bg);
    let lo = smooth.data.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = smooth
        .data
        .iter()
        .copied()
        .fold(f32::NEG_INFINITY, f32::max);
    let step = 0.15 * (hi - lo);
    let mask: Vec<bool> = smooth
        .data
        .iter()
        .zip(&local.data)
        .map(|(s, l)| *s < *l - step)
        .collect();
    // The background for coverage weights: the local level where no blob is.
    let plate = local_plate(&raw, &mask, sigma_bg);
    let points: Vec<Point2<f64>> = components(&mask, w, h)
        .iter()
        .filter(|px| px.len() < w * h / 20)
        .filter_map(|px| blob_centre(px, &raw, &plate))
        .collect();
    let mut largest = (0usize, 0usize);
    for seed in 0..points.len().min(30) {
        let Some(grown) = grid::grow(&points, seed) else {
            continue;
        };
        if grown.width * grown.height > largest.0 * largest.1 {
            largest = (grown.width, grown.height);
        }
        if let Some(ordered) = grid::orient(&grown, grid_spec.cols, grid_spec.rows, None) {
            return Ok(ordered);
        }
    }
    Err(if largest.0 * largest.1 >= 4 {
        DetectError::WrongCount {
            expected_cols: grid_spec.cols,
            expected_rows: grid_spec.rows,
            found_cols: largest.0,
            found_rows: largest.1,
        }
    } else {
        DetectError::NotFound {
            target: "circle grid",
            candidates: points.len(),
        }
    })
}

/// Brightness of the plate with the blobs masked out: a normalised
/// convolution (blur of the unmasked image over blur of the unmasked weight).
fn local_plate(raw: &Plane, mask: &[bool], sigma: f64) -> Plane {
    let keep = |dark: bool| if dark { 0.0 } else { 1.0 };
    let weights = Plane {
        width: raw.width,
        height: raw.height,
        data: mask.iter().map(|m| keep(*m)).collect(),
    };
    let values = Plane {
        width: raw.width,
        height: raw.height,
        data: raw
            .data
            .iter()
            .zip(mask)
            .map(|(v, m)| v * keep(*m))
            .collect(),
    };
    let (num, den) = (wide_blur(&values, sigma), wide_blur(&weights, sigma));
    Plane {
        width: raw.width,
        height: raw.height,
        data: num
            .data
            .iter()
            .zip(&den.data)
            .map(|(n, d)| if *d > 1e-6 { n / d } else { *n })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::rodrigues::pose_from_rodrigues;
    use crate::calibration::PinholeModel;
    use crate::synth::targets::{render_circle_grid, RenderSettings};
    use nalgebra::{Point3, Vector3};

    const GRID: CircleGrid = CircleGrid {
        cols: 7,
        rows: 5,
        spacing_m: 0.03,
        diameter_m: 0.012,
    };

    #[test]
    fn finds_circle_centres_in_order() {
        let mut cam = PinholeModel::ideal(320, 240, 330.0);
        cam.pose = pose_from_rodrigues(
            &Vector3::new(0.15, -0.2, 0.05),
            &Vector3::new(-0.09, -0.06, 0.5),
        );
        let img = render_circle_grid(&cam, &GRID, &RenderSettings::default());
        let found = detect_circle_grid(&img, &GRID).unwrap();
        assert_eq!(found.len(), 35);
        let mut worst = 0.0f64;
        for (f, c) in found.iter().zip(GRID.centres_m()) {
            let t = cam.project(&Point3::new(c.x, c.y, 0.0)).unwrap();
            worst = worst.max((f.coords - t).norm());
        }
        // Ellipse-centre bias plus noise: well under a tenth of a pixel here.
        assert!(worst < 0.1, "worst {worst} px");
    }

    #[test]
    fn wrong_grid_size_is_a_typed_error() {
        let mut cam = PinholeModel::ideal(320, 240, 330.0);
        cam.pose = pose_from_rodrigues(&Vector3::zeros(), &Vector3::new(-0.09, -0.06, 0.5));
        let img = render_circle_grid(&cam, &GRID, &RenderSettings::default());
        let bigger = CircleGrid { cols: 8, ..GRID };
        assert!(matches!(
            detect_circle_grid(&img, &bigger),
            Err(DetectError::WrongCount {
                expected_cols: 8,
                ..
            })
        ));
    }
}
