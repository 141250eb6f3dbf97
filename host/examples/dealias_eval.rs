//! Fringe recovery of the de-aliasers on held-out twin samples (never used
//! in training): per method, on the pixels both projectors light (the
//! twin's overlap that the flat fields flag), against the twin's clean
//! single-projector image: MSE / PSNR (8-bit scale), SSIM, the wrapped-phase
//! error against the true phase (all four periods), the share of those
//! pixels recovered, the network evaluations and the time.
//!
//! ```text
//! cargo run --release -p slscan --example dealias_eval -- [test|noise2] [COUNT] [SAMPLER_STEPS]
//! ```
//!
//! `test`: dataset seed 2, noise 0.7..1.4 x the scan's (training: seed 1,
//! same range). `noise2`: seed 3, noise 2 x the scan's, a level training
//! never saw. Every method is scored on its fringe: its frames less their
//! per-pixel mean, put on the target's mean (de-aliasing recovers the own
//! fringe's phase and modulation; the scan re-centres every written pixel
//! on its observed mean anyway, so a method's own DC estimate is never used).

use std::path::Path;
use std::time::Instant;

use slscan::dealias::learned::LearnedDealiaser;
use slscan::dealias::metrics::{error_stats, mse_8bit, psnr_db, ssim_frames};
use slscan::dealias::{
    dealias_frames, dealias_frames_learned, AnalyticDealiaser, AnalyticParams, EpipolarDealiaser,
    EpipolarParams, Separator,
};
use slscan::phase::{wrap_pi, PhaseShift};
use slscan::raster::Raster;
use slscan::scan::aliasing::{camera_lighting, AliasParams, CameraLighting};
use slscan::sim::aliased::{held_out, AliasedSample, AliasedSet};
use slscan::sim::scan::{noise_sigma, shot_noise_share, sim_sensor};

/// A way to treat the aliased frames.
enum Method {
    /// The twin's clean frames themselves: the floor of the phase figures
    /// (pixel footprint and defocus, not de-aliasing).
    Clean,
    /// The aliased frames as they are.
    Input,
    /// Built per sample and camera from the sample's rig.
    Epipolar,
    Analytic(AnalyticDealiaser),
    Learned(Box<LearnedDealiaser>, String),
}

impl Method {
    fn name(&self) -> String {
        match self {
            Method::Clean => "clean target (floor)".into(),
            Method::Input => "aliased input (none)".into(),
            Method::Epipolar => "epipolar".into(),
            Method::Analytic(_) => "analytic".into(),
            Method::Learned(_, n) => n.clone(),
        }
    }
}

#[derive(Default)]
struct Tally {
    squared: f64,
    samples: usize,
    ssim: Vec<f64>,
    phase: Vec<f64>,
    recovered: usize,
    wanted: usize,
    evaluations: usize,
    seconds: f64,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let which = args.get(1).map_or("test", String::as_str);
    let count: usize = args.get(2).map_or(Ok(12), |s| s.parse())?;
    let sampler_steps: usize = args.get(3).map_or(Ok(8), |s| s.parse())?;
    let set = match which {
        "test" => AliasedSet {
            seed: 2,
            camera_px: (640, 480),
            projector_px: (1280, 800),
            noise_scale: (0.7, 1.4),
        },
        "noise2" => AliasedSet {
            seed: 3,
            camera_px: (640, 480),
            projector_px: (1280, 800),
            noise_scale: (2.0, 2.0),
        },
        other => return Err(format!("unknown set {other:?}: test or noise2").into()),
    };
    let periods = slscan::scan::dealias_periods_px(set.projector_px.0);
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models");
    let mut methods = vec![
        Method::Clean,
        Method::Input,
        Method::Epipolar,
        Method::Analytic(AnalyticDealiaser::new(
            &periods,
            4,
            set.projector_px.0,
            AnalyticParams::default(),
        )?),
    ];
    for (file, steps) in [
        ("dealias_onestep.onnx", 1),
        ("dealias_diffusion.onnx", sampler_steps),
    ] {
        let l = LearnedDealiaser::load(&models.join(file), &periods, 4, steps)?;
        let name = if l.model().meta.kind == "diffusion" {
            format!("diffusion, {steps}-step DDIM")
        } else {
            "one-step network".into()
        };
        methods.push(Method::Learned(Box::new(l), name));
    }
    // Each method on the pixels it wrote, and on those the analytic solver wrote too.
    let mut own: Vec<Tally> = methods.iter().map(|_| Tally::default()).collect();
    let mut common: Vec<Tally> = methods.iter().map(|_| Tally::default()).collect();
    let analytic = methods
        .iter()
        .position(|m| matches!(m, Method::Analytic(_)))
        .ok_or("no analytic method")?;
    let sensor = sim_sensor();
    for index in 0..count {
        for sample in held_out(&set, index)? {
            let outs = methods
                .iter()
                .map(|m| run(m, &sample, &sensor))
                .collect::<Result<Vec<_>, _>>()?;
            for (k, out) in outs.iter().enumerate() {
                score(out, &out.recovered, &sample, &periods, &mut own[k])?;
                let both: Vec<bool> = out
                    .recovered
                    .iter()
                    .zip(&outs[analytic].recovered)
                    .map(|(&a, &b)| a && b)
                    .collect();
                score(out, &both, &sample, &periods, &mut common[k])?;
            }
        }
        eprintln!("sample {} of {count}", index + 1);
    }
    println!(
        "{which}: {count} held-out scenes x 2 cameras, 640x480, periods {periods:?} px x 4 steps"
    );
    for (title, tallies) in [
        ("each method on the pixels it recovered", &own),
        (
            "on the pixels the analytic solver recovered (same pixels for all)",
            &common,
        ),
    ] {
        println!("\n{title}\n");
        print_table(&methods, tallies, count);
    }
    Ok(())
}

fn print_table(methods: &[Method], tallies: &[Tally], count: usize) {
    println!("| method | recovered | MSE (8-bit) | PSNR dB | SSIM | phase max / p99 / MAE rad | evaluations | time per camera |");
    println!("|---|---|---|---|---|---|---|---|");
    for (m, t) in methods.iter().zip(tallies) {
        let mse = t.squared / t.samples.max(1) as f64;
        let ssim = t.ssim.iter().sum::<f64>() / t.ssim.len().max(1) as f64;
        let p = error_stats(&t.phase);
        println!(
            "| {} | {:.3} | {:.2} | {:.2} | {:.4} | {:.3} / {:.3} / {:.4} | {} | {:.2} s |",
            m.name(),
            t.recovered as f64 / t.wanted.max(1) as f64,
            mse,
            psnr_db(mse),
            ssim,
            p.max,
            p.p99,
            p.mae,
            t.evaluations,
            t.seconds / (2 * count) as f64
        );
    }
}

/// One method's fringe on one camera's sample.
struct Output {
    /// Its frames less their mean, on the target's mean.
    est: Vec<Raster<f32>>,
    /// Wanted pixels it wrote.
    recovered: Vec<bool>,
    /// Pixels to recover: truly lit by both, lit by the own projector, and
    /// flagged by the flat fields.
    wanted: Vec<bool>,
    evaluations: usize,
    seconds: f64,
}

/// Runs `method` on one camera's sample.
fn run(
    method: &Method,
    s: &AliasedSample,
    sensor: &slscan::sim::twin::SensorModel,
) -> Result<Output, Box<dyn std::error::Error>> {
    let lit = camera_lighting(&s.flat, s.camera, &AliasParams::default());
    let pixels = s.overlap.len();
    let wanted: Vec<bool> = (0..pixels)
        .map(|i| s.overlap[i] && s.own_u_px[i].is_finite() && lit.unusable[i])
        .collect();
    let mut frames = s.frames.clone();
    let mut evaluations = 0;
    let started = Instant::now();
    match method {
        Method::Input => {}
        Method::Clean => frames.clone_from(&s.clean_own),
        Method::Epipolar => {
            let solver = EpipolarDealiaser::new(
                &s.calibration,
                s.camera,
                &s.periods_px,
                4,
                EpipolarParams::default(),
            )?;
            separate(&mut frames, s, &lit, &solver, sensor);
        }
        Method::Analytic(solver) => separate(&mut frames, s, &lit, solver, sensor),
        Method::Learned(net, _) => {
            let stats = dealias_frames_learned(&mut frames, &s.flat, s.camera, &lit, net, 1)?;
            evaluations = stats.network.map_or(0, |n| n.evaluations);
        }
    }
    let seconds = started.elapsed().as_secs_f64();
    let recovered: Vec<bool> = (0..pixels)
        .map(|i| wanted[i] && frames.iter().any(|f| f.data[i] != 0.0))
        .collect();
    let mut est = frames.clone();
    for i in 0..pixels {
        let mean = frames.iter().map(|f| f.data[i]).sum::<f32>() / frames.len() as f32;
        let dc = s.clean_own.iter().map(|f| f.data[i]).sum::<f32>() / frames.len() as f32;
        for e in est.iter_mut() {
            e.data[i] = e.data[i] - mean + dc;
        }
    }
    Ok(Output {
        est,
        recovered,
        wanted,
        evaluations,
        seconds,
    })
}

/// Runs a per-pixel solver on one camera's frames at the sample's noise.
fn separate(
    frames: &mut [Raster<f32>],
    s: &AliasedSample,
    lit: &CameraLighting,
    solver: &impl Separator,
    sensor: &slscan::sim::twin::SensorModel,
) {
    let sigma = noise_sigma(sensor) * s.noise_scale as f32;
    let share = shot_noise_share(sensor);
    dealias_frames(frames, &s.flat, s.camera, lit, solver, sigma, share);
}

/// Adds `out`'s figures on the pixels of `mask` to `tally`.
fn score(
    out: &Output,
    mask: &[bool],
    s: &AliasedSample,
    periods: &[f64],
    tally: &mut Tally,
) -> Result<(), Box<dyn std::error::Error>> {
    let est = &out.est;
    let mse = mse_8bit(est, &s.clean_own, mask);
    let n = mask.iter().filter(|&&r| r).count();
    if n > 0 {
        tally.squared += mse * (n * est.len()) as f64;
        tally.samples += n * est.len();
        let ssim = ssim_frames(est, &s.clean_own, mask);
        if ssim.is_finite() {
            tally.ssim.push(ssim);
        }
    }
    let decoder = PhaseShift::new(4)?;
    for (k, p) in periods.iter().enumerate() {
        let period_frames: Vec<&Raster<f32>> = est[4 * k..4 * k + 4].iter().collect();
        let phase = decoder.wrapped_phase(&period_frames)?.phase;
        for i in (0..mask.len()).filter(|&i| mask[i]) {
            let truth = std::f64::consts::TAU * f64::from(s.own_u_px[i]) / p;
            tally
                .phase
                .push(f64::from(wrap_pi(phase.data[i] - truth as f32)));
        }
    }
    tally.recovered += n;
    tally.wanted += out.wanted.iter().filter(|&&r| r).count();
    tally.evaluations += out.evaluations;
    tally.seconds += out.seconds;
    Ok(())
}
