//! Fusion of the head clouds. Two heads: ICP of B onto A from the
//! calibrated pose, then a merge by quality; without shared surface
//! (simultaneous mode with the aliased overlap masked out) the calibrated
//! pose alone, loudly. Three or four: [`super::fuse_views`].

use nalgebra::{Isometry3, Vector3};

use super::clouds::{from_fusion, to_fusion, transformed, with_head_attributes};
use super::self_check::{self, SelfCheck};
use super::{Mode, ScanConfig, ScanError};
use crate::calibration::RigCalibration;
use crate::fusion::{
    self, merge_clouds_indexed, DuplicateRule, FuseParams, FusionError, IcpParams, IcpResult,
    MergeParams,
};
use crate::point_cloud::PointCloud;
use crate::reconstruct::Reconstruction;

/// The fused cloud (head A's frame) and the registration, if one ran.
pub struct Fused {
    /// The merged cloud.
    pub cloud: fusion::PointCloud,
    /// ICP of B onto A.
    pub icp: Option<IcpResult>,
    /// The points of B kept on their own (the cloud is A's points, then these).
    pub b_kept: Vec<usize>,
    /// How well the registered clouds agree in shape (needs ICP).
    pub agreement: Option<fusion::ShapeAgreement>,
}

/// What fusing a scan's heads gave.
pub struct HeadsFused {
    /// The scan's cloud in head A's frame, with the heads' normals and
    /// colours (one head: its cloud; failed fusion: empty).
    pub cloud: PointCloud,
    /// ICP of B onto A (`None` with one head, without shared surface, or
    /// when fusion failed).
    pub icp: Option<IcpResult>,
    /// Three or four heads: the joint registration of every head's pose.
    pub views: Option<fusion::MultiViewResult>,
    /// Each head's frame into head A's: the pose the scan used.
    pub a_from_head: Vec<Isometry3<f64>>,
    /// The calibration's checks that need no truth (with ICP).
    pub self_check: Option<SelfCheck>,
    /// The same for three or four heads (with a registration).
    pub views_check: Option<self_check::ViewsCheck>,
    /// Why the heads could not be fused.
    pub failure: Option<String>,
}

/// Two heads: ICP of B onto A from the calibrated head-to-head pose, the
/// calibration self-check, one cloud; when ICP fails, still a result (the
/// heads by the calibrated pose) that says why. One head: its cloud. Three
/// or four: joint registration ([`super::fuse_views::fuse_views`]).
pub fn fuse_heads(
    recons: &[Reconstruction],
    calibration: &RigCalibration,
    config: &ScanConfig,
    warnings: &mut Vec<String>,
) -> Result<HeadsFused, ScanError> {
    if recons.len() > 2 {
        return super::fuse_views::fuse_views(recons, calibration, config, warnings);
    }
    let ([a, b], Some(a_to_b)) = (recons, calibration.head_to_head()) else {
        return Ok(HeadsFused {
            cloud: recons.first().map(|r| r.cloud.clone()).unwrap_or_default(),
            icp: None,
            views: None,
            a_from_head: vec![Isometry3::identity()],
            self_check: None,
            views_check: None,
            failure: None,
        });
    };
    let a_from_b_calibrated = a_to_b.to_isometry().inverse();
    match fuse(&a.cloud, &b.cloud, &a_from_b_calibrated, config, warnings) {
        Ok(fused) => {
            let a_from_b_used = fused
                .icp
                .as_ref()
                .map_or(a_from_b_calibrated, |icp| icp.transform);
            let predicted = [a, b].map(super::measure::predicted_rms_m);
            let self_check = fused.icp.as_ref().map(|icp| {
                let c = self_check::check(icp, fused.agreement.as_ref(), predicted);
                warnings.extend(self_check::warning(&c));
                c
            });
            let cloud = with_head_attributes(
                from_fusion(&fused.cloud),
                &a.cloud,
                &transformed(&b.cloud, &a_from_b_used),
                &fused.b_kept,
            );
            Ok(HeadsFused {
                cloud,
                icp: fused.icp,
                views: None,
                a_from_head: vec![Isometry3::identity(), a_from_b_used],
                self_check,
                views_check: None,
                failure: None,
            })
        }
        Err(ScanError::Fusion(e)) => {
            let why = self_check::fusion_failure(&e);
            warnings.push(why.clone());
            Ok(HeadsFused {
                cloud: PointCloud::default(),
                icp: None,
                views: None,
                a_from_head: vec![Isometry3::identity(), a_from_b_calibrated],
                self_check: None,
                views_check: None,
                failure: Some(why),
            })
        }
        Err(e) => Err(e),
    }
}

/// Fuses `b` (head B's frame) into `a` (head A's), starting from the
/// calibrated `a_from_b`.
pub fn fuse(
    a: &PointCloud,
    b: &PointCloud,
    a_from_b: &Isometry3<f64>,
    config: &ScanConfig,
    warnings: &mut Vec<String>,
) -> Result<Fused, ScanError> {
    let params = fuse_params(config);
    let (a, b) = (to_fusion(a), to_fusion(b));
    match fusion::fuse_heads(&a, &b, a_from_b, &params) {
        Ok(f) => {
            tracing::info!(
                rotation_deg = f.icp.rotation_correction_deg,
                translation_um = f.icp.translation_correction_m * 1e6,
                overlap_rmse_um = f.icp.overlap_rmse_m * 1e6,
                merged = f.merge.b_merged,
                systematic_um = f.agreement.map(|a| a.systematic_rms_m * 1e6),
                cell_noise_um = f.agreement.map(|a| a.noise_rms_m * 1e6),
                cells = f.agreement.map(|a| a.cells),
                "ICP refined the calibrated head-to-head pose"
            );
            Ok(Fused {
                cloud: f.cloud,
                icp: Some(f.icp),
                b_kept: f.b_kept,
                agreement: f.agreement,
            })
        }
        Err(FusionError::NoOverlap {
            correspondences, ..
        }) if config.mode == Mode::Simultaneous => {
            let warning = format!(
                "simultaneous mode: the heads share no unaliased surface ({correspondences} ICP \
                 correspondences), so the clouds are merged with the calibrated pose, NOT refined by ICP"
            );
            warnings.push(warning);
            let (cloud, _, b_kept) =
                merge_clouds_indexed(&a, &b.transformed(a_from_b), &params.merge)?;
            Ok(Fused {
                cloud,
                icp: None,
                b_kept,
                agreement: None,
            })
        }
        Err(e) => Err(e.into()),
    }
}

/// Fusion settings for the scan's sampling: merge radius about one camera
/// pixel's footprint at 0.5 m.
pub fn fuse_params(config: &ScanConfig) -> FuseParams {
    // Footprint of a pixel at 0.5 m for a 42 degree camera of this width.
    let pitch_m = 0.5 * 2.0 * (21f64.to_radians()).tan() / config.camera_px.0 as f64;
    FuseParams {
        normals_k: 12,
        sensor_a_m: Vector3::zeros(),
        icp: IcpParams {
            final_gate_m: (4.0 * pitch_m).min(IcpParams::default().initial_gate_m),
            ..IcpParams::default()
        },
        merge: MergeParams {
            radius_m: pitch_m,
            rule: DuplicateRule::WeightedMean,
            default_sigma_m: 1e-4,
        },
    }
}
