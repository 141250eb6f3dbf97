//! slscan beside a peer on the same data in the same run: 3 periods x 4 steps = 12
//! float32 frames of 3072x2048 -> wrapped phase, modulation and background per period ->
//! heterodyne absolute phase of the finest period, done by numpy
//! (`benches/peers/phase_unwrap.py`, run with `python3` on `.npy` files this bench writes)
//! and by slscan four ways: the pipeline's staged row kernels
//! ([`Reconstructor::reconstruct_staged`], phase + unwrap stages), the public map APIs
//! ([`PhaseShift::wrapped_phase`] per period, then [`Heterodyne::unwrap`]), the same into
//! reused outputs, and the one-pass [`TemporalDecoder`] (fresh and reused outputs).
//!
//! The frames are `A + B cos(2 pi u / P + delta_n) + noise` with a known projector
//! coordinate `u(x, y)` (a slanted, rippled field over the 1920-px projector), a vignetted
//! modulation `B` and Gaussian noise, so each side's absolute phase is compared with the
//! truth `2 pi u / P_0`: RMS and largest error over the pixels it kept, and how many it
//! kept. Times are the best of `SLSCAN_BENCH_RUNS` (default 5) on data in memory (file
//! reading is not timed on either side); numpy runs on one thread, slscan on 1 and on all
//! rayon threads. Without an importable numpy the peer's columns say so and slscan's are
//! still printed. Run: `SLSCAN_BENCH_RUNS=7 cargo bench -p slscan --bench peers`.
//!
//! A last table says where the time goes: each side's phase and unwrap stages (the one
//! pass has none), and the memory floor (one parallel pass reading the 12 frames, and one
//! writing a map).
//!
//! On the idle 2-core development machine (Intel Xeon, AVX2 build), numpy 2.4.6 took
//! ~296-315 ms (phase ~157-166, unwrap ~139-149). slscan, 2 threads: one pass into
//! reused outputs 28.4 ms (10.4x), into fresh ones 33.7 ms (8.8x); the map APIs 32.3 ms
//! reused (9.2x), 53.4 ms fresh; staged pipeline 35.3 ms (8.4x). Reading the 302 MB of
//! frames alone takes 14.7 ms on 2 threads, 28.5 ms on 1. Accuracy: numpy, the map APIs
//! and the one pass keep the same 99.93 % with RMS 0.0263 rad (largest 0.182, no
//! miscounted order); the pipeline also refuses pixels whose modulation is too low to
//! count orders reliably (98.51 % kept, RMS 0.0260).

use std::path::{Path, PathBuf};

#[path = "common/peer.rs"]
mod peer;
use peer::run_peer;
use std::time::Instant;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use slscan::calibration::PinholeModel;
use slscan::phase::PhaseShift;
use slscan::raster::Raster;
use slscan::reconstruct::{ReconstructConfig, Reconstructor};
use slscan::unwrap::heterodyne::Heterodyne;
use slscan::unwrap::temporal::TemporalDecoder;
use slscan::unwrap::PixelStatus;

const WIDTH: usize = 3072;
const HEIGHT: usize = 2048;
const PROJECTOR_WIDTH_PX: u32 = 1920;
const PERIODS_PX: [f64; 3] = [100.0, 110.0, 120.0];
const STEPS: usize = 4;
const NOISE_SIGMA: f32 = 0.01;
const MAX_RESIDUAL_RAD: f64 = std::f64::consts::FRAC_PI_2;

/// Projector column seen by camera pixel (x, y): a slanted field with a ripple, inside
/// `[5, 1915]` of the 1920-px projector.
fn truth_u_px(x: usize, y: usize) -> f64 {
    let (s, t) = (
        (x as f64 + 0.5) / WIDTH as f64,
        (y as f64 + 0.5) / HEIGHT as f64,
    );
    30.0 + 1860.0 * s + 25.0 * (std::f64::consts::TAU * 1.5 * t + 3.0 * s).sin()
}

/// Modulation at (x, y): 0.35 in the centre, 0.14 in the corners (vignetting).
fn truth_b(x: usize, y: usize) -> f64 {
    let (s, t) = (
        2.0 * (x as f64 + 0.5) / WIDTH as f64 - 1.0,
        2.0 * (y as f64 + 0.5) / HEIGHT as f64 - 1.0,
    );
    0.35 * (1.0 - 0.3 * (s * s + t * t))
}

/// The 12 frames (period-major) and the true absolute phase of the finest period.
fn render() -> (Vec<Raster<f32>>, Raster<f32>) {
    let tau = std::f64::consts::TAU;
    let frames: Vec<Raster<f32>> = (0..PERIODS_PX.len() * STEPS)
        .into_par_iter()
        .map(|i| {
            let (period, n) = (PERIODS_PX[i / STEPS], i % STEPS);
            let delta = tau * n as f64 / STEPS as f64;
            let mut data = vec![0.0f32; WIDTH * HEIGHT];
            data.par_chunks_mut(WIDTH).enumerate().for_each(|(y, row)| {
                let mut rng = ChaCha8Rng::seed_from_u64((i * HEIGHT + y) as u64);
                let noise = Normal::new(0.0f32, NOISE_SIGMA).expect("sigma > 0");
                for (x, v) in row.iter_mut().enumerate() {
                    let phi = tau * truth_u_px(x, y) / period + delta;
                    *v = (0.45 + truth_b(x, y) * phi.cos()) as f32 + noise.sample(&mut rng);
                }
            });
            Raster {
                width: WIDTH,
                height: HEIGHT,
                data,
            }
        })
        .collect();
    let truth = Raster::from_fn(WIDTH, HEIGHT, |x, y| {
        (tau * truth_u_px(x, y) / PERIODS_PX[0]) as f32
    });
    (frames, truth)
}

/// Accuracy of an absolute-phase map against the truth (NaN = refused).
struct Accuracy {
    rms_rad: f64,
    max_rad: f64,
    kept: f64,
}

fn accuracy(phase: &[f32], truth: &Raster<f32>) -> Accuracy {
    let (sum, max, kept) = phase
        .par_iter()
        .zip(&truth.data)
        .filter(|(p, _)| !p.is_nan())
        .map(|(&p, &t)| {
            let e = f64::from(p) - f64::from(t);
            (e * e, e.abs(), 1usize)
        })
        .reduce(
            || (0.0, 0.0, 0),
            |a, b| (a.0 + b.0, a.1.max(b.1), a.2 + b.2),
        );
    Accuracy {
        rms_rad: (sum / kept.max(1) as f64).sqrt(),
        max_rad: max,
        kept: kept as f64 / phase.len() as f64,
    }
}

/// Best and the per-stage bests (phase, unwrap) of `runs` timed calls, milliseconds.
#[derive(Clone, Copy)]
struct Timing {
    total_ms: f64,
    phase_ms: f64,
    unwrap_ms: f64,
}

fn best(times: &[(f64, f64)]) -> Timing {
    let min = |f: fn(&(f64, f64)) -> f64| times.iter().map(f).fold(f64::INFINITY, f64::min);
    Timing {
        total_ms: min(|t| t.0 + t.1),
        phase_ms: min(|t| t.0),
        unwrap_ms: min(|t| t.1),
    }
}

/// The pipeline's staged phase + unwrap passes; its absolute phase (NaN where it
/// masked or refused).
fn pipeline(rec: &Reconstructor, frames: &[&Raster<f32>], runs: usize) -> (Timing, Vec<f32>) {
    let mut times = Vec::new();
    let mut phase = Vec::new();
    for _ in 0..runs {
        let (out, t) = rec.reconstruct_staged(frames).expect("staged");
        times.push((t.phase_s * 1e3, t.unwrap_s * 1e3));
        phase = out.pixels.phase_u;
    }
    (best(&times), phase)
}

/// `wrapped_phase` per period, then `Heterodyne::unwrap`; its absolute phase.
fn public_api(
    shift: &PhaseShift,
    heterodyne: &Heterodyne,
    frames: &[&Raster<f32>],
    runs: usize,
) -> (Timing, Vec<f32>) {
    let mut times = Vec::new();
    let mut phase = Vec::new();
    for _ in 0..runs {
        drop(std::mem::take(&mut phase));
        let t = Instant::now();
        let wrapped: Vec<_> = frames
            .chunks(STEPS)
            .map(|set| shift.wrapped_phase(set).expect("frames"))
            .collect();
        let phase_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let maps: Vec<&Raster<f32>> = wrapped.iter().map(|w| &w.phase).collect();
        let out = heterodyne.unwrap(&maps, None).expect("maps");
        times.push((phase_ms, t.elapsed().as_secs_f64() * 1e3));
        drop(wrapped);
        assert_eq!(out.count(PixelStatus::Masked), 0, "no mask, nothing masked");
        phase = out.phase.data;
    }
    (best(&times), phase)
}

/// [`public_api`] into results reused from call to call (`wrapped_phase_into`,
/// `unwrap_into`): no fresh memory.
fn public_api_reused(
    shift: &PhaseShift,
    heterodyne: &Heterodyne,
    frames: &[&Raster<f32>],
    runs: usize,
) -> (Timing, Vec<f32>) {
    let mut wrapped: Vec<_> = frames
        .chunks(STEPS)
        .map(|set| shift.wrapped_phase(set).expect("frames"))
        .collect();
    let maps: Vec<&Raster<f32>> = wrapped.iter().map(|w| &w.phase).collect();
    let mut out = heterodyne.unwrap(&maps, None).expect("maps");
    let mut times = Vec::new();
    for _ in 0..runs {
        let t = Instant::now();
        for (set, w) in frames.chunks(STEPS).zip(&mut wrapped) {
            shift.wrapped_phase_into(set, w).expect("frames");
        }
        let phase_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let maps: Vec<&Raster<f32>> = wrapped.iter().map(|w| &w.phase).collect();
        heterodyne.unwrap_into(&maps, None, &mut out).expect("maps");
        times.push((phase_ms, t.elapsed().as_secs_f64() * 1e3));
    }
    (best(&times), out.phase.data)
}

/// [`TemporalDecoder::decode`]: phase and unwrap in one pass over the rows (no stage
/// times: the stages interleave per row); its absolute phase.
fn one_pass(decoder: &TemporalDecoder, frames: &[&Raster<f32>], runs: usize) -> (Timing, Vec<f32>) {
    let mut times = Vec::new();
    let mut phase = Vec::new();
    for _ in 0..runs {
        drop(std::mem::take(&mut phase));
        let t = Instant::now();
        let out = decoder.decode(frames, None).expect("frames");
        times.push(t.elapsed().as_secs_f64() * 1e3);
        phase = out.phase.phase.data;
    }
    (one_pass_timing(&times), phase)
}

/// [`one_pass`] into a result reused from call to call (`decode_into`).
fn one_pass_reused(
    decoder: &TemporalDecoder,
    frames: &[&Raster<f32>],
    runs: usize,
) -> (Timing, Vec<f32>) {
    let mut out = decoder.decode(frames, None).expect("frames");
    let mut times = Vec::new();
    for _ in 0..runs {
        let t = Instant::now();
        decoder.decode_into(frames, None, &mut out).expect("frames");
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    (one_pass_timing(&times), out.phase.phase.data)
}

/// Best of one-pass times: no stage split (NaN).
fn one_pass_timing(times: &[f64]) -> Timing {
    Timing {
        total_ms: times.iter().copied().fold(f64::INFINITY, f64::min),
        phase_ms: f64::NAN,
        unwrap_ms: f64::NAN,
    }
}

/// What the peer reported.
struct Peer {
    version: String,
    timing: Timing,
    accuracy: Accuracy,
}

/// Runs the numpy peer on the frames written to `dir`; `Err` says why it did not run.
fn numpy_side(dir: &Path, truth: &Raster<f32>, runs: usize) -> Result<Peer, String> {
    let report = run_peer("numpy", "numpy", "phase_unwrap.py", dir, runs)?;
    let ms = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN) * 1e3;
    let bytes = std::fs::read(dir.join("peer_absolute.npy")).map_err(|e| e.to_string())?;
    let absolute = slscan::io::npy::decode_npy_2d(&bytes).map_err(|e| e.to_string())?;
    Ok(Peer {
        version: report["numpy"].as_str().unwrap_or("?").to_owned(),
        timing: Timing {
            total_ms: ms(&report["best_s"]),
            phase_ms: ms(&report["stages_s"]["phase"]),
            unwrap_ms: ms(&report["stages_s"]["unwrap"]),
        },
        accuracy: accuracy(&absolute.values.data, truth),
    })
}

/// Writes the frames and `job.json` for the peer.
fn write_job(dir: &Path, frames: &[Raster<f32>]) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let names: Vec<String> = (0..frames.len())
        .map(|i| format!("frame_p{}_n{}.npy", i / STEPS, i % STEPS))
        .collect();
    frames
        .par_iter()
        .zip(&names)
        .try_for_each(|(f, name)| slscan::io::npy::write_npy_f32(&dir.join(name), f))?;
    let job = serde_json::json!({
        "periods_px": PERIODS_PX,
        "steps": STEPS,
        "range_px": PROJECTOR_WIDTH_PX,
        "max_residual_rad": MAX_RESIDUAL_RAD,
        "frames": names,
    });
    std::fs::write(dir.join("job.json"), job.to_string())
}

/// Best wall time of one parallel pass reading every frame (a sum), and of one writing a
/// fresh map, milliseconds: the memory floor under the phase stage.
fn memory_floor(frames: &[&Raster<f32>], runs: usize) -> (f64, f64) {
    let (mut read, mut write) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..runs {
        let t = Instant::now();
        // XOR of the bits: a reduction that vectorises (a float sum is one long chain).
        let s: u32 = frames
            .iter()
            .map(|f| {
                f.data
                    .par_chunks(WIDTH)
                    .map(|r| r.iter().fold(0u32, |a, v| a ^ v.to_bits()))
                    .reduce(|| 0, |a, b| a ^ b)
            })
            .fold(0, |a, b| a ^ b);
        read = read.min(t.elapsed().as_secs_f64() * 1e3);
        std::hint::black_box(s);
        let t = Instant::now();
        let mut map: Vec<f32> = vec![0.0; WIDTH * HEIGHT];
        map.par_chunks_mut(WIDTH).for_each(|r| r.fill(1.0));
        std::hint::black_box(&map);
        write = write.min(t.elapsed().as_secs_f64() * 1e3);
    }
    (read, write)
}

fn main() {
    let runs: usize = std::env::var("SLSCAN_BENCH_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5);
    let t = Instant::now();
    let (frames, truth) = render();
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("peers_phase_unwrap");
    write_job(&dir, &frames).expect("write the peer's frames");
    println!(
        "set-up (render + write 12 frames of {WIDTH}x{HEIGHT}, not timed): {:.1} s; frames in {}",
        t.elapsed().as_secs_f64(),
        dir.display()
    );

    let peer = numpy_side(&dir, &truth, runs);
    match &peer {
        Ok(p) => println!("peer: numpy {} (one thread), best of {runs}", p.version),
        Err(why) => println!("peer skipped: {why}"),
    }

    let (camera, projector) = slscan::synth::stereo_rig(
        PinholeModel::ideal(WIDTH as u32, HEIGHT as u32, 4000.0),
        PinholeModel::ideal(PROJECTOR_WIDTH_PX, 1080, 2200.0),
        0.15,
        0.5,
    );
    let mut config = ReconstructConfig::new(PERIODS_PX.to_vec());
    config.steps = STEPS;
    config.noise_sigma = NOISE_SIGMA;
    config.normals = false;
    let rec = Reconstructor::new(&camera, &projector, config).expect("set-up");
    let shift = PhaseShift::new(STEPS).expect("steps");
    let heterodyne = Heterodyne::new(&PERIODS_PX, f64::from(PROJECTOR_WIDTH_PX), MAX_RESIDUAL_RAD)
        .expect("periods");
    let decoder = TemporalDecoder::new(shift.clone(), heterodyne.clone());

    let all_threads = rayon::current_num_threads();
    let mut thread_counts = vec![1];
    if all_threads > 1 {
        thread_counts.push(all_threads);
    }
    let mut breakdown = Vec::new();
    println!();
    println!("| job | slscan path | threads | numpy ms | slscan ms | ratio | numpy RMS / max error, rad (kept) | slscan RMS / max error, rad (kept) |");
    println!("|---|---|---|---|---|---|---|---|");
    for &threads in &thread_counts {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        let results = pool.install(|| {
            let (tp, pp) = pipeline(&rec, &refs, runs);
            let (ta, pa) = public_api(&shift, &heterodyne, &refs, runs);
            let (tr, pr) = public_api_reused(&shift, &heterodyne, &refs, runs);
            let (to, po) = one_pass(&decoder, &refs, runs);
            let (tor, por) = one_pass_reused(&decoder, &refs, runs);
            let floor = memory_floor(&refs, runs);
            [
                ("pipeline's staged row kernels", tp, accuracy(&pp, &truth)),
                (
                    "`wrapped_phase` + `Heterodyne::unwrap`",
                    ta,
                    accuracy(&pa, &truth),
                ),
                (
                    "`wrapped_phase_into` + `Heterodyne::unwrap_into`, outputs reused",
                    tr,
                    accuracy(&pr, &truth),
                ),
                (
                    "`TemporalDecoder::decode`, one pass",
                    to,
                    accuracy(&po, &truth),
                ),
                (
                    "`TemporalDecoder::decode_into`, one pass, outputs reused",
                    tor,
                    accuracy(&por, &truth),
                ),
            ]
            .map(|r| (r, floor))
        });
        for ((path, timing, acc), floor) in results {
            let (peer_ms, ratio, peer_acc) = match &peer {
                Ok(p) => (
                    format!("{:.0}", p.timing.total_ms),
                    format!("{:.1}x", p.timing.total_ms / timing.total_ms),
                    format!(
                        "{:.4} / {:.3} ({:.2} %)",
                        p.accuracy.rms_rad,
                        p.accuracy.max_rad,
                        100.0 * p.accuracy.kept
                    ),
                ),
                Err(_) => ("skipped".into(), "-".into(), "-".into()),
            };
            println!(
                "| phase + heterodyne unwrap, 12 x {WIDTH}x{HEIGHT} | {path} | {threads} | {peer_ms} | {:.1} | {ratio} | {peer_acc} | {:.4} / {:.3} ({:.2} %) |",
                timing.total_ms,
                acc.rms_rad,
                acc.max_rad,
                100.0 * acc.kept
            );
            breakdown.push((path, threads, timing, floor));
        }
    }

    println!();
    println!("Where the time goes (best per stage, ms; memory floor: one parallel pass reading the 12 frames / writing one fresh map):");
    println!("| side | threads | phase (atan2, modulation, background) | unwrap | floor: read frames | floor: write one map |");
    println!("|---|---|---|---|---|---|");
    if let Ok(p) = &peer {
        println!(
            "| numpy | 1 | {:.0} | {:.0} | - | - |",
            p.timing.phase_ms, p.timing.unwrap_ms
        );
    }
    for (path, threads, t, (read, write)) in breakdown {
        let stages = if t.phase_ms.is_nan() {
            format!("one pass: {:.1} | - ", t.total_ms)
        } else {
            format!("{:.1} | {:.1} ", t.phase_ms, t.unwrap_ms)
        };
        println!("| slscan, {path} | {threads} | {stages}| {read:.1} | {write:.1} |");
    }
    if std::env::var_os("SLSCAN_PEERS_KEEP").is_none() {
        let _ = std::fs::remove_dir_all(&dir);
    }
}
