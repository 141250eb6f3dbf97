//! Quality-guided spatial unwrapping: the single-frequency fallback.
//!
//! Starting from the best pixel, a flood fill always grows into the highest-quality
//! neighbour next (a max-heap), so phase errors at poor pixels cannot spread into good
//! regions. Each new pixel takes the order that brings it nearest its unwrapped neighbour.
//! Pixels below the quality floor are masked, pixels the fill never reaches (other
//! surfaces, islands behind a shadow) are unreached, and after the fill every unwrapped
//! pixel with a jump of more than `pi` to an unwrapped neighbour is marked unreliable:
//! spatial unwrapping cannot know the height of a step, so it does not claim one.
//!
//! The result is absolute only up to the seed's order: `seed_order` sets it (from a
//! reference, or 0 for a relative map).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use super::{AbsolutePhase, PixelStatus, UnwrapError};
use crate::raster::{neighbours4, Raster};

#[derive(PartialEq)]
struct Edge {
    quality: f32,
    to: usize,
    from: usize,
}

impl Eq for Edge {}

impl PartialOrd for Edge {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Edge {
    fn cmp(&self, other: &Self) -> Ordering {
        self.quality.total_cmp(&other.quality)
    }
}

/// Where the fill starts and which order it gives the seed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seed {
    /// Column, or `None` to start at the best-quality pixel.
    pub at: Option<(usize, usize)>,
    /// Fringe order of the seed pixel.
    pub order: i32,
}

/// Unwraps one wrapped phase map of period `period_px`, guided by `quality` (for
/// example the modulation), ignoring pixels with quality below `min_quality`.
pub fn unwrap_quality_guided(
    wrapped: &Raster<f32>,
    quality: &Raster<f32>,
    min_quality: f32,
    seed: Seed,
    period_px: f64,
) -> Result<AbsolutePhase, UnwrapError> {
    let (width, height) = super::same_size(&[wrapped, quality])?;
    let n = width * height;
    let mut status = Raster::filled(width, height, PixelStatus::Unreached);
    let mut phase = Raster::filled(width, height, f32::NAN);
    for i in 0..n {
        let usable = quality.data[i] >= min_quality; // false for NaN quality
        if !usable || !wrapped.data[i].is_finite() {
            status.data[i] = PixelStatus::Masked;
        }
    }
    let start = match seed.at {
        Some((x, y)) if x < width && y < height => Some(y * width + x),
        Some(_) => None,
        None => (0..n)
            .filter(|&i| status.data[i] != PixelStatus::Masked)
            .max_by(|&a, &b| quality.data[a].total_cmp(&quality.data[b])),
    };
    let Some(start) = start.filter(|&s| status.data[s] != PixelStatus::Masked) else {
        return Ok(AbsolutePhase {
            phase,
            status,
            period_px,
        });
    };
    let tau = std::f32::consts::TAU;
    phase.data[start] = wrapped.data[start] + tau * seed.order as f32;
    status.data[start] = PixelStatus::Valid;
    let mut heap = BinaryHeap::new();
    let neighbours = |i: usize| neighbours4(i, width, height).into_iter().flatten();
    let push = |heap: &mut BinaryHeap<Edge>, status: &Raster<PixelStatus>, from: usize| {
        for to in neighbours(from) {
            if status.data[to] == PixelStatus::Unreached {
                heap.push(Edge {
                    quality: quality.data[to],
                    to,
                    from,
                });
            }
        }
    };
    push(&mut heap, &status, start);
    while let Some(Edge { to, from, .. }) = heap.pop() {
        if status.data[to] != PixelStatus::Unreached {
            continue;
        }
        let k = ((phase.data[from] - wrapped.data[to]) / tau).round();
        phase.data[to] = wrapped.data[to] + tau * k;
        status.data[to] = PixelStatus::Valid;
        push(&mut heap, &status, to);
    }
    // Consistency: a jump over pi between unwrapped neighbours is a step we cannot size.
    let mut bad = vec![false; n];
    for i in 0..n {
        if status.data[i] != PixelStatus::Valid {
            continue;
        }
        for j in neighbours(i) {
            if status.data[j] == PixelStatus::Valid
                && (phase.data[i] - phase.data[j]).abs() > std::f32::consts::PI
            {
                bad[i] = true;
                bad[j] = true;
            }
        }
    }
    for i in (0..n).filter(|&i| bad[i]) {
        status.data[i] = PixelStatus::Unreliable;
        phase.data[i] = f32::NAN;
    }
    Ok(AbsolutePhase {
        phase,
        status,
        period_px,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::wrap_pi;

    #[test]
    fn unwraps_a_smooth_surface_and_skips_a_shadow() {
        let (w, h, period) = (96usize, 64usize, 12.0f64);
        let truth = |x: usize, y: usize| {
            std::f64::consts::TAU * (x as f64 + 4.0 * (y as f64 / 20.0).sin()) / period
        };
        let wrapped = Raster::from_fn(w, h, |x, y| wrap_pi(truth(x, y) as f32));
        // A shadow column band splits off the right edge: those pixels stay unreached.
        let quality = Raster::from_fn(w, h, |x, _| if (70..74).contains(&x) { 0.0 } else { 1.0 });
        let seed = Seed {
            at: Some((0, 0)),
            order: 0,
        };
        let out = unwrap_quality_guided(&wrapped, &quality, 0.1, seed, period).unwrap();
        assert_eq!(out.count(PixelStatus::Masked), 4 * h);
        assert_eq!(out.count(PixelStatus::Unreached), (w - 74) * h);
        for y in 0..h {
            for x in 0..70 {
                let got = f64::from(*out.phase.at(x, y));
                assert!((got - truth(x, y)).abs() < 1e-3, "({x},{y})");
            }
        }
    }

    #[test]
    fn a_phase_vortex_is_flagged_not_guessed() {
        // Around a vortex no unwrapping is consistent: wherever the fill closes the loop,
        // neighbours differ by about 2 pi. Those pixels must come back unreliable.
        let (w, h) = (31usize, 31usize);
        let wrapped = Raster::from_fn(w, h, |x, y| (y as f32 - 15.3).atan2(x as f32 - 15.6));
        let quality = Raster::filled(w, h, 1.0f32);
        let seed = Seed { at: None, order: 0 };
        let out = unwrap_quality_guided(&wrapped, &quality, 0.1, seed, 10.0).unwrap();
        let unreliable = out.count(PixelStatus::Unreliable);
        assert!(unreliable >= 2 && unreliable < w * h / 4, "{unreliable}");
        for i in 0..w * h {
            if out.status.data[i] == PixelStatus::Valid {
                assert!(out.phase.data[i].is_finite());
            }
        }
    }
}
