//! The learned underwater restorers against no restoration and the
//! classical one, on held-out sets of `underwater_dataset` (scenes the
//! networks never saw), per turbidity: PSNR (8-bit) and SSIM after one gain
//! and offset per frame, and wrapped-phase MAE, all against the same set
//! through clear water (`slscan::underwater::score`); time per 640x480 set.
//!
//! ```text
//! cargo run --release -p slscan --example underwater_dataset -- out/uw-test 24 2
//! cargo run --release -p slscan --example underwater_eval -- out/uw-test [SAMPLER_STEPS] [STRENGTHS]
//! ```
//!
//! `STRENGTHS` (comma-separated, default `0.01,1,4`): the diffusion network
//! again with seed 002's physics correction after every sampler step at
//! each strength (0.01 is the seed's), the PSF from each sample's level.

use std::path::{Path, PathBuf};
use std::time::Instant;

use slscan::io::npy::decode_npy_2d;
use slscan::raster::Raster;
use slscan::underwater::learned::{LearnedRestorer, PhysicsCorrection};
use slscan::underwater::score::Score;
use slscan::underwater::{ClassicalRestorer, RestoreParams, Veil};

const LEVELS: [&str; 4] = ["T1", "T2", "T3", "T4"];
const METHODS: [&str; 4] = ["none", "classical", "one-step network", "diffusion network"];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let data = PathBuf::from(
        args.first()
            .ok_or("usage: underwater_eval DATA [SAMPLER_STEPS] [STRENGTHS]")?,
    );
    let sampler_steps: usize = args.get(1).map_or(Ok(4), |s| s.parse())?;
    let strengths: Vec<f32> = args
        .get(2)
        .map_or("0.01,1,4", String::as_str)
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    let methods: Vec<String> = METHODS
        .iter()
        .map(|m| m.to_string())
        .chain(
            strengths
                .iter()
                .map(|a| format!("diffusion + physics correction, strength {a}")),
        )
        .collect();
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(data.join("manifest.json"))?)?;
    let (w, h) = (
        manifest["width"].as_u64().ok_or("width")? as usize,
        manifest["height"].as_u64().ok_or("height")? as usize,
    );
    let periods: Vec<f64> = serde_json::from_value(manifest["periods_px"].clone())?;
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models");
    let onestep = LearnedRestorer::load(&models.join("underwater_onestep.onnx"), &periods, 4, 1)?;
    let diffusion = LearnedRestorer::load(
        &models.join("underwater_diffusion.onnx"),
        &periods,
        4,
        sampler_steps,
    )?;
    // [level][method]
    let mut scores = vec![vec![Score::default(); methods.len()]; LEVELS.len()];
    let mut seconds = vec![0.0f64; methods.len()];
    let mut evaluations = vec![0usize; methods.len()];
    let mut sets = 0;
    let samples = manifest["samples"].as_array().ok_or("samples")?;
    for s in samples {
        let file = data.join(s["file"].as_str().ok_or("file")?);
        let all = decode_npy_2d(&std::fs::read(&file)?)?.values.data;
        let frame = |k: usize| Raster {
            width: w,
            height: h,
            data: all[k * w * h..(k + 1) * w * h].to_vec(),
        };
        let wet: Vec<Raster<f32>> = (0..4).map(frame).collect();
        let clean: Vec<Raster<f32>> = (4..8).map(frame).collect();
        let level = LEVELS
            .iter()
            .position(|&l| Some(l) == s["turbidity"].as_str())
            .ok_or("turbidity")?;
        let refs: Vec<&Raster<f32>> = wet.iter().collect();
        let sigma = s["psf_sigma_px"].as_f64().ok_or("psf_sigma_px")?;
        let mut estimates: Vec<Vec<Raster<f32>>> = vec![wet.clone()];
        let t = Instant::now();
        let classical = ClassicalRestorer::new(w, h, RestoreParams::new(sigma))?;
        estimates.push(
            classical
                .restore_set(&refs, Veil::Floor)?
                .into_iter()
                .map(|r| r.image)
                .collect(),
        );
        seconds[1] += t.elapsed().as_secs_f64();
        let corrected: Vec<LearnedRestorer> = strengths
            .iter()
            .map(|&strength| {
                diffusion.clone().with_physics(Some(PhysicsCorrection {
                    strength,
                    ..PhysicsCorrection::seed(sigma)
                }))
            })
            .collect();
        let nets = [&onestep, &diffusion].into_iter().chain(&corrected);
        for (m, net) in (2..).zip(nets) {
            let t = Instant::now();
            let (restored, run) = net.restore_set(&refs, sets as u64)?;
            seconds[m] += t.elapsed().as_secs_f64();
            evaluations[m] += run.evaluations;
            estimates.push(restored);
        }
        for (m, est) in estimates.iter().enumerate() {
            scores[level][m].add(est, &clean)?;
        }
        sets += 1;
        eprint!("\r{sets}/{} sets", samples.len());
    }
    eprintln!();
    println!(
        "held-out sets: {} (dataset seed {}), {w}x{h}, 4 steps of one period each; against the same set through clear water",
        sets, manifest["seed"]
    );
    println!("| level | sets | method | PSNR dB | SSIM | wrapped-phase MAE rad |");
    println!("|---|---|---|---|---|---|");
    for (l, row) in scores.iter().enumerate() {
        let n = samples
            .iter()
            .filter(|s| s["turbidity"].as_str() == Some(LEVELS[l]))
            .count();
        if n == 0 {
            continue;
        }
        for (m, score) in row.iter().enumerate() {
            let (psnr, ssim, mae) = score.figures();
            println!(
                "| {} | {n} | {} | {psnr:.2} | {ssim:.3} | {mae:.4} |",
                LEVELS[l], methods[m]
            );
        }
    }
    println!(
        "time per set: classical {:.0} ms; one-step {:.0} ms ({} evaluations per set); diffusion, {sampler_steps} DDIM steps, {:.0} ms ({} evaluations per set)",
        1e3 * seconds[1] / sets as f64,
        1e3 * seconds[2] / sets as f64,
        evaluations[2] / sets.max(1),
        1e3 * seconds[3] / sets as f64,
        evaluations[3] / sets.max(1),
    );
    for (m, a) in (4..).zip(&strengths) {
        println!(
            "with the physics correction at strength {a}: {:.0} ms per set",
            1e3 * seconds[m] / sets as f64
        );
    }
    Ok(())
}
