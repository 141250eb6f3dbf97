//! Accuracy and coverage of a scan against a per-pixel ground truth
//! ([`super::truth::CameraTruth`]: true surface point, normal, the object
//! pixels each head's own projector lights; the twin's or a measured one).
//!
//! - Per head, `rmse_um`: each valid pixel's point against the true surface
//!   point of that very pixel (same camera ray), all valid pixels counted.
//! - Point-to-plane RMSE (any cloud, the fused one too): each point against
//!   the tangent plane of its nearest true surface sample.
//! - Coverage: the *measurable object surface* is every camera pixel (of
//!   either head) that sees the object (every scene object but the
//!   background wall) and is lit by its own head's projector; a cloud covers
//!   a sample when it has a point within [`COVERED_WITHIN_M`] of it. The
//!   same denominator serves both heads and the fused cloud, so they compare.

use nalgebra::{Isometry3, Point3, Vector3};
use rayon::prelude::*;

use super::truth::CameraTruth;
use crate::fusion::{build_tree, nearest_within, FusionError};
use crate::reconstruct::Reconstruction;
use crate::unwrap::PixelStatus;

/// A true surface sample counts as covered by a point this close, metres
/// (about two camera pixels' footprint at the built-in scenes' 0.5 m).
pub const COVERED_WITHIN_M: f64 = 1.0e-3;

/// Errors beyond this are counted as outliers (still in the RMSE), metres.
pub const OUTLIER_M: f64 = 1.0e-3;

/// A true surface sample in head A's frame.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    /// Point, metres.
    pub point_m: Vector3<f64>,
    /// Unit normal.
    pub normal: Vector3<f64>,
}

/// Per-pixel accuracy of one head's reconstruction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PixelAccuracy {
    /// Valid pixels.
    pub points: usize,
    /// RMS distance to the pixel's true point, metres.
    pub rmse_m: f64,
    /// Median of that distance, metres.
    pub median_m: f64,
    /// Pixels off by more than [`OUTLIER_M`].
    pub outliers: usize,
    /// Valid pixels / the head's own object pixels lit by its projector.
    pub own_coverage: f64,
    /// RMS of the pipeline's predicted per-point sigma (phase-noise
    /// Cramer-Rao bound carried to metres along the ray), metres: the
    /// physical limit `rmse_m` is to be compared with.
    pub predicted_rms_m: f64,
}

fn to_frame(frame_from_world: &Isometry3<f64>, p: &[f32; 3]) -> Vector3<f64> {
    let w = Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
    (frame_from_world * w).coords
}

/// Distance, metres, of a reconstructed point (head frame) from the true
/// point of its pixel (world frame).
pub fn point_error_m(
    point_m: &[f32; 3],
    truth_m: &[f32; 3],
    head_from_world: &Isometry3<f64>,
) -> f64 {
    let p = Vector3::new(point_m[0] as f64, point_m[1] as f64, point_m[2] as f64);
    (p - to_frame(head_from_world, truth_m)).norm()
}

/// Compares a head's reconstruction (in its camera frame) with the truth of
/// its camera.
pub fn pixel_accuracy(
    recon: &Reconstruction,
    truth: &CameraTruth,
    head_from_world: &Isometry3<f64>,
) -> PixelAccuracy {
    let mut errors: Vec<f64> = recon
        .pixels
        .par_iter()
        .zip(&truth.point_m)
        .filter(|(px, t)| px.status == PixelStatus::Valid && t[0].is_finite())
        .map(|(px, t)| point_error_m(&px.point_m, t, head_from_world))
        .collect();
    let sigmas: Vec<f64> = recon
        .pixels
        .iter()
        .filter(|px| px.status == PixelStatus::Valid && px.sigma_m.is_finite())
        .map(|px| px.sigma_m as f64)
        .collect();
    let lit = &truth.own_object;
    let own_valid = lit
        .iter()
        .zip(recon.pixels.iter())
        .filter(|(l, px)| **l && px.status == PixelStatus::Valid)
        .count();
    let lit_count = lit.iter().filter(|&&l| l).count();
    let points = errors.len();
    let rmse_m = rms(&errors);
    let outliers = errors.iter().filter(|&&e| e > OUTLIER_M).count();
    errors.sort_by(f64::total_cmp);
    PixelAccuracy {
        points,
        rmse_m,
        median_m: errors.get(points / 2).copied().unwrap_or(f64::NAN),
        outliers,
        own_coverage: own_valid as f64 / lit_count.max(1) as f64,
        predicted_rms_m: rms(&sigmas),
    }
}

/// Per-pixel accuracy over a subset of a head's pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MaskedAccuracy {
    /// Pixels in the subset (the truth's count, whatever was reconstructed).
    pub pixels: usize,
    /// Valid reconstructed pixels in the subset.
    pub points: usize,
    /// RMS distance of those points to their pixels' true points, metres
    /// (NaN when there are none).
    pub rmse_m: f64,
}

/// The per-pixel error (as in [`pixel_accuracy`]) over the valid pixels
/// where `mask` holds: e.g. the truth's overlap (pixels lit by both
/// projectors), where the capture modes differ.
pub fn masked_accuracy(
    recon: &Reconstruction,
    truth: &CameraTruth,
    head_from_world: &Isometry3<f64>,
    mask: &[bool],
) -> MaskedAccuracy {
    let errors: Vec<f64> = recon
        .pixels
        .iter()
        .zip(&truth.point_m)
        .zip(mask)
        .filter(|((px, t), &m)| m && px.status == PixelStatus::Valid && t[0].is_finite())
        .map(|((px, t), _)| point_error_m(&px.point_m, t, head_from_world))
        .collect();
    MaskedAccuracy {
        pixels: mask.iter().filter(|&&m| m).count(),
        points: errors.len(),
        rmse_m: rms(&errors),
    }
}

fn rms(values: &[f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    (values.iter().map(|e| e * e).sum::<f64>() / values.len() as f64).sqrt()
}

/// True surface samples in the fused frame: every pixel of `truth` where
/// `keep` holds, moved by `frame_from_world`.
pub fn samples(
    truth: &CameraTruth,
    keep: &[bool],
    frame_from_world: &Isometry3<f64>,
) -> Vec<Sample> {
    truth
        .point_m
        .iter()
        .zip(&truth.normal)
        .zip(keep)
        .filter(|((p, n), k)| **k && p[0].is_finite() && n[0].is_finite())
        .map(|((p, n), _)| Sample {
            point_m: to_frame(frame_from_world, p),
            normal: frame_from_world.rotation.transform_vector(&Vector3::new(
                n[0] as f64,
                n[1] as f64,
                n[2] as f64,
            )),
        })
        .collect()
}

/// Fraction of `surface` with a point of `cloud` within [`COVERED_WITHIN_M`].
pub fn coverage(cloud: &[Vector3<f64>], surface: &[Sample]) -> Result<f64, FusionError> {
    if surface.is_empty() || cloud.is_empty() {
        return Ok(0.0);
    }
    let tree = build_tree(cloud)?;
    let r2 = COVERED_WITHIN_M * COVERED_WITHIN_M;
    let covered = surface
        .par_iter()
        .filter(|s| nearest_within(&tree, &s.point_m, r2).is_some())
        .count();
    Ok(covered as f64 / surface.len() as f64)
}

/// Point-to-plane RMSE of `cloud` against the tangent plane of its nearest
/// true sample (points with no sample within 5 mm count as 5 mm off).
pub fn point_to_plane_rmse(cloud: &[Vector3<f64>], truth: &[Sample]) -> Result<f64, FusionError> {
    if cloud.is_empty() || truth.is_empty() {
        return Ok(f64::NAN);
    }
    const FAR_M: f64 = 5.0e-3;
    let points: Vec<Vector3<f64>> = truth.iter().map(|s| s.point_m).collect();
    let tree = build_tree(&points)?;
    let sum: f64 = cloud
        .par_iter()
        .map(|p| match nearest_within(&tree, p, FAR_M * FAR_M) {
            Some((i, _)) => {
                let d = truth[i].normal.dot(&(p - truth[i].point_m));
                d * d
            }
            None => FAR_M * FAR_M,
        })
        .sum();
    Ok((sum / cloud.len() as f64).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane_samples(step: f64) -> Vec<Sample> {
        let mut s = Vec::new();
        for i in 0..50 {
            for j in 0..50 {
                s.push(Sample {
                    point_m: Vector3::new(i as f64 * step, j as f64 * step, 0.5),
                    normal: Vector3::z(),
                });
            }
        }
        s
    }

    #[test]
    fn plane_offset_gives_its_rmse_and_half_a_cloud_half_coverage() {
        let truth = plane_samples(0.5e-3);
        let cloud: Vec<Vector3<f64>> = truth
            .iter()
            .map(|s| s.point_m + Vector3::new(0.1e-3, 0.0, 20e-6))
            .collect();
        let rmse = point_to_plane_rmse(&cloud, &truth).unwrap();
        assert!((rmse - 20e-6).abs() < 1e-9, "{rmse}");
        let left: Vec<Vector3<f64>> = cloud.iter().copied().filter(|p| p.x < 12.4e-3).collect();
        let c = coverage(&left, &truth).unwrap();
        // Columns 0..=24 have a point on them, 25 and 26 are within 1 mm of one.
        assert!((c - 27.0 / 50.0).abs() < 0.021, "{c}");
        assert_eq!(coverage(&[], &truth).unwrap(), 0.0);
    }
}
