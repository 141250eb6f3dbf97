//! Checks of the calibration that need no ground truth, from what fusing
//! two heads reveals: how far ICP had to move the calibrated head-to-head
//! pose, and whether the registered clouds still disagree in shape (a
//! rigid pose error leaves none; a wrong focal length, principal point or
//! projector model bends one cloud against the other). Past a threshold
//! each says what is likely wrong and by how much.
//!
//! (A third check, the reprojection of phase-derived correspondences into
//! the calibrated projector, needs fringes in both directions: with column
//! fringes only each camera ray meets exactly one projector plane and
//! there is no residual to test.)

use crate::fusion::{FusionError, IcpResult, ShapeAgreement};

/// ICP rotation past which the calibrated head-to-head pose is called off:
/// about 3x the head-to-head error of a 12-view twin calibration (0.097 deg).
pub const POSE_ROTATION_LIMIT_DEG: f64 = 0.3;
/// The same for ICP's translation at the overlap (3x 0.67 mm).
pub const POSE_TRANSLATION_LIMIT_M: f64 = 2e-3;
/// Systematic shape disagreement past which a head's model is called off,
/// metres: 3x what a correct calibration leaves on the twin (8.7 um on
/// large-part, from normal estimation and sampling).
pub const SHAPE_LIMIT_M: f64 = 30e-6;
/// ICP's overlap residual over what the heads' predicted noise gives
/// (`hypot` of their RMS sigmas), past which the heads disagree beyond
/// their noise (a correct calibration gives 0.85 on large-part).
pub const OVERLAP_RATIO_LIMIT: f64 = 1.5;

/// What the checks found, for the report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelfCheck {
    /// ICP's rotation of the calibrated pose, degrees.
    pub pose_rotation_deg: f64,
    /// ICP's translation at the overlap, metres.
    pub pose_translation_m: f64,
    /// Systematic shape disagreement after registration, metres (`None`
    /// when the overlap was too small to tell).
    pub shape_rms_m: Option<f64>,
    /// What noise alone gives for that figure, metres.
    pub shape_noise_m: Option<f64>,
    /// ICP's point-to-plane residual over the overlap, metres.
    pub overlap_rmse_m: f64,
    /// What the heads' predicted per-point noise gives for it, metres.
    pub predicted_overlap_m: f64,
    /// The likely cause.
    pub verdict: Verdict,
}

/// The likely state of the calibration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Both checks pass.
    Consistent,
    /// The heads agree in shape, but ICP moved the pose past its limit.
    HeadToHeadPose,
    /// The heads disagree in shape: a camera's intrinsics or a projector model.
    HeadModel,
}

impl Verdict {
    /// For the report.
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Consistent => "consistent",
            Verdict::HeadToHeadPose => "head-to-head pose off",
            Verdict::HeadModel => "camera intrinsics or projector model off",
        }
    }
}

/// The checks of a two-head fusion; `predicted_m` is each head's RMS
/// predicted per-point sigma.
pub fn check(
    icp: &IcpResult,
    agreement: Option<&ShapeAgreement>,
    predicted_m: [f64; 2],
) -> SelfCheck {
    let shape_rms_m = agreement.map(|a| a.systematic_rms_m);
    let predicted_overlap_m = predicted_m[0].hypot(predicted_m[1]);
    let pose_off = icp.rotation_correction_deg > POSE_ROTATION_LIMIT_DEG
        || icp.translation_correction_m > POSE_TRANSLATION_LIMIT_M;
    let beyond_noise = icp.overlap_rmse_m > OVERLAP_RATIO_LIMIT * predicted_overlap_m;
    let verdict = match shape_rms_m {
        Some(s) if s > SHAPE_LIMIT_M => Verdict::HeadModel,
        _ if beyond_noise => Verdict::HeadModel,
        _ if pose_off => Verdict::HeadToHeadPose,
        _ => Verdict::Consistent,
    };
    SelfCheck {
        pose_rotation_deg: icp.rotation_correction_deg,
        pose_translation_m: icp.translation_correction_m,
        shape_rms_m,
        shape_noise_m: agreement.map(|a| a.noise_rms_m),
        overlap_rmse_m: icp.overlap_rmse_m,
        predicted_overlap_m,
        verdict,
    }
}

/// The warning a check gives (`None` when the calibration is consistent).
pub fn warning(c: &SelfCheck) -> Option<String> {
    let pose = format!(
        "{:.2} deg / {:.2} mm",
        c.pose_rotation_deg,
        c.pose_translation_m * 1e3
    );
    let shape = c
        .shape_rms_m
        .map_or("n/a".into(), |s| format!("{:.0} um", s * 1e6));
    let noise = c
        .shape_noise_m
        .map_or("n/a".into(), |s| format!("{:.0} um", s * 1e6));
    match c.verdict {
        Verdict::Consistent => None,
        Verdict::HeadModel => Some(format!(
            "calibration inconsistent: after the best rigid fit the two heads still disagree in shape by \
             {shape} RMS (noise alone: {noise}; limit {:.0} um) and their overlap residual is {:.0} um \
             against {:.0} um their noise predicts, so a head's camera intrinsics (focal length, \
             principal point, distortion) or its projector model is likely off; ICP turned the \
             calibrated head-to-head pose by {pose} to compensate. The fused cloud is distorted: \
             recalibrate the heads",
            SHAPE_LIMIT_M * 1e6,
            c.overlap_rmse_m * 1e6,
            c.predicted_overlap_m * 1e6
        )),
        Verdict::HeadToHeadPose => Some(format!(
            "calibration inconsistent: ICP had to move the calibrated head-to-head pose by {pose} \
             (limit {POSE_ROTATION_LIMIT_DEG} deg / {:.0} mm), while the heads agree in shape to {shape}: \
             the head-to-head pose of the calibration is likely off by that much (the fused cloud uses \
             ICP's pose); recalibrate the head-to-head pose",
            POSE_TRANSLATION_LIMIT_M * 1e3
        )),
    }
}

/// Why fusing the heads failed, in a user's words.
pub fn fusion_failure(e: &FusionError) -> String {
    match e {
        FusionError::Diverged { .. } => format!(
            "fusion failed: {e}. The calibrated head-to-head pose and the two clouds disagree by more \
             than ICP may correct: the calibration is likely wrong (a camera's intrinsics, a projector \
             model or the head-to-head pose). The per-head clouds are written, each in head A's frame \
             by the calibrated pose; no scan.ply"
        ),
        FusionError::NoOverlap { .. } | FusionError::Degenerate { .. } => format!(
            "fusion failed: {e}. The heads share too little surface to register (or it is flat or \
             cylindrical), or the calibrated pose puts them far apart. The per-head clouds are \
             written; no scan.ply"
        ),
        other => format!("fusion failed: {other}. The per-head clouds are written; no scan.ply"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Isometry3;

    /// The twin's large-part: 93.8 / 94.3 um predicted per head.
    const PREDICTED: [f64; 2] = [93.8e-6, 94.3e-6];

    fn icp(deg: f64, m: f64) -> IcpResult {
        IcpResult {
            transform: Isometry3::identity(),
            correction: Isometry3::identity(),
            rotation_correction_deg: deg,
            translation_correction_m: m,
            overlap_rmse_m: 1e-4,
            fitness: 0.9,
            inliers: 1000,
            iterations: 5,
            converged: true,
        }
    }

    fn agreement(systematic_m: f64) -> ShapeAgreement {
        ShapeAgreement {
            cells: 600,
            cell_mean_rms_m: systematic_m.hypot(8e-6),
            noise_rms_m: 8e-6,
            systematic_rms_m: systematic_m,
        }
    }

    #[test]
    fn each_case_names_its_cause_and_its_size() {
        // The twin's large-part with its true calibration.
        let ok = check(&icp(0.0014, 7e-6), Some(&agreement(8.7e-6)), PREDICTED);
        assert_eq!(ok.verdict, Verdict::Consistent);
        assert!(warning(&ok).is_none());
        // Camera fx of head A 0.5 % off (measured: 1.57 deg / 2.95 mm, 104 um).
        let fx = check(&icp(1.575, 2.95e-3), Some(&agreement(104e-6)), PREDICTED);
        assert_eq!(fx.verdict, Verdict::HeadModel);
        let w = warning(&fx).unwrap();
        assert!(
            w.contains("intrinsics") && w.contains("104 um") && w.contains("1.57 deg / 2.95 mm"),
            "{w}"
        );
        // A pose error alone.
        let pose = check(&icp(0.8, 1e-3), Some(&agreement(9e-6)), PREDICTED);
        assert_eq!(pose.verdict, Verdict::HeadToHeadPose);
        assert!(warning(&pose).unwrap().contains("0.80 deg / 1.00 mm"));
        // Too small an overlap to judge the shape: the pose check still runs.
        assert_eq!(
            check(&icp(0.1, 5e-3), None, PREDICTED).verdict,
            Verdict::HeadToHeadPose
        );
        assert_eq!(
            check(&icp(0.1, 1e-4), None, PREDICTED).verdict,
            Verdict::Consistent
        );
        // A residual far beyond the heads' noise names the heads' models.
        let mut noisy = icp(0.1, 1e-4);
        noisy.overlap_rmse_m = 300e-6;
        let c = check(&noisy, None, PREDICTED);
        assert_eq!(c.verdict, Verdict::HeadModel);
        assert!(warning(&c).unwrap().contains("300 um against 133 um"));
    }
}
