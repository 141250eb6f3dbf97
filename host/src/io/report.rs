//! `report.json` of a scan: what was measured, in units a person reads
//! (micrometres, milliseconds, degrees), written atomically. Figures against
//! a ground truth are `Option`s: `null` on hardware, where there is none.

use std::path::Path;

use serde::Serialize;

/// One head's figures.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct HeadReport {
    /// "A" or "B".
    pub name: String,
    /// Valid points.
    pub points: usize,
    /// RMS distance of each valid pixel's point to its true point, micrometres.
    pub rmse_um: Option<f64>,
    /// Median of that distance, micrometres.
    pub median_error_um: Option<f64>,
    /// RMS of the predicted per-point sigma (phase-noise Cramer-Rao bound
    /// in metres along the ray), micrometres: the limit `rmse_um` meets
    /// (needs no truth, so present on hardware too).
    pub predicted_rms_um: f64,
    /// Valid pixels off by more than 1 mm (counted in the RMSE).
    pub outliers_over_1mm: Option<usize>,
    /// Point-to-plane RMSE against the true surface, micrometres.
    pub plane_rmse_um: Option<f64>,
    /// Fraction of the rig's measurable object surface this head covers.
    pub coverage: Option<f64>,
    /// Fraction of this camera's object pixels lit by its projector that were reconstructed.
    pub own_pixel_coverage: Option<f64>,
    /// This camera's pixels whose surface point both projectors light (truth).
    pub overlap_pixels: Option<usize>,
    /// Valid points among them.
    pub overlap_points: Option<usize>,
    /// `rmse_um` over those points only, micrometres (null when none).
    pub overlap_rmse_um: Option<f64>,
    /// Simultaneous mode: the overlap the flat fields measured against the
    /// twin's true overlap; null in the other modes and on hardware.
    pub aliased_mask: Option<AliasedMaskReport>,
    /// Simultaneous mode: how the pixels the other projector lights were
    /// treated; null in the other modes.
    pub dealias: Option<DealiasReport>,
    /// Each sphere of known size this head saw, fitted (empty without any).
    pub spheres: Vec<SphereReport>,
    /// Fitted minus true distance of the first two spheres' centres,
    /// micrometres (null unless this head fitted two).
    pub sphere_centre_distance_error_um: Option<f64>,
    /// How the fringes were exposed and what the exposure left.
    pub exposure: ExposureReport,
    /// Three or four heads: what multi-view registration did to this
    /// head's calibrated pose (null with one or two heads, and when
    /// registration failed).
    pub registration: Option<HeadRegistrationReport>,
    /// The pose fusion used for this head (head A's frame <- this head's)
    /// against the twin's true one: rotation, degrees (null for head A,
    /// with one head and without a truth).
    pub pose_error_vs_truth_deg: Option<f64>,
    /// The same: translation, micrometres.
    pub pose_error_vs_truth_um: Option<f64>,
}

/// One head's correction by multi-view registration.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct HeadRegistrationReport {
    /// Rotation added to the calibrated pose, degrees (0 for head A, which stays fixed).
    pub rotation_deg: f64,
    /// Translation added at the head's points, micrometres.
    pub translation_um: f64,
    /// Fraction of the head's points with an inlier in another head's cloud.
    pub fitness: f64,
}

/// Multi-view registration of three or four heads.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct MultiViewReport {
    /// Iterations.
    pub iterations: usize,
    /// Converged before the iteration limit.
    pub converged: bool,
    /// The calibration's check that needs no truth: "consistent", "head-to-head
    /// pose off" (a head's correction past 0.3 deg / 2 mm) or "camera
    /// intrinsics or projector model off" (a pair past 1.5x its noise or 30 um
    /// of shape).
    pub verdict: String,
    /// Per overlapping pair of heads, at the registered poses.
    pub pairs: Vec<PairReport>,
}

/// Two heads' agreement where they overlap.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PairReport {
    /// "A-B", "B-C", ...
    pub heads: String,
    /// Inlier point pairs, both directions counted.
    pub inliers: usize,
    /// RMS point-to-plane residual of the inliers, micrometres.
    pub overlap_rmse_um: f64,
    /// What the two heads' predicted per-point noise gives for it, micrometres.
    pub predicted_overlap_um: Option<f64>,
    /// Systematic shape disagreement over the overlap, micrometres (null
    /// when too small an overlap to tell).
    pub shape_disagreement_um: Option<f64>,
}

/// How a head's fringes were exposed and what the exposure left.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ExposureReport {
    /// `single`, `multi-exposure` or `adaptive-hdr`.
    pub kind: String,
    /// Camera images the head took (preliminaries included).
    pub images: usize,
    /// Exposure of each fringe set reconstructed, in standard exposures.
    pub exposure_scales: Vec<f64>,
    /// Frames taken of each fringe pattern and averaged (1: none).
    pub frames_per_pattern: usize,
    /// Fraction of the camera's pixels saturated in every fringe set
    /// (masked in the sequential mode).
    pub saturated_fraction: f64,
    /// Fraction of the camera's pixels below the modulation floor
    /// (saturated ones not counted).
    pub below_modulation_floor_fraction: f64,
    /// Adaptive projection: what it measured first and chose (null otherwise).
    pub adaptive: Option<AdaptiveReport>,
}

/// What adaptive projection measured before adapting, and chose.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct AdaptiveReport {
    /// The preliminary images: the grey floods, in projection order
    /// (written as `flood_{head}_{i}.png`), and one full-intensity fringe set.
    pub flood_files: Vec<String>,
    /// Each flood's red, green and blue levels (a grey flood has all three
    /// equal; the colour mode's are grey 0, grey 100 of 255, red, green, blue).
    pub flood_colours: Vec<[f32; 3]>,
    /// The adapted patterns as sent to the DMD (`adapted_{head}_{i}.png`).
    pub pattern_files: Vec<String>,
    /// The chosen exposure of the adapted fringes, in standard exposures.
    pub exposure_scale: f64,
    /// What limited it.
    pub exposure_limited_by: String,
    /// Fraction of the camera's pixels saturated in the full-intensity set.
    pub saturated_fraction_before: f64,
    /// Fraction below the modulation floor in it (saturated ones not counted).
    pub below_modulation_floor_fraction_before: f64,
    /// Fraction saturated in the brightest flood.
    pub saturated_fraction_full_flood: f64,
    /// Pixels that saturate even at the lowest lit flood (masked if they
    /// still saturate in the adapted set).
    pub saturates_at_lowest_pixels: usize,
    /// Pixels the chosen exposure cannot hold under the target even at the
    /// lowest usable level.
    pub cannot_hold_pixels: usize,
    /// Pixels projected at less than the full level.
    pub lowered_pixels: usize,
    /// Of those, placed on the DMD through their own phase.
    pub mapped_by_phase_pixels: usize,
    /// Of those, placed by a saturated cluster's homography.
    pub mapped_by_homography_pixels: usize,
    /// Of those, not placed (left at the full level).
    pub unmapped_pixels: usize,
    /// Saturated clusters mapped by homography.
    pub clusters: usize,
    /// Pixels of the adapted scan left out for straddling a step of the DMD
    /// level map (their fringe is bent).
    pub level_step_pixels: usize,
}

/// One camera's de-aliasing of the simultaneous mode's overlap.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct DealiasReport {
    /// `analytic`, `learned` or `mask`.
    pub method: String,
    /// Pixels the other projector lights (grown).
    pub affected_pixels: usize,
    /// Of those, lit by the own projector too: the ones tried.
    pub attempted_pixels: usize,
    /// Separated and reconstructed from the own fringe.
    pub separated_pixels: usize,
    /// Refused as ill-posed (the two phasors too alike).
    pub ill_posed_pixels: usize,
    /// Refused as not fitting the two-projector model.
    pub misfit_pixels: usize,
    /// Refused with no consistent solution.
    pub unsolved_pixels: usize,
    /// Refused as disagreeing with every pair of separated neighbours.
    pub inconsistent_pixels: usize,
    /// Refused for NaN or saturated input (learned).
    pub bad_input_pixels: usize,
    /// Learned: the network, its sampler steps (0 = one-step), tiles and
    /// network evaluations.
    pub network: Option<NetworkRunReport>,
    /// Wall time of this camera's de-aliasing, milliseconds.
    pub time_ms: u64,
    /// RMS error of the separated overlap pixels of the first fringe frame
    /// against the simulator's frame of the own projector alone, on the
    /// 8-bit scale of seed 000's figures (null on hardware or with none).
    pub error_vs_clean_rms_8bit: Option<f64>,
    /// The picture of the first frame as captured, de-aliased, clean and the
    /// error (null when no de-aliaser ran).
    pub picture: Option<String>,
}

/// What a learned de-aliaser ran for one camera.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct NetworkRunReport {
    /// The ONNX file.
    pub model: String,
    /// "onestep" or "diffusion".
    pub kind: String,
    /// Sampler steps per tile (1 for a one-step network).
    pub sampler_steps: usize,
    /// Tiles run.
    pub tiles: usize,
    /// Network evaluations (tiles x sampler steps).
    pub evaluations: usize,
}

/// One head's sphere fit of a sphere of known size.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct SphereReport {
    /// The sphere's name in the truth.
    pub name: String,
    /// Valid points on it.
    pub points: usize,
    /// True radius, millimetres.
    pub true_radius_mm: f64,
    /// Fitted radius, millimetres.
    pub radius_mm: f64,
    /// Fitted minus true radius, micrometres.
    pub radius_error_um: f64,
    /// Distance of the fitted centre from the true one, micrometres.
    pub centre_error_um: f64,
    /// RMS of the fit's radial residuals, micrometres.
    pub fit_rmse_um: f64,
    /// Its physical limit: the points' predicted sigma carried onto the
    /// sphere's normal, RMS, micrometres.
    pub noise_limit_um: f64,
}

/// One camera's overlap as the flat fields measured it, against the truth.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct AliasedMaskReport {
    /// Pixels the flat fields show lit by both projectors.
    pub measured_overlap_pixels: usize,
    /// Pixels the twin's truth says both projectors light.
    pub true_overlap_pixels: usize,
    /// Intersection over union of the two.
    pub iou: f64,
    /// Share of the true overlap that was measured.
    pub recall: f64,
}

/// The ICP refinement of the calibrated head-to-head pose.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct IcpReport {
    /// Rotation ICP added to the calibrated pose, degrees.
    pub rotation_deg: f64,
    /// Translation ICP added, micrometres.
    pub translation_um: f64,
    /// RMS point-to-plane residual of the overlap, micrometres.
    pub overlap_rmse_um: f64,
    /// Fraction of B's points with an inlier correspondence.
    pub fitness: f64,
    /// Iterations.
    pub iterations: usize,
    /// Converged before the iteration limit.
    pub converged: bool,
}

/// The fused cloud's figures.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FusedReport {
    /// Points.
    pub points: usize,
    /// Point-to-plane RMSE against the true surface, micrometres.
    pub rmse_um: Option<f64>,
    /// Fraction of the measurable object surface covered.
    pub coverage: Option<f64>,
    /// Registration of two heads (null when none ran: one head, heads with
    /// no shared surface, or three or more heads).
    pub icp: Option<IcpReport>,
    /// Registration of three or four heads, every pose at once (null otherwise).
    pub registration: Option<MultiViewReport>,
    /// B->A pose used (ICP-refined, or calibrated) against the twin's
    /// true pose: rotation, degrees.
    pub pose_error_vs_truth_deg: Option<f64>,
    /// The same: translation, micrometres.
    pub pose_error_vs_truth_um: Option<f64>,
    /// The calibration's checks that need no truth (null without ICP).
    pub self_check: Option<SelfCheckReport>,
    /// Why the heads could not be fused (null when they were): then there
    /// is no scan.ply, only the per-head clouds.
    pub failure: Option<String>,
}

/// The calibration's checks that need no truth.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct SelfCheckReport {
    /// "consistent", "head-to-head pose off", or "camera intrinsics or projector model off".
    pub verdict: String,
    /// ICP's rotation of the calibrated head-to-head pose, degrees.
    pub pose_correction_deg: f64,
    /// ICP's translation at the overlap, millimetres.
    pub pose_correction_mm: f64,
    /// Systematic shape disagreement of the registered heads, micrometres.
    pub shape_disagreement_um: Option<f64>,
    /// What noise alone gives for that figure, micrometres.
    pub shape_noise_um: Option<f64>,
    /// ICP's overlap residual, micrometres.
    pub overlap_rmse_um: f64,
    /// What the heads' predicted per-point noise gives for it, micrometres.
    pub predicted_overlap_um: f64,
}

/// Size of a rigid fit.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct FrameOffset {
    /// Rotation, degrees.
    pub rotation_deg: f64,
    /// Translation, micrometres.
    pub translation_um: f64,
}

/// The frame fits of the heads and of the fused cloud.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FrameFitReport {
    /// Per head: its calibrated camera frame onto the true camera frame.
    pub heads: Vec<FrameOffset>,
    /// The fused cloud's frame (head A's calibrated frame) onto head A's true frame.
    pub fused: FrameOffset,
}

/// Everything `report.json` holds.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ScanReport {
    /// Twin scene.
    pub scene: String,
    /// Capture mode.
    pub mode: String,
    /// Camera size (width, height), pixels.
    pub camera_px: (u32, u32),
    /// Projector size, pixels.
    pub projector_px: (u32, u32),
    /// Fringe periods, projector pixels.
    pub periods_px: Vec<f64>,
    /// Phase steps.
    pub steps: usize,
    /// Where the calibration came from: a rig file's path, or the twin's truth.
    pub calibration: String,
    /// An estimated calibration's error against the twin's truth (null with
    /// the truth itself, and on hardware).
    pub calibration_vs_truth: Option<crate::calibration::truth_error::RigTruthError>,
    /// Rigid fit of each cloud's calibrated frame onto the truth, applied
    /// before measuring (`slscan::scan::truth_frame`); null without a truth.
    pub truth_frame_fit: Option<FrameFitReport>,
    /// How truth figures are defined.
    pub truth_note: String,
    /// Samples of the measurable object surface (coverage denominator).
    pub surface_samples: Option<usize>,
    /// One per head, A first.
    pub heads: Vec<HeadReport>,
    /// The fused cloud.
    pub fused: FusedReport,
    /// Loud caveats of this run (e.g. aliased pixels masked out).
    pub warnings: Vec<String>,
    /// Wall-clock milliseconds per stage.
    pub timings_ms: std::collections::BTreeMap<String, f64>,
    /// A water scan: turbidity, restorer and what it cost (absent in air).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub underwater: Option<UnderwaterReport>,
}

/// What a water scan did to its frames and rays.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct UnderwaterReport {
    /// The turbidity level named for the scan ("T1".."T4"; null when none was named).
    pub turbidity: Option<String>,
    /// "none" or "classical".
    pub restorer: String,
    /// The classical restorer's forward-scatter PSF sigma, camera pixels.
    pub psf_sigma_px: f64,
    /// Phase-shift sets restored.
    pub sets_restored: usize,
    /// Frames restored.
    pub frames_restored: usize,
    /// A learned restorer's ONNX file (null for none and classical).
    pub restorer_model: Option<String>,
    /// A learned restorer's sampler steps per tile (1 for a one-step
    /// network; null for none and classical).
    pub sampler_steps: Option<usize>,
    /// Network evaluations (0 for the classical restorer: no network).
    pub evaluations: usize,
    /// A diffusion restorer's physics-gradient correction strength after
    /// every sampler step (null: none).
    pub physics_correction: Option<f32>,
    /// Wall-clock time of the restoration, milliseconds.
    pub restore_time_ms: f64,
    /// Frame pixels masked by the restorer (NaN, saturated), all frames summed.
    pub masked_pixels: usize,
    /// Per head: decoded pixels whose ray or column missed its flat port.
    pub port_misses: Vec<usize>,
    /// Decoded pixels within this many forward-scatter PSF sigmas of a
    /// silhouette are left out (0: kept).
    pub edge_margin_sigmas: f64,
    /// Per head: decoded pixels left out for being within that margin.
    pub blur_edge_pixels: Vec<usize>,
    /// How the points were triangulated.
    pub triangulation: String,
    /// Per head: the side-by-side picture of its first fringe frame as
    /// captured, as decoded and (simulator only) through clear water.
    pub picture_files: Vec<String>,
}

/// What can go wrong writing the report.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// Serialisation failed (a non-finite number is written as null, so this is rare).
    #[error("report to JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// The file could not be written.
    #[error("writing {path}: {source}")]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The error.
        source: std::io::Error,
    },
}

/// A report figure for people (console, page): `v` with `decimals` and its
/// unit, or "n/a" when it does not exist (no truth, no points: `None` or NaN).
pub fn figure(v: Option<f64>, decimals: usize, unit: &str) -> String {
    match v.filter(|v| v.is_finite()) {
        Some(v) => format!("{v:.decimals$} {unit}").trim_end().to_string(),
        None => "n/a".into(),
    }
}

/// Writes `report` as pretty JSON (temporary file, then rename).
pub fn write_report(path: &Path, report: &ScanReport) -> Result<(), ReportError> {
    let text = serde_json::to_string_pretty(report)?;
    super::write_atomically(path, |w| w.write_all(text.as_bytes())).map_err(|source| {
        ReportError::Io {
            path: path.to_owned(),
            source,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_figures_become_null_and_the_file_appears_whole() {
        let dir = std::env::temp_dir().join(format!("slscan-report-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let head = HeadReport {
            name: "A".into(),
            points: 0,
            rmse_um: Some(f64::NAN),
            median_error_um: None,
            predicted_rms_um: f64::NAN,
            outliers_over_1mm: Some(0),
            plane_rmse_um: Some(1.0),
            coverage: None,
            own_pixel_coverage: Some(0.0),
            overlap_pixels: Some(0),
            overlap_points: Some(0),
            overlap_rmse_um: Some(f64::NAN),
            aliased_mask: None,
            dealias: None,
            spheres: Vec::new(),
            sphere_centre_distance_error_um: None,
            exposure: ExposureReport {
                kind: "single".into(),
                images: 12,
                exposure_scales: vec![1.0],
                frames_per_pattern: 1,
                saturated_fraction: 0.0,
                below_modulation_floor_fraction: f64::NAN,
                adaptive: None,
            },
            registration: None,
            pose_error_vs_truth_deg: None,
            pose_error_vs_truth_um: None,
        };
        let report = ScanReport {
            scene: "x".into(),
            mode: "sequential".into(),
            camera_px: (4, 3),
            projector_px: (8, 6),
            periods_px: vec![1.0],
            steps: 4,
            calibration: "truth".into(),
            calibration_vs_truth: None,
            truth_frame_fit: None,
            truth_note: String::new(),
            surface_samples: None,
            heads: vec![head],
            fused: FusedReport {
                points: 0,
                rmse_um: None,
                coverage: Some(0.0),
                icp: Some(IcpReport {
                    rotation_deg: 0.0,
                    translation_um: 0.0,
                    overlap_rmse_um: 0.0,
                    fitness: 0.0,
                    iterations: 0,
                    converged: true,
                }),
                registration: None,
                pose_error_vs_truth_deg: None,
                pose_error_vs_truth_um: Some(0.0),
                self_check: None,
                failure: None,
            },
            warnings: Vec::new(),
            timings_ms: [("setup".to_string(), 1.0)].into(),
            underwater: None,
        };
        let path = dir.join("report.json");
        write_report(&path, &report).unwrap();
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        assert!(v["heads"][0]["rmse_um"].is_null());
        // No truth (hardware): null, not 0 or NaN.
        assert!(v["heads"][0]["coverage"].is_null());
        assert!(v["fused"]["rmse_um"].is_null());
        assert!(v["surface_samples"].is_null());
        assert_eq!(v["heads"][0]["plane_rmse_um"], 1.0);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
