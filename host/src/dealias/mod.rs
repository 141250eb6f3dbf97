//! De-aliasing of the simultaneous mode: both projectors show identical
//! sequences at once, so in the overlap each camera sees the sum of two
//! fringes. Each camera's own projector's fringe is recovered there and
//! written back as plain N-step frames, so the unchanged reconstruction
//! runs on them; what cannot be recovered is masked.
//!
//! ```text
//! frames (K periods x N steps) + flat fields (dark, A on, B on)
//!   -> lit by the own projector only: unchanged
//!   -> lit by the other projector (and perhaps the own): a Separator per pixel
//!        (epipolar: one range along the ray; analytic: two free columns),
//!        every 8th pixel of every 8th row first, the rest starting from those
//!        separated -> own fringe re-expressed as N frames;  refused -> masked
//! ```
//!
//! [`DealiasMethod::Mask`] masks every pixel the other projector lights (the
//! behaviour before a de-aliaser existed).

pub mod analytic;
pub mod epipolar;
pub mod learned;
pub mod metrics;

use rayon::prelude::*;

pub use analytic::{AnalyticDealiaser, AnalyticParams, Refused, Separated};
pub use epipolar::{EpipolarDealiaser, EpipolarError, EpipolarParams};

use crate::raster::Raster;
use crate::scan::aliasing::{CameraLighting, FlatFields};

/// How the simultaneous mode treats pixels the other projector lights.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DealiasMethod {
    /// Separate the two fringes per pixel along its ray, through the
    /// calibrated rig ([`epipolar`]).
    #[default]
    Epipolar,
    /// Separate the two fringes per pixel with free columns, no
    /// calibration ([`analytic`]).
    Analytic,
    /// Mask every pixel the other projector lights.
    Mask,
    /// A trained network ([`learned`]; the model is
    /// [`crate::scan::ScanConfig::learned`]).
    Learned,
}

impl DealiasMethod {
    /// The name the CLI and the report use.
    pub fn name(self) -> &'static str {
        match self {
            DealiasMethod::Epipolar => "epipolar",
            DealiasMethod::Analytic => "analytic",
            DealiasMethod::Mask => "mask",
            DealiasMethod::Learned => "learned",
        }
    }
}

/// What de-aliasing one camera's frames did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DealiasStats {
    /// Pixels the other projector lights (grown), the ones that need it.
    pub affected: usize,
    /// Of those, lit by the own projector too: the ones tried.
    pub attempted: usize,
    /// Separated and written back.
    pub separated: usize,
    /// Refused: the phasors too alike.
    pub ill_posed: usize,
    /// Refused: the model did not fit.
    pub misfit: usize,
    /// Refused: no consistent solution.
    pub unsolved: usize,
    /// Refused: separated, but the own column disagrees with every pair of
    /// separated neighbours (a wrong solution of a pixel whose equations
    /// have several).
    pub inconsistent: usize,
    /// Refused: NaN or saturated input (learned; the analytic solver's
    /// misfit test catches these).
    pub bad_input: usize,
    /// Learned: tiles and network evaluations.
    pub network: Option<learned::LearnedRun>,
    /// Wall time, milliseconds.
    pub time_ms: u64,
}

/// A per-pixel separation of the two fringes.
pub trait Separator: Sync {
    /// Periods, finest first.
    fn periods_px(&self) -> &[f64];
    /// Steps per period.
    fn steps(&self) -> usize;
    /// Separates camera pixel `index`: `samples[p * steps + n]`
    /// (period-major, as the frames are), `a0`, `b0` the own and other
    /// modulations the flat fields give, `sigma` the noise of one sample.
    fn separate_pixel(
        &self,
        index: usize,
        samples: &[f32],
        a0: f64,
        b0: f64,
        sigma: f64,
    ) -> Result<Separated, Refused>;
    /// As [`Separator::separate_pixel`], given the separated neighbours
    /// `hints` (a solver that can start from them saves its search; by
    /// default they are not used).
    fn separate_near(
        &self,
        index: usize,
        samples: &[f32],
        a0: f64,
        b0: f64,
        sigma: f64,
        hints: &[Separated],
    ) -> Result<Separated, Refused> {
        let _ = hints;
        self.separate_pixel(index, samples, a0, b0, sigma)
    }
}

/// Spacing of the pixels separated first, whose solutions the pixels
/// between them start from ([`Separator::separate_near`]).
const SEED_GRID: usize = 8;

/// The seed-grid corners of the cell holding pixel `i`, nearest first.
fn cell_corners(i: usize, width: usize, height: usize) -> [Option<usize>; 4] {
    let (x, y) = (i % width, i / width);
    let (x0, y0) = (x - x % SEED_GRID, y - y % SEED_GRID);
    let at = |cx: usize, cy: usize| (cx < width && cy < height).then(|| cy * width + cx);
    let mut corners = [
        (x0, y0),
        (x0 + SEED_GRID, y0),
        (x0, y0 + SEED_GRID),
        (x0 + SEED_GRID, y0 + SEED_GRID),
    ];
    corners.sort_by_key(|&(cx, cy)| cx.abs_diff(x).pow(2) + cy.abs_diff(y).pow(2));
    corners.map(|(cx, cy)| at(cx, cy))
}

/// Pairs of opposite neighbours that must agree (of four): two, since a
/// wrong solution sometimes has one wrong neighbour pair beside it.
const MIN_AGREEING_PAIRS: usize = 2;

/// Whether pixel `i`'s own column lies on the line through at least
/// [`MIN_AGREEING_PAIRS`] pairs of opposite separated neighbours
/// (left-right, up-down, the two diagonals), within 1 px plus four of its
/// sigmas: a surface is smooth across three pixels, a wrong solution is
/// tens of pixels off.
fn agrees_with_neighbours(
    own_px: &[f64],
    width: usize,
    height: usize,
    i: usize,
    sigma: f64,
) -> bool {
    let (x, y) = ((i % width) as isize, (i / width) as isize);
    let at = |dx: isize, dy: isize| -> f64 {
        let (u, v) = (x + dx, y + dy);
        if u < 0 || v < 0 || u >= width as isize || v >= height as isize {
            return f64::NAN;
        }
        own_px[v as usize * width + u as usize]
    };
    let tolerance = 1.0 + 4.0 * sigma;
    let agreeing = [(1, 0), (0, 1), (1, 1), (1, -1)]
        .iter()
        .filter(|&&(dx, dy)| {
            let mid = 0.5 * (at(dx, dy) + at(-dx, -dy));
            (own_px[i] - mid).abs() <= tolerance
        })
        .count();
    agreeing >= MIN_AGREEING_PAIRS
}

/// The noise of one sample at level `mean`, from the half-scale noise and
/// its shot-noise share (shot variance grows with the level).
fn sample_sigma(noise_sigma: f32, shot_share: f32, mean: f32) -> f64 {
    let half = f64::from(noise_sigma).powi(2);
    let share = f64::from(shot_share.clamp(0.0, 1.0));
    (half * ((1.0 - share) + share * f64::from(mean.max(0.0)) / 0.5)).sqrt()
}

/// Zeroes `frames` where `mask` holds: zero modulation, so the
/// reconstruction masks those pixels.
pub fn mask_pixels(frames: &mut [Raster<f32>], mask: &[bool]) {
    for f in frames.iter_mut() {
        for (v, &m) in f.data.iter_mut().zip(mask) {
            if m {
                *v = 0.0;
            }
        }
    }
}

/// Masks ([`mask_pixels`]) every `affected` pixel not `written`.
fn mask_unwritten(frames: &mut [Raster<f32>], affected: &[bool], written: &[bool]) {
    let refused: Vec<bool> = affected
        .iter()
        .zip(written)
        .map(|(&a, &w)| a && !w)
        .collect();
    mask_pixels(frames, &refused);
}

/// De-aliases head `own`'s camera frames in place (period-major, `K x N`
/// as `solver` expects) with its flat fields and the lighting they give
/// (`lighting`, [`crate::scan::aliasing::camera_lighting`]): every pixel the
/// other projector lights is either separated (its own fringe written back)
/// or, when not lit by its own projector or refused, masked
/// ([`mask_pixels`]). `noise_sigma` and `shot_share` are the camera's noise
/// (as `ReconstructConfig` has them).
pub fn dealias_frames(
    frames: &mut [Raster<f32>],
    flat: &FlatFields,
    own: usize,
    lighting: &CameraLighting,
    solver: &impl Separator,
    noise_sigma: f32,
    shot_share: f32,
) -> DealiasStats {
    let affected = &lighting.unusable;
    let own_lit = lighting.lit.lit_by(own);
    let (own_flat, other_flat) = flat.own_other(own);
    let count = frames.len();
    let pixels = flat.dark.data.len();
    let (width, height) = (flat.dark.width, flat.dark.height);
    let solve = |i: usize, hints: &[Separated]| {
        let samples: Vec<f32> = frames.iter().map(|f| f.data[i]).collect();
        let mean = samples.iter().sum::<f32>() / count as f32;
        let dark = flat.dark.data[i];
        // Full-contrast fringes: half of each projector's full-on signal.
        let a0 = 0.5 * f64::from(own_flat.data[i] - dark);
        let b0 = 0.5 * f64::from(other_flat.data[i] - dark);
        let sigma = sample_sigma(noise_sigma, shot_share, mean);
        let solved = solver.separate_near(i, &samples, a0, b0, sigma, hints);
        (i, solved, own_fringe(solver, &solved, mean))
    };
    let tried = |i: &usize| affected[*i] && own_lit[*i];
    let on_grid =
        |i: &usize| (i % width).is_multiple_of(SEED_GRID) && (i / width).is_multiple_of(SEED_GRID);
    // The seed grid first, each pixel on its own; then every other pixel
    // from the seeds at its cell's corners.
    let mut results: Vec<(usize, Result<Separated, Refused>, Vec<f32>)> = (0..pixels)
        .into_par_iter()
        .filter(|i| tried(i) && on_grid(i))
        .map(|i| solve(i, &[]))
        .collect();
    let mut seeds: Vec<Option<Separated>> = vec![None; pixels];
    for (i, solved, _) in &results {
        seeds[*i] = solved.ok();
    }
    results.par_extend(
        (0..pixels)
            .into_par_iter()
            .filter(|i| tried(i) && !on_grid(i))
            .map(|i| {
                let hints: Vec<Separated> = cell_corners(i, width, height)
                    .iter()
                    .filter_map(|c| c.and_then(|c| seeds[c]))
                    .collect();
                solve(i, &hints)
            }),
    );
    let mut stats = DealiasStats {
        affected: affected.iter().filter(|&&m| m).count(),
        attempted: results.len(),
        ..DealiasStats::default()
    };
    let mut own_px = vec![f64::NAN; pixels];
    for (i, solved, _) in &results {
        if let Ok(s) = solved {
            own_px[*i] = s.x_own_px;
        }
    }
    let mut written = vec![false; pixels];
    for (i, solved, fringe) in &results {
        let solved = match solved {
            Ok(s) if !agrees_with_neighbours(&own_px, width, height, *i, s.sigma_own_px) => {
                stats.inconsistent += 1;
                continue;
            }
            other => other,
        };
        match solved {
            Ok(_) => {
                stats.separated += 1;
                written[*i] = true;
                for (f, v) in frames.iter_mut().zip(fringe) {
                    f.data[*i] = *v;
                }
            }
            Err(Refused::IllPosed) => stats.ill_posed += 1,
            Err(Refused::Misfit) => stats.misfit += 1,
            Err(Refused::NoSolution) => stats.unsolved += 1,
        }
    }
    mask_unwritten(frames, affected, &written);
    stats
}

/// A sample at or above this is clipped by the sensor (full scale 1).
const SATURATED: f32 = 0.999;

/// Whether pixel `i` holds a NaN or a clipped sample in any frame or flat
/// field: the network would invent a fringe there.
fn bad_input(frames: &[Raster<f32>], flat: &FlatFields, i: usize) -> bool {
    frames
        .iter()
        .chain([&flat.dark, &flat.lit_a, &flat.lit_b])
        .any(|f| f.data[i].is_nan() || f.data[i] >= SATURATED)
}

/// As [`dealias_frames`], with a trained network: every pixel the other
/// projector lights is written with the network's own fringe (re-centred
/// on the observed mean, as [`own_fringe`] does) when its own projector
/// lights it too and its input is finite and unclipped, and masked
/// otherwise. `seed` makes a diffusion sample reproducible.
pub fn dealias_frames_learned(
    frames: &mut [Raster<f32>],
    flat: &FlatFields,
    own: usize,
    lighting: &CameraLighting,
    network: &learned::LearnedDealiaser,
    seed: u64,
) -> Result<DealiasStats, crate::infer::ModelError> {
    let affected = &lighting.unusable;
    let own_lit = lighting.lit.lit_by(own);
    let (own_flat, _) = flat.own_other(own);
    let (width, height) = (flat.dark.width, flat.dark.height);
    let pixels = width * height;
    let tried: Vec<bool> = (0..pixels).map(|i| affected[i] && own_lit[i]).collect();
    let bad: Vec<bool> = (0..pixels)
        .map(|i| tried[i] && bad_input(frames, flat, i))
        .collect();
    let needed: Vec<bool> = tried.iter().zip(&bad).map(|(&t, &b)| t && !b).collect();
    let s_min = network.model().meta.normalisation.s_min;
    let (mut cond, scale) = learned::condition(frames, flat, own, s_min);
    // A NaN would spread through the convolutions over its whole tile, and
    // a clipped sample is not a fringe: both enter the network as zero.
    for plane in cond.chunks_mut(pixels) {
        for (i, v) in plane.iter_mut().enumerate() {
            if bad[i] || !v.is_finite() {
                *v = 0.0;
            }
        }
    }
    let planes = crate::infer::tiles::Planes {
        data: &cond,
        channels: frames.len() + 2,
        width,
        height,
    };
    let (x0, run) = network.predict(&planes, &needed, seed)?;
    let count = frames.len();
    let mut stats = DealiasStats {
        affected: affected.iter().filter(|&&m| m).count(),
        attempted: tried.iter().filter(|&&t| t).count(),
        bad_input: bad.iter().filter(|&&b| b).count(),
        network: Some(run),
        ..DealiasStats::default()
    };
    let mut written = vec![false; pixels];
    let mut clean = vec![0.0f32; count];
    for i in (0..pixels).filter(|&i| needed[i]) {
        for (k, c) in clean.iter_mut().enumerate() {
            *c = learned::clean_frame(
                x0[k * pixels + i],
                own_flat.data[i],
                flat.dark.data[i],
                scale[i],
            );
        }
        if clean.iter().any(|c| !c.is_finite()) {
            stats.unsolved += 1;
            continue;
        }
        let observed = frames.iter().map(|f| f.data[i]).sum::<f32>() / count as f32;
        let predicted = clean.iter().sum::<f32>() / count as f32;
        for (f, c) in frames.iter_mut().zip(&clean) {
            f.data[i] = observed + (c - predicted);
        }
        written[i] = true;
        stats.separated += 1;
    }
    mask_unwritten(frames, affected, &written);
    Ok(stats)
}

/// The own projector's N-step fringe of a separated pixel, period-major,
/// around the pixel's observed mean (so the reconstruction's shot-noise
/// prediction counts both projectors' light); empty when refused.
fn own_fringe(solver: &impl Separator, solved: &Result<Separated, Refused>, mean: f32) -> Vec<f32> {
    let Ok(s) = solved else {
        return Vec::new();
    };
    let n = solver.steps();
    let tau = std::f64::consts::TAU;
    solver
        .periods_px()
        .iter()
        .flat_map(|p| {
            let phi = tau * s.x_own_px / p;
            (0..n).map(move |k| {
                (f64::from(mean) + s.a * (phi + tau * k as f64 / n as f64).cos()) as f32
            })
        })
        .collect()
}
