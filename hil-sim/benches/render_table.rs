//! The same workloads as `benches/render.rs`, printed as a table of wall
//! time AND process CPU time per call. On a shared machine the wall time
//! depends on what else runs; CPU time divided by the cores the work can
//! use (rayon over rows) estimates the wall time on idle cores.
//!
//! Run: `cargo bench -p hil-sim --bench render_table`.

use std::sync::Arc;
use std::time::Instant;

use hil_sim::twin::scenes::{built_in, Detail};
use hil_sim::twin::{
    BitDepth, CameraRays, Exposure, Fringe, Pattern, ProjectorTimeline, Renderer, SensorModel,
};

const DETAIL: Detail = Detail {
    camera: (1280, 800),
    projector: (1280, 800),
};

fn cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime only writes the timespec we pass.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

fn measure<T>(name: &str, iters: usize, mut f: impl FnMut() -> T) {
    std::hint::black_box(f());
    let (w0, c0) = (Instant::now(), cpu_s());
    for _ in 0..iters {
        std::hint::black_box(f());
    }
    let wall_ms = w0.elapsed().as_secs_f64() * 1e3 / iters as f64;
    let cpu_ms = (cpu_s() - c0) * 1e3 / iters as f64;
    println!(
        "| {name:<58} | {wall_ms:>9.1} | {cpu_ms:>9.1} | {:>16.1} |",
        cpu_ms / 2.0
    );
}

fn fringe(period_px: f64, angle_rad: f64, depth: BitDepth) -> Arc<Pattern> {
    let (w, h) = DETAIL.projector;
    Arc::new(Pattern::fringe(
        w,
        h,
        &Fringe {
            period_px,
            angle_rad,
            shift_rad: 0.0,
        },
        depth,
    ))
}

fn main() {
    // `cargo bench` passes --bench; `cargo test --benches` does not, and
    // should not spend a minute here.
    if !std::env::args().any(|a| a == "--bench") {
        println!("render_table: run with `cargo bench -p hil-sim --bench render_table`");
        return;
    }
    let (scene, rig) = built_in("bumpy-mesh", &DETAIL).expect("built-in scene");
    println!("1280x800 camera (1.02 MP), bumpy-mesh scene (100,352 triangles + wall), 1280x800 DMD; rayon threads: {}", rayon::current_num_threads());
    println!(
        "| {:<58} | {:>9} | {:>9} | {:>16} |",
        "stage", "wall ms", "CPU ms", "CPU ms / 2 cores"
    );
    println!(
        "|{}|{}|{}|{}|",
        "-".repeat(60),
        "-".repeat(11),
        "-".repeat(11),
        "-".repeat(18)
    );
    measure(
        "geometry set-up: rays, hits, shadows (once per pose)",
        3,
        || Renderer::new(&scene, &rig, 0, 0.0).expect("renderer"),
    );
    measure("camera rays alone (once per rig)", 3, || {
        CameraRays::new(&rig, 0, 1).expect("rays")
    });
    let rays = CameraRays::new(&rig, 0, 1).expect("rays");
    measure(
        "geometry set-up of a new pose on the rig's cached rays",
        3,
        || Renderer::posed(&scene, &rig, &rays, 0.0).expect("renderer"),
    );
    let renderer = Renderer::new(&scene, &rig, 0, 0.0).expect("renderer");
    let exposure = Exposure {
        start_s: 0.0,
        end_s: 1e-3,
    };
    let one = vec![ProjectorTimeline::single(
        fringe(32.0, 0.0, BitDepth::Eight),
        0.0,
        1e-3,
    )];
    let mono = SensorModel::mono12();
    measure(
        "per pattern: noisy 12-bit image (cached geometry)",
        5,
        || renderer.image(&one, exposure, &mono, 7).expect("image"),
    );
    measure(
        "per pattern: full frame (+clean, per-projector, truth)",
        5,
        || renderer.frame(&one, exposure, &mono, 7).expect("frame"),
    );
    let items: Vec<(Arc<Pattern>, [f32; 3])> = (0..24)
        .map(|m| {
            let led = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]][m % 3];
            (
                fringe(
                    [23.0, 18.0, 21.0][m % 3],
                    0.314 * (m / 3) as f64,
                    BitDepth::One,
                ),
                led,
            )
        })
        .collect();
    let long = vec![ProjectorTimeline::sequence(items, 0.0, 200e-6)];
    let long_exposure = Exposure {
        start_s: 0.0,
        end_s: 4.8e-3,
    };
    let colour = SensorModel::colour8();
    measure("24-pattern long exposure: noisy colour image", 3, || {
        renderer
            .image(&long, long_exposure, &colour, 3)
            .expect("image")
    });
}
