//! Fusion of three or four heads: every head's pose refined at once by
//! joint point-to-plane ICP from the calibrated poses
//! ([`crate::fusion::register_views`], head A fixed), then the heads merged
//! one by one into head A's frame. Without a registration (the heads'
//! overlaps do not link them to head A, or ICP diverges) the scan keeps the
//! per-head results and says why, as two heads do.

use nalgebra::Isometry3;

use super::clouds::{from_fusion, to_fusion, transformed, with_head_attributes};
use super::fuse::{fuse_params, HeadsFused};
use super::{self_check, ScanConfig, ScanError, HEAD_NAMES};
use crate::calibration::RigCalibration;
use crate::fusion::{merge_clouds_indexed, register_views, MultiViewParams, MultiViewResult};
use crate::point_cloud::PointCloud;
use crate::reconstruct::Reconstruction;

/// Registers and merges the heads of `recons` (three or more, each in its
/// own calibrated frame) starting from the calibration's head poses.
pub fn fuse_views(
    recons: &[Reconstruction],
    calibration: &RigCalibration,
    config: &ScanConfig,
    warnings: &mut Vec<String>,
) -> Result<HeadsFused, ScanError> {
    let calibrated = calibrated_poses(calibration, recons.len())?;
    let params = fuse_params(config);
    let views: Vec<_> = recons.iter().map(|r| to_fusion(&r.cloud)).collect();
    let multi = MultiViewParams {
        icp: params.icp.clone(),
        normals_k: params.normals_k,
    };
    let result = match register_views(&views, &calibrated, &multi) {
        Ok(result) => result,
        Err(e) => {
            // At one standard exposure a dim or steep view loses its pixels
            // under the fringe-order noise floor, and with them the overlaps.
            let hint = if config.exposures == super::Exposures::Single {
                "; if the heads cover little of the part, --auto-exposure (or --exposures 4,1) \
                 lifts dim views over the fringe-order noise floor"
            } else {
                ""
            };
            let why = format!(
                "the {} heads could not be registered ({e}); no fused cloud is written, the \
                 per-head clouds are in their calibrated poses{hint}",
                recons.len()
            );
            warnings.push(why.clone());
            return Ok(HeadsFused {
                cloud: PointCloud::default(),
                icp: None,
                views: None,
                a_from_head: calibrated,
                self_check: None,
                views_check: None,
                failure: Some(why),
            });
        }
    };
    log_registration(&result);
    let predicted: Vec<f64> = recons.iter().map(super::measure::predicted_rms_m).collect();
    let check = self_check::check_views(&result, &predicted);
    warnings.extend(self_check::views_warning(&check, &HEAD_NAMES));
    if !result.converged {
        warnings.push(format!(
            "multi-view registration did not converge in {} iterations (last step {:.4} deg / \
             {:.1} um); the fused cloud uses its last poses",
            result.iterations,
            result.last_step_rotation_deg,
            result.last_step_translation_m * 1e6
        ));
    }
    let a_from_head = result.poses();
    let cloud = merge_heads(recons, &a_from_head, &params.merge)?;
    Ok(HeadsFused {
        cloud,
        icp: None,
        views: Some(result),
        a_from_head,
        self_check: None,
        views_check: Some(check),
        failure: None,
    })
}

/// Head A's frame <- head h's frame for each of `heads` heads, from the
/// calibration's poses (head A -> head h).
fn calibrated_poses(
    calibration: &RigCalibration,
    heads: usize,
) -> Result<Vec<Isometry3<f64>>, ScanError> {
    (0..heads)
        .map(|h| {
            calibration
                .pose_from_first(h)
                .map(|p| p.to_isometry().inverse())
                .ok_or(ScanError::NoHeadPoses {
                    heads,
                    poses: calibration.head_poses.len(),
                })
        })
        .collect()
}

/// The heads merged one by one into head A's frame (each head's points
/// moved by its registered pose; duplicates within the merge radius
/// averaged by quality), with the heads' normals and colours.
fn merge_heads(
    recons: &[Reconstruction],
    a_from_head: &[Isometry3<f64>],
    merge: &crate::fusion::MergeParams,
) -> Result<PointCloud, ScanError> {
    let mut fused = recons[0].cloud.clone();
    for (recon, pose) in recons.iter().zip(a_from_head).skip(1) {
        let head_in_a = transformed(&recon.cloud, pose);
        let (cloud, _, kept) =
            merge_clouds_indexed(&to_fusion(&fused), &to_fusion(&head_in_a), merge)?;
        fused = with_head_attributes(from_fusion(&cloud), &fused, &head_in_a, &kept);
    }
    Ok(fused)
}

fn log_registration(result: &MultiViewResult) {
    for (h, v) in result.views.iter().enumerate() {
        tracing::info!(
            head = HEAD_NAMES.get(h).copied().unwrap_or("?"),
            rotation_deg = v.rotation_correction_deg,
            translation_um = v.translation_correction_m * 1e6,
            fitness = v.fitness,
            "multi-view registration moved the calibrated pose"
        );
    }
    for p in &result.pairs {
        tracing::info!(
            pair = format_args!("{}-{}", HEAD_NAMES[p.heads.0], HEAD_NAMES[p.heads.1]),
            overlap_rmse_um = p.overlap_rmse_m * 1e6,
            inliers = p.inliers,
            "overlap after registration"
        );
    }
}
