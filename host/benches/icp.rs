//! Fusion timing on the synthetic two-head scene: normals, ICP and merge,
//! with the recovered pose error, printed as a table; beside it, in the same
//! run and on the same points, Open3D's normals and point-to-plane ICP
//! (`benches/peers/icp_open3d.py`, run with `python3`; skipped with a line
//! when `open3d` is not importable: `pip install open3d`).
//!
//! `cargo bench -p slscan --bench icp` (sizes: `ICP_BENCH_POINTS=100000,1000000`,
//! depth noise: `ICP_BENCH_NOISE_UM=20`, neighbours per normal: `ICP_BENCH_K=10`,
//! repeats, best time kept: `SLSCAN_BENCH_RUNS=3`).
//! A table rather than criterion: one 1M-point registration takes seconds,
//! and criterion's ten-sample minimum would hold two shared cores for minutes.
//! Both sides use every core (rayon; Open3D's OpenMP).

use std::path::{Path, PathBuf};

#[path = "common/peer.rs"]
mod peer;
use peer::run_peer;
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Matrix4, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use slscan::fusion::synthetic::{perturbed, pose_error, two_head_scene, TwoHeadScene};
use slscan::fusion::{
    estimate_normals, merge_clouds, DuplicateRule, IcpParams, IcpResult, IcpTarget, MergeParams,
};
use slscan::io::npy::encode_npy_f64;

/// One side's figures for one scene.
struct Row {
    normals: Duration,
    tree: Option<Duration>,
    icp: Duration,
    merge: Option<Duration>,
    iterations: Option<usize>,
    transform: Isometry3<f64>,
    rmse_m: f64,
    fitness: f64,
}

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
    let runs: usize = std::env::var("SLSCAN_BENCH_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    let params = IcpParams {
        initial_gate_m: 0.02,
        final_gate_m: 0.0015,
        ..IcpParams::default()
    };
    println!(
        "depth noise {:.1} um, normals from {k} neighbours, start error 2 deg / 5 mm, \
         gates {} -> {} mm, best of {runs}",
        noise_m * 1e6,
        params.initial_gate_m * 1e3,
        params.final_gate_m * 1e3
    );
    println!(
        "| pts/head | side | normals s | kd-tree s | icp s | normals + tree + icp s | merge s | iters | rot err deg | trans err um | rmse um | fitness | ratio |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for points in sizes {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let scene = two_head_scene(points, noise_m, || StandardNormal.sample(&mut rng));
        let initial = perturbed(
            &scene.b_to_a_m,
            &scene.centre_m,
            &Vector3::new(0.3, -0.8, 0.5),
            2.0,
            &Vector3::new(1.0, -1.0, 0.5),
            0.005,
        );
        let ours = slscan_side(&scene, &initial, &params, k, noise_m, runs);
        let ours_total = total(&ours);
        print_row(points, "slscan", &ours, &scene, "1.00x".into());
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("peers_icp_{points}"));
        match open3d_side(&dir, &scene, &initial, &params, (k, noise_m), runs) {
            Ok((version, setups)) => {
                for (name, peer) in setups {
                    let ratio = format!("{:.2}x", total(&peer) / ours_total);
                    let side = format!("Open3D {version}, {name}");
                    print_row(points, &side, &peer, &scene, ratio);
                }
            }
            Err(why) => println!("| {points} | Open3D | not run: {why} |"),
        }
    }
    println!(
        "ratio: the side's normals + kd-tree + ICP time over slscan's (above 1: slscan is faster); \
         Open3D's rmse is its inlier RMS point-to-point distance, slscan's the point-to-plane RMS"
    );
}

/// slscan's normals, kd-tree, ICP (best of `runs`) and one merge.
fn slscan_side(
    scene: &TwoHeadScene,
    initial: &Isometry3<f64>,
    params: &IcpParams,
    k: usize,
    noise_m: f64,
    runs: usize,
) -> Row {
    let mut a = scene.a.clone();
    let (mut t_normals, mut t_tree, mut t_icp) = (Duration::MAX, Duration::MAX, Duration::MAX);
    let mut result: Option<IcpResult> = None;
    for _ in 0..runs {
        let (normals, t) =
            timed(|| estimate_normals(&scene.a.points, k, &Vector3::zeros()).unwrap());
        t_normals = t_normals.min(t);
        a.normals = Some(normals);
        let (target, t) = timed(|| IcpTarget::new(&a).unwrap());
        t_tree = t_tree.min(t);
        let (r, t) = timed(|| target.register(&scene.b.points, initial, params).unwrap());
        t_icp = t_icp.min(t);
        result = Some(r);
    }
    let result = result.expect("at least one run");
    let b = scene.b.transformed(&result.transform);
    let merge = MergeParams {
        // About the sampling pitch of head A's 75 x 100 mm.
        radius_m: (0.075 * 0.1 / scene.a.len() as f64).sqrt(),
        rule: DuplicateRule::WeightedMean,
        default_sigma_m: noise_m.max(1e-6) as f32,
    };
    let (_, t_merge) = timed(|| merge_clouds(&a, &b, &merge).unwrap());
    Row {
        normals: t_normals,
        tree: Some(t_tree),
        icp: t_icp,
        merge: Some(t_merge),
        iterations: Some(result.iterations),
        transform: result.transform,
        rmse_m: result.overlap_rmse_m,
        fitness: result.fitness,
    }
}

/// Open3D's normals and ICP set-ups on the same points, through the peer script:
/// its version and one row per set-up.
fn open3d_side(
    dir: &Path,
    scene: &TwoHeadScene,
    initial: &Isometry3<f64>,
    params: &IcpParams,
    (k, noise_m): (usize, f64),
    runs: usize,
) -> Result<(String, Vec<(String, Row)>), String> {
    std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
    let write = |name: &str, bytes: Vec<u8>| {
        std::fs::write(dir.join(name), bytes).map_err(|e| format!("{name}: {e}"))
    };
    write("target.npy", npy_points(&scene.a.points))?;
    write("source.npy", npy_points(&scene.b.points))?;
    let m = initial.to_homogeneous();
    write(
        "initial.npy",
        encode_npy_f64(&[4, 4], m.transpose().as_slice()),
    )?;
    let job = serde_json::json!({
        "k": k,
        "initial_gate_m": params.initial_gate_m,
        "final_gate_m": params.final_gate_m,
        "noise_m": noise_m,
    });
    write("job.json", job.to_string().into_bytes())?;
    let report = run_peer("open3d", "open3d", "icp_open3d.py", dir, runs)?;
    let normals = report["normals_s"]
        .as_f64()
        .map(Duration::from_secs_f64)
        .ok_or("peer's report has no normals_s")?;
    let setups = report["setups"]
        .as_object()
        .ok_or("peer's report has no setups")?;
    let rows = setups
        .iter()
        .map(|(name, setup)| {
            let icp = setup["icp_s"]
                .as_f64()
                .map(Duration::from_secs_f64)
                .ok_or(format!("set-up {name} has no icp_s"))?;
            let matrix: Vec<f64> = setup["transform"]
                .as_array()
                .into_iter()
                .flatten()
                .flat_map(|r| r.as_array().into_iter().flatten().map(|v| v.as_f64()))
                .collect::<Option<_>>()
                .ok_or(format!("set-up {name}: transform is not numbers"))?;
            if matrix.len() != 16 {
                return Err(format!("set-up {name}: transform is not 4x4"));
            }
            let row = Row {
                normals,
                tree: None,
                icp,
                merge: None,
                iterations: None,
                transform: isometry(&Matrix4::from_row_slice(&matrix)),
                rmse_m: setup["inlier_rmse_m"].as_f64().unwrap_or(f64::NAN),
                fitness: setup["fitness"].as_f64().unwrap_or(f64::NAN),
            };
            Ok((name.clone(), row))
        })
        .collect::<Result<Vec<_>, String>>()?;
    Ok((report["open3d"].as_str().unwrap_or("?").to_owned(), rows))
}

/// The rigid transform of a 4x4 matrix (its rotation re-orthonormalised).
fn isometry(m: &Matrix4<f64>) -> Isometry3<f64> {
    let r = m.fixed_view::<3, 3>(0, 0).into_owned();
    let rotation = nalgebra::UnitQuaternion::from_matrix(&r);
    Isometry3::from_parts(
        nalgebra::Translation3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]),
        rotation,
    )
}

fn total(row: &Row) -> f64 {
    (row.normals + row.tree.unwrap_or_default() + row.icp).as_secs_f64()
}

fn print_row(points: usize, side: &str, row: &Row, scene: &TwoHeadScene, ratio: String) {
    let (rot, trans) = pose_error(&row.transform, &scene.b_to_a_m, &scene.centre_m);
    let opt =
        |d: Option<Duration>| d.map_or("(in icp)".into(), |d| format!("{:.3}", d.as_secs_f64()));
    println!(
        "| {points} | {side} | {:.3} | {} | {:.3} | {:.3} | {} | {} | {:.2e} | {:.3} | {:.2} | {:.3} | {ratio} |",
        row.normals.as_secs_f64(),
        opt(row.tree),
        row.icp.as_secs_f64(),
        total(row),
        row.merge.map_or("-".into(), |d| format!("{:.3}", d.as_secs_f64())),
        row.iterations.map_or("-".into(), |n| n.to_string()),
        rot,
        trans * 1e6,
        row.rmse_m * 1e6,
        row.fitness,
    );
}

/// `.npy` of an (N, 3) float64 array.
fn npy_points(points: &[Vector3<f64>]) -> Vec<u8> {
    let flat: Vec<f64> = points.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    encode_npy_f64(&[points.len(), 3], &flat)
}

fn timed<T>(f: impl FnOnce() -> T) -> (T, Duration) {
    let t0 = Instant::now();
    let out = f();
    (out, t0.elapsed())
}
