//! The k nearest neighbours of every point of a cloud at once, exactly, by
//! cubic cells: the points of one cell share their candidates (the 3x3x3
//! block of cells around it), and a point's k-th nearest candidate proves
//! the answer when it is nearer than the block's wall.
//!
//! Why not one kd-tree query per point (kiddo's `nearest_n`): for normals of
//! a million-point scan that is about 2 us of CPU per point, most of the
//! normals' time; neighbouring points redo nearly the same descent. Shared
//! candidates cost a few dozen distances per point. Points the block cannot
//! prove (sparse rims, outliers) and crowded cells (many duplicates) go to
//! a kd-tree, built only if some point needs it, so every answer is exact.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;
use std::num::NonZeroUsize;
use std::sync::OnceLock;

use kiddo::SquaredEuclidean;
use nalgebra::Vector3;
use rayon::prelude::*;

use super::{build_tree, FusionError, MortonKeys, Tree, MORTON_LEVELS};

/// Cells whose block holds more candidates than this per neighbour sought
/// (plus a floor) send their points to the tree: a pile of duplicates in one
/// cell would otherwise cost its size squared.
const MAX_CANDIDATES_PER_NEIGHBOUR: usize = 64;
const MIN_CANDIDATE_CAP: usize = 512;

/// Cells processed by one task: enough to amortise the task, few enough to
/// share two cores evenly.
const CELLS_PER_TASK: usize = 256;

/// `f(i, neighbours)` for every point `i` of `points`, where `neighbours` are
/// the indices of its `k` nearest points (itself included, in no particular
/// order; ties broken arbitrarily), results in point order. `points` must be
/// finite and at least `k >= 1` long (checked by the caller).
pub(crate) fn map_neighbourhoods<R, F>(
    points: &[Vector3<f64>],
    k: usize,
    f: F,
) -> Result<Vec<R>, FusionError>
where
    R: Send,
    F: Fn(usize, &[usize]) -> R + Sync,
{
    map_counting_tree_queries(points, k, f).map(|(results, _)| results)
}

/// As [`map_neighbourhoods`], also counting the points the cells could not
/// prove and the kd-tree answered.
fn map_counting_tree_queries<R, F>(
    points: &[Vector3<f64>],
    k: usize,
    f: F,
) -> Result<(Vec<R>, usize), FusionError>
where
    R: Send,
    F: Fn(usize, &[usize]) -> R + Sync,
{
    assert!(k >= 1 && points.len() >= k, "checked by the caller");
    let grid = CellGrid::new(points, k);
    let tree = OnceLock::new();
    let tasks: Vec<(Vec<R>, usize)> = (0..grid.cell_count())
        .step_by(CELLS_PER_TASK)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|first| {
            let mut scratch = Scratch::default();
            let last = (first + CELLS_PER_TASK).min(grid.cell_count());
            let mut out = Vec::with_capacity(grid.start[last] - grid.start[first]);
            let mut tree_queries = 0;
            for cell in first..last {
                tree_queries +=
                    grid.cell_neighbourhoods(cell, points, k, &tree, &mut scratch, |i, nb| {
                        out.push(f(i, nb))
                    })?;
            }
            Ok((out, tree_queries))
        })
        .collect::<Result<_, FusionError>>()?;
    let tree_queries = tasks.iter().map(|(_, n)| n).sum();
    // Tasks hold the points in key order; put them back in point order.
    let mut slots: Vec<Option<R>> = std::iter::repeat_with(|| None).take(points.len()).collect();
    let in_key_order = tasks.into_iter().flat_map(|(out, _)| out);
    for (&(_, i), r) in grid.keys.sorted.iter().zip(in_key_order) {
        slots[i] = Some(r);
    }
    let results = slots
        .into_iter()
        .map(|r| r.expect("every point lies in one cell"))
        .collect();
    Ok((results, tree_queries))
}

/// The cloud's points grouped into occupied cubic cells at one Morton level.
struct CellGrid {
    keys: MortonKeys,
    /// Cells per axis is `2^level`.
    level: u32,
    /// Side of a cell, metres.
    side_m: f64,
    /// Cell `c` holds `keys.sorted[start[c]..start[c + 1]]`.
    start: Vec<usize>,
    /// Cell key (its points' keys shifted to `level`) to cell number.
    cell_of_key: CellIndex,
    /// The points in key order, so that a cell's points are one slice.
    sorted_points: Block,
}

/// Per-task buffers, reused across cells.
#[derive(Default)]
struct Scratch {
    /// The points of the block of cells around the current cell.
    block: Block,
    /// The same for two rings of cells, gathered only when a point needs it.
    wide: Block,
    /// Squared distances of the block's points to one query point.
    dist: Vec<f64>,
    /// (squared distance, index) of the candidates within reach; its
    /// first k are the answer once a point is proven.
    best: Vec<(f64, usize)>,
    /// The answer handed to the caller.
    neighbours: Vec<usize>,
}

/// Points of a block of cells, by coordinate (so distances vectorise).
#[derive(Default)]
struct Block {
    x: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
    index: Vec<usize>,
}

impl Block {
    fn clear(&mut self) {
        self.x.clear();
        self.y.clear();
        self.z.clear();
        self.index.clear();
    }

    fn len(&self) -> usize {
        self.index.len()
    }

    /// Appends `other`'s points in `range`.
    fn extend_from(&mut self, other: &Block, range: std::ops::Range<usize>) {
        self.x.extend_from_slice(&other.x[range.clone()]);
        self.y.extend_from_slice(&other.y[range.clone()]);
        self.z.extend_from_slice(&other.z[range.clone()]);
        self.index.extend_from_slice(&other.index[range]);
    }
}

/// A multiplicative hash for cell keys (std's SipHash is several times
/// slower and resists attacks we do not face).
#[derive(Default)]
struct KeyHasher(u64);

impl std::hash::Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }

    fn write_u64(&mut self, v: u64) {
        self.0 = (v ^ (v >> 29)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

type CellIndex = HashMap<u64, u32, BuildHasherDefault<KeyHasher>>;

impl CellGrid {
    /// Cells sized so that a cell holds about half of `k` points or more on
    /// average (for a surface, the k-th neighbour then lies within about one
    /// cell side: the block of 3x3x3 proves most points).
    fn new(points: &[Vector3<f64>], k: usize) -> CellGrid {
        let keys = MortonKeys::of(points);
        let level = level_for(&keys.sorted, k);
        let shift = 3 * (MORTON_LEVELS - level);
        let mut cell_keys = Vec::new();
        let mut start = Vec::new();
        for (j, &(key, _)) in keys.sorted.iter().enumerate() {
            let c = key >> shift;
            if cell_keys.last() != Some(&c) {
                cell_keys.push(c);
                start.push(j);
            }
        }
        start.push(keys.sorted.len());
        let mut cell_of_key =
            CellIndex::with_capacity_and_hasher(cell_keys.len(), Default::default());
        cell_of_key.extend(
            cell_keys
                .iter()
                .enumerate()
                .map(|(c, &key)| (key, c as u32)),
        );
        let coord = |a: usize| keys.sorted.par_iter().map(|&(_, i)| points[i][a]).collect();
        let sorted_points = Block {
            x: coord(0),
            y: coord(1),
            z: coord(2),
            index: keys.sorted.iter().map(|&(_, i)| i).collect(),
        };
        let finest_cells = ((1u64 << MORTON_LEVELS) - 1) as f64;
        let side_m = keys.extent * f64::from(1u32 << (MORTON_LEVELS - level)) / finest_cells;
        CellGrid {
            keys,
            level,
            side_m,
            start,
            cell_of_key,
            sorted_points,
        }
    }

    fn cell_count(&self) -> usize {
        self.start.len() - 1
    }

    /// Integer coordinates of cell `cell` at the grid's level.
    fn coords(&self, cell: usize, points: &[Vector3<f64>]) -> [u64; 3] {
        let (_, i) = self.keys.sorted[self.start[cell]];
        let shift = MORTON_LEVELS - self.level;
        self.keys.cell(&points[i]).map(|c| c >> shift)
    }

    /// Gathers the points of the cells within `ring` cells of `centre` (a
    /// block of `2 ring + 1` cells a side) into `block`.
    fn gather(&self, centre: [u64; 3], ring: u64, block: &mut Block) {
        block.clear();
        let top = (1u64 << self.level) - 1;
        let range = |c: u64| c.saturating_sub(ring)..=(c + ring).min(top);
        for x in range(centre[0]) {
            for y in range(centre[1]) {
                for z in range(centre[2]) {
                    if let Some(&c) = self.cell_of_key.get(&self.keys.key(&[x, y, z])) {
                        let c = c as usize;
                        block.extend_from(&self.sorted_points, self.start[c]..self.start[c + 1]);
                    }
                }
            }
        }
    }

    /// Distance from `p` (in cell `centre`) to the nearest wall of the block
    /// within `ring` cells; a wall at the edge of the cloud's box has nothing
    /// beyond it and does not count. Slightly short, so rounding in the cell
    /// assignment can only make a proof fail, never pass wrongly.
    fn block_margin(&self, p: &Vector3<f64>, centre: [u64; 3], ring: u64) -> f64 {
        let top = (1u64 << self.level) - 1;
        let mut margin = f64::INFINITY;
        for a in 0..3 {
            let c = centre[a];
            if c > ring {
                let wall = self.keys.lo[a] + (c - ring) as f64 * self.side_m;
                margin = margin.min(p[a] - wall);
            }
            if c + ring < top {
                let wall = self.keys.lo[a] + (c + ring + 1) as f64 * self.side_m;
                margin = margin.min(wall - p[a]);
            }
        }
        margin - 1e-9 * self.keys.extent
    }

    /// Finds the `k` nearest neighbours of each point of `cell` and hands
    /// them to `emit` in the cell's key order; returns how many the kd-tree
    /// answered.
    fn cell_neighbourhoods(
        &self,
        cell: usize,
        points: &[Vector3<f64>],
        k: usize,
        tree: &OnceLock<Result<Tree, FusionError>>,
        s: &mut Scratch,
        mut emit: impl FnMut(usize, &[usize]),
    ) -> Result<usize, FusionError> {
        let centre = self.coords(cell, points);
        let cap = (MAX_CANDIDATES_PER_NEIGHBOUR * k).max(MIN_CANDIDATE_CAP);
        self.gather(centre, 1, &mut s.block);
        let crowded = s.block.len() > cap;
        let mut wide_gathered = false;
        let mut hint = f64::INFINITY;
        let mut tree_queries = 0;
        for &(_, i) in &self.keys.sorted[self.start[cell]..self.start[cell + 1]] {
            let p = &points[i];
            let mut proven = !crowded
                && nearest_in(
                    p,
                    k,
                    &s.block,
                    self.block_margin(p, centre, 1),
                    &mut hint,
                    &mut s.dist,
                    &mut s.best,
                );
            if !proven && !crowded {
                // Two rings cost 125 cells instead of 27; worth it for a
                // sparse rim before the tree.
                if !wide_gathered {
                    self.gather(centre, 2, &mut s.wide);
                    wide_gathered = true;
                }
                proven = s.wide.len() <= cap
                    && nearest_in(
                        p,
                        k,
                        &s.wide,
                        self.block_margin(p, centre, 2),
                        &mut hint,
                        &mut s.dist,
                        &mut s.best,
                    );
            }
            s.neighbours.clear();
            if proven {
                s.neighbours.extend(s.best.iter().map(|&(_, j)| j));
            } else {
                tree_queries += 1;
                let tree = tree
                    .get_or_init(|| build_tree(points))
                    .as_ref()
                    .map_err(Clone::clone)?;
                let k = NonZeroUsize::new(k).expect("k >= 1");
                s.neighbours.extend(
                    tree.query(&[p.x, p.y, p.z])
                        .nearest_n::<SquaredEuclidean<f64>>(k)
                        .execute()
                        .iter()
                        .map(|n| n.item as usize),
                );
            }
            emit(i, &s.neighbours);
        }
        Ok(tree_queries)
    }
}

/// The `k` nearest of `block` to `p` into `best`, if the k-th of them is no
/// farther than `margin` (then nothing outside the block is nearer).
/// `hint` carries a guess of the squared k-th distance from one point to
/// the next (infinite: no guess).
fn nearest_in(
    p: &Vector3<f64>,
    k: usize,
    block: &Block,
    margin: f64,
    hint: &mut f64,
    dist: &mut Vec<f64>,
    best: &mut Vec<(f64, usize)>,
) -> bool {
    if block.len() < k || margin <= 0.0 {
        return false;
    }
    dist.clear();
    dist.extend(
        block
            .x
            .iter()
            .zip(&block.y)
            .zip(&block.z)
            .map(|((x, y), z)| (x - p.x).powi(2) + (y - p.y).powi(2) + (z - p.z).powi(2)),
    );
    // Only candidates within `limit` can be among the k nearest: first the
    // previous point's k-th distance widened by half (a neighbour's radius
    // is nearly the same), then the margin itself. A few dozen survive.
    let wall = margin * margin;
    let mut limit = hint.min(wall);
    loop {
        best.clear();
        best.extend(
            dist.iter()
                .zip(&block.index)
                .filter(|(&d, _)| d <= limit)
                .map(|(&d, &j)| (d, j)),
        );
        if best.len() >= k {
            best.select_nth_unstable_by(k - 1, |a, b| a.0.total_cmp(&b.0));
            best.truncate(k);
            *hint = 2.25 * best[k - 1].0;
            return true;
        }
        if limit >= wall {
            return false;
        }
        limit = wall;
    }
}

/// The finest Morton level whose occupied cells hold on average at least
/// half of `k` points (level 0 if none does: the whole box is one cell).
fn level_for(sorted: &[(u64, usize)], k: usize) -> u32 {
    // Two consecutive keys fall into different cells at every level from
    // the one their highest differing bit belongs to.
    let mut splits = [0usize; MORTON_LEVELS as usize + 1];
    for w in sorted.windows(2) {
        let x = w[0].0 ^ w[1].0;
        if x != 0 {
            let bit = 63 - x.leading_zeros();
            splits[(MORTON_LEVELS - bit / 3) as usize] += 1;
        }
    }
    let n = sorted.len() as f64;
    let want = 0.5 * k as f64;
    let mut cells = 1usize;
    let mut best = 0;
    for (level, &s) in splits.iter().enumerate() {
        cells += s;
        if n / cells as f64 >= want {
            best = level as u32;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Sorted squared distances of the k nearest, the slow way.
    fn brute(points: &[Vector3<f64>], i: usize, k: usize) -> Vec<f64> {
        let mut d: Vec<f64> = points
            .iter()
            .map(|q| (q - points[i]).norm_squared())
            .collect();
        d.sort_by(f64::total_cmp);
        d.truncate(k);
        d
    }

    /// Checks every point's neighbours against brute force; returns how
    /// many the kd-tree answered.
    fn check(points: &[Vector3<f64>], k: usize) -> usize {
        let (got, tree_queries) = map_counting_tree_queries(points, k, |i, nb| {
            let mut d: Vec<f64> = nb
                .iter()
                .map(|&j| (points[j] - points[i]).norm_squared())
                .collect();
            d.sort_by(f64::total_cmp);
            d
        })
        .unwrap();
        for (i, d) in got.iter().enumerate() {
            assert_eq!(d, &brute(points, i, k), "point {i} of {}", points.len());
        }
        tree_queries
    }

    #[test]
    fn a_scanned_surface_matches_brute_force() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let points: Vec<Vector3<f64>> = (0..3000)
            .map(|_| {
                let (x, y): (f64, f64) = (rng.random_range(-0.1..0.1), rng.random_range(-0.1..0.1));
                Vector3::new(
                    x,
                    y,
                    0.3 + 0.02 * (40.0 * x).sin() * y + rng.random_range(0.0..1e-4),
                )
            })
            .collect();
        for k in [1, 3, 10, 30] {
            // A dense surface is proven by its cells: no tree queries.
            assert_eq!(check(&points, k), 0, "k = {k}");
        }
    }

    #[test]
    fn outliers_duplicates_and_a_volume_match_brute_force() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut points: Vec<Vector3<f64>> = (0..1500)
            .map(|_| Vector3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        // A pile of duplicates (a crowded cell) and far outliers (the tree).
        points.extend(std::iter::repeat_n(Vector3::new(0.5, 0.5, 0.5), 700));
        points.extend([Vector3::new(40.0, -3.0, 9.0), Vector3::new(-25.0, 0.0, 1.0)]);
        for k in [1, 10, 20] {
            // The pile is the tree's, and so are the outliers unless each
            // is its own one nearest neighbour.
            let n = check(&points, k);
            let outliers = if k > 1 { 2 } else { 0 };
            assert!(n >= 700 + outliers, "k = {k}: {n}");
        }
    }

    #[test]
    fn all_points_in_one_place_and_the_fewest_points() {
        check(&vec![Vector3::new(1.0, 2.0, 3.0); 40], 5);
        check(&[Vector3::zeros(), Vector3::x()], 2);
    }

    proptest::proptest! {
        #[test]
        fn random_clouds_match_brute_force(
            coords in proptest::collection::vec((-50i32..50, -50i32..50, -3i32..3), 1..300),
            k in 1usize..12,
        ) {
            let points: Vec<Vector3<f64>> = coords
                .iter()
                .map(|&(x, y, z)| Vector3::new(x as f64 * 1e-3, y as f64 * 1e-3, z as f64 * 1e-4))
                .collect();
            if points.len() >= k {
                check(&points, k);
            }
        }
    }
}
