//! Issue 18 (seed 002), the classical baseline: fringe restoration on
//! held-out twin samples per turbidity T1..T4, scored against two
//! references, for "none" (the underwater frames as recorded) and
//! "classical" (`slscan::underwater`: Wiener deconvolution with the
//! forward-scatter Gaussian, one filter per phase-shift set, then the
//! backscatter veil found above the set's dark frame subtracted); also
//! the veil from the frames' floor alone (no dark frame) and the
//! deconvolution alone, to show what each step does.
//!
//! ```text
//! cargo test -p slscan --release --test underwater_restore -- --nocapture
//! ```
//!
//! Each sample is one random scene of `hil-sim dataset underwater` (its
//! placement, its exposure rule: the underwater exposure makes up the
//! green attenuation of a ~0.9 m round trip, ambient light kept as in
//! air), rendered with all four steps of one seed-002 period, since the
//! dataset writes one step per sample and a wrapped phase needs four:
//!
//! - under water: the twin's water at the level (noisy sensor images),
//!   and a dark frame (projector off, same exposure) as a scan takes;
//! - in air: the dataset's target (noise-free), seed 002's reference;
//! - clear water: the same ports and refraction with no attenuation,
//!   scatter or veil (noise-free): the same pixel geometry as the
//!   underwater frame, so it isolates what a radiometric restorer can fix.
//!   Against the in-air frame, refraction at the ports moves every pixel to
//!   another surface point and projector column; no restoration of
//!   intensities undoes that (the "refraction only" row measures it).
//!
//! Every estimate gets the same least-squares gain and offset onto its
//! reference per frame before PSNR (8-bit scale) and SSIM (7 x 7); the
//! wrapped-phase MAE needs none (the 4-step phase ignores gain and offset).
//! The PSF sigma handed to the restorer is the level's forward-scatter rate
//! times the nominal camera-side water path (0.5 m working distance less
//! the 0.03 m port), not the per-pixel truth.

use std::f64::consts::TAU;
use std::sync::Arc;

use hil_sim::twin::dataset::PLACE;
use hil_sim::twin::random_scene::random_scene;
use hil_sim::twin::scenes::{single_head, Detail};
use hil_sim::twin::{
    BitDepth, Exposure, Fringe, Medium, Pattern, ProjectorTimeline, Renderer, Rig, Scene,
    SensorModel, Turbidity, Water,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slscan::raster::Raster;
use slscan::underwater::score::Score;
use slscan::underwater::{ClassicalRestorer, RestoreParams, Veil};

const SIZE_PX: u32 = 256;
/// DLP4500-sized DMD: seed 002's periods land at ~22 camera pixels.
const DMD: (u32, u32) = (912, 1140);
/// Held out: the dataset's training runs use other seeds.
const SEED: u64 = 1802;
const SAMPLES: usize = 3;
const PERIODS_PX: [f64; 3] = [59.0, 64.0, 70.0];
const PORT_M: f64 = 0.03;
const WORKING_DISTANCE_M: f64 = 0.5;
const LEVELS: [Turbidity; 4] = [Turbidity::T1, Turbidity::T2, Turbidity::T3, Turbidity::T4];

type Frames = Vec<Raster<f32>>;

/// The four steps of one period, as the renderer shows them.
fn four_steps(rig: &Rig, period_px: f64) -> Vec<Arc<Pattern>> {
    let k = &rig.projectors[0].model.intrinsics;
    (0..4)
        .map(|n| {
            let f = Fringe {
                period_px,
                angle_rad: 0.0,
                shift_rad: TAU * n as f64 / 4.0,
            };
            Arc::new(Pattern::fringe(k.width, k.height, &f, BitDepth::Eight))
        })
        .collect()
}

/// Renders the four steps; `noisy` picks the sensor image over the clean one.
fn render(
    scene: &Scene,
    rig: &Rig,
    patterns: &[Arc<Pattern>],
    exposure_s: f64,
    noisy: bool,
    rng: &mut ChaCha8Rng,
) -> Frames {
    let renderer = Renderer::new(scene, rig, 0, 0.0).expect("twin renderer");
    let exposure = Exposure {
        start_s: 0.0,
        end_s: exposure_s,
    };
    patterns
        .iter()
        .map(|p| {
            let shown = [ProjectorTimeline::single(p.clone(), 0.0, exposure_s)];
            let f = renderer
                .frame(&shown, exposure, &SensorModel::mono12(), rng.random())
                .expect("twin frame");
            let img = if noisy { f.image } else { f.clean };
            Raster::from_vec(img.width as usize, img.height as usize, img.data).expect("mono")
        })
        .collect()
}

/// One scene: in-air and clear-water references, and the frames per level.
struct Sample {
    air: Frames,
    clear: Frames,
    /// Per level: the four frames and the dark frame.
    water: Vec<(Frames, Raster<f32>)>,
}

fn sample(index: usize) -> Sample {
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    rng.set_stream(index as u64);
    let scene = random_scene(&mut rng, &PLACE, false).expect("random scene");
    let detail = Detail {
        camera: (SIZE_PX, SIZE_PX),
        projector: DMD,
    };
    let air_rig = single_head(&detail);
    let patterns = four_steps(&air_rig, PERIODS_PX[index % 3]);
    let air = render(&scene, &air_rig, &patterns, 1e-3, false, &mut rng);
    let clear_water = Water {
        attenuation_per_m: [0.0; 3],
        forward_sigma_px_per_m: 0.0,
        backscatter_fraction: 0.0,
        ..Water::preset(Turbidity::T1, PORT_M)
    };
    let mut clear_rig = air_rig.clone();
    clear_rig.medium = Medium::Water(clear_water);
    let clear = render(&scene, &clear_rig, &patterns, 1e-3, false, &mut rng);
    let water = LEVELS
        .iter()
        .map(|&level| {
            let w = Water::preset(level, PORT_M);
            let mut rig = air_rig.clone();
            rig.medium = Medium::Water(w);
            // The dataset's rule: longer exposure, ambient kept as in air.
            let exposure_s = 1e-3 * (w.attenuation_per_m[1] * 0.9).exp();
            let dim = 1e-3 / exposure_s;
            let mut wet = scene.clone();
            wet.ambient_surface = wet.ambient_surface.map(|a| a * dim);
            wet.ambient_direct = wet.ambient_direct.map(|a| a * dim);
            let k = &rig.projectors[0].model.intrinsics;
            let off = [Arc::new(Pattern::flat(k.width, k.height, 0.0))];
            let dark = render(&wet, &rig, &off, exposure_s, true, &mut rng).remove(0);
            (
                render(&wet, &rig, &patterns, exposure_s, true, &mut rng),
                dark,
            )
        })
        .collect();
    Sample { air, clear, water }
}

/// The ways compared, in table order.
const METHODS: [&str; 4] = ["none", "classical", "veil floor", "Wiener only"];

#[test]
fn underwater_classical_restoration_per_turbidity() {
    let samples: Vec<Sample> = (0..SAMPLES).map(sample).collect();
    let mut floor = Score::default();
    for s in &samples {
        floor.add(&s.clear, &s.air).expect("score");
    }
    let restorers: Vec<ClassicalRestorer> = LEVELS
        .iter()
        .map(|&level| {
            let w = Water::preset(level, PORT_M);
            let sigma_px = w.forward_sigma_px_per_m * (WORKING_DISTANCE_M - PORT_M);
            let mut params = RestoreParams::new(sigma_px);
            // About two periods (~22 px here) per block.
            params.veil_block_px = 48;
            ClassicalRestorer::new(SIZE_PX as usize, SIZE_PX as usize, params).expect("restorer")
        })
        .collect();
    // [level][method] = (against in air, against clear water).
    let mut table: Vec<Vec<(Score, Score)>> = Vec::new();
    for (li, restorer) in restorers.iter().enumerate() {
        let mut row = vec![(Score::default(), Score::default()); METHODS.len()];
        for s in &samples {
            let (wet, dark) = &s.water[li];
            let refs: Vec<&Raster<f32>> = wet.iter().collect();
            let restored = |veil| -> Frames {
                restorer
                    .restore_set(&refs, veil)
                    .expect("restore")
                    .into_iter()
                    .map(|r| r.image)
                    .collect()
            };
            let estimates = [
                wet.clone(),
                restored(Veil::AboveDark(dark)),
                restored(Veil::Floor),
                restored(Veil::Keep),
            ];
            for (m, est) in estimates.iter().enumerate() {
                row[m].0.add(est, &s.air).expect("score");
                row[m].1.add(est, &s.clear).expect("score");
            }
        }
        table.push(row);
    }

    println!(
        "\nunderwater restoration, {SAMPLES} held-out twin scenes (seed {SEED}), {SIZE_PX}x{SIZE_PX}, \
         4 steps of one period each; PSNR dB / SSIM / wrapped-phase MAE rad"
    );
    let fl = floor.figures();
    println!(
        "refraction only (clear water vs in air): {:.2} / {:.3} / {:.4}",
        fl.0, fl.1, fl.2
    );
    println!(
        "{:<5} {:>6}  {:<12} {:>24}  {:>24}",
        "level", "sigma", "restorer", "vs in air", "vs clear water"
    );
    for (li, row) in table.iter().enumerate() {
        let sigma = restorers[li].params().psf_sigma_px;
        for (m, (air, clear)) in row.iter().enumerate() {
            let (a, c) = (air.figures(), clear.figures());
            println!(
                "{:<5} {sigma:>6.2}  {:<12} {:>6.2} / {:.3} / {:.4}  {:>6.2} / {:.3} / {:.4}",
                format!("{:?}", LEVELS[li]),
                METHODS[m],
                a.0,
                a.1,
                a.2,
                c.0,
                c.1,
                c.2
            );
        }
    }
    println!("seed 002, FP-DiffNet at T4 (vs in air): 42.42 / 0.975 / 0.0354");

    // What holds with margin on these scenes, against clear water (the
    // same pixel geometry): at T3 and T4 the classical restorer cuts the
    // wrapped-phase MAE by 30 % or more and gains PSNR. At T1 it does not
    // (its phase MAE is higher than none's), and against the in-air frame
    // refraction dominates every row: neither is asserted.
    for li in [2, 3] {
        let none = table[li][0].1.figures();
        let classical = table[li][1].1.figures();
        assert!(
            classical.2 < 0.7 * none.2,
            "{:?}: phase MAE classical {:.4} vs none {:.4}",
            LEVELS[li],
            classical.2,
            none.2
        );
        assert!(
            classical.0 > none.0 + 0.3,
            "{:?}: PSNR classical {:.2} vs none {:.2} dB",
            LEVELS[li],
            classical.0,
            none.0
        );
    }
}
