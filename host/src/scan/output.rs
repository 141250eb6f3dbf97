//! Writes a finished scan: pictures, the two head clouds, `report.json`,
//! and `scan.ply` last. Each file goes through a temporary and a rename.

use std::path::{Path, PathBuf};

use super::{Mode, ScanResult};
use crate::io::images::{normalise_for_view, save_gray_png, ImageError};
use crate::io::ply::{write_ply, PlyError};
use crate::io::report::{
    write_report, FrameFitReport, FrameOffset, FusedReport, HeadReport, IcpReport, ReportError,
    ScanReport,
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
        calibration: scan.calibration.description.clone(),
        calibration_vs_truth: scan.calibration.vs_truth.clone(),
        truth_frame_fit: FrameFitReport {
            heads: scan.heads.iter().map(|h| offset(&h.frame_fit)).collect(),
            fused: offset(&scan.fused.frame_fit),
        },
        truth_note: "every cloud is measured after a rigid fit of its calibrated frame onto the true camera frame \
            (truth_frame_fit; shape and scale errors stay); \
            rmse_um per head: each valid pixel's point vs the true point of that pixel; \
            plane_rmse_um and fused.rmse_um: each point vs the tangent plane of its nearest true surface sample; \
            coverage: fraction of the measurable object surface (pixels of either camera seeing the object, \
            all scene objects but the background wall, lit by that camera's own projector) with a cloud point within 1 mm"
            .into(),
        surface_samples: scan.surface_samples,
        heads: scan
            .heads
            .iter()
            .map(|h| HeadReport {
                name: h.name.into(),
                points: h.accuracy.points,
                rmse_um: h.accuracy.rmse_m * um,
                median_error_um: h.accuracy.median_m * um,
                predicted_rms_um: h.accuracy.predicted_rms_m * um,
                outliers_over_1mm: h.accuracy.outliers,
                plane_rmse_um: h.plane_rmse_m * um,
                coverage: h.coverage,
                own_pixel_coverage: h.accuracy.own_coverage,
            })
            .collect(),
        fused: FusedReport {
            points: scan.fused.cloud.len(),
            rmse_um: scan.fused.plane_rmse_m * um,
            coverage: scan.fused.coverage,
            icp: scan.fused.icp.as_ref().map(|icp| IcpReport {
                rotation_deg: icp.rotation_correction_deg,
                translation_um: icp.translation_correction_m * um,
                overlap_rmse_um: icp.overlap_rmse_m * um,
                fitness: icp.fitness,
                iterations: icp.iterations,
                converged: icp.converged,
            }),
            pose_error_vs_truth_deg: scan.fused.residual_pose_error.0,
            pose_error_vs_truth_um: scan.fused.residual_pose_error.1 * um,
        },
        warnings: scan.warnings.clone(),
        timings_ms: scan.timings_ms.iter().map(|(n, ms)| (n.to_string(), *ms)).collect(),
    }
}

fn offset(fit: &super::truth_frame::FrameFit) -> FrameOffset {
    FrameOffset {
        rotation_deg: fit.rotation_deg(),
        translation_um: fit.translation_m() * 1e6,
    }
}

/// Writes `dir/{camera,phase,depth,error}_{a,b}.png` (error: black = exact,
/// white = 500 um or more), `head_a.ply`,
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
        // Error picture: 0 = exact, white = 500 um or more.
        let err = Raster {
            width: h.error_m.width,
            height: h.error_m.height,
            data: h
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
        write_ply(&dir.join(format!("head_{tag}.ply")), &h.cloud_in_a)?;
    }
    let report = report(scan);
    write_report(&dir.join("report.json"), &report)?;
    write_ply(&dir.join("scan.ply"), &scan.fused.cloud)?;
    Ok(report)
}
