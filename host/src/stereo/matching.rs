//! Matching a left pixel's projector coordinate on the rectified right rows.
//!
//! The right coordinate map is resampled onto the rectified grid (bilinear, only where
//! all four neighbours are decoded and bright enough). Along a rectified row the
//! coordinate is locally monotonic: each row is cut into *runs*, maximal stretches of
//! neighbour pairs that are both valid, step the same way and by at most
//! `max_step_px` (a larger step is a depth edge). A left value is matched by binary
//! search inside the runs of the disparity window, to the bracketing pair, and linear
//! interpolation between them. A value found in two runs is ambiguous and refused.
//!
//! A left pixel's rectified row `y` is not an integer: it is matched on rows
//! `floor(y)` and `floor(y) + 1` and the two positions are interpolated, refused when
//! they differ by more than `max_row_shift_px` (an edge between the rows).

use rayon::prelude::*;

use super::rectify::Rectification;
use super::StereoConfig;
use crate::raster::Raster;

/// A maximal monotonic stretch of a rectified row: samples `start..=end`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Run {
    start: u32,
    end: u32,
    increasing: bool,
}

/// A left pixel's match on the rectified right image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Match {
    /// Rectified grid x of the match, pixels.
    pub x: f32,
    /// The right coordinate's slope there, projector pixels per rectified pixel.
    pub slope: f32,
    /// The right modulation there.
    pub modulation: f32,
}

/// The right coordinate and modulation on the rectified grid, with each row's runs.
pub(super) struct RectifiedRight {
    width: usize,
    height: usize,
    u: Vec<f32>,
    modulation: Vec<f32>,
    runs: Vec<Vec<Run>>,
}

impl RectifiedRight {
    /// Resamples the right maps (sizes checked by the caller) and cuts the rows.
    pub fn new(
        r: &Rectification,
        right_u: &Raster<f32>,
        right_modulation: &Raster<f32>,
        config: &StereoConfig,
    ) -> Self {
        let grid = r.grid();
        let (w, h) = (grid.width, grid.height);
        let mut u = vec![0.0f32; w * h];
        let mut modulation = vec![0.0f32; w * h];
        let runs: Vec<Vec<Run>> = u
            .par_chunks_mut(w)
            .zip(modulation.par_chunks_mut(w))
            .enumerate()
            .map(|(j, (u_row, b_row))| {
                let (base, frac) = r.right_row(j);
                resample_row(
                    right_u,
                    right_modulation,
                    config.min_modulation,
                    base,
                    frac,
                    u_row,
                    b_row,
                );
                let mut runs = Vec::new();
                runs_of_row(u_row, config.max_step_px, &mut runs);
                runs
            })
            .collect();
        Self {
            width: w,
            height: h,
            u,
            modulation,
            runs,
        }
    }

    /// The match of coordinate `v` for a left pixel at rectified grid `(x, y)`, with
    /// disparities in `d_min..=d_max` (grid pixels); `None` where there is none, or
    /// more than one, or the two rows disagree by more than `max_row_shift_px`.
    pub fn find(
        &self,
        x: f32,
        y: f32,
        v: f32,
        d_min: f32,
        d_max: f32,
        max_row_shift_px: f32,
    ) -> Option<Match> {
        if !(x.is_finite() && y.is_finite() && y >= 0.0) {
            return None;
        }
        let row = y.floor();
        let (j, s) = (row as usize, y - row);
        if j + 1 >= self.height {
            return None;
        }
        let (lo, hi) = (x - d_max, x - d_min);
        let a = self.find_in_row(j, v, lo, hi)?;
        let b = self.find_in_row(j + 1, v, lo, hi)?;
        if (a.x - b.x).abs() > max_row_shift_px {
            return None;
        }
        Some(Match {
            x: a.x + s * (b.x - a.x),
            slope: a.slope + s * (b.slope - a.slope),
            modulation: a.modulation + s * (b.modulation - a.modulation),
        })
    }

    /// The single bracketing pair of `v` in row `j` between grid x `lo` and `hi`.
    fn find_in_row(&self, j: usize, v: f32, lo: f32, hi: f32) -> Option<Match> {
        let row = &self.u[j * self.width..(j + 1) * self.width];
        let b_row = &self.modulation[j * self.width..(j + 1) * self.width];
        let (first, last) = (lo.floor().max(0.0), hi.ceil().min((self.width - 1) as f32));
        if !(first < last) {
            return None;
        }
        let (first, last) = (first as u32, last as u32);
        let mut found = None;
        for run in &self.runs[j] {
            let (a, b) = (run.start.max(first), run.end.min(last));
            if a >= b {
                continue;
            }
            // Compare in the run's increasing direction.
            let sign = if run.increasing { 1.0 } else { -1.0 };
            let (va, vb, target) = (sign * row[a as usize], sign * row[b as usize], sign * v);
            if !(va <= target && target <= vb) {
                continue;
            }
            // Largest k in a..b with row[k] <= v (so row[k + 1] >= v).
            let (mut l, mut r) = (a as usize, b as usize - 1);
            while l < r {
                let m = (l + r).div_ceil(2);
                if sign * row[m] <= target {
                    l = m;
                } else {
                    r = m - 1;
                }
            }
            let (u0, u1) = (row[l], row[l + 1]);
            let t = (v - u0) / (u1 - u0);
            let x = l as f32 + t;
            if x < lo || x > hi {
                continue;
            }
            if found.is_some() {
                return None;
            }
            found = Some(Match {
                x,
                slope: u1 - u0,
                modulation: b_row[l] + t * (b_row[l + 1] - b_row[l]),
            });
        }
        found
    }
}

/// One rectified row of the right maps: bilinear where all four neighbours are finite
/// and at least `min_modulation`, NaN elsewhere.
fn resample_row(
    right_u: &Raster<f32>,
    right_b: &Raster<f32>,
    min_modulation: f32,
    base: &[u32],
    frac: &[[f32; 2]],
    u_out: &mut [f32],
    b_out: &mut [f32],
) {
    let w = right_u.width;
    for (i, (&k, &[fx, fy])) in base.iter().zip(frac).enumerate() {
        u_out[i] = f32::NAN;
        b_out[i] = 0.0;
        if k == u32::MAX {
            continue;
        }
        let k = k as usize;
        let q = [k, k + 1, k + w, k + w + 1];
        let u = q.map(|k| right_u.data[k]);
        let b = q.map(|k| right_b.data[k]);
        // `!(b >= min)` also refuses NaN modulation.
        if u.iter().any(|v| !v.is_finite()) || b.iter().any(|&v| !(v >= min_modulation)) {
            continue;
        }
        let lerp = |v: [f32; 4]| {
            let top = v[0] + fx * (v[1] - v[0]);
            let bottom = v[2] + fx * (v[3] - v[2]);
            top + fy * (bottom - top)
        };
        u_out[i] = lerp(u);
        b_out[i] = lerp(b);
    }
}

/// Cuts a row into runs of good neighbour pairs (both finite, nonzero step of at most
/// `max_step` in one direction).
fn runs_of_row(row: &[f32], max_step: f32, runs: &mut Vec<Run>) {
    runs.clear();
    let mut current: Option<Run> = None;
    for k in 0..row.len().saturating_sub(1) {
        let step = row[k + 1] - row[k];
        // NaN steps (an invalid neighbour) fail both comparisons.
        let good = step != 0.0 && step.abs() <= max_step;
        let increasing = step > 0.0;
        match (&mut current, good) {
            (Some(run), true) if run.increasing == increasing => run.end = k as u32 + 1,
            (_, true) => {
                runs.extend(current.take());
                current = Some(Run {
                    start: k as u32,
                    end: k as u32 + 1,
                    increasing,
                });
            }
            (_, false) => runs.extend(current.take()),
        }
    }
    runs.extend(current);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_break_at_invalid_samples_large_steps_and_turns() {
        let nan = f32::NAN;
        let row = [0.0, 1.0, 2.0, nan, 3.0, 4.0, 20.0, 21.0, 20.5, 20.0];
        let mut runs = Vec::new();
        runs_of_row(&row, 5.0, &mut runs);
        let spans: Vec<(u32, u32, bool)> = runs
            .iter()
            .map(|r| (r.start, r.end, r.increasing))
            .collect();
        assert_eq!(
            spans,
            vec![(0, 2, true), (4, 5, true), (6, 7, true), (7, 9, false)]
        );
    }

    fn right_of(rows: &[&[f32]]) -> RectifiedRight {
        let width = rows[0].len();
        let mut runs = Vec::new();
        for r in rows {
            let mut v = Vec::new();
            runs_of_row(r, 5.0, &mut v);
            runs.push(v);
        }
        RectifiedRight {
            width,
            height: rows.len(),
            u: rows.concat(),
            modulation: vec![0.5; width * rows.len()],
            runs,
        }
    }

    #[test]
    fn a_value_is_found_between_its_bracketing_pair_and_rows_are_interpolated() {
        let right = right_of(&[&[10.0, 11.0, 12.0, 13.0], &[10.5, 11.5, 12.5, 13.5]]);
        // Row 0: 11.25 at x = 1.25; row 1: at x = 0.75; a quarter of the way down: 1.125.
        let m = right.find(3.0, 0.25, 11.25, 0.0, 10.0, 2.0).unwrap();
        assert!((m.x - 1.125).abs() < 1e-6, "{m:?}");
        assert!((m.slope - 1.0).abs() < 1e-6);
        // Outside the disparity window, or beyond the last row: nothing.
        assert!(right.find(3.0, 0.25, 11.25, 2.0, 10.0, 2.0).is_none());
        assert!(right.find(3.0, 1.0, 11.25, 0.0, 10.0, 2.0).is_none());
    }

    #[test]
    fn edges_invalid_neighbours_and_ambiguity_are_refused() {
        let nan = f32::NAN;
        let edge: &[f32] = &[10.0, 11.0, 30.0, 31.0];
        let hole: &[f32] = &[10.0, nan, 12.0, 13.0];
        let twice: &[f32] = &[10.0, 12.0, 11.0, 10.0];
        for (row, v) in [(edge, 20.0), (hole, 11.0), (twice, 11.0)] {
            let right = right_of(&[row, row]);
            assert!(right.find(3.0, 0.0, v, 0.0, 10.0, 2.0).is_none(), "{row:?}");
        }
        // A decreasing row matches too.
        let down: &[f32] = &[13.0, 12.0, 11.0, 10.0];
        let m = right_of(&[down, down])
            .find(3.0, 0.0, 11.5, 0.0, 10.0, 2.0)
            .unwrap();
        assert!((m.x - 1.5).abs() < 1e-6 && (m.slope + 1.0).abs() < 1e-6);
    }
}
