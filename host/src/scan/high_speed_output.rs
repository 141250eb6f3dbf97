//! Writes a high-speed scan: per camera frame its colour exposure and the 24
//! depth maps in time order, one animated GIF of every instant, one PLY whose
//! points carry their instant (`t_us`, `frame`, `pattern`), and `report.json`
//! with the figures per instant. Earlier runs' files go first, a failed write
//! removes this run's, and the PLY comes last.

use std::io::Write;
use std::path::Path;

use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, Frame, RgbaImage};
use serde::Serialize;

use super::high_speed::{HighSpeedResult, InstantSphere, InstantTruth, SphereFit};
use super::output::OutputError;
use crate::io::images::{encode_rgb_png, save_bytes};
use crate::io::outputs::OutputSet;
use crate::io::picture::{draw, ColourMap, PictureSpec, PixelClass, Range};
use crate::io::write_atomically;
use crate::raster::Raster;

/// Most camera frames a high-speed scan writes (the names cleared before a run).
pub const MAX_FRAMES: usize = 16;
const LED_NAMES: [&str; 3] = ["R", "G", "B"];

fn exposure_file(f: usize) -> String {
    format!("exposure_{f:02}.png")
}

fn depth_file(f: usize, m: usize) -> String {
    format!("depth_{f:02}_{m:02}.png")
}

/// Every file [`write_high_speed`] may write.
pub fn output_files() -> Vec<String> {
    let mut files: Vec<String> = ["high_speed.ply", "report.json", "depth.gif"]
        .map(String::from)
        .to_vec();
    for f in 0..MAX_FRAMES {
        files.push(exposure_file(f));
        files.extend((0..24).map(|m| depth_file(f, m)));
    }
    files
}

/// The report of one instant.
#[derive(Clone, Debug, Serialize)]
pub struct InstantReport {
    /// Camera frame.
    pub frame: usize,
    /// Pattern index (projection order).
    pub pattern: usize,
    /// Fringe direction, from 1.
    pub direction: u32,
    /// LED.
    pub led: &'static str,
    /// Board-clock time of the pattern's middle, microseconds since the scan's first.
    pub t_us: f64,
    /// Decoded points.
    pub points: usize,
    /// Figures against the truth at this instant (absent without one).
    #[serde(flatten)]
    pub truth: TruthReport,
}

/// A depth map against the truth at its instant.
#[derive(Clone, Debug, Default, Serialize)]
pub struct TruthReport {
    /// Object coverage.
    pub coverage: Option<f64>,
    /// Depth RMSE, micrometres.
    pub depth_rmse_um: Option<f64>,
    /// Median absolute depth error, micrometres.
    pub depth_median_um: Option<f64>,
    /// Decoded object pixels more than 1 mm off.
    pub over_1mm: Option<usize>,
    /// Coverage of the object's interior (pixels at least
    /// `INTERIOR_MARGIN_PX` from another object).
    pub interior_coverage: Option<f64>,
    /// Depth RMSE over the interior, micrometres.
    pub interior_depth_rmse_um: Option<f64>,
    /// Median absolute depth error over the interior, micrometres.
    pub interior_depth_median_um: Option<f64>,
    /// Spheres fitted.
    pub spheres: Vec<SphereReport>,
}

impl TruthReport {
    /// The figures of `truth`, all absent without one.
    fn of(truth: Option<&InstantTruth>) -> Self {
        let Some(t) = truth else {
            return Self::default();
        };
        TruthReport {
            coverage: Some(t.coverage),
            depth_rmse_um: Some(t.depth_rmse_m * 1e6),
            depth_median_um: Some(t.depth_median_m * 1e6),
            over_1mm: Some(t.over_1mm),
            interior_coverage: Some(t.interior.coverage),
            interior_depth_rmse_um: Some(t.interior.depth_rmse_m * 1e6),
            interior_depth_median_um: Some(t.interior.depth_median_m * 1e6),
            spheres: t.spheres.iter().map(sphere_report).collect(),
        }
    }
}

/// The conventional capture beside the high-speed one (see
/// [`super::high_speed::ConventionalResult`]).
#[derive(Clone, Debug, Serialize)]
pub struct ConventionalReport {
    /// Camera frames (grey fringes, one each).
    pub frames: usize,
    /// From its first pattern's start to its last one's end, milliseconds.
    pub duration_ms: f64,
    /// Board-clock time of its middle, microseconds since the high-speed
    /// scan's first instant.
    pub t_us: f64,
    /// Decoded points.
    pub points: usize,
    /// Figures against the truth at its middle.
    #[serde(flatten)]
    pub truth: TruthReport,
}

/// A sphere fitted at one instant: all its decoded points, and its interior's.
#[derive(Clone, Debug, Serialize)]
pub struct SphereReport {
    /// Name in the truth.
    pub name: String,
    /// The fit of all its decoded points.
    #[serde(flatten)]
    pub whole: SphereFitReport,
    /// The fit of its interior points (at least
    /// [`INTERIOR_MARGIN_PX`](super::high_speed::INTERIOR_MARGIN_PX) from
    /// another object); absent under the minimum point count.
    pub interior: Option<SphereFitReport>,
}

/// One sphere fit's figures.
#[derive(Clone, Debug, Serialize)]
pub struct SphereFitReport {
    /// Points.
    pub points: usize,
    /// Fit RMSE, micrometres.
    pub fit_rmse_um: f64,
    /// Radius error, micrometres.
    pub radius_error_um: f64,
    /// Centre error, micrometres.
    pub centre_error_um: f64,
}

/// `report.json` of a high-speed scan.
#[derive(Clone, Debug, Serialize)]
pub struct HighSpeedReport {
    /// Always "high-speed".
    pub mode: &'static str,
    /// What was scanned.
    pub scene: String,
    /// 3D frames per second (one per pattern).
    pub pattern_rate_hz: f64,
    /// Camera frames per second.
    pub camera_rate_hz: f64,
    /// Camera frames.
    pub frames: usize,
    /// The decoder: "analytic", or which of seed 001's networks joined the
    /// analytic stages (ZOCR-Net first, FDD-Net third; the second is done by
    /// formula, see `sibling_cancellations`).
    pub decoder: &'static str,
    /// The first stage's network file, when ZOCR-Net ran.
    pub zocr_model: Option<String>,
    /// The third stage's network file, when FDD-Net ran.
    pub fdd_model: Option<String>,
    /// Demodulations after the first, each by the last one's phase (0: the
    /// single pass).
    pub demodulation_refinements: u32,
    /// Passes of sibling cancellation (seed 001's second stage by formula;
    /// 0: the single demodulation).
    pub sibling_cancellations: u32,
    /// Decodes after the first, each on carriers predicted from the depth
    /// the last one's patterns agree on (0: none).
    pub consensus_passes: u32,
    /// Whether the consensus passes settled their holes at depth edges.
    pub settle_edges: bool,
    /// The measured channel <- LED crosstalk, row per camera channel.
    pub crosstalk: [[f64; 3]; 3],
    /// Seconds decoding each frame took.
    pub decode_s: Vec<f64>,
    /// Whether the figures were measured with the twin's true calibration.
    pub calibration_is_true: bool,
    /// Every instant in time order.
    pub instants: Vec<InstantReport>,
    /// The conventional 12-frame capture of the same motion, when run.
    pub conventional: Option<ConventionalReport>,
}

fn sphere_report(s: &InstantSphere) -> SphereReport {
    let fit = |f: &SphereFit| SphereFitReport {
        points: f.points,
        fit_rmse_um: f.fit_rmse_m * 1e6,
        radius_error_um: f.radius_error_m * 1e6,
        centre_error_um: f.centre_error_m * 1e6,
    };
    SphereReport {
        name: s.name.clone(),
        whole: fit(&s.whole),
        interior: s.interior.as_ref().map(fit),
    }
}

/// The report of `scan`.
pub fn report(scan: &HighSpeedResult) -> HighSpeedReport {
    let t0 = scan
        .frames
        .first()
        .and_then(|f| f.instants.first())
        .map_or(0.0, |i| i.time_s);
    let instants = scan
        .frames
        .iter()
        .flat_map(|f| &f.instants)
        .map(|i| InstantReport {
            frame: i.frame,
            pattern: i.pattern.index,
            direction: i.pattern.direction,
            led: LED_NAMES[i.pattern.colour],
            t_us: (i.time_s - t0) * 1e6,
            points: i.cloud.len(),
            truth: TruthReport::of(i.truth.as_ref()),
        })
        .collect();
    let conventional = scan.conventional.as_ref().map(|c| ConventionalReport {
        frames: c.frames,
        duration_ms: c.duration_s * 1e3,
        t_us: (c.time_s - t0) * 1e6,
        points: c.depth_m.data.iter().filter(|z| z.is_finite()).count(),
        truth: TruthReport::of(c.truth.as_ref()),
    });
    let m = scan.crosstalk;
    HighSpeedReport {
        mode: "high-speed",
        scene: scan.scene.clone(),
        pattern_rate_hz: scan.pattern_rate_hz,
        camera_rate_hz: scan.camera_rate_hz,
        frames: scan.frames.len(),
        decoder: match (scan.zocr_model.is_some(), scan.fdd_model.is_some()) {
            (false, false) => "analytic",
            (true, false) => "ZOCR-Net + analytic demodulation",
            (false, true) => "analytic + FDD-Net",
            (true, true) => "ZOCR-Net + analytic demodulation + FDD-Net",
        },
        zocr_model: scan.zocr_model.as_ref().map(|p| p.display().to_string()),
        fdd_model: scan.fdd_model.as_ref().map(|p| p.display().to_string()),
        demodulation_refinements: scan.demodulation_refinements,
        sibling_cancellations: scan.sibling_cancellations,
        consensus_passes: scan.consensus_passes,
        settle_edges: scan.settle_edges,
        crosstalk: [0, 1, 2].map(|r| [0, 1, 2].map(|c| m[(r, c)])),
        decode_s: scan.frames.iter().map(|f| f.decode_s).collect(),
        calibration_is_true: scan.calibration_is_true,
        instants,
        conventional,
    }
}

/// Clears an earlier run's files from `dir` (before the rig is touched).
pub fn remove_stale(dir: &Path) -> Result<(), OutputError> {
    Ok(OutputSet::in_dir(dir, output_files()).clear()?)
}

/// Writes `scan` into `dir` (at most [`MAX_FRAMES`] frames); `depth_range_m`
/// spans the depth pictures' colour map.
pub fn write_high_speed(
    dir: &Path,
    scan: &HighSpeedResult,
    depth_range_m: (f64, f64),
) -> Result<HighSpeedReport, OutputError> {
    std::fs::create_dir_all(dir).map_err(|source| OutputError::Dir {
        path: dir.to_owned(),
        source,
    })?;
    let result = write_files(dir, scan, depth_range_m);
    if result.is_err() {
        OutputSet::in_dir(dir, output_files()).discard();
    }
    result
}

fn io_error(path: &Path, source: std::io::Error) -> OutputError {
    OutputError::Write {
        path: path.to_owned(),
        source,
    }
}

fn write_files(
    dir: &Path,
    scan: &HighSpeedResult,
    depth_range_m: (f64, f64),
) -> Result<HighSpeedReport, OutputError> {
    let mut gif_frames = Vec::new();
    for (f, frame) in scan.frames.iter().take(MAX_FRAMES).enumerate() {
        let rgb = exposure_rgb(&frame.exposure);
        save_bytes(&dir.join(exposure_file(f)), &encode_png(&rgb)?)?;
        for instant in &frame.instants {
            let mm = Raster {
                width: instant.depth_m.width,
                height: instant.depth_m.height,
                data: instant.depth_m.data.iter().map(|z| z * 1000.0).collect(),
            };
            let classes = Raster {
                width: mm.width,
                height: mm.height,
                data: mm
                    .data
                    .iter()
                    .map(|z| {
                        if z.is_finite() {
                            PixelClass::Value
                        } else {
                            PixelClass::NoFringe
                        }
                    })
                    .collect(),
            };
            let title = format!(
                "frame {f}, pattern {} (direction {}, {}): depth",
                instant.pattern.index, instant.pattern.direction, LED_NAMES[instant.pattern.colour]
            );
            let picture = draw(
                &mm,
                &classes,
                &PictureSpec {
                    title: &title,
                    unit: "mm",
                    range: Range::Fixed {
                        lo: depth_range_m.0 * 1000.0,
                        hi: depth_range_m.1 * 1000.0,
                    },
                    map: ColourMap::Viridis,
                },
            );
            save_bytes(
                &dir.join(depth_file(f, instant.pattern.index)),
                &encode_png(&picture.image)?,
            )?;
            gif_frames.push(picture.image);
        }
    }
    let gif = dir.join("depth.gif");
    write_atomically(&gif, |w| write_gif(w, &gif_frames)).map_err(|e| io_error(&gif, e))?;
    let report = report(scan);
    let json = dir.join("report.json");
    let text = serde_json::to_string_pretty(&report).map_err(|e| io_error(&json, e.into()))?;
    write_atomically(&json, |w| w.write_all(text.as_bytes())).map_err(|e| io_error(&json, e))?;
    let ply = dir.join("high_speed.ply");
    write_atomically(&ply, |w| write_timed_ply(w, scan)).map_err(|e| io_error(&ply, e))?;
    Ok(report)
}

fn encode_png(img: &Raster<[u8; 3]>) -> Result<Vec<u8>, OutputError> {
    encode_rgb_png(img).map_err(|e| OutputError::Write {
        path: "png".into(),
        source: std::io::Error::other(e),
    })
}

/// The exposure as 8-bit RGB.
fn exposure_rgb(planes: &[Raster<f32>; 3]) -> Raster<[u8; 3]> {
    let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    Raster {
        width: planes[0].width,
        height: planes[0].height,
        data: (0..planes[0].data.len())
            .map(|i| {
                [
                    q(planes[0].data[i]),
                    q(planes[1].data[i]),
                    q(planes[2].data[i]),
                ]
            })
            .collect(),
    }
}

/// Every instant's picture as one GIF, 1 frame per 100 ms, looping.
fn write_gif(w: &mut dyn Write, pictures: &[Raster<[u8; 3]>]) -> std::io::Result<()> {
    let mut encoder = GifEncoder::new_with_speed(w, 20);
    encoder
        .set_repeat(Repeat::Infinite)
        .map_err(std::io::Error::other)?;
    for p in pictures {
        let mut rgba = RgbaImage::new(p.width as u32, p.height as u32);
        for (px, c) in rgba.pixels_mut().zip(&p.data) {
            *px = image::Rgba([c[0], c[1], c[2], 255]);
        }
        encoder
            .encode_frame(Frame::from_parts(
                rgba,
                0,
                0,
                Delay::from_numer_denom_ms(100, 1),
            ))
            .map_err(std::io::Error::other)?;
    }
    Ok(())
}

/// Binary PLY of every decoded point, camera frame, metres, with its instant.
fn write_timed_ply(w: &mut dyn Write, scan: &HighSpeedResult) -> std::io::Result<()> {
    let t0 = scan
        .frames
        .first()
        .and_then(|f| f.instants.first())
        .map_or(0.0, |i| i.time_s);
    let count: usize = scan
        .frames
        .iter()
        .flat_map(|f| &f.instants)
        .map(|i| i.cloud.len())
        .sum();
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment slscan high-speed scan, metres, camera frame; t_us: board-clock time of the point's pattern since the first\nelement vertex {count}\nproperty float x\nproperty float y\nproperty float z\nproperty float t_us\nproperty uchar frame\nproperty uchar pattern\nend_header\n"
    );
    w.write_all(header.as_bytes())?;
    let mut rec = Vec::with_capacity(18);
    for instant in scan.frames.iter().flat_map(|f| &f.instants) {
        let t_us = ((instant.time_s - t0) * 1e6) as f32;
        for p in &instant.cloud.points_m {
            rec.clear();
            for c in p {
                rec.extend_from_slice(&c.to_le_bytes());
            }
            rec.extend_from_slice(&t_us.to_le_bytes());
            rec.push(instant.frame.min(255) as u8);
            rec.push(instant.pattern.index as u8);
            w.write_all(&rec)?;
        }
    }
    Ok(())
}
