//! The stereo pipeline on exact synthetic coordinate maps: a known plane seen by two
//! converging cameras, each pixel given the projector column of its true surface point.

use nalgebra::{Matrix3, Point3, Vector3};

use super::*;
use crate::calibration::{CameraModel, Distortion, PinholeModel, Pose};

/// A camera at `eye` looking at `target`, y down.
fn looking(eye: Point3<f64>, target: Point3<f64>, w: u32, h: u32, focal_px: f64) -> CameraModel {
    let z = (target - eye).normalize();
    let x = Vector3::new(0.0, 1.0, 0.0).cross(&z).normalize();
    let y = z.cross(&x);
    let rotation = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    PinholeModel {
        pose: Pose {
            rotation,
            translation_m: -(rotation * eye.coords),
        },
        ..PinholeModel::ideal(w, h, focal_px)
    }
}

/// Cameras 160 mm apart converging at 0.5 m, in a world frame that is not the left
/// camera's (so the world pose is exercised too).
fn head(w: u32, h: u32) -> StereoHead {
    let target = Point3::new(0.01, 0.005, 0.5);
    StereoHead {
        name: "S".into(),
        left: looking(Point3::new(-0.08, 0.003, 0.0), target, w, h, 1.1 * w as f64),
        right: looking(
            Point3::new(0.08, -0.002, 0.004),
            target,
            w,
            h,
            1.12 * w as f64,
        ),
    }
}

/// The plane `n . p = d`: tilted, 0.5 m away.
fn plane() -> (Vector3<f64>, f64) {
    let n = Vector3::new(0.25, -0.15, -1.0).normalize();
    (n, n.dot(&Vector3::new(0.0, 0.0, 0.5)))
}

/// The projector column of a world point: an ideal 1280 px projector at the origin.
fn column_px(p: &Point3<f64>) -> f64 {
    1100.0 * p.x / p.z + 640.0
}

/// Where a camera pixel's ray meets the plane.
fn on_plane(c: &CameraModel, x: usize, y: usize) -> Option<Point3<f64>> {
    let ray = c.pixel_ray(x as f64, y as f64)?;
    let (n, d) = plane();
    let s = (d - n.dot(&ray.origin_m.coords)) / n.dot(&ray.direction);
    (s > 0.0).then(|| ray.origin_m + ray.direction * s)
}

/// Exact coordinate and modulation maps of a camera on the plane.
fn maps(c: &CameraModel, modulation: f32) -> (Raster<f32>, Raster<f32>) {
    let (w, h) = (c.width_px as usize, c.height_px as usize);
    let u = Raster::from_fn(w, h, |x, y| {
        on_plane(c, x, y).map_or(f32::NAN, |p| column_px(&p) as f32)
    });
    (u, Raster::filled(w, h, modulation))
}

fn config() -> StereoConfig {
    StereoConfig::new(20.0, StereoConfig::coordinate_noise_px(0.01, 4, 20.0))
}

fn check_plane(head: &StereoHead, tolerance_m: f64) {
    let rec = StereoReconstructor::new(head, config()).unwrap();
    let (lu, lb) = maps(&head.left, 0.5);
    let (ru, rb) = maps(&head.right, 0.4);
    let out = rec.reconstruct(&lu, &lb, &ru, &rb).unwrap();
    let (w, h) = lu.size();
    let (mut worst, mut worst_depth, mut valid, mut sum2) = (0.0f64, 0.0f64, 0, 0.0);
    for y in 0..h {
        for x in 0..w {
            let p = out.pixels.get(y * w + x);
            if p.status != PixelStatus::Valid {
                continue;
            }
            valid += 1;
            let truth = on_plane(&head.left, x, y).unwrap();
            let got = Point3::new(p.point_m[0], p.point_m[1], p.point_m[2]).cast::<f64>();
            worst = worst.max((got - truth).norm());
            sum2 += (got - truth).norm_squared();
            let depth = head.left.pose.apply(&truth).z;
            worst_depth = worst_depth.max((f64::from(p.depth_m) - depth).abs());
            assert!(p.sigma_m > 0.0 && p.sigma_m < 1e-3, "sigma {}", p.sigma_m);
            assert!((p.modulation - 0.4).abs() < 1e-6);
        }
    }
    println!(
        "{w}x{h}: {valid} valid, point error {:.3} um RMS, {:.3} um worst; worst depth \
         error {:.3} um",
        (sum2 / valid as f64).sqrt() * 1e6,
        worst * 1e6,
        worst_depth * 1e6
    );
    // The right camera sees most of what the left one does.
    assert!(valid > w * h * 3 / 4, "{valid} valid of {}", w * h);
    assert_eq!(out.cloud.len(), valid);
    assert!(worst < tolerance_m, "worst point error {worst} m");
    assert!(
        worst_depth < tolerance_m,
        "worst depth error {worst_depth} m"
    );
}

// The matching interpolates the right map linearly three times (bilinear resampling
// onto the rectified grid, then along the row), and the maps are f32: on this plane
// that leaves the worst pixel 1.0 um off at 320x240 and 0.7 um at 640x480 (RMS about
// 0.4 um). Decoded coordinates are noisier than this by two orders of magnitude.
#[test]
fn a_plane_seen_by_ideal_cameras_is_recovered_to_sub_micron() {
    check_plane(&head(640, 480), 1e-6);
}

#[test]
fn a_plane_seen_through_distorting_lenses_is_recovered_to_sub_micron() {
    let mut h = head(640, 480);
    h.left.distortion = Distortion {
        k1: -0.08,
        k2: 0.02,
        p1: 0.0002,
        p2: -0.0001,
        k3: 0.0,
    };
    h.right.distortion = Distortion {
        k1: -0.06,
        k2: 0.01,
        ..Distortion::none()
    };
    check_plane(&h, 1e-6);
}

#[test]
fn pixels_without_a_coordinate_are_masked_and_those_without_a_match_unreliable() {
    let head = head(80, 60);
    // At 80 px wide one camera pixel spans about 12 projector columns.
    let mut c = config();
    c.max_step_px = 40.0;
    let rec = StereoReconstructor::new(&head, c).unwrap();
    let (mut lu, mut lb) = maps(&head.left, 0.5);
    let (ru, rb) = maps(&head.right, 0.5);
    lu.data[30 * 80 + 40] = f32::NAN;
    lb.data[30 * 80 + 41] = 0.01;
    // A coordinate the right image never shows.
    lu.data[30 * 80 + 42] = 1e6;
    let out = rec.reconstruct(&lu, &lb, &ru, &rb).unwrap();
    let status = |x: usize| out.pixels.status[30 * 80 + x];
    assert_eq!(status(40), PixelStatus::Masked);
    assert_eq!(status(41), PixelStatus::Masked);
    assert_eq!(status(42), PixelStatus::Unreliable);
    assert_eq!(status(43), PixelStatus::Valid);
    assert!(out.pixels.point_m[0][30 * 80 + 42].is_nan());
}

#[test]
fn bad_heads_configurations_and_map_sizes_are_refused() {
    let good = head(80, 60);
    let swapped = StereoHead {
        left: good.right,
        right: good.left,
        ..good.clone()
    };
    assert!(matches!(
        StereoReconstructor::new(&swapped, config()),
        Err(StereoError::Swapped { .. })
    ));
    let target = Point3::new(0.0, 0.0, 0.5);
    let stacked = StereoHead {
        left: looking(Point3::new(0.0, -0.08, 0.0), target, 80, 60, 90.0),
        right: looking(Point3::new(0.0, 0.08, 0.0), target, 80, 60, 90.0),
        ..good.clone()
    };
    assert!(matches!(
        StereoReconstructor::new(&stacked, config()),
        Err(StereoError::NotSideBySide { .. })
    ));
    let same = StereoHead {
        right: good.left,
        ..good.clone()
    };
    assert_eq!(
        StereoReconstructor::new(&same, config()).unwrap_err(),
        StereoError::NoBaseline
    );
    let mut nan = good.clone();
    nan.right.intrinsics.fx = f64::NAN;
    assert!(matches!(
        StereoReconstructor::new(&nan, config()),
        Err(StereoError::Calibration {
            camera: Side::Right,
            field: "fx",
            ..
        })
    ));
    let mut skew = good.clone();
    skew.left.pose.rotation[(0, 1)] += 0.1;
    assert!(matches!(
        StereoReconstructor::new(&skew, config()),
        Err(StereoError::NotARotation {
            camera: Side::Left,
            ..
        })
    ));
    let mut c = config();
    c.depth_range_m = (1.0, 0.5);
    assert!(matches!(
        StereoReconstructor::new(&good, c),
        Err(StereoError::Config { .. })
    ));
    let rec = StereoReconstructor::new(&good, config()).unwrap();
    let (lu, lb) = maps(&good.left, 0.5);
    let small = Raster::filled(80, 59, 0.5f32);
    assert_eq!(
        rec.reconstruct(&lu, &lb, &small, &lb).unwrap_err(),
        StereoError::MapSize {
            map: "right_u",
            camera: Side::Right,
            expected: (80, 60),
            got: (80, 59),
        }
    );
}
