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

use crate::fusion::{FusionError, IcpResult, MultiViewResult, ShapeAgreement};

/// ICP rotation past which the calibrated head-to-head pose is called off:
/// about 3x the head-to-head error of a 12-view twin calibration (0.097 deg).
pub const POSE_ROTATION_LIMIT_DEG: f64 = 0.3;
/// The same for ICP's translation at the overlap (3x 0.67 mm).
pub const POSE_TRANSLATION_LIMIT_M: f64 = 2e-3;
/// Systematic shape disagreement past which a head's model is called off,
/// metres: 3x what a correct calibration leaves on the twin (8.7 um on
/// large-part, from normal estimation and sampling).
pub const SHAPE_LIMIT_M: f64 = 30e-6;
/// The shape limit of a pair among three or more heads, metres. The twin's
/// blade ring leaves more systematic disagreement with a correct calibration
/// than large-part does (10-25 um per pair multiplexed, up to 38 um
/// sequential: the decoded phase of its steep flanks is biased), so the
/// two-head limit would call a true calibration off; 60 um still catches a
/// registration settled in the wrong place (94 um), while a head's focal
/// length 0.5 % off shows in its pose correction (0.56 deg) instead.
pub const VIEWS_SHAPE_LIMIT_M: f64 = 60e-6;
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

/// One overlapping pair of a multi-head registration, checked as two
/// heads are: its residual against the pair's predicted noise and its
/// shape disagreement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairCheck {
    /// The two heads (indices, lower first).
    pub heads: (usize, usize),
    /// Registration's point-to-plane residual over their overlap, metres.
    pub overlap_rmse_m: f64,
    /// What the two heads' predicted per-point noise gives for it, metres.
    pub predicted_overlap_m: f64,
    /// Systematic shape disagreement, metres (`None`: overlap too small).
    pub shape_rms_m: Option<f64>,
    /// Past a limit: the heads' models disagree.
    pub off: bool,
}

/// The checks of a registration of three or more heads: each head's
/// correction of its calibrated pose (head A's frame <- the head's; head A
/// stays fixed) and each overlapping pair's agreement.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewsCheck {
    /// Per head: (rotation degrees, translation metres at its points) that
    /// registration added to the calibrated pose.
    pub corrections: Vec<(f64, f64)>,
    /// Per overlapping pair.
    pub pairs: Vec<PairCheck>,
    /// The likely cause.
    pub verdict: Verdict,
}

/// The checks of a multi-head registration; `predicted_m` is each head's
/// RMS predicted per-point sigma. A pair whose shape disagrees past
/// [`VIEWS_SHAPE_LIMIT_M`] or whose residual is past 1.5x its noise names
/// the heads' models; otherwise a head whose pose moved past the two-head
/// limits (0.3 deg / 2 mm) names the calibrated head poses.
pub fn check_views(result: &MultiViewResult, predicted_m: &[f64]) -> ViewsCheck {
    let noise = |h: usize| predicted_m.get(h).copied().unwrap_or(f64::NAN);
    let pairs: Vec<PairCheck> = result
        .pairs
        .iter()
        .filter(|p| p.inliers > 0)
        .map(|p| {
            let predicted_overlap_m = noise(p.heads.0).hypot(noise(p.heads.1));
            let shape_rms_m = p.agreement.map(|a| a.systematic_rms_m);
            let off = shape_rms_m.is_some_and(|s| s > VIEWS_SHAPE_LIMIT_M)
                || p.overlap_rmse_m > OVERLAP_RATIO_LIMIT * predicted_overlap_m;
            PairCheck {
                heads: p.heads,
                overlap_rmse_m: p.overlap_rmse_m,
                predicted_overlap_m,
                shape_rms_m,
                off,
            }
        })
        .collect();
    let corrections: Vec<(f64, f64)> = result
        .views
        .iter()
        .map(|v| (v.rotation_correction_deg, v.translation_correction_m))
        .collect();
    let pose_off = corrections
        .iter()
        .any(|&(deg, m)| deg > POSE_ROTATION_LIMIT_DEG || m > POSE_TRANSLATION_LIMIT_M);
    let verdict = if pairs.iter().any(|p| p.off) {
        Verdict::HeadModel
    } else if pose_off {
        Verdict::HeadToHeadPose
    } else {
        Verdict::Consistent
    };
    ViewsCheck {
        corrections,
        pairs,
        verdict,
    }
}

/// The warning a multi-head check gives (`None` when consistent), naming
/// the heads past the limits (`names[h]` is head h's letter).
pub fn views_warning(c: &ViewsCheck, names: &[&str]) -> Option<String> {
    let name = |h: usize| names.get(h).copied().unwrap_or("?");
    match c.verdict {
        Verdict::Consistent => None,
        Verdict::HeadModel => {
            let pairs: Vec<String> = c
                .pairs
                .iter()
                .filter(|p| p.off)
                .map(|p| {
                    let shape = p
                        .shape_rms_m
                        .map_or("n/a".into(), |s| format!("{:.0} um", s * 1e6));
                    format!(
                        "{}-{} overlap residual {:.0} um against {:.0} um their noise predicts, \
                         shape disagreement {shape}",
                        name(p.heads.0),
                        name(p.heads.1),
                        p.overlap_rmse_m * 1e6,
                        p.predicted_overlap_m * 1e6
                    )
                })
                .collect();
            Some(format!(
                "calibration inconsistent: after registration some heads still disagree beyond \
                 their noise ({}; limits {OVERLAP_RATIO_LIMIT}x the noise, {:.0} um of shape), so a \
                 head's camera intrinsics or projector model, or a registration that settled in \
                 the wrong place, is likely: the fused cloud is distorted there; recalibrate the heads",
                pairs.join("; "),
                VIEWS_SHAPE_LIMIT_M * 1e6
            ))
        }
        Verdict::HeadToHeadPose => {
            let heads: Vec<String> = c
                .corrections
                .iter()
                .enumerate()
                .filter(|(_, &(deg, m))| {
                    deg > POSE_ROTATION_LIMIT_DEG || m > POSE_TRANSLATION_LIMIT_M
                })
                .map(|(h, &(deg, m))| format!("{} by {deg:.2} deg / {:.2} mm", name(h), m * 1e3))
                .collect();
            Some(format!(
                "calibration inconsistent: registration had to move the calibrated pose of head {} \
                 (limit {POSE_ROTATION_LIMIT_DEG} deg / {:.0} mm), while the overlaps agree within \
                 their noise: those heads' poses in the rig file are likely off by that much, or \
                 their camera intrinsics or projector model bend their clouds and registration \
                 turned them to compensate (the fused cloud uses the registered poses); recalibrate \
                 those heads",
                heads.join(", head "),
                POSE_TRANSLATION_LIMIT_M * 1e3
            ))
        }
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

    /// A ring-4 registration with the given per-head corrections (deg, m)
    /// and per-pair (heads, overlap RMSE m, shape m).
    fn ring(corrections: &[(f64, f64)], pairs: &[((usize, usize), f64, f64)]) -> MultiViewResult {
        use crate::fusion::multiview::{PairReport, ViewReport};
        MultiViewResult {
            views: corrections
                .iter()
                .map(|&(deg, m)| ViewReport {
                    pose: Isometry3::identity(),
                    correction: Isometry3::identity(),
                    rotation_correction_deg: deg,
                    translation_correction_m: m,
                    fitness: 0.5,
                })
                .collect(),
            pairs: pairs
                .iter()
                .map(|&(heads, rmse, shape)| PairReport {
                    heads,
                    inliers: 10_000,
                    overlap_rmse_m: rmse,
                    agreement: Some(agreement(shape)),
                })
                .collect(),
            iterations: 8,
            converged: true,
            last_step_rotation_deg: 0.0,
            last_step_translation_m: 0.0,
        }
    }

    /// The twin's ring-4, multiplexed: 61-70 um predicted per head.
    const RING: [f64; 4] = [65e-6, 66e-6, 60e-6, 62e-6];

    #[test]
    fn views_name_the_pair_or_the_head_past_a_limit() {
        // Measured on ring-4 multiplexed with the true devices.
        let true_ring = ring(
            &[(0.0, 0.0), (0.010, 16e-6), (0.019, 32e-6), (0.015, 30e-6)],
            &[
                ((0, 1), 69e-6, 10e-6),
                ((0, 3), 85e-6, 25e-6),
                ((1, 2), 75e-6, 17e-6),
                ((2, 3), 68e-6, 12e-6),
            ],
        );
        let c = check_views(&true_ring, &RING);
        assert_eq!(c.verdict, Verdict::Consistent);
        assert!(views_warning(&c, &["A", "B", "C", "D"]).is_none());
        // Head B's camera fx +0.5 %: registration turns B by 0.56 deg.
        let mut bent = true_ring.clone();
        bent.views[1].rotation_correction_deg = 0.555;
        bent.views[1].translation_correction_m = 635e-6;
        let c = check_views(&bent, &RING);
        assert_eq!(c.verdict, Verdict::HeadToHeadPose);
        let w = views_warning(&c, &["A", "B", "C", "D"]).unwrap();
        assert!(w.contains("head B by 0.56 deg / 0.64 mm"), "{w}");
        // A registration settled in the wrong place: one pair bent and
        // past its noise.
        let mut wrong = true_ring.clone();
        wrong.pairs[1].overlap_rmse_m = 237e-6;
        wrong.pairs[1].agreement = Some(agreement(94e-6));
        let c = check_views(&wrong, &RING);
        assert_eq!(c.verdict, Verdict::HeadModel);
        assert!(c.pairs[1].off && !c.pairs[0].off);
        let w = views_warning(&c, &["A", "B", "C", "D"]).unwrap();
        assert!(
            w.contains("A-D overlap residual 237 um against 90 um"),
            "{w}"
        );
        // A pair without inliers at the final gate is not judged.
        let mut empty = true_ring;
        empty.pairs[2].inliers = 0;
        empty.pairs[2].overlap_rmse_m = f64::NAN;
        assert_eq!(check_views(&empty, &RING).pairs.len(), 3);
    }
}
