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

/// Per pixel, whether the consensus (inverse depths, NaN at holes) cannot
/// be trusted there: a hole, or within [`HOLE_GROWTH`] px of one.
pub(crate) fn uncertain_pixels(consensus: &[f64], width: usize, height: usize) -> Vec<bool> {
    grow_holes(consensus, width, height, HOLE_GROWTH)
        .iter()
        .map(|v| !v.is_finite())
        .collect()
}

/// `consensus` (inverse depths, NaN at holes) with its `uncertain` pixels
/// ([`uncertain_pixels`]) settled: each such pixel next to an edge (where
/// the surface met going left, right, up or down within [`SURFACE_REACH`]
/// px ([`surface_toward`]) differs from its smooth fill, `filled`
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
    uncertain: &[bool],
    width: usize,
    agree: f64,
    fit: impl Fn(usize, f64) -> f64 + Sync,
) -> Vec<f64> {
    let height = consensus.len() / width.max(1);
    let trusted: Vec<f64> = consensus
        .iter()
        .zip(uncertain)
        .map(|(&c, &u)| if u { f64::NAN } else { c })
        .collect();
    (0..consensus.len())
        .into_par_iter()
        .map(|i| {
            if !uncertain[i] {
                return consensus[i];
            }
            let around = [(1, 0), (-1, 0), (0, 1), (0, -1)]
                .map(|step| surface_toward(&trusted, width, height, i, step, SURFACE_REACH));
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

/// Every pattern's absolute phase and depth (`phases[m]`, `depths[m]`)
/// cleared (NaN) at the `uncertain` pixels where the depth is more than
/// `agree` (relative) off the inverse depth `predicted` its carriers were
/// demodulated against: there the prediction was a guess (a filled or
/// settled hole), and a pattern that decodes away from its own carrier's
/// depth is one the guess did not fit.
pub(crate) fn drop_unconfirmed(
    phases: &mut [Vec<f32>],
    depths: &mut [Vec<f32>],
    predicted: &[f64],
    uncertain: &[bool],
    agree: f64,
) {
    phases
        .par_iter_mut()
        .zip(depths.par_iter_mut())
        .for_each(|(phase, depth)| {
            let pixels = phase.iter_mut().zip(depth.iter_mut());
            for ((phase, depth), (&s, &uncertain)) in pixels.zip(predicted.iter().zip(uncertain)) {
                let found = 1.0 / f64::from(*depth);
                // NaN (not decoded, or no prediction) is not confirmed either.
                let confirmed = (found - s).abs() <= agree * s;
                if uncertain && !confirmed {
                    *phase = f32::NAN;
                    *depth = f32::NAN;
                }
            }
        });
}

/// How many known pixels past the first one met set the slope a surface is
/// extrapolated with ([`surface_toward`]).
const SLOPE_SPAN: usize = 3;

/// The surface met walking from pixel `i` by `step` (dx, dy), at most
/// `reach` steps: the first finite value, extrapolated back to pixel `i`
/// along the slope between it and the value [`SLOPE_SPAN`] steps further
/// (the first value alone where the further one is unknown or past the
/// image); NaN if none. A rim recedes steeply toward the edge: on `spheres` (one
/// settled pass) the extrapolation took the all-point fits' radius errors
/// from +15.6 / +13.5 to +9.6 / +13.1 mm and the per-instant depth RMSE
/// median from 6.39 to 5.76 mm (training stream 0.0645 -> 0.0642 rad).
fn surface_toward(
    values: &[f64],
    width: usize,
    height: usize,
    i: usize,
    (dx, dy): (isize, isize),
    reach: usize,
) -> f64 {
    let (mut x, mut y) = ((i % width) as isize, (i / width) as isize);
    let inside = |x: isize, y: isize| x >= 0 && y >= 0 && x < width as isize && y < height as isize;
    for k in 1..=reach {
        (x, y) = (x + dx, y + dy);
        if !inside(x, y) {
            break;
        }
        let first = values[y as usize * width + x as usize];
        if !first.is_finite() {
            continue;
        }
        let (fx, fy) = (x + dx * SLOPE_SPAN as isize, y + dy * SLOPE_SPAN as isize);
        if !inside(fx, fy) {
            return first;
        }
        let far = values[fy as usize * width + fx as usize];
        if !far.is_finite() {
            return first;
        }
        let slope = (far - first) / SLOPE_SPAN as f64;
        return first - slope * k as f64;
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
        let uncertain = uncertain_pixels(&v, w, h);
        let settled = settle_holes(&v, &filled, &uncertain, w, 0.02, |i, s| {
            -(s - truth(i)).abs()
        });
        for (i, &s) in settled.iter().enumerate() {
            assert_eq!(s, truth(i), "pixel {i}: {s}");
        }
        // Without a fit that tells the sides apart, the fill stays.
        let settled = settle_holes(&v, &filled, &uncertain, w, 0.02, |_, _| 0.0);
        assert_eq!(settled[7], filled[7]);
        assert_ne!(filled[7], truth(7));
        // A hole with no edge around it keeps its fill, whatever the fit says.
        let flat: Vec<f64> = (0..w * h)
            .map(|i| if i == 20 { f64::NAN } else { 3.0 })
            .collect();
        let uncertain = uncertain_pixels(&flat, w, h);
        let settled = settle_holes(
            &flat,
            &fill_holes(&flat, w, h),
            &uncertain,
            w,
            0.02,
            |_, s| s,
        );
        assert_eq!(settled[20], 3.0);
    }

    #[test]
    fn a_surface_is_extrapolated_along_its_slope() {
        // A ramp 10 + x with a hole at x 3..6: walking right from x 4 meets
        // x 6 (16) and x 9 (19), so it extrapolates to 14, the ramp's value.
        let w = 12;
        let mut v: Vec<f64> = (0..w).map(|x| 10.0 + x as f64).collect();
        v[3..6].fill(f64::NAN);
        assert_eq!(surface_toward(&v, w, 1, 4, (1, 0), 8), 14.0);
        // Walking left meets x 2 (12); x -1 is past the image: 12 alone.
        assert_eq!(surface_toward(&v, w, 1, 4, (-1, 0), 8), 12.0);
        // Nothing within reach.
        assert!(surface_toward(&v, w, 1, 4, (1, 0), 1).is_nan());
        // Up and down in a one-row image: past the image at once.
        assert!(surface_toward(&v, w, 1, 4, (0, 1), 8).is_nan());
    }

    #[test]
    fn decodes_off_an_uncertain_prediction_are_dropped() {
        // Three pixels predicted at 2 m (inverse 0.5); the first two
        // uncertain. Pattern 0 decodes 2.01 m (0.5 % off: kept) at pixel 0
        // and 2.5 m (20 % off: dropped) at 1; pixel 2 is trusted, so its
        // 2.5 m stays. NaN stays NaN.
        let mut depths = vec![vec![2.01f32, 2.5, 2.5], vec![f32::NAN, 2.0, 2.0]];
        let mut phases = vec![vec![1.0f32, 2.0, 3.0], vec![f32::NAN, 5.0, 6.0]];
        let predicted = [0.5; 3];
        drop_unconfirmed(
            &mut phases,
            &mut depths,
            &predicted,
            &[true, true, false],
            0.02,
        );
        assert_eq!(depths[0][0], 2.01);
        assert_eq!(phases[0][0], 1.0);
        assert!(depths[0][1].is_nan() && phases[0][1].is_nan());
        assert_eq!((depths[0][2], phases[0][2]), (2.5, 3.0));
        assert!(depths[1][0].is_nan() && phases[1][0].is_nan());
        assert_eq!((depths[1][1], phases[1][1]), (2.0, 5.0));
    }
}
