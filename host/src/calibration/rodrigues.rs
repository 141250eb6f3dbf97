//! Rodrigues vectors (axis times angle, radians) for poses: the minimal,
//! singularity-free-near-identity rotation parameters the optimisers use.

use nalgebra::{Matrix3, Rotation3, Vector3};

use super::Pose;

/// Rotation matrix of Rodrigues vector `rvec`.
pub fn rotation_from_rodrigues(rvec: &Vector3<f64>) -> Matrix3<f64> {
    *Rotation3::from_scaled_axis(*rvec).matrix()
}

/// Rodrigues vector of rotation matrix `r` (re-orthonormalised first).
pub fn rodrigues_from_rotation(r: &Matrix3<f64>) -> Vector3<f64> {
    Rotation3::from_matrix(r).scaled_axis()
}

/// Pose from a Rodrigues vector and a translation in metres.
pub fn pose_from_rodrigues(rvec: &Vector3<f64>, translation_m: &Vector3<f64>) -> Pose {
    Pose {
        rotation: rotation_from_rodrigues(rvec),
        translation_m: *translation_m,
    }
}

/// Angle in radians of the rotation taking `a` to `b`: `atan2(sin, cos)`
/// from the relative rotation's skew part and trace, which resolves tiny
/// angles to ~1e-16 rad (`acos` of the trace alone cannot tell angles below
/// ~2e-8 rad from zero: one rounding of the trace is worth 2.1e-8).
pub fn rotation_angle_between(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let rel = a.transpose() * b;
    let skew = Vector3::new(
        rel[(2, 1)] - rel[(1, 2)],
        rel[(0, 2)] - rel[(2, 0)],
        rel[(1, 0)] - rel[(0, 1)],
    );
    (skew.norm() / 2.0).atan2((rel.trace() - 1.0) / 2.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips() {
        for rvec in [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(0.3, -0.2, 0.1),
            Vector3::new(-2.0, 1.0, 0.5),
        ] {
            let r = rotation_from_rodrigues(&rvec);
            assert!(
                (rodrigues_from_rotation(&r) - rvec).norm() < 1e-12,
                "{rvec}"
            );
        }
        let a = rotation_from_rodrigues(&Vector3::new(0.0, 0.0, 0.25));
        assert!((rotation_angle_between(&Matrix3::identity(), &a) - 0.25).abs() < 1e-12);
    }

    #[test]
    fn angle_between_resolves_tiny_and_large_angles() {
        let base = rotation_from_rodrigues(&Vector3::new(0.4, -1.1, 0.7));
        for angle in [0.0, 1e-12, 3e-9, 1e-4, 1.0, 3.0] {
            let turn = rotation_from_rodrigues(&(Vector3::new(0.6, 0.0, 0.8) * angle));
            let got = rotation_angle_between(&base, &(base * turn));
            assert!(
                (got - angle).abs() < 1e-15 + 1e-12 * angle,
                "{angle}: {got}"
            );
        }
    }
}
