//! A colour camera's raw Bayer mosaic to red, green and blue planes.
//!
//! Bilinear interpolation: each missing sample is the mean of the samples of
//! its colour in the pixel's 3x3 neighbourhood (two or four of them; fewer
//! at the border). That keeps every plane a linear function of the raw
//! values, which the high-speed decoder's crosstalk unmixing assumes, and
//! needs no tuning. Written here rather than taken from a crate: the Rust
//! demosaicing crates are unmaintained and work on integer images, and the
//! interpolation is a dozen lines.

use crate::raster::Raster;

/// The colour filter layout, named as PFNC names it: the colours of the
/// mosaic's first row, starting at its top-left pixel (`Rg`: R G / G B).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Cfa {
    /// R G / G B.
    Rg,
    /// G R / B G.
    Gr,
    /// G B / R G.
    Gb,
    /// B G / G R.
    Bg,
}

impl Cfa {
    /// The colour (0 red, 1 green, 2 blue) of the filter over pixel (x, y).
    pub fn colour_at(self, x: usize, y: usize) -> usize {
        // The 2x2 cell, row by row.
        let cell = match self {
            Cfa::Rg => [0, 1, 1, 2],
            Cfa::Gr => [1, 0, 2, 1],
            Cfa::Gb => [1, 2, 0, 1],
            Cfa::Bg => [2, 1, 1, 0],
        };
        cell[(y % 2) * 2 + x % 2]
    }
}

/// The red, green and blue planes of `raw`, a mosaic of layout `cfa`,
/// interpolated bilinearly (see the module doc).
pub fn demosaic_bilinear(raw: &Raster<f32>, cfa: Cfa) -> [Raster<f32>; 3] {
    let (w, h) = (raw.width, raw.height);
    [0, 1, 2].map(|colour| {
        Raster::from_fn(w, h, |x, y| {
            if cfa.colour_at(x, y) == colour {
                return *raw.at(x, y);
            }
            let (mut sum, mut count) = (0.0f32, 0u32);
            for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                    if cfa.colour_at(nx, ny) == colour {
                        sum += *raw.at(nx, ny);
                        count += 1;
                    }
                }
            }
            // A 1-pixel-wide or -high mosaic can lack a colour nearby.
            if count == 0 {
                f32::NAN
            } else {
                sum / count as f32
            }
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mosaic a sensor of layout `cfa` records of the planes `rgb`.
    fn mosaic(rgb: &[Raster<f32>; 3], cfa: Cfa) -> Raster<f32> {
        Raster::from_fn(rgb[0].width, rgb[0].height, |x, y| {
            *rgb[cfa.colour_at(x, y)].at(x, y)
        })
    }

    #[test]
    fn every_layout_has_one_red_one_blue_and_two_greens_per_cell() {
        for cfa in [Cfa::Rg, Cfa::Gr, Cfa::Gb, Cfa::Bg] {
            let mut counts = [0; 3];
            for (x, y) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                counts[cfa.colour_at(x, y)] += 1;
            }
            assert_eq!(counts, [1, 2, 1], "{cfa:?}");
        }
        assert_eq!(Cfa::Bg.colour_at(0, 0), 2);
        assert_eq!(Cfa::Gr.colour_at(1, 0), 0);
    }

    #[test]
    fn linear_ramps_come_back_exactly_inside_the_border() {
        // Bilinear interpolation reproduces planes linear in x and y.
        let rgb = [
            Raster::from_fn(9, 7, |x, y| 0.1 + 0.02 * x as f32 + 0.01 * y as f32),
            Raster::from_fn(9, 7, |x, y| 0.5 - 0.03 * x as f32 + 0.02 * y as f32),
            Raster::from_fn(9, 7, |x, y| 0.2 + 0.01 * x as f32 - 0.02 * y as f32),
        ];
        for cfa in [Cfa::Rg, Cfa::Gr, Cfa::Gb, Cfa::Bg] {
            let planes = demosaic_bilinear(&mosaic(&rgb, cfa), cfa);
            for c in 0..3 {
                for y in 1..6 {
                    for x in 1..8 {
                        let (got, want) = (*planes[c].at(x, y), *rgb[c].at(x, y));
                        assert!((got - want).abs() < 1e-6, "{cfa:?} {c} ({x},{y})");
                    }
                }
            }
        }
    }

    #[test]
    fn recorded_samples_pass_through_and_a_one_pixel_mosaic_lacks_two_colours() {
        let raw = Raster::from_fn(4, 4, |x, y| (x + 4 * y) as f32);
        let planes = demosaic_bilinear(&raw, Cfa::Rg);
        assert_eq!(*planes[0].at(2, 2), 10.0);
        assert_eq!(*planes[2].at(3, 3), 15.0);
        let one = demosaic_bilinear(&Raster::filled(1, 1, 0.5), Cfa::Gr);
        assert_eq!(one[1].data, vec![0.5]);
        assert!(one[0].data[0].is_nan() && one[2].data[0].is_nan());
    }
}
