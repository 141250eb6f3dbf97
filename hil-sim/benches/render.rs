//! Frame render time of the digital twin: 1 MP camera looking at a
//! 100k-triangle mesh (ray casting + shadow tests once per pose, then
//! pattern look-ups per frame), and a 24-pattern long exposure (seed 001).
//!
//! Run: `cargo bench -p hil-sim --bench render`.

use std::sync::Arc;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use hil_sim::twin::scenes::{built_in, Detail};
use hil_sim::twin::{
    render_exposure, BitDepth, Exposure, Fringe, Pattern, ProjectorTimeline, Renderer, SensorModel,
};
use rand::SeedableRng;

const DETAIL: Detail = Detail {
    camera: (1280, 800),
    projector: (1280, 800),
};

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

fn bench_mesh_frame(c: &mut Criterion) {
    let (scene, rig) = built_in("bumpy-mesh", &DETAIL).expect("built-in scene");
    let pixels = (DETAIL.camera.0 * DETAIL.camera.1) as u64;
    let exposure = Exposure {
        start_s: 0.0,
        end_s: 1e-3,
    };
    let timeline = vec![ProjectorTimeline::single(
        fringe(32.0, 0.0, BitDepth::Eight),
        0.0,
        1e-3,
    )];
    let sensor = SensorModel::mono12();
    let mut g = c.benchmark_group("1MP_100k_triangles");
    g.sample_size(10);
    g.throughput(Throughput::Elements(pixels));
    g.bench_function("geometry_setup (rays + shadows, once per pose)", |b| {
        b.iter(|| Renderer::new(&scene, &rig, 0, 0.0).expect("renderer"))
    });
    let renderer = Renderer::new(&scene, &rig, 0, 0.0).expect("renderer");
    g.bench_function(
        "per_pattern_image (cached geometry, noisy 12-bit image only)",
        |b| {
            b.iter(|| {
                renderer
                    .image(&timeline, exposure, &sensor, 7)
                    .expect("image")
            })
        },
    );
    g.bench_function(
        "per_pattern_frame (+ clean, per-projector clean, truth)",
        |b| {
            b.iter(|| {
                renderer
                    .frame(&timeline, exposure, &sensor, 7)
                    .expect("frame")
            })
        },
    );
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    g.bench_function("render_exposure (setup + frame)", |b| {
        b.iter(|| {
            render_exposure(&scene, &rig, 0, &timeline, exposure, &sensor, &mut rng).expect("frame")
        })
    });
    g.finish();
}

fn bench_long_exposure(c: &mut Criterion) {
    let (scene, rig) = built_in("bumpy-mesh", &DETAIL).expect("built-in scene");
    let pixels = (DETAIL.camera.0 * DETAIL.camera.1) as u64;
    // Seed 001: 8 directions x R/G/B binary patterns at 5 kHz, one 4.8 ms exposure.
    let items: Vec<(Arc<Pattern>, [f32; 3])> = (0..24)
        .map(|m| {
            let led = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]][m % 3];
            let period = [23.0, 18.0, 21.0][m % 3];
            (fringe(period, 0.314 * (m / 3) as f64, BitDepth::One), led)
        })
        .collect();
    let timeline = vec![ProjectorTimeline::sequence(items, 0.0, 200e-6)];
    let exposure = Exposure {
        start_s: 0.0,
        end_s: 24.0 * 200e-6,
    };
    let sensor = SensorModel::colour8();
    let renderer = Renderer::new(&scene, &rig, 0, 0.0).expect("renderer");
    let mut g = c.benchmark_group("1MP_long_exposure_24_binary_patterns");
    g.sample_size(10);
    g.throughput(Throughput::Elements(pixels));
    g.bench_function(
        "frame (cached geometry, defocus + 24 look-ups, colour sensor)",
        |b| {
            b.iter(|| {
                renderer
                    .frame(&timeline, exposure, &sensor, 3)
                    .expect("frame")
            })
        },
    );
    g.finish();
}

criterion_group!(benches, bench_mesh_frame, bench_long_exposure);
criterion_main!(benches);
