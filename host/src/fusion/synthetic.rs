//! A two-head scene with known ground truth, for fusion tests and benches.
//!
//! A wavy height field 0.3 m in front of head A (whose camera frame is the
//! world frame), 120 x 100 mm. Head A sees x in [-60, 15] mm, head B sees
//! x in [-15, 60] mm, so they overlap on a 30 mm strip. Head B's cloud is
//! given in B's own camera frame; [`TwoHeadScene::b_to_a_m`] is the truth
//! ICP must recover. Sample positions follow the R2 quasi-random sequence
//! (even coverage without a grid that both heads would share), with
//! different offsets per head so no two samples coincide.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use super::PointCloud;

/// Distance from head A's camera to the scene, metres.
pub const STANDOFF_M: f64 = 0.3;

/// Two partial clouds and the transform between their frames.
#[derive(Debug, Clone)]
pub struct TwoHeadScene {
    /// Head A's cloud, world (= camera A) frame.
    pub a: PointCloud,
    /// Head B's cloud, camera B frame.
    pub b: PointCloud,
    /// True transform from camera B's frame to camera A's.
    pub b_to_a_m: Isometry3<f64>,
    /// Centre of the scene (world frame), where errors are measured.
    pub centre_m: Vector3<f64>,
}

/// Height of the surface above the plane z = [`STANDOFF_M`], metres, at
/// lateral position (x, y) in metres. Three non-commensurate waves and a
/// tilt: enough structure to pin all six degrees of freedom, wavelengths
/// long enough (45-80 mm) that a 5 mm start error stays in the basin.
pub fn height_m(x_m: f64, y_m: f64) -> f64 {
    use std::f64::consts::TAU;
    0.006 * (TAU * x_m / 0.060 + 0.4).sin() * (TAU * y_m / 0.045).cos()
        + 0.004 * (TAU * (0.6 * x_m + 0.8 * y_m) / 0.080).sin()
        + 0.1 * x_m
}

/// The fixed head-B-to-head-A transform of the synthetic rig.
pub fn true_b_to_a() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(0.15, 0.01, 0.005),
        UnitQuaternion::from_scaled_axis(Vector3::new(0.02, -0.46, 0.03)),
    )
}

/// Builds the scene with `points_per_head` points per head and depth noise
/// `noise_sigma_m` along each camera ray; `standard_normal` draws N(0, 1)
/// samples (the caller owns the random generator). Every point's quality is
/// `noise_sigma_m` (none when it is 0).
pub fn two_head_scene(
    points_per_head: usize,
    noise_sigma_m: f64,
    mut standard_normal: impl FnMut() -> f64,
) -> TwoHeadScene {
    let b_to_a_m = true_b_to_a();
    let sensor_b = b_to_a_m.translation.vector;
    let mut sample = |x_range: (f64, f64), offset: usize, sensor: Vector3<f64>| {
        (0..points_per_head)
            .map(|n| {
                let (u, v) = r2(n + offset);
                let x = x_range.0 + u * (x_range.1 - x_range.0);
                let y = -0.05 + v * 0.1;
                let p = Vector3::new(x, y, STANDOFF_M + height_m(x, y));
                p + noise_sigma_m * standard_normal() * (p - sensor).normalize()
            })
            .collect::<Vec<_>>()
    };
    let a_points = sample((-0.060, 0.015), 0, Vector3::zeros());
    let b_world = sample((-0.015, 0.060), 7_654_321, sensor_b);
    let to_b = b_to_a_m.inverse();
    let b_points = b_world
        .iter()
        .map(|p| to_b.transform_point(&Point3::from(*p)).coords)
        .collect();
    // A noise-free scene has no meaningful sigma (and 0 is not a valid one).
    let quality = (noise_sigma_m > 0.0).then(|| vec![noise_sigma_m as f32; points_per_head]);
    TwoHeadScene {
        a: PointCloud {
            points: a_points,
            normals: None,
            quality: quality.clone(),
        },
        b: PointCloud {
            points: b_points,
            normals: None,
            quality,
        },
        b_to_a_m,
        centre_m: Vector3::new(0.0, 0.0, STANDOFF_M),
    }
}

/// `truth` with an error of `rotation_deg` about `axis` through `centre_m`
/// and a shift of `translation_m` along `direction`, both in the world frame.
pub fn perturbed(
    truth: &Isometry3<f64>,
    centre_m: &Vector3<f64>,
    axis: &Vector3<f64>,
    rotation_deg: f64,
    direction: &Vector3<f64>,
    translation_m: f64,
) -> Isometry3<f64> {
    let rotation = UnitQuaternion::from_scaled_axis(axis.normalize() * rotation_deg.to_radians());
    let about_centre = Isometry3::from_parts(
        Translation3::from(centre_m - rotation * centre_m + direction.normalize() * translation_m),
        rotation,
    );
    about_centre * truth
}

/// Error of `estimate` against `truth` as (rotation in degrees, translation
/// of the scene centre in metres).
pub fn pose_error(
    estimate: &Isometry3<f64>,
    truth: &Isometry3<f64>,
    centre_m: &Vector3<f64>,
) -> (f64, f64) {
    let delta = estimate * truth.inverse();
    let moved = delta.transform_point(&Point3::from(*centre_m)).coords;
    (
        delta.rotation.angle().to_degrees(),
        (moved - centre_m).norm(),
    )
}

/// The n-th point of the R2 low-discrepancy sequence in [0, 1)^2.
fn r2(n: usize) -> (f64, f64) {
    const G: f64 = 1.324_717_957_244_746;
    let (a1, a2) = (1.0 / G, 1.0 / (G * G));
    let n = n as f64;
    ((0.5 + a1 * n).fract(), (0.5 + a2 * n).fract())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_is_consistent_with_its_truth() {
        let scene = two_head_scene(2000, 0.0, || 0.0);
        let b_in_a = scene.b.transformed(&scene.b_to_a_m);
        for p in b_in_a.points.iter().chain(&scene.a.points) {
            assert!((p.z - STANDOFF_M - height_m(p.x, p.y)).abs() < 1e-12);
        }
        assert!(b_in_a.points.iter().all(|p| p.x >= -0.015 && p.x < 0.06));
    }

    #[test]
    fn perturbation_has_the_asked_size() {
        let t = true_b_to_a();
        let c = Vector3::new(0.0, 0.0, STANDOFF_M);
        let p = perturbed(
            &t,
            &c,
            &Vector3::new(1.0, 2.0, 3.0),
            2.0,
            &Vector3::x(),
            0.005,
        );
        let (rot, trans) = pose_error(&p, &t, &c);
        assert!((rot - 2.0).abs() < 1e-9 && (trans - 0.005).abs() < 1e-12);
    }
}
