//! Triangulation through flat ports (issue 18) for every pixel of a 640x480 camera:
//! the set-up (undistorting every pixel) and one frame's triangulation, beside the
//! in-air row path the pipeline runs, printed as a table with the worst point error.
//!
//! `cargo bench -p slscan --bench flat_port` (runs: `FLAT_PORT_BENCH_RUNS=5`). A table
//! rather than criterion, as `icp.rs`: the shared two cores are held for seconds, not
//! minutes.

use std::time::{Duration, Instant};

use nalgebra::{Matrix3, Vector3};
use slscan::calibration::{Distortion, PinholeModel, Pose};
use slscan::triangulation::flat_port::{project, FlatPort, PortTriangulator};
use slscan::triangulation::{ColumnHits, Triangulator};

/// World -> device rotation of a device at `eye` looking at `target`, image y along +y.
fn look_at(eye: Vector3<f64>, target: Vector3<f64>) -> Pose {
    let z = (target - eye).normalize();
    let x = Vector3::y().cross(&z).normalize();
    let y = z.cross(&x);
    let rotation = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    Pose {
        rotation,
        translation_m: -(rotation * eye),
    }
}

/// The twin's head: a 640x480 camera (42 deg, k1 -0.08) at the origin and a 1280x800
/// projector (56 deg, k1 0.02) 0.12 m to its right, both aimed at 0.5 m.
fn head() -> (PinholeModel, PinholeModel) {
    let focal = |w: f64, fov_deg: f64| 0.5 * w / (0.5 * fov_deg.to_radians()).tan();
    let mut camera = PinholeModel::ideal(640, 480, focal(640.0, 42.0));
    camera.distortion = Distortion {
        k1: -0.08,
        k2: 0.02,
        ..Distortion::none()
    };
    let mut projector = PinholeModel::ideal(1280, 800, focal(1280.0, 56.0));
    projector.distortion = Distortion {
        k1: 0.02,
        ..Distortion::none()
    };
    projector.pose = look_at(Vector3::new(0.12, 0.0, 0.0), Vector3::new(0.0, 0.0, 0.5));
    (camera, projector)
}

fn timed<T>(runs: usize, mut f: impl FnMut() -> T) -> (T, Duration) {
    let mut best = Duration::MAX;
    let mut out = None;
    for _ in 0..runs {
        let start = Instant::now();
        out = Some(f());
        best = best.min(start.elapsed());
    }
    (out.expect("at least one run"), best)
}

fn main() {
    let runs: usize = std::env::var("FLAT_PORT_BENCH_RUNS")
        .map(|s| s.parse().expect("FLAT_PORT_BENCH_RUNS: a count"))
        .unwrap_or(5);
    let (camera, projector) = head();
    let port = FlatPort::thin(0.03, 1.33).expect("valid port");
    let (tri, set_up) = timed(runs, || {
        PortTriangulator::new(&camera, &port, &projector, &port).expect("valid ports")
    });
    // A plane 0.5 m out, tilted 0.3 rad about y: each pixel's true point and column.
    let normal = Vector3::new(0.3f64.sin(), 0.0, 0.3f64.cos());
    let (width, height) = tri.size();
    let mut truth = vec![None; width * height];
    let columns: Vec<f32> = (0..width * height)
        .map(|i| {
            let Some(ray) = tri.water_ray(i) else {
                return f32::NAN;
            };
            let s =
                (0.5 * normal.z - normal.dot(&ray.origin_m.coords)) / normal.dot(&ray.direction);
            let p = ray.at(s);
            match project(&projector, &port, &p) {
                Some(px) if projector.contains(&px) => {
                    truth[i] = Some(p);
                    px.x as f32
                }
                _ => f32::NAN,
            }
        })
        .collect();
    let lit = truth.iter().flatten().count();
    let (hits, through) = timed(runs, || tri.intersect_columns(&columns).expect("sizes"));
    let worst_m = hits
        .iter()
        .zip(&truth)
        .filter_map(|(h, t)| Some((h.as_ref()?.point_m - t.as_ref()?).norm()))
        .fold(0.0f64, f64::max);
    let found = hits.iter().flatten().count();

    let in_air = Triangulator::new(&camera, &projector);
    let (_, in_air_s) = timed(runs, || {
        let mut hits = ColumnHits::default();
        for row in columns.chunks(width).enumerate() {
            in_air.intersect_columns(row.0 * width, row.1, &mut hits);
        }
        hits
    });
    let threads = rayon::current_num_threads();
    println!("{width}x{height} camera, plane at 0.5 m through thin ports 30 mm out, n = 1.33; best of {runs}, {threads} threads");
    println!("| step | time | points |");
    println!("|---|---|---|");
    println!(
        "| port set-up (undistort every pixel) | {:.1} ms | |",
        ms(set_up)
    );
    println!(
        "| through the ports, one frame | {:.1} ms | {found} of {lit} lit, worst error {:.2e} m |",
        ms(through),
        worst_m
    );
    println!(
        "| in air (the pipeline's row path, 1 thread, for scale) | {:.1} ms | |",
        ms(in_air_s)
    );
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}
