//! Camera calibration solve beside OpenCV's `calibrateCamera`, in one run on the same
//! corners: 15 views of an 11 x 8-corner board (25 mm pitch) seen by a 1280x1024 camera
//! with distortion, corners projected from known poses plus 0.1 px Gaussian noise. The
//! peer is `benches/peers/calibrate_opencv.py` (`pip install opencv-python-headless`;
//! skipped with a line when `cv2` is not importable). Both sides fix k3 at zero; times are
//! the best of `SLSCAN_BENCH_RUNS` (default 5) solves, detection not included; errors are
//! against the true camera.
//!
//! `SLSCAN_BENCH_RUNS=5 cargo bench -p slscan --bench calibration`.

use std::path::{Path, PathBuf};

#[path = "common/peer.rs"]
mod peer;
use peer::run_peer;
use std::time::Instant;

use nalgebra::{Point2, Point3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use slscan::calibration::bundle::{calibrate_camera, CameraCalibrationOptions};
use slscan::calibration::zhang::PlanarView;
use slscan::calibration::{Distortion, Intrinsics, PinholeModel, Pose};
use slscan::io::npy::encode_npy_f64;

const WIDTH: u32 = 1280;
const HEIGHT: u32 = 1024;
const CORNERS: (usize, usize) = (11, 8);
const PITCH_M: f64 = 0.025;
const VIEWS: usize = 15;
const NOISE_PX: f64 = 0.1;

/// One side's camera and time.
struct Solved {
    intrinsics: Intrinsics,
    distortion: Distortion,
    rms_px: f64,
    best_s: f64,
}

fn main() {
    let runs: usize = std::env::var("SLSCAN_BENCH_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5);
    let truth = true_camera();
    let views = render_views(&truth);
    let mut best_s = f64::INFINITY;
    let mut ours = None;
    for _ in 0..runs {
        let t = Instant::now();
        let c = calibrate_camera(
            &views,
            (WIDTH, HEIGHT),
            &CameraCalibrationOptions::default(),
        )
        .expect("calibration of the synthetic views");
        best_s = best_s.min(t.elapsed().as_secs_f64());
        ours = Some(c);
    }
    let ours = ours.expect("at least one run");
    let ours = Solved {
        intrinsics: ours.intrinsics,
        distortion: ours.distortion,
        rms_px: ours.rms_px,
        best_s,
    };
    println!(
        "{VIEWS} views of {}x{} corners, {WIDTH}x{HEIGHT}, noise {NOISE_PX} px, k3 fixed, best of {runs}",
        CORNERS.0, CORNERS.1
    );
    println!("| side | solve ms | rms px | fx err | fy err | cx err | cy err | k1 err | k2 err | p1 err | p2 err | ratio |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    print_row("slscan (Zhang + LM)", &ours, &truth, 1.0);
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("peers_calibration");
    match opencv_side(&dir, &views, runs) {
        Ok((version, peer)) => {
            let ratio = peer.best_s / ours.best_s;
            print_row(
                &format!("OpenCV {version} calibrateCamera"),
                &peer,
                &truth,
                ratio,
            );
        }
        Err(why) => println!("| OpenCV | not run: {why} |"),
    }
    println!("ratio: the side's solve time over slscan's (above 1: slscan is faster); errors: estimate - truth (px, or the coefficient)");
}

/// The camera the corners come from.
fn true_camera() -> PinholeModel {
    PinholeModel {
        width_px: WIDTH,
        height_px: HEIGHT,
        intrinsics: Intrinsics {
            fx: 1400.0,
            fy: 1402.5,
            cx: 645.3,
            cy: 508.7,
        },
        distortion: Distortion {
            k1: -0.12,
            k2: 0.05,
            p1: 0.0008,
            p2: -0.0006,
            k3: 0.0,
        },
        pose: Pose::identity(),
    }
}

/// Views from random board poses (tilted up to ~35 deg, 0.45-0.75 m away) whose every
/// corner lands in the image, with Gaussian corner noise.
fn render_views(camera: &PinholeModel) -> Vec<PlanarView> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let noise = Normal::new(0.0, NOISE_PX).expect("noise");
    let half = (
        (CORNERS.0 - 1) as f64 * PITCH_M / 2.0,
        (CORNERS.1 - 1) as f64 * PITCH_M / 2.0,
    );
    let board: Vec<Point2<f64>> = (0..CORNERS.1)
        .flat_map(|j| {
            (0..CORNERS.0).map(move |i| Point2::new(i as f64 * PITCH_M, j as f64 * PITCH_M))
        })
        .collect();
    let mut views = Vec::new();
    while views.len() < VIEWS {
        let rotation = Rotation3::from_scaled_axis(Vector3::new(
            rng.random_range(-0.6..0.6),
            rng.random_range(-0.6..0.6),
            rng.random_range(-0.3..0.3),
        ));
        let centre = Vector3::new(
            rng.random_range(-0.05..0.05),
            rng.random_range(-0.04..0.04),
            rng.random_range(0.45..0.75),
        );
        let image: Option<Vec<Point2<f64>>> = board
            .iter()
            .map(|b| {
                let p = rotation * Vector3::new(b.x - half.0, b.y - half.1, 0.0) + centre;
                let px = camera.project(&Point3::from(p))?;
                camera.contains(&px).then(|| {
                    Point2::new(px.x + noise.sample(&mut rng), px.y + noise.sample(&mut rng))
                })
            })
            .collect();
        if let Some(image_px) = image {
            views.push(PlanarView {
                board_m: board.clone(),
                image_px,
            });
        }
    }
    views
}

/// OpenCV's solve on the same corners, through the peer script.
fn opencv_side(dir: &Path, views: &[PlanarView], runs: usize) -> Result<(String, Solved), String> {
    std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
    let n = views[0].board_m.len();
    let board: Vec<f64> = views
        .iter()
        .flat_map(|v| v.board_m.iter().flat_map(|b| [b.x, b.y, 0.0]))
        .collect();
    let image: Vec<f64> = views
        .iter()
        .flat_map(|v| v.image_px.iter().flat_map(|p| [p.x, p.y]))
        .collect();
    let write = |name: &str, bytes: Vec<u8>| {
        std::fs::write(dir.join(name), bytes).map_err(|e| format!("{name}: {e}"))
    };
    write("board.npy", encode_npy_f64(&[views.len(), n, 3], &board))?;
    write("image.npy", encode_npy_f64(&[views.len(), n, 2], &image))?;
    let job = serde_json::json!({ "width": WIDTH, "height": HEIGHT });
    write("job.json", job.to_string().into_bytes())?;
    let r = run_peer(
        "cv2",
        "opencv-python-headless",
        "calibrate_opencv.py",
        dir,
        runs,
    )?;
    let f = |key: &str| r[key].as_f64().ok_or(format!("peer's report has no {key}"));
    Ok((
        r["opencv"].as_str().unwrap_or("?").to_owned(),
        Solved {
            intrinsics: Intrinsics {
                fx: f("fx")?,
                fy: f("fy")?,
                cx: f("cx")?,
                cy: f("cy")?,
            },
            distortion: Distortion {
                k1: f("k1")?,
                k2: f("k2")?,
                p1: f("p1")?,
                p2: f("p2")?,
                k3: f("k3")?,
            },
            rms_px: f("rms_px")?,
            best_s: f("best_s")?,
        },
    ))
}

fn print_row(side: &str, s: &Solved, truth: &PinholeModel, ratio: f64) {
    let (k, t) = (&s.intrinsics, &truth.intrinsics);
    let (d, td) = (&s.distortion, &truth.distortion);
    println!(
        "| {side} | {:.2} | {:.4} | {:+.3} | {:+.3} | {:+.3} | {:+.3} | {:+.5} | {:+.5} | {:+.6} | {:+.6} | {ratio:.2}x |",
        s.best_s * 1e3,
        s.rms_px,
        k.fx - t.fx,
        k.fy - t.fy,
        k.cx - t.cx,
        k.cy - t.cy,
        d.k1 - td.k1,
        d.k2 - td.k2,
        d.p1 - td.p1,
        d.p2 - td.p2,
    );
}
