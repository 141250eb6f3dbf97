//! Decoding one high-speed exposure (seed 001's 24-pattern colour long exposure)
//! into 24 absolute phase maps and depth maps on 2 cores, split into the
//! demultiplexer (crosstalk and zero-order removal, 24 demodulations, 3 + 48
//! 2-D FFTs) and the per-pixel unwrapping and depth, at 640x480 and 1280x1024,
//! beside seed 001's 90 ms on an RTX 4090.
//!
//! `cargo bench -p slscan --bench highspeed` (runs: `HIGHSPEED_BENCH_RUNS=5`). A
//! table, not criterion: each run holds the shared cores for about a second.

use std::time::{Duration, Instant};

use slscan::calibration::{Head, PinholeModel};
use slscan::highspeed::{Decoder, DecoderConfig, PatternSet};
use slscan::raster::Raster;
use slscan::synth::{render, stereo_rig, trace, two_spheres, Lighting};

const DMD: (u32, u32) = (1280, 800);

fn head(width: u32, height: u32) -> Head {
    // The twin head's field: 42 deg across the camera, 56 deg across the DMD.
    let camera = PinholeModel::ideal(
        width,
        height,
        0.5 * f64::from(width) / 21f64.to_radians().tan(),
    );
    let mut projector = PinholeModel::ideal(DMD.0, DMD.1, 640.0 / 28f64.to_radians().tan());
    projector.intrinsics.cy = 0.5 * f64::from(DMD.1);
    let (camera, projector) = stereo_rig(camera, projector, 0.12, 0.5);
    Head {
        name: "A".into(),
        camera,
        projector,
        view_errors: vec![],
        port: None,
    }
}

fn exposure(set: &PatternSet, head: &Head) -> [Raster<f32>; 3] {
    let truth = trace(&two_spheres(0.5, 0.6), &head.camera, &head.projector);
    let lighting = Lighting {
        ambient: 0.03,
        gain: 0.9,
        noise_sigma: 0.002,
    };
    [0, 1, 2].map(|c| {
        let pats: Vec<_> = set
            .patterns()
            .iter()
            .filter(|p| p.colour == c)
            .copied()
            .collect();
        render(
            &truth,
            |u, v| {
                pats.iter()
                    .map(|p| 0.5 + 0.5 * PatternSet::phase_at(p, u, v).cos())
                    .sum::<f64>()
                    / pats.len() as f64
            },
            &lighting,
            3 + c as u64,
        )
    })
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

fn main() {
    let runs: usize = std::env::var("HIGHSPEED_BENCH_RUNS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5);
    println!(
        "{} threads, median of {runs} runs; seed 001: 90 ms per image on an RTX 4090 (networks); goal here 1 s",
        rayon::current_num_threads()
    );
    println!("| image | set-up | demultiplex (24 fringes) | unwrap + depth | whole decode | decoded pixels (of lit) |");
    println!("|---|---|---|---|---|---|");
    for (w, h) in [(640u32, 480u32), (1280, 1024)] {
        let set = PatternSet::seed001(DMD).expect("seed set");
        let head = head(w, h);
        let planes = exposure(&set, &head);
        let t = Instant::now();
        let decoder = Decoder::new(set, &head, DecoderConfig::default()).expect("decoder");
        let setup = t.elapsed();
        let channels = [
            &planes[0].data[..],
            &planes[1].data[..],
            &planes[2].data[..],
        ];
        let (mut demux, mut whole) = (Vec::new(), Vec::new());
        let mut decoded = 0usize;
        for _ in 0..runs {
            let t = Instant::now();
            std::hint::black_box(decoder.demultiplexer().demultiplex(channels));
            demux.push(t.elapsed());
            let t = Instant::now();
            let out = decoder
                .decode([&planes[0], &planes[1], &planes[2]])
                .expect("decode");
            whole.push(t.elapsed());
            decoded = out.instants[0]
                .depth_m
                .iter()
                .filter(|z| z.is_finite())
                .count();
        }
        let (demux, whole) = (median(demux), median(whole));
        println!(
            "| {w}x{h} | {:.0} ms | {:.0} ms | {:.0} ms | **{:.0} ms** | {decoded} (instant 0) |",
            setup.as_secs_f64() * 1e3,
            demux.as_secs_f64() * 1e3,
            whole.saturating_sub(demux).as_secs_f64() * 1e3,
            whole.as_secs_f64() * 1e3
        );
    }
}
