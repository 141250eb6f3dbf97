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

/// A one-axis description with the given fringe sets and unwrapping.
fn described(sets: Vec<FringeSet>, unwrapping: Unwrapping) -> CaptureSpec {
    CaptureSpec {
        name: "manifest".into(),
        sequence: sets.into_iter().map(Frames::Fringes).collect(),
        unwrapping,
        thresholds: Thresholds::default(),
        checks: CheckLimits::default(),
    }
}

fn columns(steps: usize, periods_px: Vec<f64>) -> FringeSet {
    FringeSet {
        axis: ProjectorAxis::Column,
        steps,
        periods_px,
        phase_offset_rad: 0.0,
        phase_sign: 1,
        shift_sign: 1,
    }
}

#[test]
fn pdm_quality_guided_and_no_unwrapping_decode_to_the_pixel() {
    let cases = [
        described(vec![columns(5, vec![7.0, 9.0, 11.0])], Unwrapping::Pdm),
        // Seed at column 100: order floor(100 / 24 + 1/2) = 4 in (-pi, pi] wrapping.
        described(
            vec![columns(4, vec![24.0])],
            Unwrapping::QualityGuided {
                seed: (100, 10),
                order: 4,
            },
        ),
        described(vec![columns(4, vec![400.0])], Unwrapping::None),
        // Two sets of the heterodyne, one frame order each, with a reversed shift
        // direction on the second, described as such.
        described(
            vec![columns(4, vec![20.0]), {
                let mut s = columns(3, vec![22.0, 24.0]);
                s.shift_sign = -1;
                s
            }],
            Unwrapping::Heterodyne,
        ),
    ];
    for spec in cases {
        let axes = decoded(&spec, &frames(&spec)).unwrap();
        let a = &axes[0];
        let (w, h) = a.coord_px.size();
        for y in 0..h {
            for x in 0..w {
                assert_eq!(
                    *a.status.at(x, y),
                    PixelStatus::Valid,
                    "{:?} ({x}, {y})",
                    spec.unwrapping
                );
                let e = (a.coord_px.at(x, y) - x as f32).abs();
                assert!(e < 2e-3, "{:?} ({x}, {y}): {e}", spec.unwrapping);
            }
        }
    }
}

#[test]
fn descriptions_that_cannot_unwrap_are_refused_before_decoding() {
    // One period with heterodyne, a period shorter than the projector without
    // unwrapping, Gray blocks wider than half the period.
    let het = described(vec![columns(4, vec![20.0])], Unwrapping::Heterodyne);
    let none = described(vec![columns(4, vec![100.0])], Unwrapping::None);
    let mut gray = described(vec![columns(4, vec![20.0])], Unwrapping::GrayCode);
    gray.sequence.push(Frames::Gray(GraySet {
        axis: ProjectorAxis::Column,
        bits: 5,
        block_px: 16,
        inverse: false,
    }));
    for (spec, want) in [
        (het, "heterodyne"),
        (none, "at least as long"),
        (gray, "half the period"),
    ] {
        let err = spec.validate(PROJECTOR).unwrap_err().to_string();
        assert!(err.contains(want), "{err}");
    }
}
