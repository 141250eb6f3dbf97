//! Matching a left pixel's projector coordinate on the rectified right rows.
//!
//! The right coordinate map is resampled onto the rectified grid. Along a rectified
//! row the coordinate is locally monotonic: each row is cut into *runs*, maximal
//! stretches of neighbour pairs that are both valid, step the same way and by at most
//! `max_step_px` (a larger step is a depth edge). A left value is matched by binary
//! search inside the runs of the disparity window, to the bracketing pair. A value found
//! in two runs is ambiguous and refused.
//!
//! A left pixel's rectified row `y` is not an integer: it is matched on the rows around
//! it and the positions are interpolated in `y`, refused when neighbouring rows differ
//! by more than `max_row_shift_px` (an edge between the rows).
//!
//! Every interpolation is cubic (Catmull-Rom: exact for quadratics) and needs all four
//! of its samples (sixteen for the resampling): a linear interpolant of a curved
//! coordinate is biased by up to an eighth of a sample's curvature, which on the twin's
//! 25 mm spheres at 320 x 240 put points 12 um (centre) to 40 um (limb) too far; with
//! exact coordinates the cubic one leaves 0.2 um RMS. The price is a margin of two
//! pixels around every invalid region, where the limb's curvature is largest anyway.

use rayon::prelude::*;

use super::rectify::Rectification;
use super::StereoConfig;
use crate::raster::Raster;

/// Steps walked from a hint before a binary search takes over.
const HINT_STEPS: usize = 4;

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

    /// Hints for [`RectifiedRight::find`]: one position per rectified row, any value.
    pub fn hints(&self) -> Vec<usize> {
        vec![0; self.height]
    }

    /// The match of coordinate `v` for a left pixel at rectified grid `(x, y)`, with
    /// disparities in `d_min..=d_max` (grid pixels): matched on the four rows around
    /// `y`, cubic in `y`. `None` where a row has no match, or more than one, or
    /// neighbouring rows disagree by more than `max_row_shift_px`. `hint` (from
    /// [`RectifiedRight::hints`]) holds each row's last match, where the search starts.
    pub fn find(
        &self,
        x: f32,
        y: f32,
        v: f32,
        (d_min, d_max): (f32, f32),
        max_row_shift_px: f32,
        hint: &mut [usize],
    ) -> Option<Match> {
        if !(x.is_finite() && y.is_finite() && y >= 0.0) {
            return None;
        }
        let row = y.floor();
        let (j, s) = (row as usize, y - row);
        if j < 1 || j + 2 >= self.height {
            return None;
        }
        let (lo, hi) = (x - d_max, x - d_min);
        let mut m = [None; 4];
        for (k, slot) in m.iter_mut().enumerate() {
            *slot = Some(self.find_in_row(j + k - 1, v, lo, hi, hint)?);
        }
        let m = m.map(|m| m.expect("all four rows matched"));
        if m.windows(2)
            .any(|p| (p[0].x - p[1].x).abs() > max_row_shift_px)
        {
            return None;
        }
        let w = catmull_rom(s);
        let cubic = |f: fn(&Match) -> f32| (0..4).map(|k| w[k] * f(&m[k])).sum::<f32>();
        Some(Match {
            x: cubic(|m| m.x),
            slope: cubic(|m| m.slope),
            modulation: m[1].modulation + s * (m[2].modulation - m[1].modulation),
        })
    }

    /// The single bracketing pair of `v` in row `j` between grid x `lo` and `hi`.
    fn find_in_row(&self, j: usize, v: f32, lo: f32, hi: f32, hint: &mut [usize]) -> Option<Match> {
        let row = &self.u[j * self.width..(j + 1) * self.width];
        let b_row = &self.modulation[j * self.width..(j + 1) * self.width];
        let (first, last) = (lo.floor().max(0.0), hi.ceil().min((self.width - 1) as f32));
        if first >= last {
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
            // Largest l in a..b with row[l] <= v (so row[l + 1] >= v): a few steps from
            // the hint (the neighbouring left pixel's match on this row), else a binary
            // search.
            let (a, b) = (a as usize, b as usize);
            let is_bracket =
                |l: usize| sign * row[l] <= target && (l + 1 >= b || sign * row[l + 1] > target);
            let mut l = hint[j].clamp(a, b - 1);
            for _ in 0..HINT_STEPS {
                if is_bracket(l) {
                    break;
                }
                if sign * row[l] > target {
                    l = l.saturating_sub(1).max(a);
                } else {
                    l = (l + 1).min(b - 1);
                }
            }
            if !is_bracket(l) {
                let (mut lo, mut hi) = (a, b - 1);
                while lo < hi {
                    let m = (lo + hi).div_ceil(2);
                    if sign * row[m] <= target {
                        lo = m;
                    } else {
                        hi = m - 1;
                    }
                }
                l = lo;
            }
            hint[j] = l;
            let (u0, u1) = (row[l], row[l + 1]);
            // Cubic through the pair and its outer neighbours, which must be in the run:
            // a few Newton steps from the linear root (the cubic is monotonic here).
            if !(l > run.start as usize && l + 2 <= run.end as usize) {
                continue;
            }
            // About u0: f32 sums of small differences keep their digits.
            let q = [row[l - 1] - u0, 0.0, u1 - u0, row[l + 2] - u0];
            let target = v - u0;
            let mut t = target / (u1 - u0);
            let mut slope = u1 - u0;
            for _ in 0..2 {
                let (w, dw) = (catmull_rom(t), catmull_rom_slope(t));
                let p: f32 = (0..4).map(|k| w[k] * q[k]).sum();
                slope = (0..4).map(|k| dw[k] * q[k]).sum();
                t = (t - (p - target) / slope).clamp(0.0, 1.0);
            }
            let x = l as f32 + t;
            if x < lo || x > hi {
                continue;
            }
            if found.is_some() {
                return None;
            }
            found = Some(Match {
                x,
                slope,
                modulation: b_row[l] + t * (b_row[l + 1] - b_row[l]),
            });
        }
        found
    }
}

/// One rectified row of the right maps: bicubic (Catmull-Rom) where all sixteen
/// neighbours are finite and at least `min_modulation`, NaN elsewhere. The modulation
/// (for the noise prediction only) is bilinear.
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
    // `!(b >= min)` also refuses NaN modulation.
    let good = |k: usize| right_u.data[k].is_finite() && right_b.data[k] >= min_modulation;
    for (i, (&k, &[fx, fy])) in base.iter().zip(frac).enumerate() {
        u_out[i] = f32::NAN;
        b_out[i] = 0.0;
        if k == u32::MAX {
            continue;
        }
        // Sources keep a pixel from the edge (see rectify), so the 4 x 4 exists.
        let k = k as usize;
        let first = k - w - 1;
        let all = (0..4).all(|r| (0..4).all(|c| good(first + r * w + c)));
        if !all {
            continue;
        }
        let b = [k, k + 1, k + w, k + w + 1].map(|k| right_b.data[k]);
        let (top, bottom) = (b[0] + fx * (b[1] - b[0]), b[2] + fx * (b[3] - b[2]));
        b_out[i] = top + fy * (bottom - top);
        let (wx, wy) = (catmull_rom(fx), catmull_rom(fy));
        // About the nearest sample: f32 sums of small differences keep their digits.
        let origin = right_u.data[k];
        let mut sum = 0.0;
        for (r, wy) in wy.iter().enumerate() {
            let line = &right_u.data[first + r * w..first + r * w + 4];
            let dot: f32 = (0..4).map(|c| wx[c] * (line[c] - origin)).sum();
            sum += wy * dot;
        }
        u_out[i] = origin + sum;
    }
}

/// Catmull-Rom weights of samples -1, 0, 1, 2 at `t` in [0, 1] between 0 and 1.
#[inline(always)]
fn catmull_rom(t: f32) -> [f32; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    ]
}

/// d/dt of [`catmull_rom`]'s weights.
#[inline(always)]
fn catmull_rom_slope(t: f32) -> [f32; 4] {
    let t2 = t * t;
    [
        0.5 * (-3.0 * t2 + 4.0 * t - 1.0),
        0.5 * (9.0 * t2 - 10.0 * t),
        0.5 * (-9.0 * t2 + 8.0 * t + 1.0),
        0.5 * (3.0 * t2 - 2.0 * t),
    ]
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

    fn right_of(rows: &[Vec<f32>]) -> RectifiedRight {
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

    /// Four rows of `u = a + slope x + shift y` (a plane's coordinate).
    fn ramp(width: usize, shift: f32) -> Vec<Vec<f32>> {
        (0..4)
            .map(|y| {
                (0..width)
                    .map(|x| 10.0 + x as f32 + shift * y as f32)
                    .collect()
            })
            .collect()
    }

    #[test]
    fn a_value_is_found_between_its_bracketing_pair_and_rows_are_interpolated() {
        let right = right_of(&ramp(8, -0.5));
        // Row 1: 12.25 at x = 2.75; row 2: at x = 3.25; a quarter of the way down: 2.875.
        let m = right
            .find(6.0, 1.25, 12.25, (0.0, 10.0), 2.0, &mut [0; 4])
            .unwrap();
        assert!((m.x - 2.875).abs() < 1e-5, "{m:?}");
        assert!((m.slope - 1.0).abs() < 1e-5);
        // Outside the disparity window, or without a row above and two below: nothing.
        assert!(right
            .find(6.0, 1.25, 12.25, (4.0, 10.0), 2.0, &mut [0; 4])
            .is_none());
        assert!(right
            .find(6.0, 0.5, 12.25, (0.0, 10.0), 2.0, &mut [0; 4])
            .is_none());
        assert!(right
            .find(6.0, 2.0, 12.25, (0.0, 10.0), 2.0, &mut [0; 4])
            .is_none());
    }

    #[test]
    fn a_curved_row_is_solved_exactly_to_second_order() {
        // u = 10 + x + 0.05 x^2 on every row: 13.0 at x = (-1 + sqrt(1 + 0.6)) / 0.1.
        let row: Vec<f32> = (0..8)
            .map(|x| 10.0 + x as f32 + 0.05 * (x * x) as f32)
            .collect();
        let right = right_of(&vec![row; 4]);
        let m = right
            .find(7.0, 1.5, 13.0, (0.0, 10.0), 2.0, &mut [0; 4])
            .unwrap();
        let want = (-1.0 + 1.6f32.sqrt()) / 0.1;
        assert!((m.x - want).abs() < 1e-4, "{} vs {want}", m.x);
        assert!((m.slope - (1.0 + 0.1 * want)).abs() < 1e-4);
    }

    #[test]
    fn edges_invalid_neighbours_and_ambiguity_are_refused() {
        let nan = f32::NAN;
        let edge = vec![10.0, 11.0, 12.0, 30.0, 31.0, 32.0];
        let hole = vec![10.0, 11.0, nan, 13.0, 14.0, 15.0];
        let twice = vec![10.0, 11.0, 12.0, 11.0, 10.0, 9.0];
        // The pair 11..12 exists but its outer neighbour does not (the cubic needs it).
        let short = vec![nan, 11.0, 12.0, 13.0, nan, nan];
        for (row, v) in [(edge, 20.0), (hole, 12.0), (twice, 11.5), (short, 11.5)] {
            let right = right_of(&vec![row.clone(); 4]);
            assert!(
                right
                    .find(5.0, 1.0, v, (0.0, 10.0), 2.0, &mut [0; 4])
                    .is_none(),
                "{row:?}"
            );
        }
        // A decreasing row matches too.
        let down: Vec<f32> = (0..6).map(|x| 15.0 - x as f32).collect();
        let m = right_of(&vec![down; 4])
            .find(5.0, 1.0, 12.5, (0.0, 10.0), 2.0, &mut [0; 4])
            .unwrap();
        assert!(
            (m.x - 2.5).abs() < 1e-5 && (m.slope + 1.0).abs() < 1e-5,
            "{m:?}"
        );
        // Rows that disagree by more than the allowed shift are an edge between them.
        let right = right_of(&ramp(8, -3.0));
        assert!(right
            .find(7.0, 1.5, 12.0, (0.0, 10.0), 2.0, &mut [0; 4])
            .is_none());
    }
}
