//! The pattern families users have, as capture descriptions.
//!
//! | preset | frames | unwrapping |
//! |---|---|---|
//! | `slscan` | N steps x K periods per axis, columns then rows, DESIGN.md convention (N = 4, periods 100/110/120 px unless given) | heterodyne |
//! | `heterodyne` | the same with the N >= 3 and periods the user gives | heterodyne |
//! | `sinus-comple-gray` | SLMaster / OpenCV `SinusCompleGrayCodePattern`: N phase frames of one period with phase `2 pi (u mod P) / P - pi`, then `n + 1` Gray bits (MSB first, finest block P / 2) thresholded against the phase frames' mean; per axis | complementary Gray code |
//! | `opencv-graycode` | OpenCV `GrayCodePattern`: column bits then row bits, each bit followed by its inverse, MSB first, 1 px blocks, then the white and black shadow-mask frames | Gray code alone (whole projector pixels) |
//!
//! The OpenCV orders are our reading of those generators; a capture whose convention
//! differs is refused by the self-checks ([`super::checks`]) where the frames can tell,
//! and a manifest can describe it exactly.

use super::{
    CaptureError, CaptureSpec, CheckLimits, Frames, FringeSet, GraySet, ProjectorAxis, Thresholds,
    Unwrapping,
};

/// A named family.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Preset {
    /// Ours: multi-frequency heterodyne.
    Slscan,
    /// Any N-step x K-period heterodyne set (steps and periods given).
    Heterodyne,
    /// SLMaster / OpenCV `SinusCompleGrayCodePattern`.
    SinusCompleGray,
    /// OpenCV `GrayCodePattern`.
    OpencvGrayCode,
}

/// Every preset with its name.
pub const PRESETS: [(&str, Preset); 4] = [
    ("slscan", Preset::Slscan),
    ("heterodyne", Preset::Heterodyne),
    ("sinus-comple-gray", Preset::SinusCompleGray),
    ("opencv-graycode", Preset::OpencvGrayCode),
];

/// What a user may set on a preset; `None` takes the preset's default.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PresetOptions {
    /// Phase steps N.
    pub steps: Option<usize>,
    /// Fringe periods, projector pixels (one for `sinus-comple-gray`).
    pub periods_px: Option<Vec<f64>>,
    /// Columns and rows (two-ray triangulation) instead of columns only.
    pub both: bool,
}

/// What can be wrong with a preset request.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PresetError {
    /// No preset has this name.
    #[error("no capture preset named {0:?}; presets: slscan, heterodyne, sinus-comple-gray, opencv-graycode")]
    Unknown(String),
    /// A preset that needs an option was not given it.
    #[error("preset {preset} needs {option}")]
    Missing {
        /// The preset.
        preset: &'static str,
        /// The option, as the CLI spells it.
        option: &'static str,
    },
    /// An option the preset does not take.
    #[error("preset {preset} does not take {option}: {why}")]
    Conflict {
        /// The preset.
        preset: &'static str,
        /// The option, as the CLI spells it.
        option: &'static str,
        /// Why.
        why: &'static str,
    },
}

impl Preset {
    /// The preset of this name.
    pub fn from_name(name: &str) -> Result<Preset, PresetError> {
        PRESETS
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, p)| *p)
            .ok_or_else(|| PresetError::Unknown(name.to_string()))
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        PRESETS
            .iter()
            .find(|(_, p)| *p == self)
            .map(|(n, _)| *n)
            .unwrap_or("?")
    }

    /// The description for a projector of `projector` (width, height) pixels.
    pub fn spec(
        self,
        options: &PresetOptions,
        projector: (u32, u32),
    ) -> Result<CaptureSpec, CaptureError> {
        let sequence = match self {
            Preset::Slscan => heterodyne_sequence(
                options.steps.unwrap_or(4),
                options
                    .periods_px
                    .clone()
                    .unwrap_or_else(|| vec![100.0, 110.0, 120.0]),
                options.both,
            ),
            Preset::Heterodyne => heterodyne_sequence(
                options.steps.ok_or_else(|| missing(self, "--steps"))?,
                options
                    .periods_px
                    .clone()
                    .ok_or_else(|| missing(self, "--periods"))?,
                options.both,
            ),
            Preset::SinusCompleGray => {
                let period = match options.periods_px.as_deref() {
                    None => 32.0,
                    Some([p]) => *p,
                    Some(_) => {
                        return Err(preset_error(PresetError::Conflict {
                            preset: self.name(),
                            option: "--periods",
                            why: "it has exactly one fringe period",
                        }))
                    }
                };
                comple_gray_sequence(options.steps.unwrap_or(12), period, options.both, projector)
            }
            Preset::OpencvGrayCode => {
                for (given, option) in [
                    (options.steps.is_some(), "--steps"),
                    (options.periods_px.is_some(), "--periods"),
                ] {
                    if given {
                        return Err(preset_error(PresetError::Conflict {
                            preset: self.name(),
                            option,
                            why: "it has no fringes",
                        }));
                    }
                }
                opencv_gray_sequence(projector)
            }
        };
        let unwrapping = match self {
            Preset::Slscan | Preset::Heterodyne => Unwrapping::Heterodyne,
            Preset::SinusCompleGray => Unwrapping::ComplementaryGrayCode,
            Preset::OpencvGrayCode => Unwrapping::GrayCode,
        };
        let spec = CaptureSpec {
            name: self.name().to_string(),
            sequence,
            unwrapping,
            thresholds: Thresholds::default(),
            checks: CheckLimits::default(),
        };
        spec.validate(projector)?;
        Ok(spec)
    }
}

fn preset_error(e: PresetError) -> CaptureError {
    CaptureError::Preset(e)
}

fn missing(preset: Preset, option: &'static str) -> CaptureError {
    preset_error(PresetError::Missing {
        preset: preset.name(),
        option,
    })
}

/// Axes in capture order.
fn axes(both: bool) -> Vec<ProjectorAxis> {
    if both {
        vec![ProjectorAxis::Column, ProjectorAxis::Row]
    } else {
        vec![ProjectorAxis::Column]
    }
}

/// Ours: one fringe set per axis.
fn heterodyne_sequence(steps: usize, periods_px: Vec<f64>, both: bool) -> Vec<Frames> {
    axes(both)
        .into_iter()
        .map(|axis| {
            Frames::Fringes(FringeSet {
                axis,
                steps,
                periods_px: periods_px.clone(),
                phase_offset_rad: 0.0,
                phase_sign: 1,
                shift_sign: 1,
            })
        })
        .collect()
}

/// Bits `n + 1` so that `n` bits of one-period blocks cover `extent` pixels.
fn comple_bits(period_px: f64, extent: u32) -> u32 {
    let periods = (f64::from(extent) / period_px).ceil().max(1.0);
    (periods.log2().ceil() as u32).max(1) + 1
}

/// SLMaster: per axis, the phase frames then the complementary Gray bits.
fn comple_gray_sequence(
    steps: usize,
    period_px: f64,
    both: bool,
    projector: (u32, u32),
) -> Vec<Frames> {
    let block = (period_px / 2.0).round().max(1.0) as u32;
    axes(both)
        .into_iter()
        .flat_map(|axis| {
            [
                Frames::Fringes(FringeSet {
                    axis,
                    steps,
                    periods_px: vec![period_px],
                    phase_offset_rad: -std::f64::consts::PI,
                    phase_sign: 1,
                    shift_sign: 1,
                }),
                Frames::Gray(GraySet {
                    axis,
                    bits: comple_bits(period_px, super::extent(axis, projector)),
                    block_px: block,
                    inverse: false,
                }),
            ]
        })
        .collect()
}

/// Bits that number every pixel of `extent`.
fn pixel_bits(extent: u32) -> u32 {
    (f64::from(extent.max(2))).log2().ceil() as u32
}

/// OpenCV `GrayCodePattern`: columns, rows, white, black.
fn opencv_gray_sequence(projector: (u32, u32)) -> Vec<Frames> {
    let mut sequence: Vec<Frames> = axes(true)
        .into_iter()
        .map(|axis| {
            Frames::Gray(GraySet {
                axis,
                bits: pixel_bits(super::extent(axis, projector)),
                block_px: 1,
                inverse: true,
            })
        })
        .collect();
    sequence.extend([Frames::White, Frames::Black]);
    sequence
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_validates_and_counts_its_frames() {
        let projector = (1280, 800);
        let opts = PresetOptions::default();
        let ours = Preset::Slscan.spec(&opts, projector).unwrap();
        assert_eq!(ours.frame_count(), 12);
        let comple = Preset::SinusCompleGray.spec(&opts, projector).unwrap();
        // 12 steps + (ceil(log2(1280 / 32)) + 1 = 7) bits.
        assert_eq!(comple.frame_count(), 12 + 7);
        let opencv = Preset::OpencvGrayCode.spec(&opts, projector).unwrap();
        // 2 x (11 + 10) + white + black.
        assert_eq!(opencv.frame_count(), 2 * (11 + 10) + 2);
        let het = Preset::Heterodyne.spec(
            &PresetOptions {
                steps: Some(5),
                periods_px: Some(vec![20.0, 22.0, 24.0]),
                both: true,
            },
            projector,
        );
        assert_eq!(het.unwrap().frame_count(), 2 * 15);
    }

    #[test]
    fn wrong_options_are_named() {
        let projector = (1280, 800);
        let err = Preset::Heterodyne
            .spec(&PresetOptions::default(), projector)
            .unwrap_err();
        assert!(err.to_string().contains("--steps"), "{err}");
        let err = Preset::OpencvGrayCode
            .spec(
                &PresetOptions {
                    steps: Some(4),
                    ..Default::default()
                },
                projector,
            )
            .unwrap_err();
        assert!(err.to_string().contains("no fringes"), "{err}");
        assert!(matches!(
            Preset::from_name("sinus"),
            Err(PresetError::Unknown(_))
        ));
    }
}
