//! The pictures of one head's reconstruction, each named by what it shows:
//! the camera's mean image, the decoded projector column, depth, fringe
//! modulation and (with a truth) the error. Each pixel without a value is
//! drawn as what it is: no fringe, masked, unreliable or saturated.

use crate::io::images::{encode_rgb_png, ExposureLimits};
use crate::io::picture::{draw, ColourMap, PictureSpec, PixelClass, Range};
use crate::raster::Raster;
use crate::reconstruct::Reconstruction;
use crate::unwrap::PixelStatus;

/// The picture kinds of a head, in file-name form (`{kind}_{head}.png`, or
/// `{kind}.png` for one unnamed head).
pub const KINDS: [&str; 5] = [
    "camera_mean",
    "projector_column",
    "depth",
    "fringe_modulation",
    "error_vs_truth",
];

/// Full scale of the error picture, micrometres (about 5x the scan's noise).
pub const ERROR_FULL_SCALE_UM: f64 = 500.0;

/// A masked pixel whose frames span less than this share of full scale saw
/// no fringe at all (shadow, off the object) rather than an unusable one
/// (a fringe of modulation 0.02 spans 0.04, plus the noise's spread).
const NO_FRINGE_RANGE: f32 = 0.05;

/// What the pictures are drawn from.
pub struct HeadPictures<'a> {
    /// Title prefix, e.g. "head A".
    pub head: &'a str,
    /// The reconstruction.
    pub reconstruction: &'a Reconstruction,
    /// The finest column period, projector pixels (phase -> column).
    pub finest_period_px: f64,
    /// The mean of the camera's frames and where they saturated.
    pub frames: &'a FrameSummary,
    /// Per-pixel error against the truth, metres (NaN where not measured).
    pub error_m: Option<&'a Raster<f32>>,
}

/// The mean of a camera's frames and which pixels reached full scale in any.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameSummary {
    /// Mean over the frames, [0, 1].
    pub mean: Raster<f32>,
    /// At or above the saturation level in at least one frame.
    pub saturated: Raster<bool>,
    /// Brightest minus darkest value over the frames.
    pub range: Raster<f32>,
}

/// The mean and the saturated pixels of `frames` (all the same size; none
/// gives an empty summary).
pub fn summarise_frames(frames: &[Raster<f32>]) -> FrameSummary {
    let level = ExposureLimits::default().saturation_level;
    let (w, h) = frames.first().map_or((0, 0), |f| f.size());
    let mut mean = Raster::filled(w, h, 0.0f32);
    let mut saturated = Raster::filled(w, h, false);
    let mut lo = Raster::filled(w, h, f32::INFINITY);
    let mut hi = Raster::filled(w, h, f32::NEG_INFINITY);
    for f in frames {
        for (i, &v) in f.data.iter().enumerate() {
            mean.data[i] += v;
            saturated.data[i] |= v >= level;
            lo.data[i] = lo.data[i].min(v);
            hi.data[i] = hi.data[i].max(v);
        }
    }
    let n = frames.len().max(1) as f32;
    mean.data.iter_mut().for_each(|m| *m /= n);
    let range = Raster {
        width: w,
        height: h,
        data: hi.data.iter().zip(&lo.data).map(|(h, l)| h - l).collect(),
    };
    FrameSummary {
        mean,
        saturated,
        range,
    }
}

/// What each pixel of the reconstruction shows: a value where it has one
/// (the reconstruction accepted it), else why not: saturated frames, no
/// fringe seen, masked, or refused by the order check.
pub fn classes(rec: &Reconstruction, frames: &FrameSummary) -> Raster<PixelClass> {
    let p = &rec.pixels;
    let sized = frames.saturated.size() == p.size();
    Raster::from_fn(p.width, p.height, |x, y| {
        let i = y * p.width + x;
        if p.status[i] == PixelStatus::Valid {
            return PixelClass::Value;
        }
        if sized && frames.saturated.data[i] {
            return PixelClass::Saturated;
        }
        match p.status[i] {
            PixelStatus::Masked if sized && frames.range.data[i] < NO_FRINGE_RANGE => {
                PixelClass::NoFringe
            }
            PixelStatus::Valid | PixelStatus::Masked => PixelClass::Masked,
            PixelStatus::Unreliable | PixelStatus::Unreached => PixelClass::Unreliable,
        }
    })
}

/// One encoded picture and its file-name kind.
pub struct Encoded {
    /// One of [`KINDS`].
    pub kind: &'static str,
    /// What it shows, for the report page.
    pub caption: String,
    /// PNG bytes.
    pub png: Vec<u8>,
}

/// Draws and encodes every picture of a head ([`KINDS`]; the error only
/// with a truth).
pub fn head_pictures(h: &HeadPictures) -> Result<Vec<Encoded>, image::ImageError> {
    let rec = h.reconstruction;
    let classes = classes(rec, h.frames);
    let (w, height) = rec.pixels.size();
    let map_of = |data: Vec<f32>| Raster {
        width: w,
        height,
        data,
    };
    let column = map_of(
        rec.pixels
            .phase_u
            .iter()
            .map(|p| p * (h.finest_period_px / std::f64::consts::TAU) as f32)
            .collect(),
    );
    let depth_mm = map_of(rec.pixels.depth_m.iter().map(|d| d * 1e3).collect());
    let modulation = map_of(rec.pixels.modulation.iter().map(|m| m * 100.0).collect());
    // The camera image shows every pixel; only saturation is marked.
    let camera_classes = Raster {
        width: w,
        height,
        data: h
            .frames
            .saturated
            .data
            .iter()
            .map(|&s| {
                if s {
                    PixelClass::Saturated
                } else {
                    PixelClass::Value
                }
            })
            .collect(),
    };
    let mut out = Vec::new();
    let mut add = |kind: &'static str,
                   caption: String,
                   values: &Raster<f32>,
                   classes: &Raster<PixelClass>,
                   unit: &str,
                   range: Range,
                   map: ColourMap|
     -> Result<(), image::ImageError> {
        let picture = draw(
            values,
            classes,
            &PictureSpec {
                title: &caption,
                unit,
                range,
                map,
            },
        );
        out.push(Encoded {
            kind,
            caption,
            png: encode_rgb_png(&picture.image)?,
        });
        Ok(())
    };
    if h.frames.mean.size() == (w, height) {
        add(
            "camera_mean",
            format!("{}: camera, mean of its frames", h.head),
            &h.frames.mean,
            &camera_classes,
            "of full scale",
            Range::Robust,
            ColourMap::Grey,
        )?;
    }
    add(
        "projector_column",
        format!("{}: decoded projector column", h.head),
        &column,
        &classes,
        "DMD px",
        Range::Robust,
        ColourMap::Viridis,
    )?;
    add(
        "depth",
        format!("{}: depth along the camera axis", h.head),
        &depth_mm,
        &classes,
        "mm",
        Range::Robust,
        ColourMap::Viridis,
    )?;
    add(
        "fringe_modulation",
        format!("{}: fringe modulation (weakest period)", h.head),
        // Modulation exists wherever light fell: only saturation is marked.
        &modulation,
        &camera_classes,
        "% of full scale",
        Range::Fixed { lo: 0.0, hi: 50.0 },
        ColourMap::Viridis,
    )?;
    if let Some(err) = h.error_m {
        let um = map_of(err.data.iter().map(|e| e * 1e6).collect());
        add(
            "error_vs_truth",
            format!("{}: point error against the twin's truth", h.head),
            &um,
            &classes,
            "um",
            Range::Fixed {
                lo: 0.0,
                hi: ERROR_FULL_SCALE_UM,
            },
            ColourMap::Viridis,
        )?;
    }
    Ok(out)
}

/// Frames side by side, 8 px apart (gap black), each stretched from its own
/// 1st to 99th percentile of finite values to [0, 1] so a faint, veiled
/// fringe shows as well as a restored one. Frames of unequal height are
/// top-aligned.
pub fn side_by_side(frames: &[&Raster<f32>]) -> Raster<f32> {
    const GAP: usize = 8;
    let height = frames.iter().map(|f| f.height).max().unwrap_or(0);
    let width =
        frames.iter().map(|f| f.width).sum::<usize>() + GAP * frames.len().saturating_sub(1);
    let mut out = Raster::filled(width, height, 0.0f32);
    let mut x0 = 0;
    for f in frames {
        let (lo, hi) = percentile_range(&f.data);
        let scale = if hi > lo { 1.0 / (hi - lo) } else { 0.0 };
        for y in 0..f.height {
            let src = &f.data[y * f.width..(y + 1) * f.width];
            let dst = &mut out.data[y * width + x0..y * width + x0 + f.width];
            for (d, &s) in dst.iter_mut().zip(src) {
                *d = if s.is_finite() {
                    ((s - lo) * scale).clamp(0.0, 1.0)
                } else {
                    0.0
                };
            }
        }
        x0 += f.width + GAP;
    }
    out
}

/// The 1st and 99th percentiles of the finite values (0, 0 when none).
fn percentile_range(values: &[f32]) -> (f32, f32) {
    let mut v: Vec<f32> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if v.is_empty() {
        return (0.0, 0.0);
    }
    v.sort_unstable_by(f32::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    (at(0.01), at(0.99))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_summary_is_the_mean_and_any_full_scale_frame_saturates() {
        let a = Raster::from_fn(4, 2, |x, _| x as f32 * 0.1);
        let mut b = a.clone();
        b.data[3] = 1.0;
        let s = summarise_frames(&[a, b]);
        assert!((s.mean.data[1] - 0.1).abs() < 1e-6);
        assert!((s.mean.data[3] - 0.65).abs() < 1e-6);
        assert_eq!(s.saturated.data.iter().filter(|&&v| v).count(), 1);
        assert!(s.saturated.data[3]);
        assert!(summarise_frames(&[]).mean.is_empty());
    }

    /// A 64x48 reconstruction: a valid ramp, and a band of each other status.
    fn reconstruction() -> (Reconstruction, FrameSummary) {
        let (w, h) = (64, 48);
        let status: Vec<PixelStatus> = (0..w * h)
            .map(|i| match i % w {
                0..=7 => PixelStatus::Masked,
                8..=15 => PixelStatus::Unreliable,
                _ => PixelStatus::Valid,
            })
            .collect();
        let ramp = |scale: f32| {
            (0..w * h)
                .map(|i| (i % w) as f32 * scale)
                .collect::<Vec<_>>()
        };
        let pixels = crate::reconstruct::PixelMaps {
            width: w,
            height: h,
            status,
            phase_u: ramp(0.1),
            point_m: [ramp(1e-3), ramp(1e-3), ramp(1e-3)],
            depth_m: ramp(1e-3),
            sigma_m: ramp(1e-6),
            modulation: ramp(0.004),
            background: ramp(0.01),
        };
        // Frames: dark where x < 4 (no fringe), lit elsewhere, one saturated row.
        let frames: Vec<Raster<f32>> = (0..4)
            .map(|k| {
                Raster::from_fn(w, h, |x, y| match (x, y) {
                    (0..=3, _) => 0.01,
                    (_, 0) => 1.0,
                    _ => 0.4 + 0.2 * (k as f32 * 1.57).cos(),
                })
            })
            .collect();
        let rec = Reconstruction {
            pixels,
            cloud: crate::point_cloud::PointCloud::default(),
        };
        (rec, summarise_frames(&frames))
    }

    #[test]
    fn each_pixel_class_follows_its_status_light_and_saturation() {
        let (rec, frames) = reconstruction();
        let c = classes(&rec, &frames);
        assert_eq!(*c.at(1, 10), PixelClass::NoFringe, "dark and masked");
        assert_eq!(*c.at(5, 10), PixelClass::Masked, "lit but masked");
        assert_eq!(*c.at(10, 10), PixelClass::Unreliable);
        assert_eq!(
            *c.at(10, 0),
            PixelClass::Saturated,
            "saturated and not valid"
        );
        assert_eq!(
            *c.at(30, 0),
            PixelClass::Value,
            "a valid pixel keeps its value"
        );
        assert_eq!(*c.at(30, 10), PixelClass::Value);
    }

    #[test]
    fn every_picture_marks_its_pixels_and_carries_the_legend() {
        let (rec, frames) = reconstruction();
        let error = Raster::from_fn(64, 48, |x, _| x as f32 * 1e-5);
        let pictures = head_pictures(&HeadPictures {
            head: "head A",
            reconstruction: &rec,
            finest_period_px: 20.0,
            frames: &frames,
            error_m: Some(&error),
        })
        .unwrap();
        let kinds: Vec<_> = pictures.iter().map(|p| p.kind).collect();
        assert_eq!(kinds, KINDS);
        for p in &pictures {
            let img = image::load_from_memory(&p.png).unwrap().to_rgb8();
            let px = |x: u32, y: u32| img.get_pixel(x, y).0;
            let marked = |class: PixelClass| class.colour().unwrap();
            match p.kind {
                // The camera and modulation pictures mark saturation only.
                "camera_mean" | "fringe_modulation" => {
                    assert_eq!(px(30, 0), marked(PixelClass::Saturated), "{}", p.kind);
                    assert_ne!(px(5, 10), marked(PixelClass::Masked), "{}", p.kind);
                }
                _ => {
                    assert_eq!(px(1, 10), marked(PixelClass::NoFringe), "{}", p.kind);
                    assert_eq!(px(5, 10), marked(PixelClass::Masked), "{}", p.kind);
                    assert_eq!(px(10, 10), marked(PixelClass::Unreliable), "{}", p.kind);
                }
            }
            // The legend below the data: a swatch of every marked colour.
            for class in PixelClass::MARKED {
                let found =
                    (48..img.height()).any(|y| (0..img.width()).any(|x| px(x, y) == marked(class)));
                assert!(found, "{}: no {class:?} swatch", p.kind);
            }
        }
    }

    #[test]
    fn side_by_side_stretches_each_frame_to_its_own_range_with_a_black_gap() {
        let dim = Raster::from_fn(10, 4, |x, _| 0.10 + 0.01 * x as f32);
        let mut bright = Raster::from_fn(6, 5, |x, _| 0.5 * x as f32);
        bright.data[0] = f32::NAN;
        let out = side_by_side(&[&dim, &bright]);
        assert_eq!((out.width, out.height), (10 + 8 + 6, 5));
        // Each frame spans [0, 1] after its own stretch.
        let row = |y: usize, x0: usize, w: usize| out.data[y * out.width + x0..][..w].to_vec();
        let left = row(1, 0, 10);
        assert!(left[0] < 0.05 && left[9] > 0.95, "{left:?}");
        assert!(left.windows(2).all(|w| w[0] <= w[1]));
        let right = row(1, 18, 6);
        assert!(right[0] < 0.05 && right[5] > 0.95, "{right:?}");
        // Gap, the NaN pixel and the rows below the shorter frame are black.
        assert!(row(1, 10, 8).iter().all(|&v| v == 0.0));
        assert_eq!(out.data[18], 0.0);
        assert!(row(4, 0, 10).iter().all(|&v| v == 0.0));
    }
}
