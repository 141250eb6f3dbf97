//! The few-step sampler of the diffusion networks: the cosine schedule of
//! `training/dealias/sampling.py` and deterministic DDIM over an
//! x0-predicting denoiser, shared by every learned module.

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

use super::{Model, ModelError};

/// The cosine schedule's alpha-bar at `t` in [0, 1] (offset `s`).
pub fn alpha_bar(t: f64, s: f64) -> f64 {
    let f = |x: f64| {
        ((x + s) / (1.0 + s) * std::f64::consts::FRAC_PI_2)
            .cos()
            .powi(2)
    };
    (f(t) / f(0.0)).clamp(0.0, 1.0)
}

/// Deterministic DDIM (eta = 0) with an x0-predicting `denoise(x_t, t)`:
/// `steps` evaluations from `x` (pure noise at t = 1) down to t = 0.
pub fn ddim<E>(
    x: Vec<f32>,
    steps: usize,
    s: f64,
    denoise: impl FnMut(&[f32], f32) -> Result<Vec<f32>, E>,
) -> Result<Vec<f32>, E> {
    ddim_corrected(x, steps, s, denoise, 0, |_| {})
}

/// [`ddim`] with seed 002's periodic correction: after every `every`-th
/// step (0: never) the new state goes through `correct` before the next
/// evaluation; the last step's state, the sample, is corrected too when its
/// turn comes.
pub fn ddim_corrected<E>(
    mut x: Vec<f32>,
    steps: usize,
    s: f64,
    mut denoise: impl FnMut(&[f32], f32) -> Result<Vec<f32>, E>,
    every: usize,
    mut correct: impl FnMut(&mut [f32]),
) -> Result<Vec<f32>, E> {
    for i in 0..steps {
        let (t_now, t_next) = (
            1.0 - i as f64 / steps as f64,
            1.0 - (i + 1) as f64 / steps as f64,
        );
        let x0 = denoise(&x, t_now as f32)?;
        let (a_now, a_next) = (alpha_bar(t_now, s), alpha_bar(t_next, s));
        let root_rest = (1.0 - a_now).sqrt().max(1e-6);
        for (xi, &x0i) in x.iter_mut().zip(&x0) {
            let eps = (f64::from(*xi) - a_now.sqrt() * f64::from(x0i)) / root_rest;
            *xi = (a_next.sqrt() * f64::from(x0i) + (1.0 - a_next).sqrt() * eps) as f32;
        }
        if every > 0 && (i + 1) % every == 0 {
            correct(&mut x);
        }
    }
    // At t = 0 the schedule's alpha-bar is 1: the state is the last x0.
    Ok(x)
}

/// One tile of a diffusion `model`: deterministic DDIM over `steps`
/// evaluations from noise seeded by `seed`, conditioned on `cond`.
pub fn sample_tile(
    model: &Model,
    cond: &[f32],
    steps: usize,
    seed: u64,
) -> Result<Vec<f32>, ModelError> {
    sample_tile_corrected(model, cond, steps, seed, 0, |_| {})
}

/// [`sample_tile`] with [`ddim_corrected`]'s periodic correction.
pub fn sample_tile_corrected(
    model: &Model,
    cond: &[f32],
    steps: usize,
    seed: u64,
    every: usize,
    correct: impl FnMut(&mut [f32]),
) -> Result<Vec<f32>, ModelError> {
    let meta = &model.meta;
    let s = meta.schedule.as_ref().map_or(0.008, |s| s.s);
    let n = meta.frame_channels * meta.tile * meta.tile;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let noise: Vec<f32> = (0..n).map(|_| StandardNormal.sample(&mut rng)).collect();
    ddim_corrected(
        noise,
        steps,
        s,
        |x, t| model.run(&[cond, x, &[t]]),
        every,
        correct,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_schedule_runs_from_clean_to_pure_noise() {
        assert!((alpha_bar(0.0, 0.008) - 1.0).abs() < 1e-12);
        assert!(alpha_bar(1.0, 0.008) < 1e-8);
        assert!(alpha_bar(0.3, 0.008) > alpha_bar(0.6, 0.008));
    }

    /// With a denoiser that knows x0, DDIM lands on it from any noise, and
    /// calls the denoiser once per step.
    #[test]
    fn ddim_with_a_perfect_denoiser_returns_x0() {
        let truth = vec![0.3f32, -0.7, 0.1];
        let mut calls = 0;
        let out = ddim::<()>(vec![1.5, -2.0, 0.4], 5, 0.008, |_, _| {
            calls += 1;
            Ok(truth.clone())
        })
        .unwrap();
        assert_eq!(calls, 5);
        assert_eq!(out, truth);
    }

    /// The correction runs after every `every`-th step and its change
    /// carries into the next evaluation and the sample; 0 never runs it.
    #[test]
    fn the_correction_runs_on_its_period_and_reaches_the_sample() {
        let run = |every: usize| {
            let mut seen = Vec::new();
            let mut corrections = 0;
            let out = ddim_corrected::<()>(
                vec![0.0; 2],
                6,
                0.008,
                |x, _| {
                    seen.push(x[0]);
                    Ok(vec![0.5, 0.5])
                },
                every,
                |x| {
                    corrections += 1;
                    x[1] += 1.0;
                },
            )
            .unwrap();
            (out, corrections)
        };
        assert_eq!(run(0), (vec![0.5, 0.5], 0));
        let (out, n) = run(3);
        assert_eq!(n, 2);
        // Corrected last: the sample keeps the shift.
        assert!((out[1] - 1.5).abs() < 1e-6, "{out:?}");
        assert_eq!(out[0], 0.5);
        let (_, n) = run(4);
        assert_eq!(n, 1);
    }
}
