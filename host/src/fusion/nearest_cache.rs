//! Exact nearest target points of a moving source cloud, searched again only
//! where the motion since the last search could have changed the answer.
//!
//! ICP moves the source a little each iteration and asks, for each source
//! point, for the nearest target point within a gate. A search that also
//! finds the second-nearest distance certifies its answer for later
//! placements: if the point has since moved by `delta`, the old nearest is
//! still the nearest while `nearest + delta < second - delta` (triangle
//! inequality), and a search of radius `r` that found nothing still finds
//! nothing within any gate up to `r - delta`. In the last ICP iterations the
//! source moves by micrometres, so almost no point is searched again; the
//! answers are the same as a fresh search's (up to exact ties).

use nalgebra::{Isometry3, Point3, Vector3};
use rayon::prelude::*;

use super::Tree;

/// How far past the old nearest point (at most the gate) a search looks, as a
/// fraction of the gate: the room later motion has before the point needs a
/// new search.
const MARGIN: f64 = 0.25;

/// A point not searched yet.
const NEVER: u32 = u32::MAX;

/// What the last search of one source point established.
#[derive(Debug, Clone, Copy)]
struct Entry {
    /// Nearest target point, `None` when none was within the searched radius.
    nearest: Option<usize>,
    /// Distance to it, metres.
    nearest_m: f64,
    /// Every other target point was at least this far, metres.
    others_beyond_m: f64,
    /// Index of the placement the search was made at, or [`NEVER`].
    placed_by: u32,
}

/// Per source point, the last search's certificate; and the placements of the
/// source those searches were made at.
pub(crate) struct NearestCache {
    entries: Vec<Entry>,
    placements: Vec<Isometry3<f64>>,
}

impl NearestCache {
    /// A cache for a source of `points` points, nothing searched yet.
    pub(crate) fn new(points: usize) -> Self {
        let empty = Entry {
            nearest: None,
            nearest_m: f64::INFINITY,
            others_beyond_m: 0.0,
            placed_by: NEVER,
        };
        Self {
            entries: vec![empty; points],
            placements: Vec::new(),
        }
    }

    /// `pair(q, j)` for every `stride`-th source point whose placement
    /// `q = transform * p` has a target point within `gate` metres, `j`
    /// being the nearest of them. `source` and `targets` must be the same
    /// slices at every call (the cache is indexed by them), and `tree` must
    /// be built over `targets`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn nearest_within<T: Send>(
        &mut self,
        tree: &Tree,
        targets: &[Vector3<f64>],
        source: &[Vector3<f64>],
        stride: usize,
        transform: &Isometry3<f64>,
        gate: f64,
        pair: impl Fn(Vector3<f64>, usize) -> T + Sync,
    ) -> Vec<T> {
        debug_assert_eq!(source.len(), self.entries.len());
        let now = u32::try_from(self.placements.len())
            .ok()
            .filter(|&n| n != NEVER)
            .expect("fewer than 2^32 - 1 placements");
        self.placements.push(*transform);
        let placements = &self.placements;
        source
            .par_iter()
            .zip(self.entries.par_iter_mut())
            .step_by(stride)
            .filter_map(|(p, entry)| {
                let q = transform.transform_point(&Point3::from(*p)).coords;
                let j = match certified(entry, placements, p, &q, targets, gate) {
                    Some(answer) => answer,
                    None => {
                        *entry = search(tree, targets, entry.nearest, &q, gate, now);
                        entry.nearest.filter(|_| entry.nearest_m <= gate)
                    }
                }?;
                Some(pair(q, j))
            })
            .collect()
    }
}

/// The answer at `q` (nearest target point within `gate`, or none) when the
/// entry's last search still proves it, `None` when a new search is needed.
fn certified(
    entry: &Entry,
    placements: &[Isometry3<f64>],
    p: &Vector3<f64>,
    q: &Vector3<f64>,
    targets: &[Vector3<f64>],
    gate: f64,
) -> Option<Option<usize>> {
    let placement = placements.get(entry.placed_by as usize)?;
    let delta = (q - placement.transform_point(&Point3::from(*p)).coords).norm();
    // A hair of slack so rounding cannot turn a near-tie into a false proof.
    let others_beyond = (entry.others_beyond_m - delta) * (1.0 - 1e-9);
    match entry.nearest {
        None => (others_beyond >= gate).then_some(None),
        Some(j) if entry.nearest_m + delta < others_beyond => {
            Some(((q - targets[j]).norm_squared() <= gate * gate).then_some(j))
        }
        Some(_) => None,
    }
}

/// Searches the two nearest target points of `q` within the gate plus a
/// margin (or, when an old nearest point is closer than the gate, within its
/// distance plus the margin: the nearest can be no farther than it).
fn search(
    tree: &Tree,
    targets: &[Vector3<f64>],
    old: Option<usize>,
    q: &Vector3<f64>,
    gate: f64,
    now: u32,
) -> Entry {
    let bound = old.map_or(gate, |j| (q - targets[j]).norm().min(gate));
    let radius = bound + MARGIN * gate;
    let found = tree
        .query(&[q.x, q.y, q.z])
        .nearest_n::<kiddo::SquaredEuclidean<f64>>(std::num::NonZeroUsize::new(2).expect("2"))
        .within(radius * radius)
        .execute();
    let mut distances: Vec<(f64, usize)> = found
        .iter()
        .map(|nn| (nn.distance.sqrt(), nn.item as usize))
        .collect();
    distances.sort_by(|a, b| a.0.total_cmp(&b.0));
    Entry {
        nearest: distances.first().map(|&(_, j)| j),
        nearest_m: distances.first().map_or(f64::INFINITY, |&(d, _)| d),
        others_beyond_m: distances.get(1).map_or(radius, |&(d, _)| d),
        placed_by: now,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fusion::{build_tree, nearest_within};
    use nalgebra::{Translation3, UnitQuaternion};
    use rand::{Rng, SeedableRng};

    /// Every answer of the cache, over a path of small and large moves, is
    /// the answer of a fresh search at that placement.
    #[test]
    fn answers_match_a_fresh_search_along_a_path() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let targets: Vec<Vector3<f64>> = (0..4000)
            .map(|_| {
                let (x, y): (f64, f64) =
                    (rng.random_range(-0.05..0.05), rng.random_range(-0.05..0.05));
                Vector3::new(x, y, 0.01 * (40.0 * x).sin() * (30.0 * y).cos())
            })
            .collect();
        let source: Vec<Vector3<f64>> = (0..3000)
            .map(|_| {
                Vector3::new(
                    rng.random_range(-0.07..0.07),
                    rng.random_range(-0.07..0.07),
                    rng.random_range(-0.01..0.01),
                )
            })
            .collect();
        let tree = build_tree(&targets).unwrap();
        let mut cache = NearestCache::new(source.len());
        let mut transform = Isometry3::identity();
        let mut searched_again = Vec::new();
        for step in 0..12 {
            // Large moves first, then ever smaller ones (as ICP converges).
            let size = 0.004 * 0.3f64.powi(step);
            let update = Isometry3::from_parts(
                Translation3::new(size, -0.5 * size, 0.3 * size),
                UnitQuaternion::from_scaled_axis(Vector3::new(0.0, size, 2.0 * size)),
            );
            transform = update * transform;
            let gate = if step < 3 { 0.008 } else { 0.002 };
            let before = cache.placements.len() as u32;
            let got =
                cache.nearest_within(&tree, &targets, &source, 1, &transform, gate, |q, j| (q, j));
            let want: Vec<(Vector3<f64>, usize)> = source
                .iter()
                .filter_map(|p| {
                    let q = transform.transform_point(&Point3::from(*p)).coords;
                    nearest_within(&tree, &q, gate * gate).map(|(j, _)| (q, j))
                })
                .collect();
            assert_eq!(got, want, "step {step}");
            searched_again.push(
                cache
                    .entries
                    .iter()
                    .filter(|e| e.placed_by == before)
                    .count(),
            );
        }
        // The proofs do their job: once the moves are micrometres, hardly
        // any point is searched again.
        assert_eq!(searched_again[0], source.len());
        assert!(
            *searched_again.last().unwrap() < source.len() / 50,
            "{searched_again:?}"
        );
    }
}
