//! Decoding one high-speed exposure (seed 001's 24-pattern colour long exposure)
//! into 24 absolute phase maps and depth maps on 2 cores, split into the
//! demultiplexer (crosstalk and zero-order removal, 24 demodulations, 3 + 48
//! 2-D FFTs) and the per-pixel unwrapping and depth, at 640x480 and 1280x1024,
//! beside seed 001's 90 ms on an RTX 4090; each size with the single
//! demodulation (the default), with one pass of sibling cancellation
//! (`--sibling-cancellations 1`, 24 demodulations more) and with one
//! consensus pass (`--consensus-passes 1`: 24 demodulations and the
//! unwrapping and depth again), also with its holes at depth edges settled
//! (`--settle-edges`: a fringe fit per candidate at those pixels).
//!
//! Then the first stage alone, analytic (crosstalk unmixing, Gaussian low
//! band) beside ZOCR-Net on tract (`models/highspeed_zocr.onnx`), whose time
//! replaces the analytic stage's in a decode with `--zocr-model`; and the
//! analytic demodulation beside FDD-Net's correction of its phases
//! (`models/highspeed_fdd.onnx`), which a decode with `--fdd-model` adds.
//!
//! `cargo bench -p slscan --bench highspeed` (runs: `HIGHSPEED_BENCH_RUNS=5`). A
//! table, not criterion: each run holds the shared cores for about a second.

use std::path::Path;
use std::time::{Duration, Instant};

use slscan::highspeed::{Decoder, DecoderConfig, FddNet, LearnedStage, PatternSet, ZocrNet};
use slscan::synth::high_speed::{high_speed_exposure, high_speed_head};
use slscan::synth::{trace, two_spheres};

const DMD: (u32, u32) = (1280, 800);

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
    println!("| image | sibling cancellation passes | consensus passes | holes settled | set-up | epipolar samples | demultiplex (24 fringes) | unwrap + depth (and the consensus pass) | whole decode | decoded pixels (of lit) |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for ((w, h), (cancellations, consensus, settle)) in [(640u32, 480u32), (1280, 1024)]
        .into_iter()
        .flat_map(|size| {
            [(0, 0, false), (1, 0, false), (0, 1, false), (0, 1, true)].map(|v| (size, v))
        })
    {
        let set = PatternSet::seed001(DMD).expect("seed set");
        let head = high_speed_head(w, h, DMD);
        let truth = trace(&two_spheres(0.5, 0.6), &head.camera, &head.projector);
        let planes = high_speed_exposure(&set, &truth, 0.002, 3);
        let mut config = DecoderConfig::default();
        config.demux.cancellations = cancellations;
        config.consensus_passes = consensus;
        config.settle_edges = settle;
        let t = Instant::now();
        let decoder = Decoder::new(set, &head, config).expect("decoder");
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
            "| {w}x{h} | {cancellations} | {consensus} | {} | {:.0} ms | {} | {:.0} ms | {:.0} ms | **{:.0} ms** | {decoded} (instant 0) |",
            if settle { "yes" } else { "no" },
            setup.as_secs_f64() * 1e3,
            decoder.samples(),
            demux.as_secs_f64() * 1e3,
            whole.saturating_sub(demux).as_secs_f64() * 1e3,
            whole.as_secs_f64() * 1e3
        );
    }
    first_stage(runs);
    third_stage(runs);
}

/// One learned stage beside the analytic step it replaces or follows, at
/// both image sizes: `stage(w, h)` sets up the exposure and gives the two
/// steps to time (analytic, learned: the learned one may use the analytic
/// one's output, so they run in that order).
fn stage_table<N: LearnedStage>(
    runs: usize,
    net: &N,
    columns: &str,
    stage: impl Fn(u32, u32) -> Box<dyn FnMut() -> (Duration, Duration)>,
) {
    println!("\n| image | {columns} | ratio |");
    println!("|---|---|---|---|");
    for (w, h) in [(640u32, 480u32), (1280, 1024)] {
        let mut step = stage(w, h);
        let (analytic, learned): (Vec<_>, Vec<_>) = (0..runs).map(|_| step()).unzip();
        let (a, l) = (median(analytic), median(learned));
        println!(
            "| {w}x{h} | {:.0} ms | {:.0} ms ({}) | {:.1}x |",
            a.as_secs_f64() * 1e3,
            l.as_secs_f64() * 1e3,
            net.tiles_per_exposure(w as usize, h as usize),
            l.as_secs_f64() / a.as_secs_f64()
        );
    }
}

/// The bench's exposure of two spheres before a wall at `w` x `h`, and its
/// decoder.
fn exposure(set: &PatternSet, w: u32, h: u32) -> (Decoder, [Vec<f32>; 3]) {
    let head = high_speed_head(w, h, DMD);
    let truth = trace(&two_spheres(0.5, 0.6), &head.camera, &head.projector);
    let planes = high_speed_exposure(set, &truth, 0.002, 3).map(|p| p.data);
    let decoder = Decoder::new(set.clone(), &head, DecoderConfig::default()).expect("decoder");
    (decoder, planes)
}

/// The first stage alone: the analytic formula beside ZOCR-Net.
fn first_stage(runs: usize) {
    let onnx = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/highspeed_zocr.onnx");
    let set = PatternSet::seed001(DMD).expect("seed set");
    let net = match ZocrNet::load(&onnx, &set) {
        Ok(net) => net,
        Err(e) => {
            println!("\nZOCR-Net row skipped: {e}");
            return;
        }
    };
    stage_table(
        runs,
        &net,
        "stage 1, analytic | stage 1, ZOCR-Net (tiles)",
        |w, h| {
            let (decoder, planes) = exposure(&set, w, h);
            let net = net.clone();
            Box::new(move || {
                let channels = [&planes[0][..], &planes[1][..], &planes[2][..]];
                let t = Instant::now();
                std::hint::black_box(decoder.demultiplexer().remove_zero_order(channels));
                let analytic = t.elapsed();
                let t = Instant::now();
                std::hint::black_box(
                    net.remove_zero_order(channels, w as usize, h as usize)
                        .expect("ZOCR-Net runs"),
                );
                (analytic, t.elapsed())
            })
        },
    );
}

/// The third stage: FDD-Net's correction beside the analytic demodulation
/// whose phases it corrects.
fn third_stage(runs: usize) {
    let onnx = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/highspeed_fdd.onnx");
    let set = PatternSet::seed001(DMD).expect("seed set");
    let net = match FddNet::load(&onnx, &set) {
        Ok(net) => net,
        Err(e) => {
            println!("\nFDD-Net row skipped: {e}");
            return;
        }
    };
    stage_table(
        runs,
        &net,
        "demodulation, analytic | FDD-Net's correction after it (tiles)",
        |w, h| {
            let (decoder, planes) = exposure(&set, w, h);
            let cleaned = decoder.demultiplexer().remove_zero_order([
                &planes[0][..],
                &planes[1][..],
                &planes[2][..],
            ]);
            let (net, set) = (net.clone(), set.clone());
            Box::new(move || {
                let demux = decoder.demultiplexer();
                let t = Instant::now();
                let fringes = demux.demodulate_all(cleaned.clone());
                let analytic = t.elapsed();
                let t = Instant::now();
                std::hint::black_box(
                    net.correct(demux, &set, &fringes, w as usize, h as usize)
                        .expect("FDD-Net runs"),
                );
                (analytic, t.elapsed())
            })
        },
    );
}
