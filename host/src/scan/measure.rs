//! The "measure" stage of a scan that has a ground truth (plain data,
//! [`GroundTruth`]: the digital twin's, or a measured reference): each
//! head's reconstruction and the fused cloud against the true surface.
//! Without one (hardware, usually) this stage does not run.

use nalgebra::Isometry3;

use super::clouds::{points_f64, transformed};
use super::metrics::{self, Sample};
use super::spheres;
use super::truth::{CameraTruth, GroundTruth};
use super::truth_frame::{fit_frame, FrameFit};
use super::{aliasing, FusedTruth, HeadTruth, ScanError, HEAD_NAMES};
use crate::point_cloud::PointCloud;
use crate::raster::Raster;
use crate::reconstruct::Reconstruction;
use crate::unwrap::PixelStatus;

/// Per-head and fused figures against the truth, and the coverage denominator.
pub struct Measured {
    /// Per head, A first.
    pub heads: Vec<HeadTruth>,
    /// The fused cloud.
    pub fused: FusedTruth,
    /// Samples of the measurable object surface.
    pub surface_samples: usize,
}

/// Measures `recons` (each in its head's calibrated frame; each head alone,
/// moved into head A's frame through its own frame fit) and `fused` (head
/// A's calibrated frame), where `a_from_head[h]` is the pose fusion used for
/// head `h` (identity for A). Every cloud is measured after a rigid fit of its calibrated frame
/// onto the true one ([`super::truth_frame`]); fit problems go to `warnings`.
/// `aliased_masks` are the overlaps the flat fields measured per head
/// (simultaneous mode; else empty), compared with the truth's.
pub fn measure(
    truth: &GroundTruth,
    recons: &[Reconstruction],
    fused: &PointCloud,
    a_from_head: &[Isometry3<f64>],
    aliased_masks: &[Vec<bool>],
    warnings: &mut Vec<String>,
) -> Result<Measured, ScanError> {
    if truth.cameras.len() < recons.len() {
        return Err(ScanError::TruthHeads {
            heads: recons.len(),
            truths: truth.cameras.len(),
        });
    }
    truth.validate()?;
    let geometries = &truth.cameras[..recons.len()];
    let fused_pts = points_f64(fused);
    let true_a_from_world = truth.head_from_world(0);
    let surfaces: Vec<Vec<bool>> = geometries.iter().map(CameraTruth::has_surface).collect();
    let truth_in_true_a: Vec<Sample> = geometries
        .iter()
        .zip(&surfaces)
        .flat_map(|(g, s)| metrics::samples(g, s, &true_a_from_world))
        .collect();
    let fit = |cloud: &[nalgebra::Vector3<f64>],
               samples: &[Sample],
               true_from_world: &Isometry3<f64>,
               what: &str,
               warnings: &mut Vec<String>| {
        if truth.calibration_is_true {
            // The truth's own devices: the calibrated frames are the true ones.
            FrameFit::exact(true_from_world)
        } else {
            fit_frame(cloud, samples, true_from_world, what, warnings)
        }
    };
    let fused_fit = fit(
        &fused_pts,
        &truth_in_true_a,
        &true_a_from_world,
        "fused cloud",
        warnings,
    );
    let a_from_world = fused_fit.frame_from_world;
    let mut surface: Vec<Sample> = Vec::new();
    let mut all_surface: Vec<Sample> = Vec::new();
    for (g, s) in geometries.iter().zip(&surfaces) {
        surface.extend(metrics::samples(g, &g.own_object, &a_from_world));
        all_surface.extend(metrics::samples(g, s, &a_from_world));
    }
    let mut heads = Vec::new();
    for (h, recon) in recons.iter().enumerate() {
        let g = &geometries[h];
        let true_head_from_world = truth.head_from_world(h);
        let frame_fit = fit(
            &points_f64(&recon.cloud),
            &metrics::samples(g, &surfaces[h], &true_head_from_world),
            &true_head_from_world,
            &format!("head {}", HEAD_NAMES[h]),
            warnings,
        );
        let head_from_world = frame_fit.frame_from_world;
        let accuracy = metrics::pixel_accuracy(recon, g, &head_from_world);
        let overlap = metrics::masked_accuracy(recon, g, &head_from_world, &g.overlap);
        let spheres = spheres::sphere_figures(recon, g, &truth.spheres, &head_from_world);
        let a_from_head = a_from_world * head_from_world.inverse();
        let pts = points_f64(&transformed(&recon.cloud, &a_from_head));
        heads.push(HeadTruth {
            plane_rmse_m: metrics::point_to_plane_rmse(&pts, &all_surface)?,
            coverage: metrics::coverage(&pts, &surface)?,
            error_m: error_map(recon, g, &head_from_world),
            accuracy,
            overlap,
            frame_fit,
            spheres,
            residual_pose_error: None,
            aliased_mask: aliased_masks
                .get(h)
                .map(|m| aliasing::agreement(m, &g.overlap)),
        });
    }
    // The pose used maps each head's calibrated frame into A's; in true frames:
    for h in 1..heads.len() {
        let Some(a_from_h_used) = a_from_head.get(h) else {
            break;
        };
        let used_in_true_frames = heads[0].frame_fit.true_from_estimate
            * a_from_h_used
            * heads[h].frame_fit.true_from_estimate.inverse();
        let diff = used_in_true_frames * truth.b_from_a(0, h);
        heads[h].residual_pose_error = Some((
            diff.rotation.angle().to_degrees(),
            diff.translation.vector.norm(),
        ));
    }
    let residual_pose_error = match &heads[..] {
        [_, b] => b.residual_pose_error,
        _ => None,
    };
    Ok(Measured {
        heads,
        fused: FusedTruth {
            plane_rmse_m: metrics::point_to_plane_rmse(&fused_pts, &all_surface)?,
            coverage: metrics::coverage(&fused_pts, &surface)?,
            residual_pose_error,
            frame_fit: fused_fit,
        },
        surface_samples: surface.len(),
    })
}

/// RMS of the reconstruction's predicted per-point sigma (phase-noise
/// Cramer-Rao bound carried to metres along the ray) over valid pixels,
/// metres (NaN without any): the one accuracy figure that needs no truth.
pub fn predicted_rms_m(recon: &Reconstruction) -> f64 {
    let (n, sum) = recon
        .pixels
        .iter()
        .filter(|px| px.status == PixelStatus::Valid && px.sigma_m.is_finite())
        .fold((0usize, 0.0f64), |(n, s), px| {
            (n + 1, s + f64::from(px.sigma_m).powi(2))
        });
    if n == 0 {
        return f64::NAN;
    }
    (sum / n as f64).sqrt()
}

/// |reconstructed - true| per pixel, metres (NaN where either is missing).
fn error_map(
    recon: &Reconstruction,
    truth: &CameraTruth,
    head_from_world: &Isometry3<f64>,
) -> Raster<f32> {
    let data = recon
        .pixels
        .iter()
        .zip(&truth.point_m)
        .map(|(px, t)| {
            if !(px.point_m[0].is_finite() && t[0].is_finite()) {
                return f32::NAN;
            }
            metrics::point_error_m(&px.point_m, t, head_from_world) as f32
        })
        .collect();
    Raster {
        width: recon.pixels.width,
        height: recon.pixels.height,
        data,
    }
}
