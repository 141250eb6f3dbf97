//! Ordering corner candidates into the board's grid.
//!
//! From a seed candidate and its two nearest non-parallel neighbours the grid
//! grows cell by cell: each new cell's position is predicted by extrapolating
//! its assigned neighbours (which follows perspective), and the nearest
//! candidate within a fraction of the local spacing is taken. A full
//! `cols x rows` rectangle is then oriented: board x along `cols`, a
//! right-handed frame (z away from the camera), and the dark squares where
//! the board says they are.

use std::collections::{HashMap, VecDeque};

use nalgebra::{Point2, Vector2};

use super::filter::Plane;

/// A grid grown from a seed: cell `(i, j)` -> candidate index.
type Cells = HashMap<(i64, i64), usize>;

/// Result of growing one seed.
#[derive(Debug, Clone, PartialEq)]
pub struct Grown {
    /// Corners in grid order, row by row, as grown (before orientation).
    pub points: Vec<Point2<f64>>,
    /// Cells along the first grown axis.
    pub width: usize,
    /// Cells along the second grown axis.
    pub height: usize,
}

fn nearest(
    points: &[Point2<f64>],
    target: &Point2<f64>,
    within: f64,
    used: &[bool],
) -> Option<usize> {
    points
        .iter()
        .enumerate()
        .filter(|(k, p)| !used[*k] && (*p - target).norm() <= within)
        .min_by(|a, b| (a.1 - target).norm().total_cmp(&(b.1 - target).norm()))
        .map(|(k, _)| k)
}

/// Grows a grid from candidate `seed`; `None` if it has no usable neighbours.
pub fn grow(points: &[Point2<f64>], seed: usize) -> Option<Grown> {
    let s = points[seed];
    let mut by_dist: Vec<(usize, f64)> = points
        .iter()
        .enumerate()
        .filter(|(k, _)| *k != seed)
        .map(|(k, p)| (k, (p - s).norm()))
        .collect();
    by_dist.sort_by(|a, b| a.1.total_cmp(&b.1));
    let &(n1, d1) = by_dist.first()?;
    if d1 < 2.0 {
        return None;
    }
    let e1 = points[n1] - s;
    let &(n2, _) = by_dist.iter().skip(1).take(8).find(|(k, d)| {
        let e = points[*k] - s;
        *d < 2.0 * d1 && (e.dot(&e1) / (e.norm() * d1)).abs() < 0.5
    })?;
    let mut cells: Cells = HashMap::new();
    let mut used = vec![false; points.len()];
    for (cell, k) in [((0, 0), seed), ((1, 0), n1), ((0, 1), n2)] {
        cells.insert(cell, k);
        used[k] = true;
    }
    let mut queue: VecDeque<(i64, i64)> = cells.keys().copied().collect();
    let e2 = points[n2] - s;
    while let Some((i, j)) = queue.pop_front() {
        let p = points[cells[&(i, j)]];
        for (di, dj) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
            let next = (i + di, j + dj);
            if cells.contains_key(&next) {
                continue;
            }
            // Step along this axis: from the cell behind us if known, else
            // from any assigned neighbour on the same axis, else the seed basis.
            let back = cells.get(&(i - di, j - dj)).map(|&k| p - points[k]);
            let fwd_axis = |a: i64, b: i64| {
                cells
                    .get(&(a + di, b + dj))
                    .zip(cells.get(&(a, b)))
                    .map(|(&x, &y)| points[x] - points[y])
            };
            let step = back
                .or_else(|| fwd_axis(i + dj, j + di))
                .or_else(|| fwd_axis(i - dj, j - di))
                .unwrap_or_else(|| e1 * di as f64 + e2 * dj as f64);
            let predicted = p + step;
            let Some(k) = nearest(points, &predicted, 0.35 * step.norm(), &used) else {
                continue;
            };
            used[k] = true;
            cells.insert(next, k);
            queue.push_back(next);
        }
    }
    trim_sparse_border(&mut cells);
    let (imin, imax, jmin, jmax) = extent(&cells);
    let width = (imax - imin + 1) as usize;
    let height = (jmax - jmin + 1) as usize;
    if cells.len() != width * height {
        // Holes: not a clean rectangle (missed corners or clutter).
        return Some(Grown {
            points: Vec::new(),
            width,
            height,
        });
    }
    let mut ordered = Vec::with_capacity(width * height);
    for j in jmin..=jmax {
        for i in imin..=imax {
            ordered.push(points[cells[&(i, j)]]);
        }
    }
    Some(Grown {
        points: ordered,
        width,
        height,
    })
}

/// Smallest and largest cell index along each axis: `(imin, imax, jmin, jmax)`.
fn extent(cells: &Cells) -> (i64, i64, i64, i64) {
    cells.keys().fold(
        (i64::MAX, i64::MIN, i64::MAX, i64::MIN),
        |(a, b, c, d), k| (a.min(k.0), b.max(k.0), c.min(k.1), d.max(k.1)),
    )
}

/// Drops incomplete outer rows and columns, the emptiest first, until the cells fill
/// their bounding rectangle: a lone saddle just outside the board (where a board cut
/// by the image edge meets the border, or clutter in line with the grid) would
/// otherwise stretch the grid by a row and hide the full board inside it.
fn trim_sparse_border(cells: &mut Cells) {
    while !cells.is_empty() {
        let (imin, imax, jmin, jmax) = extent(cells);
        let (width, height) = (imax - imin + 1, jmax - jmin + 1);
        if cells.len() as i64 == width * height {
            return;
        }
        let count = |on: &dyn Fn(&(i64, i64)) -> bool| cells.keys().filter(|k| on(k)).count();
        // (cells on the line, full length of the line, which line)
        let lines = [
            (count(&|k| k.0 == imin), height, (0, imin)),
            (count(&|k| k.0 == imax), height, (0, imax)),
            (count(&|k| k.1 == jmin), width, (1, jmin)),
            (count(&|k| k.1 == jmax), width, (1, jmax)),
        ];
        let Some(&(_, _, (axis, at))) = lines
            .iter()
            .filter(|(n, full, _)| (*n as i64) < *full)
            .min_by(|a, b| (a.0 as f64 / a.1 as f64).total_cmp(&(b.0 as f64 / b.1 as f64)))
        else {
            // Holes inside, borders complete: nothing to trim.
            return;
        };
        cells.retain(|k, _| if axis == 0 { k.0 != at } else { k.1 != at });
    }
}

/// One of the eight symmetries of a rectangular grid: maps board `(i, j)`
/// to grown `(a, b)`.
#[derive(Debug, Clone, Copy)]
struct Symmetry {
    transpose: bool,
    flip_a: bool,
    flip_b: bool,
}

fn board_order(grown: &Grown, cols: usize, rows: usize, sym: Symmetry) -> Vec<Point2<f64>> {
    let mut out = Vec::with_capacity(cols * rows);
    for j in 0..rows {
        for i in 0..cols {
            let (mut a, mut b) = if sym.transpose { (j, i) } else { (i, j) };
            if sym.flip_a {
                a = grown.width - 1 - a;
            }
            if sym.flip_b {
                b = grown.height - 1 - b;
            }
            out.push(grown.points[b * grown.width + a]);
        }
    }
    out
}

/// Mean grey of dark-expected minus light-expected interior squares
/// (negative when the parity is right).
fn parity_contrast(ordered: &[Point2<f64>], cols: usize, rows: usize, plane: &Plane) -> f64 {
    let (mut dark, mut light, mut nd, mut nl) = (0.0, 0.0, 0, 0);
    for j in 1..rows {
        for i in 1..cols {
            let c = [(i - 1, j - 1), (i, j - 1), (i - 1, j), (i, j)]
                .iter()
                .fold(Vector2::zeros(), |acc, &(a, b)| {
                    acc + ordered[b * cols + a].coords
                })
                / 4.0;
            let g = plane.bilinear(c.x, c.y);
            // Square (a, b) = (i, j) is dark when i + j is even (see board.rs).
            if (i + j) % 2 == 0 {
                dark += g;
                nd += 1;
            } else {
                light += g;
                nl += 1;
            }
        }
    }
    if nd == 0 || nl == 0 {
        return 0.0;
    }
    dark / nd as f64 - light / nl as f64
}

/// Orders a full grown grid as the board: `None` if its size does not match.
/// With `parity` (the smoothed image of a checkerboard) the dark squares
/// decide between orientations; without (a symmetric circle grid) the point
/// nearest the image's top-left becomes `(0, 0)`.
pub fn orient(
    grown: &Grown,
    cols: usize,
    rows: usize,
    parity: Option<&Plane>,
) -> Option<Vec<Point2<f64>>> {
    let mut best: Option<(f64, f64, Vec<Point2<f64>>)> = None;
    for transpose in [false, true] {
        let (w, h) = if transpose {
            (rows, cols)
        } else {
            (cols, rows)
        };
        if (w, h) != (grown.width, grown.height) || grown.points.len() != w * h {
            continue;
        }
        for flip_a in [false, true] {
            for flip_b in [false, true] {
                let sym = Symmetry {
                    transpose,
                    flip_a,
                    flip_b,
                };
                let ordered = board_order(grown, cols, rows, sym);
                // Right-handed in the image (y down): x axis to y axis turns clockwise.
                let ex = ordered[cols.min(2) - 1] - ordered[0];
                let ey = ordered[(rows.min(2) - 1) * cols] - ordered[0];
                if ex.x * ey.y - ex.y * ey.x <= 0.0 {
                    continue;
                }
                let contrast = parity.map_or(0.0, |p| parity_contrast(&ordered, cols, rows, p));
                let top_left = ordered[0].x + ordered[0].y;
                // Quantise the contrast so that a point-symmetric board (equal
                // contrasts) falls through to the top-left rule.
                let key = (contrast * 1e6).round();
                let better = match &best {
                    None => true,
                    Some((c, t, _)) => key < *c || (key == *c && top_left < *t),
                };
                if better {
                    best = Some((key, top_left, ordered));
                }
            }
        }
    }
    best.map(|(_, _, o)| o)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice(w: usize, h: usize, noise: bool) -> Vec<Point2<f64>> {
        let mut pts = Vec::new();
        for j in 0..h {
            for i in 0..w {
                // A mild perspective-like warp.
                let (x, y) = (i as f64, j as f64);
                let s = 1.0 + 0.03 * x;
                pts.push(Point2::new(
                    50.0 + 20.0 * x * s + 3.0 * y,
                    40.0 + 18.0 * y * s - 2.0 * x,
                ));
            }
        }
        if noise {
            pts.push(Point2::new(5.0, 5.0));
            pts.push(Point2::new(61.0, 49.0));
        }
        pts
    }

    #[test]
    fn grows_the_full_lattice_despite_clutter() {
        let pts = lattice(7, 5, true);
        let g = grow(&pts, 17).unwrap();
        assert_eq!(g.points.len(), 35);
        assert_eq!((g.width * g.height), 35);
    }

    #[test]
    fn a_lone_candidate_in_line_beyond_the_lattice_is_trimmed_off() {
        // One saddle a row below the lattice's bottom row, in line with its columns.
        let mut pts = lattice(7, 5, false);
        let (a, b) = (pts[4 * 7 + 3], pts[3 * 7 + 3]);
        pts.push(a + (a - b));
        let g = grow(&pts, 17).unwrap();
        let dims = (g.width.max(g.height), g.width.min(g.height));
        assert_eq!((dims, g.points.len()), ((7, 5), 35));
        // A hole inside is not trimmed away: no clean grid.
        let mut holed = lattice(7, 5, false);
        holed.remove(2 * 7 + 3);
        assert!(grow(&holed, 0).unwrap().points.is_empty());
    }

    #[test]
    fn orientation_is_right_handed_and_size_checked() {
        let pts = lattice(7, 5, false);
        let g = grow(&pts, 10).unwrap();
        let o = orient(&g, 7, 5, None).unwrap();
        let ex = o[1] - o[0];
        let ey = o[7] - o[0];
        assert!(ex.x * ey.y - ex.y * ey.x > 0.0);
        assert!(orient(&g, 6, 5, None).is_none());
    }
}
