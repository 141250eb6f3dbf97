//! Writes a finished scan: pictures, the two head clouds, `report.json`,
//! and `scan.ply` last. Each file goes through a temporary and a rename.

use std::path::{Path, PathBuf};

use super::spheres::{centre_distance_error_m, SphereFigures};
use super::{dealias_picture, Mode, Progress, ScanResult, HEAD_NAMES};
use crate::io::cloud_render::{render_cloud, splat_radius_for, CloudView};
use crate::io::images::{encode_rgb_png, save_bytes, save_gray_png, ImageError};
use crate::io::outputs::{OutputSet, OutputSetError};
use crate::io::ply::{write_ply, PlyError};
use crate::io::report::{
    write_report, AdaptiveReport, AliasedMaskReport, DealiasReport, ExposureReport, FrameFitReport,
    FrameOffset, FusedReport, HeadRegistrationReport, HeadReport, IcpReport, MultiViewReport,
    NetworkRunReport, PairReport, ReportError, ScanReport, SelfCheckReport, SphereReport,
    UnderwaterReport,
};
use crate::io::report_html::{scan_page, write_html, PageError, PagePicture};
use crate::pictures::{head_pictures, HeadPictures, KINDS};
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
    /// A file could not be written (the run's files are removed again).
    #[error("writing {path}: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// An earlier run's output could not be removed (or is not a regular file).
    #[error("clearing the earlier run's outputs")]
    Stale(#[from] OutputSetError),
    /// A picture could not be encoded.
    #[error("encoding a picture")]
    Encode(#[from] image::ImageError),
    /// A picture.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// A cloud.
    #[error(transparent)]
    Ply(#[from] PlyError),
    /// The report.
    #[error(transparent)]
    Report(#[from] ReportError),
    /// The report page.
    #[error(transparent)]
    Page(#[from] PageError),
}

/// Every file [`write_scan`] writes into its folder (for either head).
pub fn output_files() -> Vec<String> {
    let mut files: Vec<String> = ["scan.ply", "report.json", "report.html"]
        .map(String::from)
        .to_vec();
    for head in HEAD_NAMES {
        let tag = head.to_lowercase();
        files.push(format!("head_{tag}.ply"));
        files.extend(KINDS.iter().map(|kind| format!("{kind}_{tag}.png")));
    }
    files.extend(CLOUD_VIEWS.map(|(name, ..)| format!("cloud_{name}.png")));
    files.extend(HEAD_NAMES.map(|h| super::underwater::picture_file(&h.to_lowercase())));
    files.extend(HEAD_NAMES.map(|h| dealias_picture::picture_file(&h.to_lowercase())));
    for head in HEAD_NAMES {
        let tag = head.to_lowercase();
        files.extend((0..MAX_FLOODS).map(|i| flood_file(&tag, i)));
        files.extend((0..protocol::limits::MAX_EXPOSURES).map(|i| adapted_file(&tag, i)));
    }
    // Earlier versions' picture names, so an old run's leave too.
    for old in ["camera", "phase", "error"] {
        files.extend(HEAD_NAMES.map(|h| format!("{old}_{}.png", h.to_lowercase())));
    }
    files
}

/// Most flood images an adaptive scan writes per head (the names an
/// earlier run may have left).
const MAX_FLOODS: usize = crate::adaptive::hdr::MAX_FLOOD_LEVELS;

/// Adaptive scan: flood `i` of the head tagged `tag`, as the camera took it.
fn flood_file(tag: &str, i: usize) -> String {
    format!("flood_{tag}_{i}.png")
}

/// Adaptive scan: adapted pattern `i` of the head tagged `tag`, as sent to its DMD.
fn adapted_file(tag: &str, i: usize) -> String {
    format!("adapted_{tag}_{i:02}.png")
}

/// [`output_files`] in `dir`.
pub fn output_set(dir: &Path) -> OutputSet {
    OutputSet::in_dir(dir, output_files())
}

/// Removes an earlier run's outputs ([`output_files`], nothing else) from
/// `dir`, so a scan that fails leaves no old `scan.ply` or `report.json`
/// that could be read as its result; refuses (before removing anything)
/// when one of those names is a symlink, folder or device. A missing folder
/// or file is fine. Call it before the rig is touched.
pub fn remove_stale(dir: &Path) -> Result<(), OutputError> {
    Ok(output_set(dir).clear()?)
}

/// The frame fits of the heads and the fused cloud (`None` without a truth).
fn frame_fits(scan: &ScanResult) -> Option<FrameFitReport> {
    let offset = |fit: &super::truth_frame::FrameFit| FrameOffset {
        rotation_deg: fit.rotation_deg(),
        translation_um: fit.translation_m() * 1e6,
    };
    let heads = scan
        .heads
        .iter()
        .map(|h| h.truth.as_ref().map(|t| offset(&t.frame_fit)))
        .collect::<Option<Vec<_>>>()?;
    let fused = offset(&scan.fused.truth.as_ref()?.frame_fit);
    Some(FrameFitReport { heads, fused })
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
        calibration_vs_truth: scan.calibration_vs_truth.clone(),
        truth_frame_fit: frame_fits(scan),
        truth_note: if scan.surface_samples.is_none() {
            "no ground truth (hardware): rmse, coverage and pose-error figures are null".into()
        } else {
            "every cloud is measured after a rigid fit of its calibrated frame onto the true camera frame \
            (truth_frame_fit; shape and scale errors stay); \
            rmse_um per head: each valid pixel's point vs the true point of that pixel; \
            plane_rmse_um and fused.rmse_um: each point vs the tangent plane of its nearest true surface sample; \
            coverage: fraction of the measurable object surface (pixels of either camera seeing the object, \
            all scene objects but the background wall, lit by that camera's own projector) with a cloud point within 1 mm; \
            overlap_rmse_um: rmse_um over the pixels whose surface point both projectors light (twin truth)"
            .into()
        },
        surface_samples: scan.surface_samples,
        heads: scan
            .heads
            .iter()
            .enumerate()
            .map(|(index, h)| {
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
                    overlap_pixels: t.map(|t| t.overlap.pixels),
                    overlap_points: t.map(|t| t.overlap.points),
                    overlap_rmse_um: t.map(|t| t.overlap.rmse_m * um),
                    aliased_mask: t.and_then(|t| t.aliased_mask).map(|a| AliasedMaskReport {
                        measured_overlap_pixels: a.measured,
                        true_overlap_pixels: a.truth,
                        iou: a.iou,
                        recall: a.recall,
                    }),
                    dealias: h.dealias.map(|d| DealiasReport {
                        method: scan.config.dealias.name().into(),
                        affected_pixels: d.affected,
                        attempted_pixels: d.attempted,
                        separated_pixels: d.separated,
                        ill_posed_pixels: d.ill_posed,
                        misfit_pixels: d.misfit,
                        unsolved_pixels: d.unsolved,
                        inconsistent_pixels: d.inconsistent,
                        bad_input_pixels: d.bad_input,
                        network: d.network.zip(scan.config.learned.as_ref()).map(|(run, l)| {
                            NetworkRunReport {
                                model: l.model().path.display().to_string(),
                                kind: l.model().meta.kind.clone(),
                                sampler_steps: l.evaluations_per_tile(),
                                tiles: run.tiles,
                                evaluations: run.evaluations,
                            }
                        }),
                        time_ms: d.time_ms,
                        error_vs_clean_rms_8bit: h
                            .dealias_sample
                            .as_ref()
                            .and_then(|s| s.error_rms_8bit()),
                        picture: h
                            .dealias_sample
                            .as_ref()
                            .map(|_| dealias_picture::picture_file(&h.name.to_lowercase())),
                    }),
                    spheres: t
                        .map_or_else(Vec::new, |t| t.spheres.iter().map(sphere_report).collect()),
                    sphere_centre_distance_error_um: t
                        .and_then(|t| centre_distance_error_m(&t.spheres))
                        .map(|e| e * um),
                    exposure: exposure_report(h, &c.exposures, c.frames_per_pattern),
                    registration: scan.fused.views.as_ref().and_then(|v| {
                        let view = v.views.get(index)?;
                        Some(HeadRegistrationReport {
                            rotation_deg: view.rotation_correction_deg,
                            translation_um: view.translation_correction_m * um,
                            fitness: view.fitness,
                        })
                    }),
                    pose_error_vs_truth_deg: t
                        .and_then(|t| t.residual_pose_error)
                        .map(|(deg, _)| deg),
                    pose_error_vs_truth_um: t
                        .and_then(|t| t.residual_pose_error)
                        .map(|(_, m)| m * um),
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
            registration: scan.fused.views.as_ref().map(|v| {
                let check = scan.fused.views_check.as_ref();
                let pair_check = |heads| check?.pairs.iter().find(|c| c.heads == heads);
                MultiViewReport {
                    iterations: v.iterations,
                    converged: v.converged,
                    verdict: check.map_or("not checked", |c| c.verdict.name()).into(),
                    pairs: v
                        .pairs
                        .iter()
                        .map(|p| PairReport {
                            heads: format!("{}-{}", HEAD_NAMES[p.heads.0], HEAD_NAMES[p.heads.1]),
                            inliers: p.inliers,
                            overlap_rmse_um: p.overlap_rmse_m * um,
                            predicted_overlap_um: pair_check(p.heads)
                                .map(|c| c.predicted_overlap_m * um),
                            shape_disagreement_um: p.agreement.map(|a| a.systematic_rms_m * um),
                        })
                        .collect(),
                }
            }),
            pose_error_vs_truth_deg: scan
                .fused
                .truth
                .as_ref()
                .and_then(|t| t.residual_pose_error)
                .map(|(deg, _)| deg),
            pose_error_vs_truth_um: scan
                .fused
                .truth
                .as_ref()
                .and_then(|t| t.residual_pose_error)
                .map(|(_, m)| m * um),
            self_check: scan.fused.self_check.map(|c| SelfCheckReport {
                verdict: c.verdict.name().into(),
                pose_correction_deg: c.pose_rotation_deg,
                pose_correction_mm: c.pose_translation_m * 1e3,
                shape_disagreement_um: c.shape_rms_m.map(|s| s * um),
                shape_noise_um: c.shape_noise_m.map(|s| s * um),
                overlap_rmse_um: c.overlap_rmse_m * um,
                predicted_overlap_um: c.predicted_overlap_m * um,
            }),
            failure: scan.fused.failure.clone(),
        },
        warnings: scan.warnings.clone(),
        timings_ms: scan
            .timings_ms
            .iter()
            .map(|(n, ms)| (n.to_string(), *ms))
            .collect(),
        underwater: scan.underwater.as_ref().map(underwater_report),
    }
}

/// A water scan's restoration and port figures for the report.
fn underwater_report(w: &super::underwater::RestoreFigures) -> UnderwaterReport {
    let net = match &w.water.restorer {
        super::underwater::Restorer::Learned(net) => Some(net),
        _ => None,
    };
    UnderwaterReport {
        turbidity: w.water.turbidity.map(|t| t.name().to_string()),
        restorer: w.water.restorer.name().into(),
        psf_sigma_px: w.water.psf_sigma_px,
        sets_restored: w.sets,
        frames_restored: w.frames,
        restorer_model: net.map(|n| n.model().path.display().to_string()),
        sampler_steps: net.map(|n| n.evaluations_per_tile()),
        evaluations: w.evaluations,
        physics_correction: net.and_then(|n| n.physics()).map(|p| p.strength),
        restore_time_ms: w.time_ms,
        masked_pixels: w.masked_px,
        port_misses: w.port_misses.clone(),
        edge_margin_sigmas: w.water.edge_margin_sigmas,
        blur_edge_pixels: w.blur_edge_px.clone(),
        triangulation: "through each head's flat port (Snell at both faces)".into(),
        picture_files: HEAD_NAMES
            .iter()
            .take(w.samples.len())
            .map(|h| super::underwater::picture_file(&h.to_lowercase()))
            .collect(),
    }
}

/// Head `head`'s first fringe frame as captured (aliased in the overlap),
/// as de-aliased, and, from the simulator, the frame of its own projector
/// alone and the separated pixels' error against it; each stretched to its
/// own range.
fn write_dealias_picture(
    dir: &Path,
    head: &str,
    sample: &dealias_picture::DealiasSample,
) -> Result<PagePicture, OutputError> {
    let file = dealias_picture::picture_file(&head.to_lowercase());
    let error = sample.error();
    let mut panels: Vec<&crate::raster::Raster<f32>> = sample
        .aliased
        .iter()
        .take(1)
        .chain(sample.separated.iter().take(1))
        .collect();
    panels.extend(sample.reference.iter().flat_map(|r| r.first()));
    panels.extend(error.as_ref());
    let png = save_side_by_side(dir, &file, &panels)?;
    let caption = match sample.error_rms_8bit() {
        Some(rms) => format!(
            "head {head}: first fringe frame as captured (aliased where both projectors light it), \
             as de-aliased (masked pixels black), its own projector alone (the simulator's \
             noise-free frame) and the de-aliased fringe's error against it on the separated \
             overlap pixels (each less its pixel's mean over the period's steps), RMS {rms:.2} on \
             the 8-bit scale; each stretched to its own range"
        ),
        None => format!(
            "head {head}: first fringe frame as captured (aliased where both projectors light it) \
             and as de-aliased (masked pixels black), each stretched to its own range"
        ),
    };
    Ok(PagePicture { file, caption, png })
}

/// Writes `panels` side by side ([`crate::pictures::side_by_side`]) as
/// `dir/file` and returns the PNG's bytes for the page.
fn save_side_by_side(
    dir: &Path,
    file: &str,
    panels: &[&crate::raster::Raster<f32>],
) -> Result<Vec<u8>, OutputError> {
    let path = dir.join(file);
    save_gray_png(&path, &crate::pictures::side_by_side(panels), false)?;
    std::fs::read(&path).map_err(|source| OutputError::Write { path, source })
}

/// Per head, its first fringe frame as captured beside the same frame as
/// decoded (restored), each stretched to its own range.
fn write_underwater_pictures(
    dir: &Path,
    w: &super::underwater::RestoreFigures,
) -> Result<Vec<PagePicture>, OutputError> {
    let mut page = Vec::new();
    for (h, (head, (captured, decoded))) in HEAD_NAMES.iter().zip(&w.samples).enumerate() {
        let file = super::underwater::picture_file(&head.to_lowercase());
        let mut panels = vec![captured, decoded];
        panels.extend(w.references.get(h));
        let png = save_side_by_side(dir, &file, &panels)?;
        page.push(PagePicture {
            file,
            caption: format!(
                "head {head}: first fringe frame as captured, as decoded after the {} restorer{}, each stretched to its own range",
                w.water.restorer.name(),
                if w.references.get(h).is_some() {
                    ", and through clear water (the simulator's noise-free reference)"
                } else {
                    ""
                }
            ),
            png,
        });
    }
    Ok(page)
}

/// A head's exposure figures; adaptive, with its preliminaries' files.
fn exposure_report(
    h: &super::HeadResult,
    kind: &super::Exposures,
    frames_per_pattern: usize,
) -> ExposureReport {
    let e = &h.exposure;
    let share = |px: usize| px as f64 / e.pixels.max(1) as f64;
    let tag = h.name.to_lowercase();
    let adaptive = e.adaptive.zip(h.adaptive.as_ref()).map(|(a, record)| {
        let colours = match kind {
            super::Exposures::AdaptiveHdr(p) => p.levels.iter().map(|&l| [l; 3]).collect(),
            super::Exposures::AdaptiveColour(_) => crate::adaptive::colour::FLOODS.to_vec(),
            _ => Vec::new(),
        };
        AdaptiveReport {
            flood_files: (0..record.floods.len())
                .map(|i| flood_file(&tag, i))
                .collect(),
            flood_colours: colours,
            pattern_files: (0..record.patterns.len())
                .map(|i| adapted_file(&tag, i))
                .collect(),
            exposure_scale: a.exposure.scale,
            exposure_limited_by: a.exposure.limit.name().into(),
            saturated_fraction_before: share(a.before_saturated_px),
            below_modulation_floor_fraction_before: share(a.before_below_floor_px),
            saturated_fraction_full_flood: share(a.stats.saturated_in_full_flood_px),
            saturates_at_lowest_pixels: a.stats.saturates_at_lowest_px,
            cannot_hold_pixels: a.stats.cannot_hold_px,
            lowered_pixels: a.stats.lowered_px,
            mapped_by_phase_pixels: a.stats.mapped_by_phase_px,
            mapped_by_homography_pixels: a.stats.mapped_by_homography_px,
            unmapped_pixels: a.stats.unmapped_px,
            clusters: a.stats.clusters,
            level_step_pixels: a.level_step_px,
        }
    });
    ExposureReport {
        kind: kind.name().into(),
        images: e.images,
        exposure_scales: e.scales.clone(),
        frames_per_pattern,
        saturated_fraction: share(e.saturated_px),
        below_modulation_floor_fraction: share(e.below_floor_px),
        adaptive,
    }
}

/// Adaptive scan: the floods (16-bit, as the camera took them) and the
/// adapted patterns (8-bit, as the DMD shows them).
fn write_adaptive_images(
    dir: &Path,
    tag: &str,
    record: &super::capture::AdaptiveRecord,
) -> Result<(), OutputError> {
    for (i, f) in record.floods.iter().enumerate().take(MAX_FLOODS) {
        save_gray_png(&dir.join(flood_file(tag, i)), f, true)?;
    }
    for (i, p) in record.patterns.iter().enumerate() {
        save_gray_png(&dir.join(adapted_file(tag, i)), p, false)?;
    }
    Ok(())
}

fn sphere_report(f: &SphereFigures) -> SphereReport {
    let (mm, um) = (1e3, 1e6);
    SphereReport {
        name: f.name.clone(),
        points: f.points,
        true_radius_mm: f.true_radius_m * mm,
        radius_mm: f.radius_m * mm,
        radius_error_um: f.radius_error_m() * um,
        centre_error_um: f.centre_error_m().norm() * um,
        fit_rmse_um: f.fit_rmse_m * um,
        noise_limit_um: f.noise_limit_m * um,
    }
}

/// The two views of the fused cloud's pictures (name, yaw, pitch in
/// degrees, about head A's frame): nearly head A's line of sight, and from
/// the right and above, where the relief shows.
pub const CLOUD_VIEWS: [(&str, f64, f64); 2] = [("front", 0.0, 0.0), ("oblique", -35.0, 25.0)];

/// Writes the scan into `dir`: per head the pictures of
/// [`crate::pictures::KINDS`] (`{kind}_{a,b}.png`; the error only with a
/// ground truth) and `head_{a,b}.ply`; `cloud_{front,oblique}.png` (the
/// fused cloud, Lambert-shaded), `report.json`, `report.html` (every figure
/// and picture on one self-contained page), then `scan.ply`. When any write
/// fails, every file of this run is removed again.
pub fn write_scan(
    dir: &Path,
    scan: &ScanResult,
    progress: &mut dyn FnMut(Progress),
) -> Result<ScanReport, OutputError> {
    std::fs::create_dir_all(dir).map_err(|source| OutputError::Dir {
        path: dir.to_owned(),
        source,
    })?;
    progress(Progress::Stage {
        name: "write outputs",
        total: scan.heads.len() as u64 + 1,
    });
    let result = write_files(dir, scan, progress);
    progress(Progress::Done);
    if result.is_err() {
        output_set(dir).discard();
    }
    result
}

fn write_files(
    dir: &Path,
    scan: &ScanResult,
    progress: &mut dyn FnMut(Progress),
) -> Result<ScanReport, OutputError> {
    let mut page = Vec::new();
    for h in &scan.heads {
        let tag = h.name.to_lowercase();
        let pictures = head_pictures(&HeadPictures {
            head: &format!("head {}", h.name),
            reconstruction: &h.reconstruction,
            finest_period_px: scan.config.periods_px.first().copied().unwrap_or(1.0),
            frames: &h.frames,
            error_m: h.truth.as_ref().map(|t| &t.error_m),
        })?;
        for p in pictures {
            let file = format!("{}_{tag}.png", p.kind);
            save_bytes(&dir.join(&file), &p.png)?;
            page.push(PagePicture {
                file,
                caption: p.caption,
                png: p.png,
            });
        }
        if let Some(record) = &h.adaptive {
            write_adaptive_images(dir, &tag, record)?;
        }
        write_ply(&dir.join(format!("head_{tag}.ply")), &h.cloud_in_a)?;
        progress(Progress::Step);
    }
    if scan.fused.failure.is_none() {
        page.extend(write_cloud_pictures(
            dir,
            &scan.fused.cloud,
            scan.config.camera_px,
        )?);
    }
    if let Some(water) = &scan.underwater {
        page.extend(write_underwater_pictures(dir, water)?);
    }
    for h in &scan.heads {
        if let Some(sample) = &h.dealias_sample {
            page.push(write_dealias_picture(dir, h.name, sample)?);
        }
    }
    let report = report(scan);
    write_report(&dir.join("report.json"), &report)?;
    write_html(&dir.join("report.html"), &scan_page(&report, &page))?;
    // Without a fused cloud there is no scan: the per-head clouds and the
    // report say why.
    if scan.fused.failure.is_none() {
        write_ply(&dir.join("scan.ply"), &scan.fused.cloud)?;
    }
    progress(Progress::Step);
    Ok(report)
}

/// `cloud_{view}.png` for each of [`CLOUD_VIEWS`]: normals from the
/// cloud, else estimated by PCA (12 neighbours; the renderer ignores their
/// sign), else none (shaded by depth) when the cloud is too small for PCA.
fn write_cloud_pictures(
    dir: &Path,
    cloud: &crate::point_cloud::PointCloud,
    size_px: (u32, u32),
) -> Result<Vec<PagePicture>, OutputError> {
    let estimated: Option<Vec<[f32; 3]>> = match &cloud.normals {
        Some(_) => None,
        None => crate::fusion::estimate_normals(
            &super::clouds::points_f64(cloud),
            12,
            &nalgebra::Vector3::zeros(),
        )
        .ok()
        .map(|ns| {
            ns.iter()
                .map(|n| [n.x as f32, n.y as f32, n.z as f32])
                .collect()
        }),
    };
    let normals = cloud.normals.as_deref().or(estimated.as_deref());
    let splat = splat_radius_for(cloud.len(), size_px);
    let mut page = Vec::new();
    for (name, yaw_deg, pitch_deg) in CLOUD_VIEWS {
        let picture = match CloudView::framing(&cloud.points_m, yaw_deg, pitch_deg, size_px) {
            Some(view) => render_cloud(&cloud.points_m, normals, &view, splat),
            None => Raster::filled(
                size_px.0 as usize,
                size_px.1 as usize,
                crate::io::cloud_render::BACKGROUND,
            ),
        };
        let file = format!("cloud_{name}.png");
        let png = encode_rgb_png(&picture)?;
        save_bytes(&dir.join(&file), &png)?;
        page.push(PagePicture {
            file,
            caption: format!("fused cloud, {name} view (shaded by its normals)"),
            png,
        });
    }
    Ok(page)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stale_outputs_go_and_other_files_stay() {
        let dir = std::env::temp_dir().join(format!("slscan-stale-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for name in ["scan.ply", "report.json", "cloud_front.png", "notes.txt"] {
            std::fs::write(dir.join(name), b"old").unwrap();
        }
        remove_stale(&dir).unwrap();
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left, ["notes.txt"]);
        // Nothing there (or no folder at all) is fine.
        remove_stale(&dir).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        remove_stale(&dir).unwrap();
    }
}
