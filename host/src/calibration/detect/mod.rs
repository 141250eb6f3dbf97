//! Checkerboard detection with sub-pixel corners.
//!
//! ```text
//! image --blur--> saddle response --local maxima--> candidates
//!   --grid growth (grid.rs)--> cols x rows lattice --orientation--> board order
//!   --gradient refinement (subpix.rs)--> sub-pixel corners
//! ```
//!
//! Images are grey f32 in [0, 1] (see [`crate::calibration::board::GrayImage`]);
//! load 8- or 16-bit PNG/TIFF with [`load_gray`].

pub mod circles;
pub mod filter;
pub mod grid;
pub mod saddle;
pub mod subpix;

use std::path::{Path, PathBuf};

use nalgebra::Point2;

use super::board::{Checkerboard, GrayImage, Target};
use filter::{gaussian_blur, Plane};

/// Errors of checkerboard detection.
#[derive(Debug, thiserror::Error)]
pub enum DetectError {
    /// The image is smaller than any board could be.
    #[error("image is {width}x{height} pixels: too small for a board")]
    ImageTooSmall {
        /// Width, pixels.
        width: u32,
        /// Height, pixels.
        height: u32,
    },
    /// The image holds NaN or infinite samples.
    #[error("image has {count} non-finite pixels")]
    NonFinitePixels {
        /// How many.
        count: usize,
    },
    /// The board spec is unusable.
    #[error("a board needs >= 2x2 inner corners, got {cols}x{rows}")]
    BadBoard {
        /// Inner corners along x.
        cols: usize,
        /// Inner corners along y.
        rows: usize,
    },
    /// No grid of the target was found at all.
    #[error("no {target} found ({candidates} {} candidates)", if *target == "checkerboard" { "corner" } else { "circle" })]
    NotFound {
        /// The target looked for: "checkerboard" or "circle grid".
        target: &'static str,
        /// Saddle (or blob) candidates seen.
        candidates: usize,
    },
    /// A grid was found but its size is not the board's (partly hidden,
    /// cut by the image edge, or the wrong board size given).
    #[error("expected {expected_cols}x{expected_rows} inner corners (or circles), found a {found_cols}x{found_rows} grid")]
    WrongCount {
        /// Inner corners expected along x.
        expected_cols: usize,
        /// Inner corners expected along y.
        expected_rows: usize,
        /// Largest grid found, first axis.
        found_cols: usize,
        /// Largest grid found, second axis.
        found_rows: usize,
    },
    /// Sub-pixel refinement failed at a corner (no structure around it).
    #[error("corner {index} at ({x:.1}, {y:.1}) could not be refined")]
    RefineFailed {
        /// Corner index in board order.
        index: usize,
        /// Pixel x of the coarse corner.
        x: f64,
        /// Pixel y of the coarse corner.
        y: f64,
    },
    /// The image file could not be read or decoded.
    #[error("cannot read image {path}: {source}")]
    Load {
        /// The file.
        path: PathBuf,
        /// Why.
        source: image::ImageError,
    },
}

/// Knobs of [`detect_checkerboard`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectOptions {
    /// Smoothing before the saddle response, pixels (about a fifth of the
    /// smallest square side works; 1.5 suits squares of 10..200 px).
    pub blur_sigma_px: f64,
    /// Corner candidates (X-junctions) weaker than this fraction of the
    /// strongest are dropped.
    pub min_response_fraction: f32,
    /// Seeds tried for grid growth, strongest candidates first.
    pub max_seeds: usize,
}

impl Default for DetectOptions {
    fn default() -> Self {
        Self {
            blur_sigma_px: 1.5,
            min_response_fraction: 0.05,
            max_seeds: 30,
        }
    }
}

/// Loads an 8- or 16-bit (grey or colour) PNG/TIFF as grey f32 in [0, 1].
pub fn load_gray(path: &Path) -> Result<GrayImage, DetectError> {
    image::open(path)
        .map(|img| img.to_luma32f())
        .map_err(|source| DetectError::Load {
            path: path.to_owned(),
            source,
        })
}

/// Finds the target's feature points (checkerboard corners or circle
/// centres) in board order.
pub fn detect_target(
    image: &GrayImage,
    target: &Target,
    options: &DetectOptions,
) -> Result<Vec<Point2<f64>>, DetectError> {
    match target {
        Target::Checkerboard(b) => detect_checkerboard(image, b, options),
        Target::CircleGrid(g) => circles::detect_circle_grid(image, g),
    }
}

/// The image checks every detector makes: size and finite samples.
fn check_image(image: &GrayImage) -> Result<(), DetectError> {
    let (w, h) = image.dimensions();
    if w < 16 || h < 16 {
        return Err(DetectError::ImageTooSmall {
            width: w,
            height: h,
        });
    }
    let bad = image.as_raw().iter().filter(|v| !v.is_finite()).count();
    if bad > 0 {
        return Err(DetectError::NonFinitePixels { count: bad });
    }
    Ok(())
}

fn plane_of(image: &GrayImage) -> Plane {
    Plane {
        width: image.width() as usize,
        height: image.height() as usize,
        data: image.as_raw().clone(),
    }
}

/// Finds the board's inner corners, in board order (row by row, see
/// [`Checkerboard`]), refined to sub-pixel precision.
pub fn detect_checkerboard(
    image: &GrayImage,
    board: &Checkerboard,
    options: &DetectOptions,
) -> Result<Vec<Point2<f64>>, DetectError> {
    if board.cols < 2 || board.rows < 2 {
        return Err(DetectError::BadBoard {
            cols: board.cols,
            rows: board.rows,
        });
    }
    check_image(image)?;
    let raw = plane_of(image);
    let smooth = gaussian_blur(&raw, options.blur_sigma_px);
    let response = saddle::saddle_response(&smooth);
    let radius = (2.0 * options.blur_sigma_px).ceil().max(2.0) as usize;
    let ring_px = (3.0 * options.blur_sigma_px + 1.0).max(3.0);
    let border = radius.max(ring_px.ceil() as usize) + 1;
    // Maxima down to 1% of the strongest saddle, then only X-junctions, and
    // the response threshold relative to the strongest X-junction: a
    // high-contrast saddle in the background (an L-corner, a T-junction)
    // must not push the board's corners under the threshold.
    let all = saddle::local_maxima(
        &response,
        raw.width,
        raw.height,
        radius,
        0.01,
        border,
        usize::MAX,
    );
    let crossings: Vec<&saddle::Candidate> = all
        .iter()
        .filter(|c| saddle::is_x_junction(&smooth, &c.position, ring_px))
        .collect();
    let strongest = crossings.first().map_or(0.0, |c| c.response);
    let max_candidates = 4 * board.corner_count() + 100;
    let points: Vec<Point2<f64>> = crossings
        .iter()
        .filter(|c| c.response >= f64::from(options.min_response_fraction) * strongest)
        .take(max_candidates)
        .map(|c| c.position)
        .collect();
    let mut largest = (0usize, 0usize);
    let mut coarse = None;
    for seed in 0..points.len().min(options.max_seeds) {
        let Some(grown) = grid::grow(&points, seed) else {
            continue;
        };
        if grown.width * grown.height > largest.0 * largest.1 {
            largest = (grown.width, grown.height);
        }
        if let Some(ordered) = grid::orient(&grown, board.cols, board.rows, Some(&smooth)) {
            coarse = Some(ordered);
            break;
        }
    }
    let Some(coarse) = coarse else {
        return Err(if largest.0 * largest.1 >= 4 {
            DetectError::WrongCount {
                expected_cols: board.cols,
                expected_rows: board.rows,
                found_cols: largest.0,
                found_rows: largest.1,
            }
        } else {
            DetectError::NotFound {
                target: "checkerboard",
                candidates: points.len(),
            }
        });
    };
    refine_all(&coarse, board, &raw, options)
}

/// Sub-pixel refinement of every corner with a window sized to its
/// neighbours (at most 40% of the spacing, so no other corner enters it).
fn refine_all(
    coarse: &[Point2<f64>],
    board: &Checkerboard,
    raw: &Plane,
    options: &DetectOptions,
) -> Result<Vec<Point2<f64>>, DetectError> {
    // Light smoothing keeps gradients from amplifying sensor noise; a
    // symmetric blur does not move an X-junction.
    let gradient_plane = gaussian_blur(raw, 0.7 * options.blur_sigma_px.min(1.5));
    let mut refined = Vec::with_capacity(coarse.len());
    for (index, p) in coarse.iter().enumerate() {
        let (i, j) = (index % board.cols, index / board.cols);
        let mut spacing = f64::INFINITY;
        for (di, dj) in [(1i64, 0i64), (-1, 0), (0, 1), (0, -1)] {
            let (a, b) = (i as i64 + di, j as i64 + dj);
            if a >= 0 && b >= 0 && (a as usize) < board.cols && (b as usize) < board.rows {
                let q = coarse[b as usize * board.cols + a as usize];
                spacing = spacing.min((q - p).norm());
            }
        }
        // Near the image edge the window shrinks to fit (refinement needs
        // the window plus one pixel of margin inside the image).
        let to_edge =
            p.x.min(p.y)
                .min(raw.width as f64 - 1.0 - p.x)
                .min(raw.height as f64 - 1.0 - p.y);
        let half = (0.4 * spacing).min(to_edge - 3.0).floor().clamp(2.0, 10.0) as usize;
        let q =
            subpix::refine_corner(&gradient_plane, *p, half).ok_or(DetectError::RefineFailed {
                index,
                x: p.x,
                y: p.y,
            })?;
        refined.push(q);
    }
    Ok(refined)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::rodrigues::pose_from_rodrigues;
    use crate::calibration::{Distortion, PinholeModel};
    use crate::synth::targets::{render_checkerboard, true_corners, RenderSettings};
    use nalgebra::Vector3;

    fn camera(rvec: Vector3<f64>, t: Vector3<f64>) -> PinholeModel {
        let mut cam = PinholeModel::ideal(320, 240, 330.0);
        cam.distortion = Distortion {
            k1: -0.15,
            k2: 0.05,
            ..Distortion::none()
        };
        cam.pose = pose_from_rodrigues(&rvec, &t);
        cam
    }

    const BOARD: Checkerboard = Checkerboard {
        cols: 9,
        rows: 6,
        square_m: 0.022,
    };

    #[test]
    fn detects_rendered_board_to_subpixel_accuracy() {
        let views = [
            (
                Vector3::new(0.2, -0.25, 0.1),
                Vector3::new(-0.09, -0.055, 0.42),
            ),
            // Turned upside down: the detector must still start at the dark corner.
            (Vector3::new(-0.1, 0.3, 2.9), Vector3::new(0.09, 0.05, 0.42)),
        ];
        for (rvec, t) in views {
            let cam = camera(rvec, t);
            let img = render_checkerboard(&cam, &BOARD, &RenderSettings::default());
            let found = detect_checkerboard(&img, &BOARD, &DetectOptions::default()).unwrap();
            let truth = true_corners(&cam, &BOARD);
            let sq: f64 = found
                .iter()
                .zip(&truth)
                .map(|(f, t)| (f - t.unwrap()).norm_squared())
                .sum();
            let rms = (sq / found.len() as f64).sqrt();
            eprintln!("detection rms {rms:.4} px (view {rvec:?})");
            assert!(rms < 0.1, "rms {rms} px for {rvec:?}");
        }
    }

    #[test]
    fn wrong_size_and_empty_images_are_typed_errors() {
        let cam = camera(
            Vector3::new(0.1, 0.1, 0.0),
            Vector3::new(-0.09, -0.055, 0.42),
        );
        let img = render_checkerboard(&cam, &BOARD, &RenderSettings::default());
        let bigger = Checkerboard { cols: 10, ..BOARD };
        assert!(matches!(
            detect_checkerboard(&img, &bigger, &DetectOptions::default()),
            Err(DetectError::WrongCount {
                expected_cols: 10,
                ..
            })
        ));
        let flat = GrayImage::from_pixel(64, 64, image::Luma([0.5]));
        assert!(matches!(
            detect_checkerboard(&flat, &BOARD, &DetectOptions::default()),
            Err(DetectError::NotFound { .. })
        ));
        let mut nan = flat.clone();
        nan.put_pixel(3, 3, image::Luma([f32::NAN]));
        assert!(matches!(
            detect_checkerboard(&nan, &BOARD, &DetectOptions::default()),
            Err(DetectError::NonFinitePixels { count: 1 })
        ));
    }

    #[test]
    fn loads_8_and_16_bit_png_and_tiff_as_unit_grey() {
        let dir = std::env::temp_dir().join(format!("slscan-load-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let img16 =
            image::ImageBuffer::from_fn(7, 5, |x, y| image::Luma([(x * 9000 + y * 700) as u16]));
        let img8 = image::ImageBuffer::from_fn(7, 5, |x, y| image::Luma([(x * 30 + y) as u8]));
        for (name, dynamic) in [
            ("a.tiff", image::DynamicImage::ImageLuma16(img16.clone())),
            ("a.png", image::DynamicImage::ImageLuma16(img16.clone())),
            ("b.png", image::DynamicImage::ImageLuma8(img8.clone())),
            ("b.tif", image::DynamicImage::ImageLuma8(img8.clone())),
        ] {
            let path = dir.join(name);
            dynamic.save(&path).unwrap();
            let g = load_gray(&path).unwrap();
            let (x, y) = (5, 3);
            let want = if name.starts_with('a') {
                f32::from(img16.get_pixel(x, y)[0]) / 65535.0
            } else {
                f32::from(img8.get_pixel(x, y)[0]) / 255.0
            };
            assert!((g.get_pixel(x, y)[0] - want).abs() < 1e-6, "{name}");
        }
        assert!(matches!(
            load_gray(&dir.join("missing.png")),
            Err(DetectError::Load { .. })
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
