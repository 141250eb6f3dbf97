//! The full pipeline at seed 000's camera size: 3 periods x 4 steps = 12 frames of
//! 3072x2048 -> wrapped phase -> heterodyne -> triangulation -> point cloud.
//!
//! Prints a table (fused pass, and the staged passes with their per-stage times) for 1 and
//! 2 rayon threads. Frames come from the formula-based renderer (`slscan::synth`): a plane
//! with the two calibration spheres, projector covering the view. Run:
//! `cargo bench -p slscan --bench pipeline` (set `SLSCAN_BENCH_RUNS` to change the repeat).

use std::time::Instant;

use slscan::calibration::PinholeModel;
use slscan::raster::Raster;
use slscan::reconstruct::{ReconstructConfig, Reconstructor, StageTimes};
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
    println!(
        "set-up (render 12 frames, not timed below): {:.2} s",
        t.elapsed().as_secs_f64()
    );

    println!("| threads | constructor ms | fused wall ms | fused CPU ms | staged wall: phase | unwrap | triangulate | cloud | total ms | points |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| {
            let t = Instant::now();
            let mut config = ReconstructConfig::new(periods.clone());
            config.normals = true;
            let rec = Reconstructor::new(&camera, &projector, config).expect("set-up");
            let ctor_ms = t.elapsed().as_secs_f64() * 1e3;
            let mut fused = Vec::new();
            let mut fused_cpu = Vec::new();
            let mut points = 0;
            for _ in 0..runs {
                let (t, c) = (Instant::now(), cpu_s());
                let out = rec.reconstruct(&refs, None).expect("reconstruct");
                fused.push(t.elapsed().as_secs_f64() * 1e3);
                fused_cpu.push((cpu_s() - c) * 1e3);
                points = out.cloud.len();
                drop(out);
            }
            let mut stages: Vec<StageTimes> = Vec::new();
            for _ in 0..runs.min(3) {
                let (out, times) = rec.reconstruct_staged(&refs).expect("staged");
                drop(out);
                stages.push(times);
            }
            let m = |f: fn(&StageTimes) -> f64| median(stages.iter().map(f).collect()) * 1e3;
            let (p, u, tr, c) = (m(|s| s.phase_s), m(|s| s.unwrap_s), m(|s| s.triangulate_s), m(|s| s.cloud_s));
            println!(
                "| {threads} | {ctor_ms:.0} | {:.1} | {:.1} | {p:.1} | {u:.1} | {tr:.1} | {c:.1} | {:.1} | {points} |",
                median(fused),
                median(fused_cpu),
                p + u + tr + c
            );
        });
    }
}
