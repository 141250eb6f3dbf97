//! The stereo head at a common stereo camera size, 1624x1240: rectification set-up
//! (`StereoReconstructor::new`: each left pixel undistorted and rotated, each rectified
//! right pixel's source) and one capture's reconstruction (`reconstruct`: bicubic
//! resampling of the right coordinate map, matching on four rectified rows per left
//! pixel, triangulation, cloud with normals), printed as a table for 1 and 2 rayon
//! threads.
//!
//! The coordinate maps are exact and synthetic (no twin): two cameras 160 mm apart
//! converging at 0.5 m with lens distortion, a tilted plane filling both views, each
//! pixel given the projector column of its surface point, so almost every left pixel is
//! matched (the most work a capture can give). A table rather than criterion: the
//! set-up takes a second and two shared cores should not be held for minutes. Run:
//! `SLSCAN_BENCH_RUNS=5 cargo bench -p slscan --bench stereo`.

use std::time::{Duration, Instant};

use nalgebra::{Matrix3, Point3, Vector3};
use slscan::calibration::{CameraModel, Distortion, PinholeModel, Pose, StereoHead};
use slscan::raster::Raster;
use slscan::stereo::{StereoConfig, StereoReconstructor};
use slscan::unwrap::PixelStatus;

const WIDTH: u32 = 1624;
const HEIGHT: u32 = 1240;

/// A camera at `eye` looking at `target`, y down, 42 degrees across, with the twin's lens.
fn looking(eye: Point3<f64>, target: Point3<f64>) -> CameraModel {
    let z = (target - eye).normalize();
    let x = Vector3::new(0.0, 1.0, 0.0).cross(&z).normalize();
    let y = z.cross(&x);
    let rotation = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    let focal_px = f64::from(WIDTH) / 2.0 / 21f64.to_radians().tan();
    PinholeModel {
        distortion: Distortion {
            k1: -0.08,
            k2: 0.02,
            p1: 0.0002,
            p2: -0.0001,
            k3: 0.0,
        },
        pose: Pose {
            rotation,
            translation_m: -(rotation * eye.coords),
        },
        ..PinholeModel::ideal(WIDTH, HEIGHT, focal_px)
    }
}

/// Projector column and modulation maps of a camera looking at the plane
/// `z = 0.5 + 0.2 x + 0.1 y`, lit by a 1280-column projector at the origin.
fn maps(c: &CameraModel) -> (Raster<f32>, Raster<f32>) {
    let n = Vector3::new(-0.2, -0.1, 1.0);
    let (w, h) = (c.width_px as usize, c.height_px as usize);
    let u = Raster::from_fn(w, h, |x, y| {
        let Some(ray) = c.pixel_ray(x as f64, y as f64) else {
            return f32::NAN;
        };
        let s = (0.5 - n.dot(&ray.origin_m.coords)) / n.dot(&ray.direction);
        let p = ray.origin_m + ray.direction * s;
        (1100.0 * p.x / p.z + 640.0) as f32
    });
    (u, Raster::filled(w, h, 0.5))
}

fn timed<T>(f: impl FnOnce() -> T) -> (T, Duration) {
    let t0 = Instant::now();
    let out = f();
    (out, t0.elapsed())
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn main() {
    let runs: usize = std::env::var("SLSCAN_BENCH_RUNS")
        .map(|s| s.parse().expect("SLSCAN_BENCH_RUNS: a count"))
        .unwrap_or(5);
    let target = Point3::new(0.0, 0.0, 0.5);
    let head = StereoHead {
        name: "bench".into(),
        left: looking(Point3::new(-0.08, 0.0, 0.0), target),
        right: looking(Point3::new(0.08, 0.0, 0.0), target),
    };
    let (lu, lb) = maps(&head.left);
    let (ru, rb) = maps(&head.right);
    let config = StereoConfig::new(20.0, StereoConfig::coordinate_noise_px(0.01, 4, 20.0));
    println!(
        "stereo head {WIDTH}x{HEIGHT}, distorted lenses, synthetic plane; median of {runs} runs"
    );
    println!(
        "{:>7} {:>10} {:>12} {:>10} {:>9} {:>14}",
        "threads", "set-up ms", "capture ms", "min ms", "valid %", "Mpixel/s"
    );
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        pool.install(|| {
            let (stereo, setup) =
                timed(|| StereoReconstructor::new(&head, config.clone()).expect("valid head"));
            let mut times = Vec::new();
            let mut valid = 0;
            for _ in 0..runs {
                let (rec, t) = timed(|| stereo.reconstruct(&lu, &lb, &ru, &rb).expect("sizes"));
                valid = rec.count(PixelStatus::Valid);
                times.push(t);
            }
            times.sort();
            let median = times[times.len() / 2];
            let pixels = f64::from(WIDTH * HEIGHT);
            println!(
                "{threads:>7} {:>10.1} {:>12.1} {:>10.1} {:>9.1} {:>14.1}",
                ms(setup),
                ms(median),
                ms(times[0]),
                100.0 * valid as f64 / pixels,
                pixels / median.as_secs_f64() / 1e6
            );
        });
    }
}
