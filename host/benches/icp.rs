//! Fusion timing on the synthetic two-head scene: normals, ICP and merge,
//! with the recovered pose error, printed as a table.
//!
//! `cargo bench -p slscan --bench icp` (sizes: `ICP_BENCH_POINTS=100000,1000000`,
//! depth noise: `ICP_BENCH_NOISE_UM=20`, neighbours per normal: `ICP_BENCH_K=10`).
//! A table rather than criterion: one 1M-point registration takes seconds,
//! and criterion's ten-sample minimum would hold two shared cores for minutes.

use std::time::{Duration, Instant};

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use slscan::fusion::synthetic::{perturbed, pose_error, two_head_scene};
use slscan::fusion::{
    estimate_normals, merge_clouds, DuplicateRule, IcpParams, IcpTarget, MergeParams,
};

fn main() {
    let sizes: Vec<usize> = std::env::var("ICP_BENCH_POINTS")
        .unwrap_or_else(|_| "100000,1000000".into())
        .split(',')
        .map(|s| {
            s.trim()
                .parse()
                .expect("ICP_BENCH_POINTS: comma-separated counts")
        })
        .collect();
    let noise_m = std::env::var("ICP_BENCH_NOISE_UM")
        .map(|s| s.parse::<f64>().expect("ICP_BENCH_NOISE_UM: micrometres"))
        .unwrap_or(20.0)
        * 1e-6;
    let k: usize = std::env::var("ICP_BENCH_K")
        .map(|s| s.parse().expect("ICP_BENCH_K: neighbours"))
        .unwrap_or(10);
    println!(
        "depth noise {:.1} um, normals from {k} neighbours, start error 2 deg / 5 mm",
        noise_m * 1e6
    );
    println!(
        "{:>10} {:>9} {:>9} {:>9} {:>9} {:>5} {:>11} {:>9} {:>8} {:>8}",
        "pts/head",
        "normals",
        "kd-tree",
        "icp",
        "merge",
        "iters",
        "rot err deg",
        "trans um",
        "rmse um",
        "fitness"
    );
    for points in sizes {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut scene = two_head_scene(points, noise_m, || StandardNormal.sample(&mut rng));
        let (normals, t_normals) =
            timed(|| estimate_normals(&scene.a.points, k, &Vector3::zeros()).unwrap());
        scene.a.normals = Some(normals);
        let initial = perturbed(
            &scene.b_to_a_m,
            &scene.centre_m,
            &Vector3::new(0.3, -0.8, 0.5),
            2.0,
            &Vector3::new(1.0, -1.0, 0.5),
            0.005,
        );
        let params = IcpParams {
            initial_gate_m: 0.02,
            final_gate_m: 0.0015,
            ..IcpParams::default()
        };
        let (target, t_tree) = timed(|| IcpTarget::new(&scene.a).unwrap());
        let (result, t_icp) =
            timed(|| target.register(&scene.b.points, &initial, &params).unwrap());
        let (rot, trans) = pose_error(&result.transform, &scene.b_to_a_m, &scene.centre_m);
        let b = scene.b.transformed(&result.transform);
        let merge = MergeParams {
            // About the sampling pitch of head A's 75 x 100 mm.
            radius_m: (0.075 * 0.1 / points as f64).sqrt(),
            rule: DuplicateRule::WeightedMean,
            default_sigma_m: noise_m.max(1e-6) as f32,
        };
        let (_, t_merge) = timed(|| merge_clouds(&scene.a, &b, &merge).unwrap());
        println!(
            "{:>10} {:>8.3}s {:>8.3}s {:>8.3}s {:>8.3}s {:>5} {:>11.2e} {:>9.3} {:>8.2} {:>8.3}",
            points,
            t_normals.as_secs_f64(),
            t_tree.as_secs_f64(),
            t_icp.as_secs_f64(),
            t_merge.as_secs_f64(),
            result.iterations,
            rot,
            trans * 1e6,
            result.overlap_rmse_m * 1e6,
            result.fitness
        );
    }
}

fn timed<T>(f: impl FnOnce() -> T) -> (T, Duration) {
    let t0 = Instant::now();
    let out = f();
    (out, t0.elapsed())
}
