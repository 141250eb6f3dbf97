//! The calibration target: a planar checkerboard and its corner layout.
//!
//! Board frame: origin at inner corner (0, 0), x along the `cols` direction,
//! y along the `rows` direction, z into the board (away from a camera that
//! sees the printed side), metres. Corners are listed row by row:
//! index `j * cols + i` is at `(i * square_m, j * square_m, 0)`.
//! The square touching corner (0, 0) from outside, and every square of the
//! same parity, is dark.

use nalgebra::Point2;

/// An image as the detector reads it: grey, f32 in [0, 1], row-major.
pub type GrayImage = image::ImageBuffer<image::Luma<f32>, Vec<f32>>;

/// A checkerboard of `cols x rows` inner corners with square side `square_m`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Checkerboard {
    /// Inner corners along the board's x axis.
    pub cols: usize,
    /// Inner corners along the board's y axis.
    pub rows: usize,
    /// Side of one square, metres.
    pub square_m: f64,
}

impl Checkerboard {
    /// Number of inner corners.
    pub fn corner_count(&self) -> usize {
        self.cols * self.rows
    }

    /// Inner corners in the board plane, row by row, metres.
    pub fn corners_m(&self) -> Vec<Point2<f64>> {
        (0..self.rows)
            .flat_map(|j| {
                (0..self.cols)
                    .map(move |i| Point2::new(i as f64 * self.square_m, j as f64 * self.square_m))
            })
            .collect()
    }

    /// Whether the board point `(x_m, y_m)` lies on a dark square; `None`
    /// outside the squares (on the white margin or beyond).
    pub fn is_dark(&self, x_m: f64, y_m: f64) -> Option<bool> {
        let a = (x_m / self.square_m).floor() + 1.0;
        let b = (y_m / self.square_m).floor() + 1.0;
        let inside = (0.0..=self.cols as f64).contains(&a) && (0.0..=self.rows as f64).contains(&b);
        inside.then(|| (a as i64 + b as i64) % 2 == 0)
    }

    /// Whether a 180-degree turn of the board looks the same (`cols + rows`
    /// even): then the detector cannot tell corner (0, 0) from the opposite
    /// one and picks the one nearer the image's top-left.
    pub fn is_point_symmetric(&self) -> bool {
        (self.cols + self.rows).is_multiple_of(2)
    }
}

/// A symmetric grid of `cols x rows` dark circles on a light plate, centres
/// `spacing_m` apart. Board frame as [`Checkerboard`]'s, with circle
/// `(i, j)` at `(i * spacing_m, j * spacing_m, 0)`, listed row by row. The
/// grid looks the same turned by 180 degrees, so the detector takes the
/// circle nearest the image's top-left as `(0, 0)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircleGrid {
    /// Circles along the board's x axis.
    pub cols: usize,
    /// Circles along the board's y axis.
    pub rows: usize,
    /// Centre-to-centre distance, metres.
    pub spacing_m: f64,
    /// Circle diameter, metres.
    pub diameter_m: f64,
}

impl CircleGrid {
    /// Circle centres in the board plane, row by row, metres.
    pub fn centres_m(&self) -> Vec<Point2<f64>> {
        (0..self.rows)
            .flat_map(|j| {
                (0..self.cols)
                    .map(move |i| Point2::new(i as f64 * self.spacing_m, j as f64 * self.spacing_m))
            })
            .collect()
    }
}

/// The calibration targets the detector knows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Target {
    /// A checkerboard (inner corners).
    Checkerboard(Checkerboard),
    /// A symmetric circle grid (circle centres).
    CircleGrid(CircleGrid),
}

impl Target {
    /// The target's feature points in its plane, row by row, metres.
    pub fn points_m(&self) -> Vec<Point2<f64>> {
        match self {
            Target::Checkerboard(b) => b.corners_m(),
            Target::CircleGrid(g) => g.centres_m(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_and_colours() {
        let b = Checkerboard {
            cols: 9,
            rows: 6,
            square_m: 0.02,
        };
        let c = b.corners_m();
        assert_eq!(c.len(), 54);
        assert_eq!(c[10], Point2::new(0.02, 0.02));
        assert_eq!(b.is_dark(-0.01, -0.01), Some(true));
        assert_eq!(b.is_dark(0.01, -0.01), Some(false));
        assert_eq!(b.is_dark(0.01, 0.01), Some(true));
        assert_eq!(b.is_dark(-0.03, 0.01), None);
        assert_eq!(b.is_dark(0.179, 0.119), Some(false));
        assert_eq!(b.is_dark(0.181, 0.119), None);
        assert!(!b.is_point_symmetric());
    }
}
