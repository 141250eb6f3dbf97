//! Formula-based renders of calibration views (NOT the digital twin): the
//! calibration kernel tests use these closed-form images to test detection
//! and calibration in isolation (`slscan calibrate --sim` renders with the
//! twin, `crate::sim::calibration`). Each pixel
//! is integrated over `supersample^2` sub-pixel rays: the ray through the
//! sub-pixel (after inverting the lens distortion) meets the board plane, and
//! the checker colour there is averaged, so squares are anti-aliased exactly
//! as a box-filter sensor sees them. Gaussian noise is added and the result
//! quantised to 8 or 16 bits. The true corner pixels are the board corners
//! projected through the same model, so detection error is measurable.

use nalgebra::{Point2, Point3, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

use crate::calibration::board::{Checkerboard, CircleGrid, GrayImage};
use crate::calibration::PinholeModel;

/// Sensor bit depth of a rendered view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BitDepth {
    /// 8-bit: 255 levels.
    Eight,
    /// 16-bit: 65535 levels.
    Sixteen,
}

impl BitDepth {
    /// Largest code value.
    pub fn max_code(self) -> f64 {
        match self {
            BitDepth::Eight => 255.0,
            BitDepth::Sixteen => 65535.0,
        }
    }
}

/// How a view is rendered.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderSettings {
    /// Sub-pixel rays per pixel side.
    pub supersample: u32,
    /// Grey level of dark squares, [0, 1].
    pub dark: f64,
    /// Grey level of light squares and the board margin, [0, 1].
    pub light: f64,
    /// Grey level off the board, [0, 1].
    pub background: f64,
    /// White margin around the squares, in squares.
    pub margin_squares: f64,
    /// Standard deviation of additive Gaussian noise, grey levels in [0, 1].
    pub noise_sigma: f64,
    /// Quantisation.
    pub bit_depth: BitDepth,
    /// Seed of the noise.
    pub seed: u64,
    /// Lens blur after pixel integration: Gaussian sigma, pixels (0 = none).
    pub psf_sigma_px: f64,
    /// Vignetting: grey falls by this fraction at the image corners (r^2 law).
    pub vignetting: f64,
    /// Random grey rectangles behind the board, as a cluttered lab would be.
    pub clutter_rects: usize,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            supersample: 4,
            dark: 0.12,
            light: 0.85,
            background: 0.35,
            margin_squares: 1.0,
            noise_sigma: 0.01,
            bit_depth: BitDepth::Eight,
            seed: 1,
            psf_sigma_px: 0.0,
            vignetting: 0.0,
            clutter_rects: 0,
        }
    }
}

/// Undistorted normalised ray `(x, y)` at every pixel *corner*: entry
/// `(i, j)` is at pixel position `(i - 0.5, j - 0.5)`. Sub-pixel rays are
/// interpolated bilinearly inside a pixel (distortion is smooth at that scale).
fn corner_rays(camera: &PinholeModel) -> Vec<Option<(f64, f64)>> {
    let (w, h) = (camera.width_px as usize + 1, camera.height_px as usize + 1);
    (0..w * h)
        .into_par_iter()
        .map(|k| camera.pixel_to_normalised((k % w) as f64 - 0.5, (k / w) as f64 - 0.5))
        .collect()
}

/// Where the camera ray `(x, y, 1)` meets the board plane, board frame.
fn hit_board(camera: &PinholeModel, x: f64, y: f64) -> Option<Point2<f64>> {
    let r = &camera.pose.rotation;
    let t = &camera.pose.translation_m;
    let normal = r.column(2).into_owned();
    let d = Vector3::new(x, y, 1.0);
    let denom = normal.dot(&d);
    if denom.abs() < 1e-12 {
        return None;
    }
    let s = normal.dot(t) / denom;
    if s <= 0.0 {
        return None;
    }
    let p = r.transpose() * (d * s - t);
    Some(Point2::new(p.x, p.y))
}

/// Grey of the board at `p`; `None` off the board (background shows).
fn board_grey(board: &Checkerboard, s: &RenderSettings, p: Option<Point2<f64>>) -> Option<f64> {
    let p = p?;
    match board.is_dark(p.x, p.y) {
        Some(true) => Some(s.dark),
        Some(false) => Some(s.light),
        None => {
            let m = s.margin_squares * board.square_m;
            let (x1, y1) = (
                board.cols as f64 * board.square_m,
                board.rows as f64 * board.square_m,
            );
            let on_margin = p.x >= -board.square_m - m
                && p.x <= x1 + m
                && p.y >= -board.square_m - m
                && p.y <= y1 + m;
            on_margin.then_some(s.light)
        }
    }
}

/// Rectangles `(x0, y0, x1, y1, grey)` of background clutter.
fn clutter_rects(s: &RenderSettings, w: usize, h: usize) -> Vec<(usize, usize, usize, usize, f64)> {
    use rand::Rng;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(s.seed ^ 0x00c1_077e);
    (0..s.clutter_rects)
        .map(|_| {
            let (x0, y0) = (rng.random_range(0..w), rng.random_range(0..h));
            let (rw, rh) = (
                rng.random_range(5..w / 4 + 6),
                rng.random_range(5..h / 4 + 6),
            );
            (
                x0,
                y0,
                (x0 + rw).min(w),
                (y0 + rh).min(h),
                rng.random_range(0.0..1.0),
            )
        })
        .collect()
}

/// Lens blur and vignetting of the integrated image.
fn lens_and_vignetting(pixels: Vec<f32>, w: usize, h: usize, s: &RenderSettings) -> Vec<f32> {
    use crate::calibration::detect::filter::{gaussian_blur, Plane};
    let plane = gaussian_blur(
        &Plane {
            width: w,
            height: h,
            data: pixels,
        },
        s.psf_sigma_px,
    );
    if s.vignetting == 0.0 {
        return plane.data;
    }
    let (cx, cy) = (0.5 * (w as f64 - 1.0), 0.5 * (h as f64 - 1.0));
    let r2_max = cx * cx + cy * cy;
    plane
        .data
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let (x, y) = ((k % w) as f64 - cx, (k / w) as f64 - cy);
            (f64::from(*v) * (1.0 - s.vignetting * (x * x + y * y) / r2_max)) as f32
        })
        .collect()
}

/// At least `n^2` sample offsets in the unit pixel on a Fibonacci lattice
/// (`F_k` points, generator `F_(k-1)`, the smallest `F_k >= n^2`): every
/// sample has its own x and its own y, and the lattice has no direction in
/// which its points line up coarsely. A square `n x n` grid resolves edges
/// parallel to the pixel grid only to `1/n` px, and a rank-1 lattice of
/// `n^2` points does as badly along its own lattice lines: both biased the
/// rendered truth of some corners by up to 0.1 px (measured at n = 4).
fn subpixel_offsets(n: usize) -> Vec<(f64, f64)> {
    let (mut prev, mut count) = (1usize, 1usize);
    while count < n * n {
        (prev, count) = (count, prev + count);
    }
    (0..count)
        .map(|k| {
            let fx = (k as f64 + 0.5) / count as f64;
            let fy = ((k * prev) % count) as f64 / count as f64 + 0.5 / count as f64;
            (fx, fy)
        })
        .collect()
}

fn quantise(v: f64, depth: BitDepth) -> f32 {
    let m = depth.max_code();
    ((v.clamp(0.0, 1.0) * m).round() / m) as f32
}

/// Renders `board` seen by `camera`, whose pose maps board -> camera.
pub fn render_checkerboard(
    camera: &PinholeModel,
    board: &Checkerboard,
    settings: &RenderSettings,
) -> GrayImage {
    render_planar(camera, settings, |p| board_grey(board, settings, p))
}

/// Renders a symmetric grid of dark circles on a light plate (see
/// [`CircleGrid`]) seen by `camera`, whose pose maps board -> camera.
pub fn render_circle_grid(
    camera: &PinholeModel,
    grid: &CircleGrid,
    settings: &RenderSettings,
) -> GrayImage {
    let margin = grid.spacing_m * settings.margin_squares;
    let (x1, y1) = (
        (grid.cols - 1) as f64 * grid.spacing_m + margin,
        (grid.rows - 1) as f64 * grid.spacing_m + margin,
    );
    let r = 0.5 * grid.diameter_m;
    render_planar(camera, settings, |p| {
        let p = p?;
        if p.x < -margin || p.y < -margin || p.x > x1 || p.y > y1 {
            return None;
        }
        // Nearest circle centre.
        let i = (p.x / grid.spacing_m)
            .round()
            .clamp(0.0, (grid.cols - 1) as f64);
        let j = (p.y / grid.spacing_m)
            .round()
            .clamp(0.0, (grid.rows - 1) as f64);
        let (dx, dy) = (p.x - i * grid.spacing_m, p.y - j * grid.spacing_m);
        Some(if dx * dx + dy * dy <= r * r {
            settings.dark
        } else {
            settings.light
        })
    })
}

/// Renders a planar target whose grey at a board point is `grey` (`None`
/// off the target, where the background shows).
fn render_planar(
    camera: &PinholeModel,
    settings: &RenderSettings,
    grey: impl Fn(Option<Point2<f64>>) -> Option<f64> + Sync,
) -> GrayImage {
    let (w, h) = (camera.width_px as usize, camera.height_px as usize);
    let rays = corner_rays(camera);
    let offsets = subpixel_offsets(settings.supersample.max(1) as usize);
    let clutter = clutter_rects(settings, w, h);
    let background = |u: usize, v: usize| {
        clutter
            .iter()
            .rev()
            .find(|r| u >= r.0 && u < r.2 && v >= r.1 && v < r.3)
            .map_or(settings.background, |r| r.4)
    };
    let pixels: Vec<f32> = (0..w * h)
        .into_par_iter()
        .map(|k| {
            let (u, v) = (k % w, k / w);
            let c = |i: usize, j: usize| rays[j * (w + 1) + i];
            let (Some(a), Some(b), Some(cc), Some(d)) =
                (c(u, v), c(u + 1, v), c(u, v + 1), c(u + 1, v + 1))
            else {
                return background(u, v) as f32;
            };
            let mut sum = 0.0;
            for &(fx, fy) in &offsets {
                let x = (a.0 * (1.0 - fx) + b.0 * fx) * (1.0 - fy)
                    + (cc.0 * (1.0 - fx) + d.0 * fx) * fy;
                let y = (a.1 * (1.0 - fx) + b.1 * fx) * (1.0 - fy)
                    + (cc.1 * (1.0 - fx) + d.1 * fx) * fy;
                sum += grey(hit_board(camera, x, y)).unwrap_or_else(|| background(u, v));
            }
            (sum / offsets.len() as f64) as f32
        })
        .collect();
    let mut pixels = lens_and_vignetting(pixels, w, h, settings);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(settings.seed);
    let noise = Normal::new(0.0, settings.noise_sigma.max(0.0)).ok();
    for p in &mut pixels {
        let e = noise.map_or(0.0, |d| d.sample(&mut rng));
        *p = quantise(f64::from(*p) + e, settings.bit_depth);
    }
    GrayImage::from_raw(w as u32, h as u32, pixels)
        .unwrap_or_else(|| GrayImage::new(w as u32, h as u32))
}

/// The true pixel positions of the board's inner corners (row by row);
/// `None` for a corner behind the camera.
pub fn true_corners(camera: &PinholeModel, board: &Checkerboard) -> Vec<Option<Point2<f64>>> {
    board
        .corners_m()
        .iter()
        .map(|p| {
            camera
                .project(&Point3::new(p.x, p.y, 0.0))
                .map(Point2::from)
        })
        .collect()
}

/// Absolute phase maps in x and y that a projector would produce on the board.
///
/// `camera` and `projector` carry their poses board -> device. At each camera
/// pixel centre the ray meets the board; that point's projector pixel
/// `(u_p, v_p)` gives `phase_x = 2 pi u_p / period_px`, `phase_y = 2 pi v_p /
/// period_px`, plus Gaussian noise of `noise_rad`. Pixels off the board or
/// outside the projector's DMD are NaN (no fringe there).
pub fn render_phase_maps(
    camera: &PinholeModel,
    projector: &PinholeModel,
    board: &Checkerboard,
    period_px: f64,
    noise_rad: f64,
    seed: u64,
) -> (GrayImage, GrayImage) {
    let (w, h) = (camera.width_px as usize, camera.height_px as usize);
    let tau = std::f64::consts::TAU;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, noise_rad.max(0.0)).ok();
    let mut px = vec![f32::NAN; w * h];
    let mut py = vec![f32::NAN; w * h];
    for k in 0..w * h {
        let (u, v) = ((k % w) as f64, (k / w) as f64);
        let Some(hit) = camera
            .pixel_to_normalised(u, v)
            .and_then(|(x, y)| hit_board(camera, x, y))
        else {
            continue;
        };
        let m = board.square_m;
        let inside = hit.x >= -m
            && hit.y >= -m
            && hit.x <= board.cols as f64 * m
            && hit.y <= board.rows as f64 * m;
        if !inside {
            continue;
        }
        let Some(p) = projector.project(&Point3::new(hit.x, hit.y, 0.0)) else {
            continue;
        };
        if !projector.contains(&p) {
            continue;
        }
        let mut e = || noise.map_or(0.0, |d| d.sample(&mut rng));
        px[k] = (tau * p.x / period_px + e()) as f32;
        py[k] = (tau * p.y / period_px + e()) as f32;
    }
    let make = |d: Vec<f32>| {
        GrayImage::from_raw(w as u32, h as u32, d)
            .unwrap_or_else(|| GrayImage::new(w as u32, h as u32))
    };
    (make(px), make(py))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::rodrigues::pose_from_rodrigues;

    fn scene() -> (PinholeModel, Checkerboard) {
        let mut cam = PinholeModel::ideal(160, 120, 200.0);
        cam.pose = pose_from_rodrigues(
            &Vector3::new(0.1, -0.1, 0.0),
            &Vector3::new(-0.09, -0.06, 0.5),
        );
        let board = Checkerboard {
            cols: 9,
            rows: 6,
            square_m: 0.02,
        };
        (cam, board)
    }

    #[test]
    fn renders_dark_and_light_squares_where_the_model_says() {
        let (cam, board) = scene();
        let s = RenderSettings {
            noise_sigma: 0.0,
            ..Default::default()
        };
        let img = render_checkerboard(&cam, &board, &s);
        // Centre of the dark square touching corner (0, 0) from inside (+x, +y).
        let centre = cam.project(&Point3::new(0.01, 0.01, 0.0)).unwrap();
        let dark = img.get_pixel(centre.x.round() as u32, centre.y.round() as u32)[0];
        let centre = cam.project(&Point3::new(0.03, 0.01, 0.0)).unwrap();
        let light = img.get_pixel(centre.x.round() as u32, centre.y.round() as u32)[0];
        assert!((f64::from(dark) - s.dark).abs() < 0.01, "{dark}");
        assert!((f64::from(light) - s.light).abs() < 0.01, "{light}");
        // Quantised to 8 bits.
        assert!(img
            .pixels()
            .all(|p| ((p[0] * 255.0).round() - p[0] * 255.0).abs() < 1e-3));
    }

    #[test]
    fn clutter_blur_and_vignetting_change_the_image() {
        let (cam, board) = scene();
        let plain = RenderSettings {
            noise_sigma: 0.0,
            ..Default::default()
        };
        let base = render_checkerboard(&cam, &board, &plain);
        let cluttered = render_checkerboard(
            &cam,
            &board,
            &RenderSettings {
                clutter_rects: 10,
                ..plain
            },
        );
        let changed = base
            .as_raw()
            .iter()
            .zip(cluttered.as_raw())
            .filter(|(a, b)| a != b)
            .count();
        assert!(changed > 100, "{changed} pixels changed");
        let vignetted = render_checkerboard(
            &cam,
            &board,
            &RenderSettings {
                vignetting: 0.5,
                psf_sigma_px: 1.0,
                ..plain
            },
        );
        // Corner pixel (background) darkened by half.
        let (a, b) = (base.get_pixel(0, 0)[0], vignetted.get_pixel(0, 0)[0]);
        assert!((f64::from(b) - 0.5 * f64::from(a)).abs() < 0.01, "{a} {b}");
    }

    #[test]
    fn subpixel_offsets_are_distinct_in_x_and_y() {
        for (n, fibonacci) in [(1, 1), (2, 5), (4, 21), (5, 34)] {
            let o = subpixel_offsets(n);
            assert_eq!(o.len(), fibonacci);
            let mut xs: Vec<u64> = o.iter().map(|p| (p.0 * 1e9) as u64).collect();
            let mut ys: Vec<u64> = o.iter().map(|p| (p.1 * 1e9) as u64).collect();
            xs.dedup();
            ys.sort();
            ys.dedup();
            assert_eq!((xs.len(), ys.len()), (fibonacci, fibonacci), "n = {n}");
        }
    }

    #[test]
    fn phase_maps_encode_projector_pixels() {
        let (cam, board) = scene();
        let mut proj = PinholeModel::ideal(320, 240, 400.0);
        proj.pose = cam.pose;
        let (px, _py) = render_phase_maps(&cam, &proj, &board, 16.0, 0.0, 3);
        let corner = cam.project(&Point3::new(0.04, 0.04, 0.0)).unwrap();
        let (u, v) = (corner.x.round(), corner.y.round());
        let phase = f64::from(px.get_pixel(u as u32, v as u32)[0]);
        // Same pose, double focal, centred principal point: u_p = 2 u + 0.5.
        let expected = std::f64::consts::TAU * (2.0 * (u - 79.5) + 159.5) / 16.0;
        assert!((phase - expected).abs() < 1e-3, "{phase} vs {expected}");
        assert!(px.get_pixel(0, 0)[0].is_nan());
    }
}
