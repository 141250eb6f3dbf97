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

/// Angle in radians of the rotation taking `a` to `b`.
pub fn rotation_angle_between(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let rel = a.transpose() * b;
    ((rel.trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos()
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
}
