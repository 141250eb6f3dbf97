//! The classical underwater restorer (`slscan::underwater`) on one frame of
//! 512x512 (seed 002's crop; its FP-DiffNet: 430 ms on an RTX 4090; issue
//! 18's goal: at most 1 s per frame on 2 cores) and one of 640x480 (the
//! simulated rig's camera).
//!
//! `cargo bench -p slscan --bench underwater`
//!
//! The frame is synthetic (no twin): a vertical fringe of 22 px over three
//! albedo bands, blurred by the T4 forward-scatter sigma at 0.5 m (5.2 px),
//! under a veil, with noise; the restorer's work does not depend on the
//! content. `restore` is the per-frame call of a restorer built once for
//! the size; `plan + restore` adds the set-up a single call pays.

use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use slscan::raster::Raster;
use slscan::underwater::{restore_classical, ClassicalRestorer, RestoreParams, Veil};

/// T4's 11 px/m of forward scatter over 0.47 m of water.
const SIGMA_PX: f64 = 5.17;

fn frame(w: usize, h: usize) -> Raster<f32> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(18);
    let noise = Normal::new(0.0f32, 0.004).expect("noise sigma");
    // Already blurred: the modulation a 22 px fringe keeps under sigma 5.2 px.
    let kept = (-2.0 * std::f64::consts::PI.powi(2) * SIGMA_PX.powi(2) / 22.0f64.powi(2)).exp();
    Raster::from_fn(w, h, |x, y| {
        let albedo = [0.4, 0.9, 0.6][(3 * y) / h];
        let t = std::f64::consts::TAU * x as f64 / 22.0;
        let v = 0.2 + 0.3 * albedo * (1.0 + kept * t.cos());
        v as f32 + noise.sample(&mut rng)
    })
}

fn restore(c: &mut Criterion) {
    let mut group = c.benchmark_group("underwater_restore");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));
    let params = RestoreParams::new(SIGMA_PX);
    for (w, h) in [(512, 512), (640, 480)] {
        let img = frame(w, h);
        let id = format!("{w}x{h}");
        group.throughput(Throughput::Elements((w * h) as u64));
        let restorer = ClassicalRestorer::new(w, h, params).expect("valid parameters");
        group.bench_with_input(BenchmarkId::new("restore", &id), &img, |b, img| {
            b.iter(|| restorer.restore(img, Veil::Floor).expect("restores"))
        });
        group.bench_with_input(BenchmarkId::new("plan + restore", &id), &img, |b, img| {
            b.iter(|| restore_classical(img, &params, Veil::Floor).expect("restores"))
        });
    }
    group.finish();
}

criterion_group!(benches, restore);
criterion_main!(benches);
