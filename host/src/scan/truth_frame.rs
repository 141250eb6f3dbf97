//! The frame a reconstructed cloud is compared with the twin's truth in.
//!
//! A head's cloud lives in the head frame *its calibration* defines: the
//! camera frame as the calibration estimated it. With the twin's true
//! devices that is the true camera frame; with an estimated calibration it
//! is off by a small rigid motion (e.g. a principal point a few pixels off
//! turns every ray by a fraction of a degree, and the calibrated projector
//! pose turns with it), which no user of the scanner can see or needs to:
//! it only fixes where the scanner's own coordinate axes are. So every
//! cloud is measured after the best rigid fit of its frame onto the truth
//! (point-to-plane ICP against the true surface, from the true camera
//! pose): shape and scale errors stay in the RMSE, and the fit itself (the
//! "frame offset") is reported. For the fused cloud one fit moves the whole
//! cloud, so an error in the head-to-head pose still shows. A scan that
//! reconstructs with the truth's own devices is measured in the true frames
//! unfitted ([`FrameFit::exact`]): there is nothing to fit, and on a scene
//! that pins fewer than six degrees of freedom (two spheres turn freely
//! about the line through their centres) a fit would only drift.

use nalgebra::{Isometry3, Vector3};

use super::metrics::Sample;
use crate::fusion::{self, IcpParams, IcpTarget};

/// Most cloud points used for the fit (a stride through the cloud): six
/// degrees of freedom are pinned long before this.
const FIT_POINTS: usize = 60_000;

/// How the estimated frame sits on the truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameFit {
    /// The estimated frame's pose from the twin world (use it where the true
    /// camera's `head_from_world` would go).
    pub frame_from_world: Isometry3<f64>,
    /// True frame <- estimated frame: the correction the fit applied.
    pub true_from_estimate: Isometry3<f64>,
}

impl FrameFit {
    /// No fit: the estimated frame is the true one (`true_from_world`).
    pub fn exact(true_from_world: &Isometry3<f64>) -> Self {
        FrameFit {
            frame_from_world: *true_from_world,
            true_from_estimate: Isometry3::identity(),
        }
    }

    /// Rotation of the fit, degrees.
    pub fn rotation_deg(&self) -> f64 {
        self.true_from_estimate.rotation.angle().to_degrees()
    }

    /// Translation of the fit, metres.
    pub fn translation_m(&self) -> f64 {
        self.true_from_estimate.translation.vector.norm()
    }
}

/// Fits `cloud` (estimated frame) onto `truth` (samples in the true frame,
/// `true_from_world`). Without a usable fit (too few points, no overlap) the
/// true frame is kept and a warning says so.
pub fn fit_frame(
    cloud: &[Vector3<f64>],
    truth: &[Sample],
    true_from_world: &Isometry3<f64>,
    what: &str,
    warnings: &mut Vec<String>,
) -> FrameFit {
    let keep = |true_from_estimate: Isometry3<f64>| FrameFit {
        frame_from_world: true_from_estimate.inverse() * true_from_world,
        true_from_estimate,
    };
    let stride = cloud.len().div_ceil(FIT_POINTS).max(1);
    let source: Vec<Vector3<f64>> = cloud.iter().step_by(stride).copied().collect();
    let target = fusion::PointCloud {
        points: truth.iter().map(|s| s.point_m).collect(),
        normals: Some(truth.iter().map(|s| s.normal).collect()),
        quality: None,
    };
    let fitted = IcpTarget::new(&target)
        .and_then(|t| t.register(&source, &Isometry3::identity(), &IcpParams::default()));
    match fitted {
        Ok(icp) => keep(icp.transform),
        Err(e) => {
            let warning = format!(
                "{what}: no rigid fit onto the truth ({e}); measured in the true camera frame"
            );
            warnings.push(warning);
            keep(Isometry3::identity())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_turned_copy_of_a_wavy_surface_is_fitted_back() {
        let mut truth = Vec::new();
        for i in 0..120 {
            for j in 0..120 {
                let (x, y) = (i as f64 * 1e-3 - 0.06, j as f64 * 1e-3 - 0.06);
                let z = 0.5 + 0.004 * (x * 90.0).sin() * (y * 70.0).cos();
                let dzdx = 0.004 * 90.0 * (x * 90.0).cos() * (y * 70.0).cos();
                let dzdy = -0.004 * 70.0 * (x * 90.0).sin() * (y * 70.0).sin();
                truth.push(Sample {
                    point_m: Vector3::new(x, y, z),
                    normal: Vector3::new(-dzdx, -dzdy, 1.0).normalize(),
                });
            }
        }
        // The estimated frame is the true one turned by 0.3 deg and moved 1 mm.
        let estimate_from_true = Isometry3::new(
            Vector3::new(0.0, 1e-3, 0.0),
            Vector3::new(0.3f64.to_radians(), 0.0, 0.0),
        );
        let cloud: Vec<Vector3<f64>> = truth
            .iter()
            .map(|s| (estimate_from_true * nalgebra::Point3::from(s.point_m)).coords)
            .collect();
        let mut warnings = Vec::new();
        let fit = fit_frame(
            &cloud,
            &truth,
            &Isometry3::identity(),
            "test",
            &mut warnings,
        );
        assert!(warnings.is_empty());
        let err = fit.true_from_estimate * estimate_from_true;
        assert!(err.rotation.angle().to_degrees() < 1e-3, "{err:?}");
        assert!(err.translation.vector.norm() < 1e-6, "{err:?}");
        assert!((fit.rotation_deg() - 0.3).abs() < 1e-3);
    }
}
