//! The full pipeline at seed 000's camera size: 3 periods x 4 steps = 12 frames of
//! 3072x2048 -> wrapped phase -> heterodyne -> triangulation -> point cloud with normals.
//!
//! Prints a table for 1 and 2 rayon threads and several inputs: `u16 (12-bit)` (what a
//! machine-vision camera delivers; `ReconstructConfig::full_scale = 4095`), `f32` (the
//! same frames as floats in [0, 1]), u16 through a projector model with lens distortion
//! (triangulation then adds a first-order start and 2 vectorised Newton steps on the
//! depth), and that again with the row loops' baseline x86-64 (SSE2) build instead of the
//! AVX2 one the CPU gets at run time (`slscan::simd`). Columns: the fused pass into a
//! fresh result (`reconstruct`), the fused pass into a reused result (`reconstruct_into`,
//! no fresh memory), and the staged passes with their per-stage wall times (these
//! allocate per stage, so they add up to more than the fused pass). Frames come from the
//! formula-based renderer (`slscan::synth`): a plane with the two calibration spheres,
//! projector covering the view. Run:
//! `SLSCAN_BENCH_RUNS=7 cargo bench -p slscan --bench pipeline`.
//!
//! On the idle 2-core development machine (AMD EPYC, AVX2), 2 threads, u16 input: ideal
//! projector ~94 ms fresh / ~65 ms reused; distorted projector (k1 0.02, k2 -0.005, p1
//! 2e-4, p2 -1e-4, what calibrated heads have) ~112 ms fresh / ~86 ms reused (CPU ~220 /
//! ~170 ms); the SSE2 build of the same ~170-205 / ~140 ms. Session 2 ended at 157 / 113
//! (ideal) and 199 / 164 ms (distorted); session 1 at ~380 ms. perf on the reused
//! distorted pass: triangulation (Newton steps) ~29 %, phase decode (atan2) ~23 %, cloud
//! and normals ~19 %, per-pixel maps ~13 %, heterodyne ~6 %. A fresh result adds the
//! kernel's clearing of ~390 MB (huge pages, filled by both threads; ~25-45 ms).
//!
//! A last line times both directions (24 f32 frames, two-ray triangulation, 2 threads):
//! ~230-275 ms fresh / ~175-220 ms reused (three runs). The per-pixel f64 two-ray path it replaced took ~343
//! ms fresh (and ~440 against ~230 ms now with a distorted projector, measured once with
//! a throwaway harness).

use std::time::Instant;

use slscan::calibration::{Distortion, PinholeModel};
use slscan::phase::Sample;
use slscan::raster::Raster;
use slscan::reconstruct::{ReconstructConfig, Reconstructor, StageTimes};
use slscan::simd::Simd;
use slscan::synth::{self, Lighting};

/// CPU seconds used by the whole process so far (all threads): on a shared, loaded
/// machine this is the stable number; wall time includes waiting for a core.
fn cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec through a valid pointer.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let runs: usize = std::env::var("SLSCAN_BENCH_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5);
    let (camera, projector) = synth::stereo_rig(
        PinholeModel::ideal(3072, 2048, 4000.0),
        PinholeModel::ideal(1920, 1080, 2200.0),
        0.15,
        0.5,
    );
    let periods = vec![100.0, 110.0, 120.0];
    let t = Instant::now();
    let truth = synth::trace(&synth::two_spheres(0.5, 0.56), &camera, &projector);
    let light = Lighting {
        ambient: 0.1,
        gain: 0.7,
        noise_sigma: 0.01,
    };
    let frames = synth::render_fringe_set(&truth, &periods, 4, true, &light, 1);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    // What a machine-vision camera delivers: 12-bit samples in u16 words.
    let frames_u16: Vec<Raster<u16>> = frames
        .iter()
        .map(|f| Raster {
            width: f.width,
            height: f.height,
            data: f
                .data
                .iter()
                .map(|&v| (v.clamp(0.0, 1.0) * FULL_SCALE_12_BIT + 0.5) as u16)
                .collect(),
        })
        .collect();
    let refs_u16: Vec<&Raster<u16>> = frames_u16.iter().collect();
    println!(
        "set-up (render 12 frames, not timed below): {:.2} s; row loops built for {:?}",
        t.elapsed().as_secs_f64(),
        Simd::best()
    );

    println!("| input | threads | constructor ms | fused wall ms | fused CPU ms | reused wall ms | reused CPU ms | staged wall ms: phase | unwrap | triangulate | cloud + normals | total | points |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| {
            let t = Instant::now();
            let mut config = ReconstructConfig::new(periods.clone());
            config.normals = true;
            let rec = Reconstructor::new(&camera, &projector, config.clone()).expect("set-up");
            let ctor_ms = t.elapsed().as_secs_f64() * 1e3;
            config.full_scale = Some(FULL_SCALE_12_BIT);
            let rec_u16 = Reconstructor::new(&camera, &projector, config.clone()).expect("set-up");
            row(&rec_u16, &refs_u16, "u16 (12-bit)", threads, ctor_ms, runs);
            row(&rec, &refs, "f32", threads, ctor_ms, runs);
            // A calibrated projector has lens distortion, and then each column is no
            // plane and triangulation iterates per pixel: time that path on the same
            // frames (the geometry is then off by the distortion; only the cost counts).
            let mut distorted = projector;
            distorted.distortion = Distortion {
                k1: 0.02,
                k2: -0.005,
                p1: 0.0002,
                p2: -0.0001,
                k3: 0.0,
            };
            let rec_distorted = Reconstructor::new(&camera, &distorted, config).expect("set-up");
            row(
                &rec_distorted,
                &refs_u16,
                "u16, distorted projector",
                threads,
                ctor_ms,
                runs,
            );
            // The same without the AVX2 build of the row loops: what a CPU without AVX2
            // gets, and the ratio the runtime dispatch buys on this one.
            if Simd::best() != Simd::Baseline {
                row(
                    &rec_distorted.with_simd(Simd::Baseline),
                    &refs_u16,
                    "u16, distorted, baseline SSE2",
                    threads,
                    ctor_ms,
                    runs,
                );
            }
        });
    }
    both_directions(&camera, &projector, &truth, &periods, &light, runs);
}

/// Columns and rows (24 f32 frames, two-ray triangulation), 2 threads: fused pass into
/// a fresh and a reused result, one line.
fn both_directions(
    camera: &PinholeModel,
    projector: &PinholeModel,
    truth: &synth::GroundTruth,
    periods: &[f64],
    light: &Lighting,
    runs: usize,
) {
    let columns = synth::render_fringe_set(truth, periods, 4, true, light, 1);
    let rows = synth::render_fringe_set(truth, periods, 4, false, light, 2);
    let (cu, cv): (Vec<&Raster<f32>>, Vec<&Raster<f32>>) =
        (columns.iter().collect(), rows.iter().collect());
    let mut config = ReconstructConfig::new(periods.to_vec());
    config.directions = slscan::reconstruct::Directions::Both;
    let rec = Reconstructor::new(camera, projector, config).expect("set-up");
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("pool");
    let (fresh, reused) = pool.install(|| {
        let mut fresh = Vec::new();
        for _ in 0..runs {
            let t = Instant::now();
            let out = rec.reconstruct(&cu, Some(&cv)).expect("reconstruct");
            fresh.push(t.elapsed().as_secs_f64() * 1e3);
            drop(out);
        }
        let mut out = rec.reconstruct(&cu, Some(&cv)).expect("reconstruct");
        let mut reused = Vec::new();
        for _ in 0..runs {
            let t = Instant::now();
            rec.reconstruct_into(&cu, Some(&cv), &mut out)
                .expect("reconstruct");
            reused.push(t.elapsed().as_secs_f64() * 1e3);
        }
        (median(fresh), median(reused))
    });
    println!(
        "both directions (24 f32 frames, two-ray triangulation), 2 threads: {fresh:.1} ms fresh, {reused:.1} ms reused"
    );
}

/// 12-bit camera data: full white.
const FULL_SCALE_12_BIT: f32 = 4095.0;

/// Times the fused pass (`runs` times) and the staged passes (up to 3 times) on one
/// input type; prints one table row of medians.
fn row<T: Sample>(
    rec: &Reconstructor,
    refs: &[&Raster<T>],
    input: &str,
    threads: usize,
    ctor_ms: f64,
    runs: usize,
) {
    let mut fused = Vec::new();
    let mut fused_cpu = Vec::new();
    let mut points = 0;
    for _ in 0..runs {
        let (t, c) = (Instant::now(), cpu_s());
        let out = rec.reconstruct(refs, None).expect("reconstruct");
        fused.push(t.elapsed().as_secs_f64() * 1e3);
        fused_cpu.push((cpu_s() - c) * 1e3);
        points = out.cloud.len();
        drop(out);
    }
    // The same into one reused result: no fresh memory, so no page faults.
    let mut reused = Vec::new();
    let mut reused_cpu = Vec::new();
    let mut out = rec.reconstruct(refs, None).expect("reconstruct");
    for _ in 0..runs {
        let (t, c) = (Instant::now(), cpu_s());
        rec.reconstruct_into(refs, None, &mut out)
            .expect("reconstruct");
        reused.push(t.elapsed().as_secs_f64() * 1e3);
        reused_cpu.push((cpu_s() - c) * 1e3);
    }
    assert_eq!(out.cloud.len(), points);
    drop(out);
    let mut stages: Vec<StageTimes> = Vec::new();
    for _ in 0..runs.min(3) {
        let (out, times) = rec.reconstruct_staged(refs).expect("staged");
        drop(out);
        stages.push(times);
    }
    let m = |f: fn(&StageTimes) -> f64| median(stages.iter().map(f).collect()) * 1e3;
    let (p, u, tr, c) = (
        m(|s| s.phase_s),
        m(|s| s.unwrap_s),
        m(|s| s.triangulate_s),
        m(|s| s.cloud_s),
    );
    println!(
        "| {input} | {threads} | {ctor_ms:.0} | {:.1} | {:.1} | {:.1} | {:.1} | {p:.1} | {u:.1} | {tr:.1} | {c:.1} | {:.1} | {points} |",
        median(fused),
        median(fused_cpu),
        median(reused),
        median(reused_cpu),
        p + u + tr + c
    );
}
