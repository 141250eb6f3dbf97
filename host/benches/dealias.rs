//! Prints a table: the time to de-alias one simultaneous 640x480 capture
//! (both cameras, all 16 frames each) with every method, as ratios in one
//! run; and one network pass over a whole 512x512 image (every tile), the
//! size seed 002 times its diffusion model at (430 ms on an RTX 4090).
//!
//! `cargo bench -p slscan --bench dealias`

use std::path::Path;
use std::time::Instant;

use slscan::dealias::learned::LearnedDealiaser;
use slscan::dealias::{
    dealias_frames, dealias_frames_learned, AnalyticDealiaser, AnalyticParams, EpipolarDealiaser,
    EpipolarParams,
};
use slscan::infer::tiles::Planes;
use slscan::scan::aliasing::{camera_lighting, AliasParams};
use slscan::sim::aliased::{held_out, AliasedSet};
use slscan::sim::scan::{noise_sigma, shot_noise_share, sim_sensor};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let set = AliasedSet {
        seed: 2,
        camera_px: (640, 480),
        projector_px: (1280, 800),
        noise_scale: (1.0, 1.0),
    };
    let periods = slscan::scan::dealias_periods_px(1280);
    let sample = held_out(&set, 0)?;
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models");
    let onestep = LearnedDealiaser::load(&models.join("dealias_onestep.onnx"), &periods, 4, 1)?;
    let diffusion = LearnedDealiaser::load(&models.join("dealias_diffusion.onnx"), &periods, 4, 8)?;
    let analytic = AnalyticDealiaser::new(&periods, 4, 1280, AnalyticParams::default())?;
    let sensor = sim_sensor();
    println!(
        "one simultaneous 640x480 capture, 2 cameras x 16 frames, {} rayon threads",
        rayon::current_num_threads()
    );
    println!("| method | evaluations | time | vs analytic |");
    println!("|---|---|---|---|");
    let mut base = None;
    for (name, which) in [
        ("analytic", 0),
        ("epipolar (default)", 3),
        ("one-step network", 1),
        ("diffusion, 8 DDIM steps", 2),
    ] {
        let started = Instant::now();
        let mut evaluations = 0;
        for s in &sample {
            let lit = camera_lighting(&s.flat, s.camera, &AliasParams::default());
            let mut frames = s.frames.clone();
            match which {
                0 => {
                    dealias_frames(
                        &mut frames,
                        &s.flat,
                        s.camera,
                        &lit,
                        &analytic,
                        noise_sigma(&sensor),
                        shot_noise_share(&sensor),
                    );
                }
                3 => {
                    let solver = EpipolarDealiaser::new(
                        &s.calibration,
                        s.camera,
                        &periods,
                        4,
                        EpipolarParams::default(),
                    )?;
                    dealias_frames(
                        &mut frames,
                        &s.flat,
                        s.camera,
                        &lit,
                        &solver,
                        noise_sigma(&sensor),
                        shot_noise_share(&sensor),
                    );
                }
                _ => {
                    let net = if which == 1 { &onestep } else { &diffusion };
                    let st = dealias_frames_learned(&mut frames, &s.flat, s.camera, &lit, net, 1)?;
                    evaluations += st.network.map_or(0, |n| n.evaluations);
                }
            }
        }
        let t = started.elapsed().as_secs_f64();
        let b = *base.get_or_insert(t);
        println!("| {name} | {evaluations} | {t:.2} s | {:.2}x |", t / b);
    }
    println!();
    println!("one network pass over a whole 512x512 image (every tile)");
    println!("| network | tiles | evaluations | time |");
    println!("|---|---|---|---|");
    let channels = onestep.model().meta.cond_channels;
    let cond: Vec<f32> = (0..channels * 512 * 512)
        .map(|i| ((i % 977) as f32 / 977.0) - 0.5)
        .collect();
    let planes = Planes {
        data: &cond,
        channels,
        width: 512,
        height: 512,
    };
    let needed = vec![true; 512 * 512];
    for (name, net) in [("one-step", &onestep), ("diffusion, 8 steps", &diffusion)] {
        let started = Instant::now();
        let (_, run) = net.predict(&planes, &needed, 1)?;
        println!(
            "| {name} | {} | {} | {:.2} s |",
            run.tiles,
            run.evaluations,
            started.elapsed().as_secs_f64()
        );
    }
    Ok(())
}
