//! The depth a pixel's patterns agree on, for predicting every pattern's
//! carrier in a second demodulation ([`super::DecoderConfig::consensus_passes`]).

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
}
