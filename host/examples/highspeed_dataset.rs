//! Training data for the high-speed decoder's learned stages (issue 17,
//! seed 001), in the scan's own geometry: `spheres`' single head (640x480
//! colour camera, 1280x800 DMD), random scenes of `hil-sim dataset`'s
//! placement, seed 001's 24 binary patterns at 5 kHz in one
//! 4.8 ms exposure ([`slscan::sim::high_speed_samples`]).
//!
//! ```text
//! cargo run --release -p slscan --example highspeed_dataset -- OUT COUNT SEED [zocr|fdd] [moving]
//! ```
//!
//! `moving`: the same scenes with their objects spinning or flying through
//! the exposure (`SceneMotion::Moving`), each pattern's truth taken at its
//! own instant; without it they are static.
//!
//! `zocr` (the default; ZOCR-Net's data) writes `OUT/sample_NNNN.npy`
//! (float32, 2-D `[9 H, W]`: the exposure's R, G, B planes as the camera
//! takes them; each LED band's noise-free AC without crosstalk; each band's
//! zero order; camera full scale). `fdd` (FDD-Net's data) decodes each
//! exposure as a scan does (crosstalk from the scene's own LED flats, the
//! analytic first two stages and demodulation) and writes `CROPS` random
//! crops of `CROP` px per scene, `OUT/crop_NNNN_K.npy` (float32, 2-D
//! `[96 CROP, CROP]`: FDD-Net's 72 input planes
//! ([`slscan::highspeed::fdd::condition`]), then per pattern the phase the
//! network should add, the truth minus the demodulated phase wrapped to
//! (-pi, pi], NaN where the pattern is unlit, undecoded or below the
//! decoder's modulation floor). Both write `OUT/manifest.json`. The
//! held-out scenes of `highspeed_eval` are stream 9001; train on another.

use std::path::{Path, PathBuf};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use slscan::calibration::Head;
use slscan::highspeed::learned::set_periods;
use slscan::highspeed::{
    crosstalk_from_flats, fdd, Decoder, DecoderConfig, DemuxOptions, PatternSet,
};
use slscan::io::npy::encode_npy_f32_rows;
use slscan::phase::wrap_pi;
use slscan::sim::high_speed_samples::{random_high_speed_sample, HighSpeedSample, SceneMotion};
use slscan::sim::twin::Detail;

const CAMERA: (u32, u32) = (640, 480);
const DMD: (u32, u32) = (1280, 800);
/// FDD-Net's crops: side and count per scene.
const CROP: usize = 96;
const CROPS: usize = 4;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (out, count, seed, kind, motion) = match args.as_slice() {
        [o, c, s] => (o, c, s, "zocr", SceneMotion::Static),
        [o, c, s, k] => (o, c, s, k.as_str(), SceneMotion::Static),
        [o, c, s, k, m] if m == "moving" => (o, c, s, k.as_str(), SceneMotion::Moving),
        _ => return Err("usage: highspeed_dataset OUT COUNT SEED [zocr|fdd] [moving]".into()),
    };
    let out = PathBuf::from(out);
    let count: usize = count.parse()?;
    let seed: u64 = seed.parse()?;
    if seed == 9001 {
        return Err("stream 9001 is highspeed_eval's held-out set: train on another".into());
    }
    std::fs::create_dir_all(&out)?;
    let set = PatternSet::seed001(DMD)?;
    let detail = Detail {
        camera: CAMERA,
        projector: DMD,
    };
    let calibration =
        slscan::sim::truth::twin_calibration(&hil_sim::twin::scenes::single_head(&detail), 1);
    let head = &calibration.heads[0];
    let started = std::time::Instant::now();
    let (files, layout): (Vec<String>, &str) = match kind {
        "zocr" => (
            (0..count)
                .into_par_iter()
                .map(|i| write_zocr_sample(&out, &set, &detail, seed, motion, i))
                .collect::<Result<_, String>>()?,
            "float32 [9 H, W]: camera R, G, B (noisy, crosstalk, 8-bit); per LED band the noise-free AC (sum of its 8 patterns' B cos phi, no crosstalk); per band the zero order (patterns' mean + ambient); camera full scale",
        ),
        "fdd" => (
            (0..count)
                .into_par_iter()
                .map(|i| write_fdd_crops(&out, &set, head, &detail, seed, motion, i))
                .collect::<Result<Vec<Vec<String>>, String>>()?
                .into_iter()
                .flatten()
                .collect(),
            "float32 [96 C, C]: FDD-Net's 72 input planes (per pattern cos and sin of the demodulated baseband phase, then per pattern modulation over its LED's zero order per pattern, capped at 2), then per pattern the phase correction to learn (truth minus demodulated phase, wrapped; NaN where not to learn)",
        ),
        other => return Err(format!("unknown kind {other:?}: zocr or fdd").into()),
    };
    let manifest = serde_json::json!({
        "kind": format!("highspeed-{kind}"),
        "seed": seed,
        "moving": motion == SceneMotion::Moving,
        "count": count,
        "width": CAMERA.0,
        "height": CAMERA.1,
        "crop": (kind == "fdd").then_some(CROP),
        "dmd": [DMD.0, DMD.1],
        "periods_px": set_periods(&set),
        "layout": layout,
        "samples": files,
    });
    std::fs::write(
        out.join("manifest.json"),
        serde_json::to_string_pretty(&manifest)?,
    )?;
    eprintln!(
        "{count} scenes in {:.1} s -> {}",
        started.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(())
}

fn sample(
    set: &PatternSet,
    detail: &Detail,
    seed: u64,
    motion: SceneMotion,
    i: usize,
) -> Result<HighSpeedSample, String> {
    random_high_speed_sample(set, detail, seed, i as u64, motion).map_err(|e| e.to_string())
}

/// ZOCR-Net's sample: the whole exposure with its stage-1 targets.
fn write_zocr_sample(
    out: &Path,
    set: &PatternSet,
    detail: &Detail,
    seed: u64,
    motion: SceneMotion,
    i: usize,
) -> Result<String, String> {
    let s = sample(set, detail, seed, motion, i)?;
    let data: Vec<f32> = s
        .channels
        .iter()
        .map(|r| &r.data[..])
        .chain(s.ac.iter().map(|v| &v[..]))
        .chain(s.dc.iter().map(|v| &v[..]))
        .flatten()
        .copied()
        .collect();
    let (w, h) = (CAMERA.0 as usize, CAMERA.1 as usize);
    let file = format!("sample_{i:04}.npy");
    std::fs::write(out.join(&file), encode_npy_f32_rows(w, 9 * h, &data))
        .map_err(|e| e.to_string())?;
    Ok(file)
}

/// FDD-Net's crops of one scene: its input planes and the corrections.
fn write_fdd_crops(
    out: &Path,
    set: &PatternSet,
    head: &Head,
    detail: &Detail,
    seed: u64,
    motion: SceneMotion,
    i: usize,
) -> Result<Vec<String>, String> {
    let s = sample(set, detail, seed, motion, i)?;
    let view = |l: usize| [&s.flats[l][0][..], &s.flats[l][1][..], &s.flats[l][2][..]];
    let config = DecoderConfig::default();
    let crosstalk = crosstalk_from_flats([view(0), view(1), view(2)], config.saturation_level)
        .map_err(|e| e.to_string())?;
    let decoder = Decoder::new(
        set.clone(),
        head,
        DecoderConfig {
            // FDD-Net corrects the single demodulation, without sibling
            // cancellation (the decoder refuses it beside cancellation).
            demux: DemuxOptions {
                crosstalk: Some(crosstalk),
                cancellations: 0,
                ..DemuxOptions::default()
            },
            ..config
        },
    )
    .map_err(|e| e.to_string())?;
    let demux = decoder.demultiplexer();
    let planes = [
        &s.channels[0].data[..],
        &s.channels[1].data,
        &s.channels[2].data,
    ];
    let fringes = demux.demodulate_all(demux.remove_zero_order(planes));
    let mut planes = fdd::condition(demux, set, &fringes);
    let n = fringes.wrapped[0].len();
    let per_led = set.directions() as f32;
    for (m, pattern) in set.patterns().iter().enumerate() {
        let zero = &fringes.zero_order[pattern.colour];
        planes.extend((0..n).map(|i| {
            let keep = fringes.modulation[m][i] * per_led >= config.min_modulation_ratio * zero[i]
                && zero[i] > 0.0;
            let d = wrap_pi(s.phase[m][i] - fringes.wrapped[m][i]);
            if keep {
                d
            } else {
                f32::NAN
            }
        }));
    }
    let channels = planes.len() / n;
    let (w, h) = (CAMERA.0 as usize, CAMERA.1 as usize);
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(7_919).wrapping_add(i as u64));
    (0..CROPS)
        .map(|k| {
            let (x0, y0) = (
                rng.random_range(0..=w - CROP),
                rng.random_range(0..=h - CROP),
            );
            let crop: Vec<f32> = (0..channels)
                .flat_map(|c| {
                    let plane = &planes[c * n..(c + 1) * n];
                    (0..CROP).flat_map(move |y| {
                        plane[(y0 + y) * w + x0..(y0 + y) * w + x0 + CROP]
                            .iter()
                            .copied()
                    })
                })
                .collect();
            let file = format!("crop_{i:04}_{k}.npy");
            std::fs::write(
                out.join(&file),
                encode_npy_f32_rows(CROP, channels * CROP, &crop),
            )
            .map_err(|e| e.to_string())?;
            Ok(file)
        })
        .collect()
}
