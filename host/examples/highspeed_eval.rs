//! Phase error of the analytic high-speed decoder (seed 001's 24-pattern colour
//! long exposure), stage by stage, on random twin scenes it has never seen:
//! wrapped-phase MAE against the twin's true phase, and for the whole decoder
//! the share of pixels unwrapped right and the depth error per instant.
//!
//! `cargo run --release -p slscan --example highspeed_eval -- [--count N] [--seed S]`

use std::sync::Arc;

use anyhow::Context;
use hil_sim::twin::random_scene::{random_scene, Placement};
use hil_sim::twin::scenes::{single_head, Detail};
use hil_sim::twin::{Exposure, Illum, Image, Pattern, ProjectorTimeline, Renderer};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use slscan::highspeed::{crosstalk_from_flats, Decoder, DecoderConfig, DemuxOptions, PatternSet};
use slscan::phase::ftp::{ftp_phase, FringeAxis};
use slscan::raster::Raster;

const SLOT_S: f64 = 200e-6;
/// The dataset exporter's placement: objects 0.44-0.54 m away, wall at 0.6 m.
const PLACE: Placement = Placement {
    x_m: (-0.08, 0.08),
    y_m: (-0.06, 0.06),
    z_m: (0.44, 0.54),
    wall_z_m: 0.6,
};

struct Sample {
    channels: [Raster<f32>; 3],
    flats: [[Vec<f32>; 3]; 3],
    /// Per pattern, true absolute phase (NaN where unlit).
    phase: Vec<Vec<f32>>,
    depth_m: Vec<f32>,
}

fn planes(image: &Image) -> [Raster<f32>; 3] {
    let (w, h) = (image.width as usize, image.height as usize);
    [0, 1, 2].map(|c| Raster {
        width: w,
        height: h,
        data: image.data.chunks(3).map(|p| p[c]).collect(),
    })
}

fn render(set: &PatternSet, detail: &Detail, seed: u64, index: u64) -> anyhow::Result<Sample> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(1_000_003).wrapping_add(index));
    let scene = random_scene(&mut rng, &PLACE, true)?;
    let rig = single_head(detail);
    let (dw, dh) = set.dmd_px();
    let to_twin = |r: &Raster<f32>| {
        Arc::new(Pattern {
            width: dw,
            height: dh,
            values: r.data.clone(),
        })
    };
    let items: Vec<_> = set
        .binary_frames()
        .iter()
        .map(to_twin)
        .zip(set.leds())
        .collect();
    let timeline = ProjectorTimeline::sequence(items, 0.0, SLOT_S);
    let exposure = Exposure {
        start_s: 0.0,
        end_s: 24.0 * SLOT_S,
    };
    let sensor = slscan::sim::high_speed::high_speed_sensor();
    let renderer = Renderer::new(&scene, &rig, 0, 0.0)?;
    let frame = renderer.frame(&[timeline], exposure, &sensor, index + 17)?;
    let white = to_twin(&Raster::filled(dw as usize, dh as usize, 1.0));
    // As the scan does: each LED's flat minus a dark frame (the ambient light).
    let flat = |colour: [f32; 3], noise: u64| {
        let t = ProjectorTimeline::sequence([(white.clone(), colour)], 0.0, 7.0 * SLOT_S);
        let e = Exposure {
            start_s: 0.0,
            end_s: 7.0 * SLOT_S,
        };
        renderer
            .frame(&[t], e, &sensor, noise)
            .map(|f| planes(&f.image).map(|p| p.data))
    };
    let dark = flat([0.0; 3], index + 99)?;
    let flats = [0, 1, 2].map(|led| {
        let mut colour = [0.0f32; 3];
        colour[led] = 1.0;
        flat(colour, index + 100 + led as u64).map(|mut planes| {
            for (plane, d) in planes.iter_mut().zip(&dark) {
                plane.iter_mut().zip(d).for_each(|(v, d)| *v -= d);
            }
            planes
        })
    });
    let [f0, f1, f2] = flats;
    let uv = frame.truth.projector_uv_px(0);
    let lit = frame.truth.illum(0);
    let phase = set
        .patterns()
        .iter()
        .map(|p| {
            uv.iter()
                .zip(lit)
                .map(|(q, il)| match il {
                    Illum::Lit => PatternSet::phase_at(p, f64::from(q[0]), f64::from(q[1])) as f32,
                    _ => f32::NAN,
                })
                .collect()
        })
        .collect();
    Ok(Sample {
        channels: planes(&frame.image),
        flats: [f0?, f1?, f2?],
        phase,
        depth_m: frame.truth.depth_m().to_vec(),
    })
}

fn wrap(a: f32) -> f32 {
    let t = std::f32::consts::TAU;
    a - t * (a / t).round()
}

#[derive(Default)]
struct Tally {
    abs_err: f64,
    n: usize,
}

impl Tally {
    fn add(&mut self, wrapped: &[f32], truth: &[f32]) {
        for (w, t) in wrapped.iter().zip(truth) {
            if t.is_finite() && w.is_finite() {
                self.abs_err += f64::from(wrap(w - t).abs());
                self.n += 1;
            }
        }
    }
    fn mae(&self) -> f64 {
        self.abs_err / self.n.max(1) as f64
    }
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str, default: u64| -> anyhow::Result<u64> {
        match args.iter().position(|a| a == name) {
            Some(i) => args
                .get(i + 1)
                .context("missing value")?
                .parse()
                .with_context(|| name.to_string()),
            None => Ok(default),
        }
    };
    let count = arg("--count", 6)?;
    let seed = arg("--seed", 9001)?;
    let detail = Detail::default();
    let set = PatternSet::seed001(detail.projector)?;
    let calibration = slscan::sim::truth::twin_calibration(&single_head(&detail), 1);
    let head = &calibration.heads[0];
    println!(
        "{count} random twin scenes (seed {seed}), {}x{} colour camera (8-bit), {}x{} DMD, 24 x 200 us in one 4.8 ms exposure",
        detail.camera.0, detail.camera.1, detail.projector.0, detail.projector.1
    );
    let samples: Vec<Sample> = (0..count)
        .map(|i| render(&set, &detail, seed, i))
        .collect::<anyhow::Result<_>>()?;
    let flats0 = &samples[0].flats;
    let view = |l: usize| [&flats0[l][0][..], &flats0[l][1][..], &flats0[l][2][..]];
    let crosstalk = crosstalk_from_flats([view(0), view(1), view(2)], 0.995)?;
    println!("crosstalk measured from scene 0's three LED flats (channel <- LED): {crosstalk:.3}");
    let variants = [
        (
            "linear carrier (FTP-like), raw channels",
            false,
            false,
            false,
        ),
        (
            "linear carrier + crosstalk + zero-order removal",
            false,
            true,
            true,
        ),
        (
            "reference carrier, raw channels, zero-order removal",
            true,
            false,
            true,
        ),
        (
            "reference carrier + crosstalk, no zero-order removal",
            true,
            true,
            false,
        ),
        (
            "reference carrier + crosstalk + zero-order removal (shipped)",
            true,
            true,
            true,
        ),
    ];
    // Plain row FTP per pattern: each channel as if it held one fringe.
    let mut ftp = Tally::default();
    let probe = Decoder::new(set.clone(), head, DecoderConfig::default())?;
    for s in &samples {
        for (p, w) in set.patterns().iter().zip(probe.demultiplexer().windows()) {
            let period = 1.0 / f64::from(w.carrier[0].abs());
            if let Ok(out) = ftp_phase(&s.channels[p.colour], period, FringeAxis::X) {
                ftp.add(&out.phase.data, &s.phase[p.index]);
            }
        }
    }
    println!("\n| decoder | wrapped-phase MAE, rad | decoded, of lit | unwrapped right, of decoded | depth RMSE of those, um |");
    println!("|---|---|---|---|---|");
    println!(
        "| row FTP per pattern (slscan::phase::ftp) | {:.4} | | | |",
        ftp.mae()
    );
    for (name, reference, xtalk, zero) in variants {
        let config = DecoderConfig {
            demux: DemuxOptions {
                crosstalk: xtalk.then_some(crosstalk),
                zero_order_removal: zero,
                reference_demodulation: reference,
                ..DemuxOptions::default()
            },
            ..DecoderConfig::default()
        };
        let decoder = Decoder::new(set.clone(), head, config)?;
        let mut tally = Tally::default();
        let (mut decoded, mut right, mut lit) = (0usize, 0usize, 0usize);
        let mut depth_sq = 0.0f64;
        for s in &samples {
            let out = decoder.decode([&s.channels[0], &s.channels[1], &s.channels[2]])?;
            for (m, instant) in out.instants.iter().enumerate() {
                tally.add(&out.fringes.wrapped[m], &s.phase[m]);
                for i in 0..s.depth_m.len() {
                    let t = s.phase[m][i];
                    if !t.is_finite() {
                        continue;
                    }
                    lit += 1;
                    let a = instant.absolute_phase[i];
                    if a.is_finite() {
                        decoded += 1;
                        if (a - t).abs() < std::f32::consts::PI {
                            right += 1;
                            depth_sq += f64::from(instant.depth_m[i] - s.depth_m[i]).powi(2);
                        }
                    }
                }
            }
        }
        println!(
            "| {name} | {:.4} | {:.3} | {:.4} | {:.1} |",
            tally.mae(),
            decoded as f64 / lit.max(1) as f64,
            right as f64 / decoded.max(1) as f64,
            1e6 * (depth_sq / right.max(1) as f64).sqrt()
        );
    }
    Ok(())
}
