//! The depth a pixel's patterns agree on, for predicting every pattern's
//! carrier in a second demodulation ([`super::DecoderConfig::consensus_passes`]),
//! and where they do not (depth edges), the surface around it that best
//! explains the fringes there.

use rayon::prelude::*;

/// Per pixel, the mean of the inverse depths `1 / depths_m[m][i]` (one map
/// per pattern) within `agree` (relative) of their median, where at least
/// `inliers` of the patterns decoded the pixel and agree; NaN elsewhere.
pub(crate) fn consensus_inverse_depth(
    depths_m: &[&[f32]],
    len: usize,
    agree: f64,
    inliers: usize,
) -> Vec<f64> {
    (0..len)
        .into_par_iter()
        .map_init(Vec::new, |found: &mut Vec<f64>, i| {
            found.clear();
            found.extend(
                depths_m
                    .iter()
                    .map(|d| 1.0 / f64::from(d[i]))
                    .filter(|s| s.is_finite() && *s > 0.0),
            );
            if found.len() < inliers.max(1) {
                return f64::NAN;
            }
            let mid = found.len() / 2;
            let median = *found.select_nth_unstable_by(mid, f64::total_cmp).1;
            let (sum, n) = found
                .iter()
                .filter(|s| (*s - median).abs() <= agree * median)
                .fold((0.0, 0usize), |(sum, n), s| (sum + s, n + 1));
            if n < inliers {
                f64::NAN
            } else {
                sum / n as f64
            }
        })
        .collect()
}

/// `values` (`width` x `height`, row-major) with every NaN replaced by a
/// smooth fill from the known values around it (push-pull: each hole takes
/// the bilinear sample of the half-size image, itself filled the same way),
/// so that nothing jumps where the known values end. All NaN stays all NaN.
pub(crate) fn fill_holes(values: &[f64], width: usize, height: usize) -> Vec<f64> {
    if values.iter().all(|v| v.is_finite()) || values.iter().all(|v| !v.is_finite()) {
        return values.to_vec();
    }
    let (cw, ch) = (width.div_ceil(2), height.div_ceil(2));
    let mut coarse = vec![f64::NAN; cw * ch];
    for (j, c) in coarse.iter_mut().enumerate() {
        let (cx, cy) = (j % cw, j / cw);
        let (mut sum, mut n) = (0.0, 0u32);
        for y in 2 * cy..(2 * cy + 2).min(height) {
            for x in 2 * cx..(2 * cx + 2).min(width) {
                let v = values[y * width + x];
                if v.is_finite() {
                    sum += v;
                    n += 1;
                }
            }
        }
        if n > 0 {
            *c = sum / f64::from(n);
        }
    }
    let coarse = fill_holes(&coarse, cw, ch);
    let at = |x: usize, y: usize| coarse[y.min(ch - 1) * cw + x.min(cw - 1)];
    values
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            if v.is_finite() {
                return v;
            }
            // The pixel's centre in the half-size image's pixel units.
            let fx = ((i % width) as f64 + 0.5) / 2.0 - 0.5;
            let fy = ((i / width) as f64 + 0.5) / 2.0 - 0.5;
            let (x0, y0) = (fx.floor().max(0.0), fy.floor().max(0.0));
            let (tx, ty) = ((fx - x0).clamp(0.0, 1.0), (fy - y0).clamp(0.0, 1.0));
            let (x0, y0) = (x0 as usize, y0 as usize);
            let top = at(x0, y0) * (1.0 - tx) + at(x0 + 1, y0) * tx;
            let bottom = at(x0, y0 + 1) * (1.0 - tx) + at(x0 + 1, y0 + 1) * tx;
            top * (1.0 - ty) + bottom * ty
        })
        .collect()
}

/// How far (pixels) from a hole's pixel the consensus is searched, along
/// each axis both ways, for the surfaces around it ([`settle_holes`]).
/// Training stream (`highspeed_eval --seed 1`, one pass, holes grown by 0,
/// with the nearest and the farthest consensus in the square as the
/// candidates): 4, 8, 16 px gave 0.0633, 0.0626, 0.0649 rad.
const SURFACE_REACH: usize = 8;

/// How far (pixels) holes in the consensus are grown before they are settled:
/// next to a hole the 24 depths often agree on a blend of both sides of an
/// edge. Training stream, 8 px reach: 0, 2, 4 px gave 0.0626, 0.0620,
/// 0.0633 rad.
const HOLE_GROWTH: usize = 2;

/// `consensus` (inverse depths, NaN at holes) with its holes, grown by
/// [`HOLE_GROWTH`], settled: each such pixel next to an edge (where the
/// first consensus met going left, right, up or down within
/// [`SURFACE_REACH`] px differs from its smooth fill, `filled`
/// ([`fill_holes`]), by more than `agree`, relative) takes whichever of its
/// fill, its own consensus (where it had one) and those four scores highest
/// on `fit(pixel, inverse depth)`. A hole at a depth edge lies between two
/// surfaces, and the smooth fill predicts neither; which one the pixel sees
/// is decided by its own light. The closest surface each way, not the
/// nearest or farthest in a square around it: on `spheres` the square's
/// extremes (the sphere's front, the wall) put rim pixels on the wall's
/// depth (the all-point fits' radius errors +33 / +37 mm against +16 / +13
/// mm), though the training stream's MAE was 0.0627 against 0.0643 rad.
/// Eight ways instead of four did as badly on `spheres` as the square: more
/// candidates, more chances for the noisy fit to pick a wrong one.
pub(crate) fn settle_holes(
    consensus: &[f64],
    filled: &[f64],
    width: usize,
    height: usize,
    agree: f64,
    fit: impl Fn(usize, f64) -> f64 + Sync,
) -> Vec<f64> {
    let grown = grow_holes(consensus, width, height, HOLE_GROWTH);
    (0..consensus.len())
        .into_par_iter()
        .map(|i| {
            if grown[i].is_finite() {
                return grown[i];
            }
            let around = [(1, 0), (-1, 0), (0, 1), (0, -1)]
                .map(|step| first_known(&grown, width, height, i, step, SURFACE_REACH));
            // Every surface around it within `agree` of the fill: no edge
            // to decide, the fill is as good as any.
            let near_fill = |c: f64| !c.is_finite() || (c - filled[i]).abs() <= agree * filled[i];
            if around.iter().all(|&c| near_fill(c)) {
                return filled[i];
            }
            let mut best = (filled[i], fit(i, filled[i]));
            for candidate in std::iter::once(consensus[i]).chain(around) {
                if candidate.is_finite() && candidate != best.0 {
                    let score = fit(i, candidate);
                    if score > best.1 || !best.1.is_finite() {
                        best = (candidate, score);
                    }
                }
            }
            best.0
        })
        .collect()
}

/// The first finite value met walking from pixel `i` by `step` (dx, dy),
/// at most `reach` steps and not past the image; NaN if none.
fn first_known(
    values: &[f64],
    width: usize,
    height: usize,
    i: usize,
    (dx, dy): (isize, isize),
    reach: usize,
) -> f64 {
    let (mut x, mut y) = ((i % width) as isize, (i / width) as isize);
    for _ in 0..reach {
        (x, y) = (x + dx, y + dy);
        if x < 0 || y < 0 || x >= width as isize || y >= height as isize {
            break;
        }
        let v = values[y as usize * width + x as usize];
        if v.is_finite() {
            return v;
        }
    }
    f64::NAN
}

/// `values` with NaN wherever a NaN lies within `by` pixels (square
/// neighbourhood; separable: a hole within `by` along the row, then within
/// `by` rows of that).
fn grow_holes(values: &[f64], width: usize, height: usize, by: usize) -> Vec<f64> {
    let mut in_row = vec![false; values.len()];
    in_row
        .par_chunks_mut(width)
        .zip(values.par_chunks(width))
        .for_each(|(out, row)| {
            for (x, o) in out.iter_mut().enumerate() {
                let span = &row[x.saturating_sub(by)..(x + by + 1).min(width)];
                *o = span.iter().any(|v| !v.is_finite());
            }
        });
    let mut grown = values.to_vec();
    grown
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(y, out)| {
            let rows = y.saturating_sub(by)..(y + by + 1).min(height);
            for (x, o) in out.iter_mut().enumerate() {
                if rows.clone().any(|yy| in_row[yy * width + x]) {
                    *o = f64::NAN;
                }
            }
        });
    grown
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holes_are_filled_between_their_known_neighbours() {
        // A ramp with a hole in the middle: the fill stays within the ramp's
        // values around the hole and leaves known values alone.
        let (w, h) = (16, 12);
        let mut v: Vec<f64> = (0..w * h).map(|i| (i % w) as f64).collect();
        for y in 4..8 {
            for x in 5..11 {
                v[y * w + x] = f64::NAN;
            }
        }
        let filled = fill_holes(&v, w, h);
        for (i, (&a, &b)) in v.iter().zip(&filled).enumerate() {
            assert!(b.is_finite());
            if a.is_finite() {
                assert_eq!(a, b);
            } else {
                let x = (i % w) as f64;
                assert!((b - x).abs() < 2.5, "pixel {i}: {b} for {x}");
            }
        }
        assert!(fill_holes(&[f64::NAN; 6], 3, 2).iter().all(|v| v.is_nan()));
    }

    #[test]
    fn the_consensus_ignores_patterns_that_disagree() {
        let maps: Vec<Vec<f32>> = (0..24)
            .map(|m| {
                vec![
                    1.0 / if m < 4 { 3.0 } else { 2.0 + m as f32 * 1e-4 },
                    f32::NAN,
                ]
            })
            .collect();
        let views: Vec<&[f32]> = maps.iter().map(|m| &m[..]).collect();
        let s = consensus_inverse_depth(&views, 2, 0.01, 16);
        let mean = (4..24).map(|m| 2.0 + f64::from(m) * 1e-4).sum::<f64>() / 20.0;
        assert!((s[0] - mean).abs() < 1e-5, "{}", s[0]);
        assert!(s[1].is_nan());
    }

    #[test]
    fn holes_grow_along_rows_and_columns() {
        // One row: 1, NaN, 5, NaN, NaN, NaN, 2.
        let v = [1.0, f64::NAN, 5.0, f64::NAN, f64::NAN, f64::NAN, 2.0];
        let grown = grow_holes(&v, 7, 1, 1);
        assert!(grown[..4].iter().all(|g| g.is_nan()));
        assert!(grown[6].is_nan());
        assert_eq!(grow_holes(&[1.0, 2.0], 2, 1, 1), vec![1.0, 2.0]);
        // Columns too: a 1x4 image.
        let col = grow_holes(&[1.0, 2.0, 3.0, f64::NAN], 1, 4, 1);
        assert_eq!(&col[..2], &[1.0, 2.0]);
        assert!(col[2].is_nan() && col[3].is_nan());
        // And by more than one pixel, diagonally (square neighbourhood).
        let mut square = vec![0.0; 25];
        square[0] = f64::NAN;
        let grown = grow_holes(&square, 5, 5, 2);
        for (i, g) in grown.iter().enumerate() {
            assert_eq!(g.is_nan(), i % 5 <= 2 && i / 5 <= 2, "pixel {i}");
        }
    }

    #[test]
    fn a_hole_at_a_step_takes_the_side_its_fit_prefers() {
        // A step from 2 (left) to 4 (right) with a hole across it: the fill
        // blends the two, the fit here prefers whichever side the pixel is
        // truly on (x < 8: 2), and every known pixel away from the hole stays.
        let (w, h) = (16, 4);
        let truth = |i: usize| if i % w < 8 { 2.0 } else { 4.0 };
        let mut v: Vec<f64> = (0..w * h).map(truth).collect();
        for y in 0..h {
            for x in 6..10 {
                v[y * w + x] = f64::NAN;
            }
        }
        let filled = fill_holes(&v, w, h);
        let settled = settle_holes(&v, &filled, w, h, 0.02, |i, s| -(s - truth(i)).abs());
        for (i, &s) in settled.iter().enumerate() {
            assert_eq!(s, truth(i), "pixel {i}: {s}");
        }
        // Without a fit that tells the sides apart, the fill stays.
        let settled = settle_holes(&v, &filled, w, h, 0.02, |_, _| 0.0);
        assert_eq!(settled[7], filled[7]);
        assert_ne!(filled[7], truth(7));
        // A hole with no edge around it keeps its fill, whatever the fit says.
        let flat: Vec<f64> = (0..w * h)
            .map(|i| if i == 20 { f64::NAN } else { 3.0 })
            .collect();
        let settled = settle_holes(&flat, &fill_holes(&flat, w, h), w, h, 0.02, |_, s| s);
        assert_eq!(settled[20], 3.0);
    }
}
