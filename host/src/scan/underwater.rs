//! A scan under water (issue 18, seed 002): every head looks through a flat
//! port, each captured phase-shift set is restored before decoding, and
//! every decoded pixel is triangulated through the ports.
//!
//! ```text
//! captured sets (period by period, `steps` frames each)
//!   --restore_captured (none | classical: Wiener + veil floor)--> decoded as in air
//!   --through_ports (finest absolute phase -> DMD column -> Snell at both ports)
//!   --blur edges (pixels within 2 PSF sigmas of a silhouette left out)--> cloud
//! ```
//!
//! In air the pinhole triangulation of the decoded columns would leave a
//! depth error of centimetres that no restoration removes, so a water scan
//! refuses a calibration without a port on every head.

use std::sync::Arc;
use std::time::Instant;

use super::{capture::Captured, Exposures, Mode, Progress, ScanConfig, ScanError, HEAD_NAMES};
use crate::calibration::{Head, RigCalibration};
use crate::raster::Raster;
use crate::reconstruct::{Reconstruction, Reconstructor};
use crate::triangulation::flat_port::{FlatPort, PortTriangulator};
use crate::underwater::edges;
pub use crate::underwater::edges::EDGE_MARGIN_SIGMAS;
use crate::underwater::learned::LearnedRestorer;
use crate::underwater::{ClassicalRestorer, RestoreError, RestoreParams, Veil};
use crate::unwrap::PixelStatus;

/// Default fringe periods under water, DMD pixels, finest first: seed
/// 004's three pitches of 21 / 16 / 12 fringes over the DMD width (61 / 80
/// / 107 px on 1280 px), as coarse as seed 002's 59 / 64 / 70 px so the
/// forward-scatter blur of turbid water leaves them modulation. Seed 002's
/// own set beats to 66,338 px only through a third heterodyne level whose
/// ~88x noise gain the twin's noise cannot carry: with it no pixel of the
/// `spheres` scene decodes, not even in air (measured; `--periods
/// 59,64,70` still runs it).
pub fn water_periods_px(dmd_width_px: u32) -> Vec<f64> {
    crate::patterns::three_pitch_periods_px(f64::from(dmd_width_px), 16).to_vec()
}

/// What the heads look through.
#[derive(Clone, Debug, Default)]
pub enum Medium {
    /// Air: pinhole triangulation, no restoration.
    #[default]
    Air,
    /// Water behind each head's flat port.
    Water(WaterScan),
}

/// Seed 002's turbidity levels, as the user names the water (the twin's
/// presets of the same names set its coefficients).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Turbidity {
    /// Relatively clear water.
    T1,
    /// Mildly turbid nearshore water.
    T2,
    /// Highly turbid, sediment-rich water.
    T3,
    /// Extremely turbid water, strong backscatter.
    T4,
}

impl Turbidity {
    /// "T1" .. "T4".
    pub fn name(self) -> &'static str {
        match self {
            Turbidity::T1 => "T1",
            Turbidity::T2 => "T2",
            Turbidity::T3 => "T3",
            Turbidity::T4 => "T4",
        }
    }
}

/// How a water scan restores its fringes before decoding.
#[derive(Clone, Debug)]
pub enum Restorer {
    /// The frames as the cameras took them.
    None,
    /// [`crate::underwater::ClassicalRestorer`]: Wiener deconvolution with
    /// the forward-scatter Gaussian, then the set's veil floor subtracted.
    Classical,
    /// A network trained on twin data ([`LearnedRestorer`]), loaded and
    /// checked against the scan's fringes before capture.
    Learned(Arc<LearnedRestorer>),
}

impl Restorer {
    /// Name for the report.
    pub fn name(&self) -> &'static str {
        match self {
            Restorer::None => "none",
            Restorer::Classical => "classical",
            Restorer::Learned(_) => "learned",
        }
    }
}

/// A scan under water.
#[derive(Clone, Debug)]
pub struct WaterScan {
    /// The level, when the user named one (for the report).
    pub turbidity: Option<Turbidity>,
    /// How each fringe set is restored.
    pub restorer: Restorer,
    /// The classical restorer's forward-scatter PSF sigma, camera pixels
    /// (the water's sigma per metre times the camera-side water path).
    pub psf_sigma_px: f64,
    /// Decoded pixels within this many PSF sigmas of a silhouette are left
    /// out ([`crate::underwater::edges`]; 0 keeps them).
    pub edge_margin_sigmas: f64,
}

/// What restoring a scan's frames did.
#[derive(Clone, Debug)]
pub struct RestoreFigures {
    /// The water scan it ran for.
    pub water: WaterScan,
    /// Phase-shift sets restored (every head, period and exposure).
    pub sets: usize,
    /// Frames restored.
    pub frames: usize,
    /// Network evaluations (0: the classical restorer has no network).
    pub evaluations: usize,
    /// Wall-clock time of the restoration, milliseconds.
    pub time_ms: f64,
    /// Pixels masked as NaN, saturated or not finite (every frame summed).
    pub masked_px: usize,
    /// Per head: its first fringe frame as captured and as decoded (after
    /// restoration), for the side-by-side picture.
    pub samples: Vec<(Raster<f32>, Raster<f32>)>,
    /// Per head: decoded pixels whose ray or column missed a port (left out).
    pub port_misses: Vec<usize>,
    /// Per head: decoded pixels within the blur margin of a silhouette (left out).
    pub blur_edge_px: Vec<usize>,
    /// Per head: the same first fringe frame through clear water (the
    /// ports' refraction only), noise-free, when a simulator can render it;
    /// empty on hardware.
    pub references: Vec<Raster<f32>>,
}

/// What a water scan refuses before any capture: a head without a port, a
/// mode or exposure kind it does not run, a classical restorer's bad PSF.
pub fn check_before_capture(
    calibration: &RigCalibration,
    config: &ScanConfig,
) -> Result<(), ScanError> {
    let Medium::Water(water) = &config.medium else {
        return Ok(());
    };
    if let Some(h) = calibration.heads.iter().position(|h| h.port.is_none()) {
        return Err(ScanError::NoPort {
            head: HEAD_NAMES.get(h).copied().unwrap_or("?"),
        });
    }
    if config.mode != Mode::Sequential {
        return Err(ScanError::WaterNeedsSequential { mode: config.mode });
    }
    if !matches!(config.exposures, Exposures::Single | Exposures::Multi(_)) {
        return Err(ScanError::ExposuresNeedSequential {
            mode: config.mode,
            exposures: "adaptive or auto exposure under water",
        });
    }
    if let Restorer::Classical = water.restorer {
        RestoreParams::new(water.psf_sigma_px)
            .validate()
            .map_err(ScanError::Restore)?;
    }
    let m = water.edge_margin_sigmas;
    if !(m.is_finite() && m >= 0.0) {
        return Err(ScanError::Restore(RestoreError::BadParameter {
            name: "edge margin (PSF sigmas)",
            value: m,
            why: "must be finite and >= 0",
        }));
    }
    Ok(())
}

/// Restores every captured phase-shift set of every head in place (the
/// frames the reconstruction reads; the raw frames stay for the pictures
/// and the saturation check). Masked pixels come back as 0, which no
/// modulation threshold passes.
pub fn restore_captured(
    captured: &mut Captured,
    water: &WaterScan,
    progress: &mut dyn FnMut(Progress),
) -> Result<RestoreFigures, ScanError> {
    let start = Instant::now();
    let steps = captured.steps.max(1);
    let mut figures = RestoreFigures {
        water: water.clone(),
        sets: 0,
        frames: 0,
        evaluations: 0,
        time_ms: 0.0,
        masked_px: 0,
        samples: Vec::new(),
        port_misses: Vec::new(),
        blur_edge_px: Vec::new(),
        references: Vec::new(),
    };
    let sets: usize = captured.frames.iter().map(|f| f.len() / steps).sum();
    progress(Progress::Stage {
        name: "restore",
        total: if let Restorer::None = water.restorer {
            0
        } else {
            sets as u64
        },
    });
    for frames in &mut captured.frames {
        let before = frames.first().cloned();
        match (&water.restorer, frames.first()) {
            (Restorer::Classical, Some(first)) => {
                // One restorer (FFT plans, Wiener gain) per camera: its frames share one size.
                let params = RestoreParams::new(water.psf_sigma_px);
                let r = ClassicalRestorer::new(first.width, first.height, params)
                    .map_err(ScanError::Restore)?;
                for set in frames.chunks_mut(steps) {
                    let refs: Vec<&Raster<f32>> = set.iter().collect();
                    let restored = r
                        .restore_set(&refs, Veil::Floor)
                        .map_err(ScanError::Restore)?;
                    figures.frames += restored.len();
                    for (frame, out) in set.iter_mut().zip(restored) {
                        figures.masked_px += out.masked;
                        *frame = out.image;
                    }
                    figures.sets += 1;
                    progress(Progress::Step);
                }
            }
            (Restorer::Learned(net), Some(_)) => {
                for set in frames.chunks_mut(steps) {
                    let refs: Vec<&Raster<f32>> = set.iter().collect();
                    let seed = figures.sets as u64;
                    let (restored, run) = net
                        .restore_set(&refs, seed)
                        .map_err(ScanError::RestoreNetwork)?;
                    figures.frames += restored.len();
                    figures.evaluations += run.evaluations;
                    for (frame, out) in set.iter_mut().zip(restored) {
                        figures.masked_px += out.data.iter().filter(|v| !v.is_finite()).count();
                        *frame = out;
                    }
                    figures.sets += 1;
                    progress(Progress::Step);
                }
            }
            _ => {}
        }
        for frame in frames.iter_mut() {
            frame
                .data
                .iter_mut()
                .filter(|v| !v.is_finite())
                .for_each(|v| *v = 0.0);
        }
        if let (Some(before), Some(after)) = (before, frames.first()) {
            figures.samples.push((before, after.clone()));
        }
    }
    progress(Progress::Done);
    figures.time_ms = start.elapsed().as_secs_f64() * 1e3;
    Ok(figures)
}

/// Head `h`'s decoded pixels triangulated again through its port: each
/// valid pixel's finest absolute phase is its DMD column, and the point is
/// where the camera's water ray meets that column's refracted surface.
/// Pixels whose ray or column misses the port are left out; the cloud is
/// compacted again. Returns the result and the pixels left out.
///
/// The predicted per-point sigma stays the in-air triangulation's (the
/// ports change the ray angles a little, not the phase noise).
pub fn through_port(
    rc: &Reconstructor,
    head: &Head,
    port: &FlatPort,
    recon: Reconstruction,
) -> Result<(Reconstruction, usize), ScanError> {
    let tri = PortTriangulator::new(&head.camera, port, &head.projector, port)
        .map_err(ScanError::Port)?;
    let px_per_rad = rc.config().periods_px[0] / std::f64::consts::TAU;
    let mut maps = recon.pixels;
    let columns: Vec<f32> = maps
        .phase_u
        .iter()
        .zip(&maps.status)
        .map(|(&p, &s)| {
            if s == PixelStatus::Valid {
                (f64::from(p) * px_per_rad) as f32
            } else {
                f32::NAN
            }
        })
        .collect();
    let hits = tri.intersect_columns(&columns).map_err(ScanError::Port)?;
    let mut misses = 0;
    for (i, hit) in hits.into_iter().enumerate() {
        if maps.status[i] != PixelStatus::Valid {
            continue;
        }
        match hit {
            Some(hit) => {
                for (axis, v) in maps.point_m.iter_mut().zip(hit.point_m.coords.iter()) {
                    axis[i] = *v as f32;
                }
                maps.depth_m[i] = hit.depth_m as f32;
            }
            None => {
                misses += 1;
                maps.mark_unreliable(i);
            }
        }
    }
    Ok((rc.from_maps(maps), misses))
}

/// One head's decoded pixels a water scan left out after decoding.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LeftOut {
    /// Pixels whose ray or column missed the port.
    pub port_misses: usize,
    /// Pixels within the blur margin of a silhouette.
    pub blur_edges: usize,
}

/// Head `head`'s decoded pixels triangulated through its port
/// ([`through_port`]), then those within `water`'s blur margin of a
/// silhouette left out ([`crate::underwater::edges`]).
pub fn finish_head(
    rc: &Reconstructor,
    head: &Head,
    port: &FlatPort,
    water: &WaterScan,
    recon: Reconstruction,
) -> Result<(Reconstruction, LeftOut), ScanError> {
    let (recon, port_misses) = through_port(rc, head, port, recon)?;
    let margin = edges::margin_px(water.psf_sigma_px, water.edge_margin_sigmas);
    if margin == 0 {
        if water.edge_margin_sigmas > 0.0 {
            tracing::warn!(
                "no forward-scatter PSF sigma known: pixels near silhouettes are kept (biased by \
                 the blur); give --water-psf-sigma-px to leave them out"
            );
        }
        return Ok((
            recon,
            LeftOut {
                port_misses,
                blur_edges: 0,
            },
        ));
    }
    let mut maps = recon.pixels;
    let blur_edges = edges::mark_blur_edges(&mut maps, margin);
    tracing::info!(
        pixels = blur_edges,
        margin_px = margin,
        "left out decoded pixels within the forward-scatter blur of a silhouette (--water-edge-margin 0 keeps them)"
    );
    Ok((
        rc.from_maps(maps),
        LeftOut {
            port_misses,
            blur_edges,
        },
    ))
}

/// The picture file of head `tag`'s captured and decoded fringe frame.
pub fn picture_file(tag: &str) -> String {
    format!("underwater_{tag}.png")
}
