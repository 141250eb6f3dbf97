//! Bouguet's rectification (as `cv::stereoRectify`): each camera turned about its
//! centre, half the relative rotation each, then both together so that the baseline is
//! the x axis; with one focal length for both, rectified rows are epipolar lines.
//!
//! Set up once per head: every left pixel's rectified position (undistorted, rotated,
//! projected), and for every pixel of the rectified right grid the original, distorted
//! right pixel it samples (its top-left neighbour and the fractions between neighbours).

use nalgebra::{Matrix3, Rotation3, Vector3};
use rayon::prelude::*;

use super::{Side, StereoError};
use crate::calibration::{CameraModel, Intrinsics};

/// The rectified right image's extent in rectified pixel coordinates `f x_n`, `f y_n`
/// (`x_n`, `y_n` normalised in the rectified frame): grid pixel `(i, j)` is at
/// `(x0 + i, y0 + j)`. Left pixels are given in the same grid coordinates, so a match's
/// disparity is the difference of the two `x`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RectifiedGrid {
    /// Rectified x of grid column 0, pixels.
    pub x0: f64,
    /// Rectified y of grid row 0, pixels.
    pub y0: f64,
    /// Columns.
    pub width: usize,
    /// Rows: the rows both cameras see.
    pub height: usize,
}

/// The rectification of one stereo head and its maps.
#[derive(Clone, Debug)]
pub struct Rectification {
    focal_px: f64,
    baseline_m: f64,
    left_rotation: Matrix3<f64>,
    right_rotation: Matrix3<f64>,
    grid: RectifiedGrid,
    left_size: (usize, usize),
    right_size: (usize, usize),
    /// Per left pixel, row-major: rectified grid x and y (NaN where it has no ray).
    left_x: Vec<f32>,
    left_y: Vec<f32>,
    /// Per rectified grid pixel: index of the top-left of the four right pixels nearest
    /// its source (`u32::MAX` where it has none) and the fractions between them.
    right_base: Vec<u32>,
    right_frac: Vec<[f32; 2]>,
}

/// Largest rectified grid, in units of the right camera's pixel count.
const MAX_GRID_FACTOR: usize = 4;

impl Rectification {
    /// Checks both cameras and sets up the rotations and maps.
    pub fn new(left: &CameraModel, right: &CameraModel) -> Result<Self, StereoError> {
        check_camera(left, Side::Left)?;
        check_camera(right, Side::Right)?;
        // Right from left: x_R = R x_L + t.
        let relative = right.pose.rotation * left.pose.rotation.transpose();
        let t = right.pose.translation_m - relative * left.pose.translation_m;
        if t.norm() < 1e-6 {
            return Err(StereoError::NoBaseline);
        }
        // Half the relative rotation each (Bouguet): r_half rotates the left camera
        // forward, its inverse the right camera back, to a common orientation.
        let half = Rotation3::new(-0.5 * Rotation3::from_matrix(&relative).scaled_axis());
        let t_half = half * t;
        // The right centre in the common (half-rotated) left frame is -t_half.
        let baseline = -t_half;
        let baseline_m = [baseline.x, baseline.y, baseline.z];
        if baseline.x.abs() <= baseline.y.abs().max(baseline.z.abs()) {
            return Err(StereoError::NotSideBySide { baseline_m });
        }
        if baseline.x < 0.0 {
            return Err(StereoError::Swapped { baseline_m });
        }
        // Then both together, turning t_half onto -x (the right camera on +x).
        let target = Vector3::new(-1.0, 0.0, 0.0);
        let axis = t_half.cross(&target);
        let turn = if axis.norm() > 0.0 {
            let angle = (t_half.x.abs() / t_half.norm()).clamp(-1.0, 1.0).acos();
            Rotation3::new(axis.normalize() * angle)
        } else {
            Rotation3::identity()
        };
        let left_rotation = (turn * half.inverse()).into_inner();
        let right_rotation = (turn * half).into_inner();
        // One focal length for both, the smallest: the rectified grid never samples
        // the right image more coarsely than its own pixels in either direction.
        let k = [left.intrinsics, right.intrinsics];
        let focal_px = k
            .iter()
            .map(|k| k.fx.min(k.fy))
            .fold(f64::INFINITY, f64::min);
        let left_box = footprint(left, &left_rotation, focal_px);
        let right_box = footprint(right, &right_rotation, focal_px);
        let (Some(lb), Some(rb)) = (left_box, right_box) else {
            return Err(StereoError::NoOverlap);
        };
        let (y_lo, y_hi) = (lb[2].max(rb[2]).floor(), lb[3].min(rb[3]).ceil());
        if y_hi <= y_lo {
            return Err(StereoError::NoOverlap);
        }
        let (x_lo, x_hi) = (rb[0].floor(), rb[1].ceil());
        let width = (x_hi - x_lo) as usize + 1;
        let height = (y_hi - y_lo) as usize + 1;
        let right_px = right.width_px as usize * right.height_px as usize;
        if width.saturating_mul(height) > MAX_GRID_FACTOR * right_px {
            return Err(StereoError::RectifiedTooLarge { width, height });
        }
        let grid = RectifiedGrid {
            x0: x_lo,
            y0: y_lo,
            width,
            height,
        };
        let (left_x, left_y) = left_maps(left, &left_rotation, focal_px, &grid);
        let (right_base, right_frac) = right_maps(right, &right_rotation, focal_px, &grid);
        Ok(Self {
            focal_px,
            baseline_m: t.norm(),
            left_rotation,
            right_rotation,
            grid,
            left_size: (left.width_px as usize, left.height_px as usize),
            right_size: (right.width_px as usize, right.height_px as usize),
            left_x,
            left_y,
            right_base,
            right_frac,
        })
    }

    /// The common rectified focal length, pixels.
    pub fn focal_px(&self) -> f64 {
        self.focal_px
    }

    /// Distance between the camera centres, metres.
    pub fn baseline_m(&self) -> f64 {
        self.baseline_m
    }

    /// Left camera frame -> rectified frame (OpenCV's `R1`).
    pub fn left_rotation(&self) -> &Matrix3<f64> {
        &self.left_rotation
    }

    /// Right camera frame -> rectified frame (OpenCV's `R2`).
    pub fn right_rotation(&self) -> &Matrix3<f64> {
        &self.right_rotation
    }

    /// The rectified right grid.
    pub fn grid(&self) -> RectifiedGrid {
        self.grid
    }

    /// The rectified intrinsics of grid pixels (no distortion): `cx = -x0`, `cy = -y0`.
    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics {
            fx: self.focal_px,
            fy: self.focal_px,
            cx: -self.grid.x0,
            cy: -self.grid.y0,
        }
    }

    /// The left camera's `(width, height)`.
    pub fn left_size(&self) -> (usize, usize) {
        self.left_size
    }

    /// The right camera's `(width, height)`.
    pub fn right_size(&self) -> (usize, usize) {
        self.right_size
    }

    /// Rectified grid x and y of every pixel of left row `y` (NaN where no ray).
    pub fn left_row(&self, y: usize) -> (&[f32], &[f32]) {
        let w = self.left_size.0;
        (
            &self.left_x[y * w..(y + 1) * w],
            &self.left_y[y * w..(y + 1) * w],
        )
    }

    /// The original right pixel `(x, y)` that rectified grid pixel `(i, j)` samples;
    /// `None` outside the right image.
    pub fn right_source(&self, i: usize, j: usize) -> Option<[f32; 2]> {
        let k = j * self.grid.width + i;
        let base = *self.right_base.get(k)?;
        (base != u32::MAX).then(|| {
            let w = self.right_size.0;
            let (bx, by) = (base as usize % w, base as usize / w);
            let [fx, fy] = self.right_frac[k];
            [bx as f32 + fx, by as f32 + fy]
        })
    }

    /// Grid row `j`'s sampling: base indices and bilinear fractions.
    pub(super) fn right_row(&self, j: usize) -> (&[u32], &[[f32; 2]]) {
        let w = self.grid.width;
        (
            &self.right_base[j * w..(j + 1) * w],
            &self.right_frac[j * w..(j + 1) * w],
        )
    }
}

fn check_camera(c: &CameraModel, camera: Side) -> Result<(), StereoError> {
    let k = &c.intrinsics;
    let d = &c.distortion;
    let t = &c.pose.translation_m;
    let fields = [
        ("width_px", f64::from(c.width_px), c.width_px >= 4),
        ("height_px", f64::from(c.height_px), c.height_px >= 4),
        ("fx", k.fx, k.fx.is_finite() && k.fx > 0.0),
        ("fy", k.fy, k.fy.is_finite() && k.fy > 0.0),
        ("cx", k.cx, k.cx.is_finite()),
        ("cy", k.cy, k.cy.is_finite()),
        ("k1", d.k1, d.k1.is_finite()),
        ("k2", d.k2, d.k2.is_finite()),
        ("p1", d.p1, d.p1.is_finite()),
        ("p2", d.p2, d.p2.is_finite()),
        ("k3", d.k3, d.k3.is_finite()),
        ("translation_m.x", t.x, t.x.is_finite()),
        ("translation_m.y", t.y, t.y.is_finite()),
        ("translation_m.z", t.z, t.z.is_finite()),
    ];
    if let Some(&(field, value, _)) = fields.iter().find(|f| !f.2) {
        return Err(StereoError::Calibration {
            camera,
            field,
            value,
        });
    }
    let defect = c.pose.rotation_defect();
    if defect.is_nan() || defect >= 1e-6 {
        return Err(StereoError::NotARotation { camera, defect });
    }
    Ok(())
}

/// Whether the radial distortion is still monotonic at `r2 = x^2 + y^2`: beyond, the
/// polynomial folds outside points back onto the image.
fn radially_monotonic(c: &CameraModel, x: f64, y: f64) -> bool {
    let d = &c.distortion;
    let r2 = x * x + y * y;
    1.0 + r2 * (3.0 * d.k1 + r2 * (5.0 * d.k2 + r2 * 7.0 * d.k3)) > 0.0
}

/// Rectified pixel `(f x_n, f y_n)` of an original pixel; `None` without a ray in front.
fn rectified(c: &CameraModel, rotation: &Matrix3<f64>, f: f64, u: f64, v: f64) -> Option<[f64; 2]> {
    let (x, y) = c.pixel_to_normalised(u, v)?;
    let r = rotation * Vector3::new(x, y, 1.0);
    (r.z > 1e-9).then(|| [f * r.x / r.z, f * r.y / r.z])
}

/// Bounding box `[x_min, x_max, y_min, y_max]` of a camera's border pixels rectified.
fn footprint(c: &CameraModel, rotation: &Matrix3<f64>, f: f64) -> Option<[f64; 4]> {
    let (w, h) = (f64::from(c.width_px) - 1.0, f64::from(c.height_px) - 1.0);
    let mut border = Vec::new();
    for i in 0..c.width_px {
        border.extend([(f64::from(i), 0.0), (f64::from(i), h)]);
    }
    for j in 0..c.height_px {
        border.extend([(0.0, f64::from(j)), (w, f64::from(j))]);
    }
    let mut b = [
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for (u, v) in border {
        if let Some([x, y]) = rectified(c, rotation, f, u, v) {
            b = [b[0].min(x), b[1].max(x), b[2].min(y), b[3].max(y)];
        }
    }
    b[0].is_finite().then_some(b)
}

/// Every left pixel's rectified grid position.
fn left_maps(
    c: &CameraModel,
    rotation: &Matrix3<f64>,
    f: f64,
    grid: &RectifiedGrid,
) -> (Vec<f32>, Vec<f32>) {
    let w = c.width_px as usize;
    let rows: Vec<(Vec<f32>, Vec<f32>)> = (0..c.height_px as usize)
        .into_par_iter()
        .map(|y| {
            (0..w)
                .map(|x| match rectified(c, rotation, f, x as f64, y as f64) {
                    Some([rx, ry]) => ((rx - grid.x0) as f32, (ry - grid.y0) as f32),
                    None => (f32::NAN, f32::NAN),
                })
                .unzip()
        })
        .collect();
    let mut xs = Vec::with_capacity(w * rows.len());
    let mut ys = Vec::with_capacity(w * rows.len());
    for (rx, ry) in rows {
        xs.extend(rx);
        ys.extend(ry);
    }
    (xs, ys)
}

/// Every rectified grid pixel's source in the right image: the index of the top-left of
/// its four nearest pixels and the fractions between them (`u32::MAX` where the source
/// is within a pixel of the edge or off the image, or where the distortion polynomial
/// has folded over).
fn right_maps(
    c: &CameraModel,
    rotation: &Matrix3<f64>,
    f: f64,
    grid: &RectifiedGrid,
) -> (Vec<u32>, Vec<[f32; 2]>) {
    let back = rotation.transpose();
    let (w, h) = (c.width_px as usize, c.height_px as usize);
    let rows: Vec<(Vec<u32>, Vec<[f32; 2]>)> = (0..grid.height)
        .into_par_iter()
        .map(|j| {
            (0..grid.width)
                .map(|i| {
                    let xn = (i as f64 + grid.x0) / f;
                    let yn = (j as f64 + grid.y0) / f;
                    let ray = back * Vector3::new(xn, yn, 1.0);
                    if ray.z <= 1e-9 {
                        return (u32::MAX, [0.0; 2]);
                    }
                    let (x, y) = (ray.x / ray.z, ray.y / ray.z);
                    if !radially_monotonic(c, x, y) {
                        return (u32::MAX, [0.0; 2]);
                    }
                    let p = c.normalised_to_pixel(x, y);
                    // Bicubic resampling reads a 4 x 4 neighbourhood: the source keeps one
                    // pixel from the edge, and the last inner column / row samples with
                    // fraction 1 from its left / upper neighbour.
                    let inside =
                        p.x >= 1.0 && p.y >= 1.0 && p.x <= (w - 2) as f64 && p.y <= (h - 2) as f64;
                    if !inside {
                        return (u32::MAX, [0.0; 2]);
                    }
                    let bx = (p.x.floor() as usize).min(w - 3);
                    let by = (p.y.floor() as usize).min(h - 3);
                    let frac = [(p.x - bx as f64) as f32, (p.y - by as f64) as f32];
                    ((by * w + bx) as u32, frac)
                })
                .unzip()
        })
        .collect();
    let mut base = Vec::with_capacity(grid.width * grid.height);
    let mut frac = Vec::with_capacity(grid.width * grid.height);
    for (b, fr) in rows {
        base.extend(b);
        frac.extend(fr);
    }
    (base, frac)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::{PinholeModel, Pose};
    use nalgebra::Point3;

    #[test]
    fn rectified_rows_are_epipolar_lines_and_the_baseline_is_the_x_axis() {
        let mut left = PinholeModel::ideal(320, 240, 350.0);
        left.pose = Pose {
            rotation: *Rotation3::from_euler_angles(0.02, 0.15, -0.01).matrix(),
            translation_m: Vector3::new(0.01, -0.02, 0.03),
        };
        let mut right = PinholeModel::ideal(320, 240, 360.0);
        right.pose = Pose {
            rotation: *Rotation3::from_euler_angles(-0.01, -0.17, 0.02).matrix(),
            translation_m: Vector3::new(-0.15, 0.01, 0.02),
        };
        let r = Rectification::new(&left, &right).unwrap();
        let (r1, r2) = (r.left_rotation(), r.right_rotation());
        for w in [
            Point3::new(0.1, 0.05, 0.6),
            Point3::new(-0.2, -0.1, 0.4),
            Point3::new(0.0, 0.2, 1.5),
        ] {
            let a = r1 * left.pose.apply(&w).coords;
            let b = r2 * right.pose.apply(&w).coords;
            assert!((a.y / a.z - b.y / b.z).abs() < 1e-12, "{a} {b}");
            // Same depth, shifted by the baseline along x.
            assert!((a.z - b.z).abs() < 1e-12 && (a.x - b.x - r.baseline_m()).abs() < 1e-12);
        }
        // Grid sources of the rectified right grid project back where they came from.
        let g = r.grid();
        let (i, j) = (g.width / 2, g.height / 2);
        let src = r.right_source(i, j).unwrap();
        let k = r.intrinsics();
        let ray =
            r2.transpose() * Vector3::new((i as f64 - k.cx) / k.fx, (j as f64 - k.cy) / k.fy, 1.0);
        let p = right.normalised_to_pixel(ray.x / ray.z, ray.y / ray.z);
        assert!((f64::from(src[0]) - p.x).abs() < 1e-4 && (f64::from(src[1]) - p.y).abs() < 1e-4);
    }
}
