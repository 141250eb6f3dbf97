//! Writes a finished scan: pictures, the two head clouds, `report.json`,
//! and `scan.ply` last. Each file goes through a temporary and a rename.

use std::path::{Path, PathBuf};

use super::{Mode, ScanResult};
use crate::io::images::{normalise_for_view, save_gray_png, ImageError};
use crate::io::ply::{write_ply, PlyError};
use crate::io::report::{
    write_report, FusedReport, HeadReport, IcpReport, ReportError, ScanReport,
};
use crate::raster::Raster;

/// What can go wrong writing a scan.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The output folder could not be made.
    #[error("creating {path}: {source}")]
    Dir {
        /// The folder.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A picture.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// A cloud.
    #[error(transparent)]
    Ply(#[from] PlyError),
    /// The report.
    #[error(transparent)]
    Report(#[from] ReportError),
}

/// The report of a finished scan.
pub fn report(scan: &ScanResult) -> ScanReport {
    let um = 1e6;
    let c = &scan.config;
    ScanReport {
        scene: c.scene.clone(),
        mode: match c.mode {
            Mode::Sequential => "sequential",
            Mode::Simultaneous => "simultaneous",
            Mode::SimultaneousMultiplexed => "simultaneous-multiplexed",
        }
        .into(),
        camera_px: c.camera_px,
        projector_px: c.projector_px,
        periods_px: c.periods_px.clone(),
        steps: c.steps,
        calibration: scan.calibration_source.clone(),
        truth_note: if scan.surface_samples.is_none() {
            "no ground truth (hardware): rmse, coverage and pose-error figures are null".into()
        } else {
            "rmse_um per head: each valid pixel's point vs the true point of that pixel; \
            plane_rmse_um and fused.rmse_um: each point vs the tangent plane of its nearest true surface sample; \
            coverage: fraction of the measurable object surface (pixels of either camera seeing the object, \
            all scene objects but the background wall, lit by that camera's own projector) with a cloud point within 1 mm"
            .into()
        },
        surface_samples: scan.surface_samples,
        heads: scan
            .heads
            .iter()
            .map(|h| {
                let t = h.truth.as_ref();
                HeadReport {
                    name: h.name.into(),
                    // Without a truth: every point of the cloud.
                    points: t.map_or(h.reconstruction.cloud.len(), |t| t.accuracy.points),
                    rmse_um: t.map(|t| t.accuracy.rmse_m * um),
                    median_error_um: t.map(|t| t.accuracy.median_m * um),
                    predicted_rms_um: h.predicted_rms_m * um,
                    outliers_over_1mm: t.map(|t| t.accuracy.outliers),
                    plane_rmse_um: t.map(|t| t.plane_rmse_m * um),
                    coverage: t.map(|t| t.coverage),
                    own_pixel_coverage: t.map(|t| t.accuracy.own_coverage),
                }
            })
            .collect(),
        fused: FusedReport {
            points: scan.fused.cloud.len(),
            rmse_um: scan.fused.truth.as_ref().map(|t| t.plane_rmse_m * um),
            coverage: scan.fused.truth.as_ref().map(|t| t.coverage),
            icp: scan.fused.icp.as_ref().map(|icp| IcpReport {
                rotation_deg: icp.rotation_correction_deg,
                translation_um: icp.translation_correction_m * um,
                overlap_rmse_um: icp.overlap_rmse_m * um,
                fitness: icp.fitness,
                iterations: icp.iterations,
                converged: icp.converged,
            }),
            pose_error_vs_truth_deg: scan.fused.truth.as_ref().map(|t| t.residual_pose_error.0),
            pose_error_vs_truth_um: scan
                .fused
                .truth
                .as_ref()
                .map(|t| t.residual_pose_error.1 * um),
        },
        warnings: scan.warnings.clone(),
        timings_ms: scan
            .timings_ms
            .iter()
            .map(|(n, ms)| (n.to_string(), *ms))
            .collect(),
    }
}

/// Writes `dir/{camera,phase,depth,error}_{a,b}.png` (error: black = exact,
/// white = 500 um or more; only with a ground truth), `head_a.ply`,
/// `head_b.ply`, `report.json`, then `scan.ply`.
pub fn write_scan(dir: &Path, scan: &ScanResult) -> Result<ScanReport, OutputError> {
    std::fs::create_dir_all(dir).map_err(|source| OutputError::Dir {
        path: dir.to_owned(),
        source,
    })?;
    for h in &scan.heads {
        let tag = h.name.to_lowercase();
        save_gray_png(
            &dir.join(format!("camera_{tag}.png")),
            &h.first_frame,
            false,
        )?;
        let phase = h.reconstruction.phase_u();
        save_gray_png(
            &dir.join(format!("phase_{tag}.png")),
            &normalise_for_view(&phase),
            true,
        )?;
        let depth = h.reconstruction.depth_m();
        save_gray_png(
            &dir.join(format!("depth_{tag}.png")),
            &normalise_for_view(&depth),
            true,
        )?;
        if let Some(truth) = &h.truth {
            // Error picture: 0 = exact, white = 500 um or more.
            let err = Raster {
                width: truth.error_m.width,
                height: truth.error_m.height,
                data: truth
                    .error_m
                    .data
                    .iter()
                    .map(|e| {
                        if e.is_finite() {
                            (e / 500e-6).min(1.0)
                        } else {
                            0.0
                        }
                    })
                    .collect(),
            };
            save_gray_png(&dir.join(format!("error_{tag}.png")), &err, false)?;
        }
        write_ply(&dir.join(format!("head_{tag}.ply")), &h.cloud_in_a)?;
    }
    let report = report(scan);
    write_report(&dir.join("report.json"), &report)?;
    write_ply(&dir.join("scan.ply"), &scan.fused.cloud)?;
    Ok(report)
}
