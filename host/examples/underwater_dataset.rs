//! Training and held-out data for the learned underwater restorer (issue 18,
//! seed 002), in the scan's own geometry: the `spheres` scene's single head
//! (640x480 camera, 1280x800 DMD) under the twin's water behind 30 mm ports,
//! random scenes of `hil-sim dataset underwater`'s placement, a random
//! turbidity T1..T4 and one of the water scan's three periods per sample.
//!
//! Each sample is one 4-step phase-shift set: the frames as the scan's
//! camera takes them under water (noisy, the scan's exposure rule), and the
//! same set through clear water (the ports' refraction only, noise-free, at
//! the standard exposure so that nothing clips): the target, with the same
//! pixel geometry.
//!
//! ```text
//! cargo run --release -p slscan --example underwater_dataset -- OUT COUNT SEED [SCENE]
//! ```
//!
//! With `SCENE` (a built-in twin scene, e.g. `spheres`) every sample is that
//! scene in its own rig, sample `i` at level `i % 4` and period `(i / 4) %
//! 3`: 12 samples are the sets a water scan of it takes at each level, so
//! the networks can be scored on a scan's scene, not only on random ones.
//!
//! writes `OUT/sample_NNNN.npy` (float32, 2-D `[8 H, W]`: 4 underwater
//! frames, then 4 clear-water frames, full-scale units) and
//! `OUT/manifest.json`.

use std::f64::consts::TAU;
use std::path::PathBuf;
use std::sync::Arc;

use hil_sim::twin::dataset::PLACE;
use hil_sim::twin::random_scene::random_scene;
use hil_sim::twin::scenes::{built_in, single_head, Detail};
use hil_sim::twin::{
    BitDepth, Exposure, Fringe, Medium, Pattern, ProjectorTimeline, Renderer, Rig, Scene,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use slscan::io::npy::encode_npy_f32_rows;
use slscan::scan::plan::display_s;
use slscan::scan::underwater::{water_periods_px, Turbidity};
use slscan::sim::scan::sim_sensor;
use slscan::sim::underwater::{clear, exposure_scale, nominal_psf_sigma_px, submerge};

const CAMERA: (u32, u32) = (640, 480);
const DMD: (u32, u32) = (1280, 800);
const STEPS: usize = 4;
/// The clear-water target's exposure, standard exposures (see `sample`).
const TARGET_EXPOSURE: f64 = 1.0;
const LEVELS: [Turbidity; 4] = [Turbidity::T1, Turbidity::T2, Turbidity::T3, Turbidity::T4];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (out, count, seed, scene) = match args.as_slice() {
        [out, count, seed] => (out, count, seed, None),
        [out, count, seed, scene] => (out, count, seed, Some(scene.as_str())),
        _ => return Err("usage: underwater_dataset OUT COUNT SEED [SCENE]".into()),
    };
    let out = PathBuf::from(out);
    let count: usize = count.parse()?;
    let seed: u64 = seed.parse()?;
    std::fs::create_dir_all(&out)?;
    let started = std::time::Instant::now();
    let entries: Vec<serde_json::Value> = (0..count)
        .into_par_iter()
        .map(|i| sample(&out, seed, i, scene))
        .collect::<Result<_, String>>()?;
    let manifest = serde_json::json!({
        "kind": "underwater-sets",
        "seed": seed,
        "scene": scene,
        "count": count,
        "width": CAMERA.0,
        "height": CAMERA.1,
        "dmd": [DMD.0, DMD.1],
        "periods_px": water_periods_px(DMD.0),
        "steps": STEPS,
        "layout": "float32 [8 H, W]: 4 underwater frames (noisy), then the 4 clear-water frames (noise-free)",
        "samples": entries,
    });
    std::fs::write(
        out.join("manifest.json"),
        serde_json::to_string_pretty(&manifest)?,
    )?;
    eprintln!(
        "{count} samples in {:.1} s -> {}",
        started.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(())
}

/// Sample `i`: renders it, writes its file, returns its manifest entry.
fn sample(
    out: &std::path::Path,
    seed: u64,
    i: usize,
    built: Option<&str>,
) -> Result<serde_json::Value, String> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(i as u64);
    let periods = water_periods_px(DMD.0);
    let detail = Detail {
        camera: CAMERA,
        projector: DMD,
    };
    let (scene, mut rig, level, period_px) = match built {
        None => {
            let scene = random_scene(&mut rng, &PLACE, false).map_err(|e| e.to_string())?;
            let level = LEVELS[rng.random_range(0..LEVELS.len())];
            let period_px = periods[rng.random_range(0..periods.len())];
            (scene, single_head(&detail), level, period_px)
        }
        Some(name) => {
            let (scene, rig) = built_in(name, &detail).map_err(|e| e.to_string())?;
            (scene, rig, LEVELS[i % 4], periods[(i / 4) % periods.len()])
        }
    };
    submerge(&mut rig, level);
    let Medium::Water(water) = rig.medium else {
        return Err("submerge left the rig in air".into());
    };
    let mut clear_rig = rig.clone();
    clear_rig.medium = Medium::Water(clear(&water));
    let scale = exposure_scale(level);
    let noise_seed: u64 = rng.random();
    let wet = render(&scene, &rig, period_px, scale, Some(noise_seed))?;
    // The target at the standard exposure, not the wet one: through clear
    // water the 8x of T3 / T4 clips a quarter of the pixels, and a network
    // trained on clipped targets learns fringes whose phase is bent (a
    // scan's order checks then fail on bright surfaces). x0 is the target's
    // AC over DC, so its exposure is otherwise irrelevant.
    let target = render(&scene, &clear_rig, period_px, TARGET_EXPOSURE, None)?;
    let (w, h) = (CAMERA.0 as usize, CAMERA.1 as usize);
    let data: Vec<f32> = wet.into_iter().chain(target).flatten().collect();
    let file = format!("sample_{i:04}.npy");
    std::fs::write(
        out.join(&file),
        encode_npy_f32_rows(w, 2 * STEPS * h, &data),
    )
    .map_err(|e| e.to_string())?;
    Ok(serde_json::json!({
        "file": file,
        "turbidity": level.name(),
        "period_px": period_px,
        "psf_sigma_px": nominal_psf_sigma_px(level),
        "exposure_scale": scale,
        "target_exposure_scale": TARGET_EXPOSURE,
    }))
}

/// The four steps of `period_px` at `scale` standard exposures: sensor
/// images with noise seeded from `noise_seed`, or noise-free when `None`.
fn render(
    scene: &Scene,
    rig: &Rig,
    period_px: f64,
    scale: f64,
    noise_seed: Option<u64>,
) -> Result<Vec<Vec<f32>>, String> {
    let renderer = Renderer::new(scene, rig, 0, 0.0).map_err(|e| e.to_string())?;
    let exposure = Exposure {
        start_s: 0.0,
        end_s: display_s() * scale,
    };
    (0..STEPS)
        .map(|n| {
            let fringe = Fringe {
                period_px,
                angle_rad: 0.0,
                shift_rad: TAU * n as f64 / STEPS as f64,
            };
            let pattern = Arc::new(Pattern::fringe(DMD.0, DMD.1, &fringe, BitDepth::Eight));
            let shown = [ProjectorTimeline::single(pattern, 0.0, exposure.end_s)];
            let seed = noise_seed.unwrap_or(0).wrapping_add(n as u64);
            let frame = renderer
                .frame(&shown, exposure, &sim_sensor(), seed)
                .map_err(|e| e.to_string())?;
            Ok(if noise_seed.is_some() {
                frame.image.data
            } else {
                frame.clean.data
            })
        })
        .collect()
}
