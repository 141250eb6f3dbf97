//! Each family decoded from its own ideal projector images (a camera that sees projector
//! pixel (x, y) exactly), and the wrong conventions refused with their causes.

use super::decode::decode;
use super::patterns::projector_images;
use super::presets::{Preset, PresetOptions};
use super::*;
use crate::raster::Raster;
use crate::unwrap::PixelStatus;

const PROJECTOR: (u32, u32) = (320, 96);

fn frames(spec: &CaptureSpec) -> Vec<Raster<f32>> {
    // Keep every level off the saturation threshold, as a camera exposed for it would.
    projector_images(spec, PROJECTOR.0, PROJECTOR.1)
        .into_iter()
        .map(|f| Raster {
            data: f.data.iter().map(|v| 0.05 + 0.9 * v).collect(),
            ..f
        })
        .collect()
}

fn decoded(
    spec: &CaptureSpec,
    images: &[Raster<f32>],
) -> Result<Vec<decode::AxisCoordinates>, CaptureError> {
    let refs: Vec<&Raster<f32>> = images.iter().collect();
    decode(spec, &refs, PROJECTOR, 0.01)
}

#[test]
fn every_preset_decodes_its_own_patterns_to_the_pixel() {
    let options = [
        (
            Preset::Slscan,
            PresetOptions {
                periods_px: Some(vec![20.0, 22.0, 24.0]),
                both: true,
                ..Default::default()
            },
        ),
        (
            Preset::Heterodyne,
            PresetOptions {
                steps: Some(3),
                periods_px: Some(vec![16.0, 18.0, 21.0]),
                both: false,
            },
        ),
        (
            Preset::SinusCompleGray,
            PresetOptions {
                steps: Some(12),
                periods_px: Some(vec![32.0]),
                both: true,
            },
        ),
        (Preset::OpencvGrayCode, PresetOptions::default()),
    ];
    for (preset, opts) in options {
        let spec = preset.spec(&opts, PROJECTOR).unwrap();
        let axes = decoded(&spec, &frames(&spec)).unwrap();
        for a in &axes {
            let (w, h) = a.coord_px.size();
            let mut worst = 0.0f32;
            for y in 0..h {
                for x in 0..w {
                    let want = match a.axis {
                        ProjectorAxis::Column => x,
                        ProjectorAxis::Row => y,
                    } as f32;
                    assert_eq!(
                        *a.status.at(x, y),
                        PixelStatus::Valid,
                        "{preset:?} {:?} ({x}, {y})",
                        a.axis
                    );
                    worst = worst.max((a.coord_px.at(x, y) - want).abs());
                }
            }
            assert!(worst < 2e-3, "{preset:?} {:?}: worst {worst} px", a.axis);
            assert!(a.checks.iter().all(|c| c.passed()));
        }
    }
}

#[test]
fn a_capture_with_the_wrong_convention_is_refused_with_its_cause() {
    let comple = Preset::SinusCompleGray
        .spec(
            &PresetOptions {
                periods_px: Some(vec![32.0]),
                ..Default::default()
            },
            PROJECTOR,
        )
        .unwrap();
    let images = frames(&comple);
    // The same frames described with our phase origin (0 instead of -pi).
    let mut ours = comple.clone();
    let mut reversed = comple.clone();
    for (spec, offset, sign) in [
        (&mut ours, 0.0, 1),
        (&mut reversed, -std::f64::consts::PI, -1),
    ] {
        for e in &mut spec.sequence {
            if let Frames::Fringes(f) = e {
                f.phase_offset_rad = offset;
                f.phase_sign = sign;
            }
        }
    }
    let err = decoded(&ours, &images).unwrap_err().to_string();
    assert!(
        err.contains("half a period") && err.contains("phase origin"),
        "{err}"
    );
    let err = decoded(&reversed, &images).unwrap_err().to_string();
    assert!(err.contains("other way"), "{err}");

    // Heterodyne: the periods' frames given in the other order, and a reversed sign.
    let het = Preset::Slscan
        .spec(
            &PresetOptions {
                periods_px: Some(vec![20.0, 22.0, 24.0]),
                ..Default::default()
            },
            PROJECTOR,
        )
        .unwrap();
    let images = frames(&het);
    let mut swapped = het.clone();
    let mut flipped = het.clone();
    if let Frames::Fringes(f) = &mut swapped.sequence[0] {
        f.periods_px.reverse();
    }
    if let Frames::Fringes(f) = &mut flipped.sequence[0] {
        f.phase_sign = -1;
    }
    let err = decoded(&swapped, &images).unwrap_err().to_string();
    assert!(err.contains("other order"), "{err}");
    let err = decoded(&flipped, &images).unwrap_err().to_string();
    assert!(err.contains("other way"), "{err}");
}

#[test]
fn frame_counts_and_sizes_are_checked_before_decoding() {
    let spec = Preset::SinusCompleGray
        .spec(&PresetOptions::default(), PROJECTOR)
        .unwrap();
    let mut images = frames(&spec);
    images.pop();
    let err = decoded(&spec, &images).unwrap_err();
    assert!(matches!(err, CaptureError::FrameCount { .. }), "{err}");
    let mut images = frames(&spec);
    images[3] = Raster::filled(10, 10, 0.5);
    assert!(matches!(
        decoded(&spec, &images),
        Err(CaptureError::Phase(_))
    ));
}
