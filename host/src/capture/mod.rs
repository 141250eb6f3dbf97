//! Capture descriptions: what a folder of frames from any structured-light system holds,
//! so that `reconstruct` decodes captures it did not make.
//!
//! ```text
//! manifest.json / preset + flags --(manifest, presets)--> CaptureSpec --validate-->
//! frames --(decode: phase per fringe set in DESIGN.md convention, Gray codes, masks,
//!           unwrapping per axis, checks: convention self-checks)--> projector coordinates
//!        --(triangulate: camera ray / projector plane or ray)--> Reconstruction
//! ```
//!
//! A [`CaptureSpec`] is the frame order (a sequence of fringe sets, Gray-code sets, white
//! and black frames), each fringe set's convention (steps, periods, axis, phase at
//! projector coordinate 0, phase sign, shift direction), the unwrapping and the
//! thresholds. Every fringe set is turned into the DESIGN.md convention
//! (`phi = 2 pi u / P`, shifts `+2 pi n / N`) as soon as it is decoded, so the unwrapping
//! methods of [`crate::unwrap`] serve every family unchanged; a convention the
//! description gets wrong is caught by [`checks`] rather than returned as wrong points.

pub mod checks;
pub mod decode;
pub mod manifest;
pub mod patterns;
pub mod presets;
pub mod triangulate;

pub use crate::triangulation::ProjectorAxis;
use crate::unwrap::UnwrapError;

/// One N-step fringe set: `steps` frames per period, periods in frame order.
///
/// The pattern it describes is `I_n(u) = A + B cos(psi(u) + s_d 2 pi n / N)` with
/// `psi(u) = s_p 2 pi u / P + psi_0`: `s_p` is [`FringeSet::phase_sign`], `s_d`
/// [`FringeSet::shift_sign`], `psi_0` [`FringeSet::phase_offset_rad`]. Ours is
/// `s_p = s_d = +1`, `psi_0 = 0`; SLMaster / OpenCV `SinusCompleGrayCodePattern` has
/// `psi_0 = -pi` (phase `2 pi (u mod P) / P - pi`).
#[derive(Clone, Debug, PartialEq)]
pub struct FringeSet {
    /// The projector coordinate the phase grows along.
    pub axis: ProjectorAxis,
    /// Phase steps N per period (>= 3).
    pub steps: usize,
    /// Fringe periods, projector pixels, in the order their frames come.
    pub periods_px: Vec<f64>,
    /// The pattern's phase at projector coordinate 0, radians.
    pub phase_offset_rad: f64,
    /// +1: the phase grows with the coordinate; -1: it falls.
    pub phase_sign: i8,
    /// +1: frame n is shifted by `+2 pi n / N`; -1: by `-2 pi n / N`.
    pub shift_sign: i8,
}

/// A Gray-code set: `bits` frames, most significant bit first; block `g` (projector
/// pixels `g * block_px .. (g + 1) * block_px`) shows `gray(g)`.
#[derive(Clone, Debug, PartialEq)]
pub struct GraySet {
    /// The projector coordinate the code counts along.
    pub axis: ProjectorAxis,
    /// Number of bits (frames without the inverses).
    pub bits: u32,
    /// Width of the finest block, projector pixels.
    pub block_px: u32,
    /// Each bit's frame is followed by its inverse (compared pixel by pixel) instead
    /// of thresholded.
    pub inverse: bool,
}

/// One element of the frame order.
#[derive(Clone, Debug, PartialEq)]
pub enum Frames {
    /// A fringe set.
    Fringes(FringeSet),
    /// A Gray-code set.
    Gray(GraySet),
    /// A full-white frame (shadow mask and Gray threshold).
    White,
    /// A full-black frame.
    Black,
}

/// How each axis's wrapped phase becomes an absolute coordinate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Unwrapping {
    /// Multi-frequency heterodyne over the axis's periods (finest gives the phase).
    Heterodyne,
    /// Projection distance minimisation over the axis's (integer) periods.
    Pdm,
    /// Gray code (+ one fringe period with blocks at most half of it), or the code
    /// alone when the axis has no fringes.
    GrayCode,
    /// Complementary Gray code: one fringe period and `n + 1` bits whose finest block
    /// is half the period.
    ComplementaryGrayCode,
    /// Spatial quality-guided flood fill of one period, absolute from a seed pixel of
    /// known fringe order.
    QualityGuided {
        /// Seed pixel (x, y).
        seed: (usize, usize),
        /// Its fringe order.
        order: i32,
    },
    /// One period at least as long as the projector: the phase is absolute already.
    None,
}

/// Per-pixel thresholds, in units of full scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thresholds {
    /// Smallest fringe modulation B (every set).
    pub min_modulation: f32,
    /// Smallest mean intensity A (every set).
    pub min_mean: f32,
    /// A pixel at or above this level in any frame is masked as saturated.
    pub saturation: f32,
    /// Smallest difference between a Gray bit and its threshold (or inverse) read as a
    /// bit; also the smallest white - black difference where both are captured.
    pub min_code_contrast: f32,
}

impl Default for Thresholds {
    /// B >= 0.05, A >= 0.02, saturated at 0.995, code contrast 0.03.
    fn default() -> Self {
        Self {
            min_modulation: 0.05,
            min_mean: 0.02,
            saturation: 0.995,
            min_code_contrast: 0.03,
        }
    }
}

/// Limits of the convention self-checks ([`checks`]); past one, decoding is refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CheckLimits {
    /// Gray + phase: largest share of pixels whose phase and code disagree by about
    /// half a period.
    pub max_half_period: f64,
    /// Heterodyne / PDM: largest share of modulated pixels whose orders do not agree.
    pub max_wrong_order: f64,
    /// Any method: largest share of decoded pixels whose coordinate falls outside the
    /// projector.
    pub max_outside: f64,
}

impl Default for CheckLimits {
    /// 10 % half-period disagreement, 25 % wrong-order votes, 10 % outside.
    fn default() -> Self {
        Self {
            max_half_period: 0.10,
            max_wrong_order: 0.25,
            max_outside: 0.10,
        }
    }
}

/// A whole capture description.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureSpec {
    /// Where it came from (a preset's name, or "manifest").
    pub name: String,
    /// The frames, in order.
    pub sequence: Vec<Frames>,
    /// The unwrapping of every axis.
    pub unwrapping: Unwrapping,
    /// Per-pixel thresholds.
    pub thresholds: Thresholds,
    /// Self-check limits.
    pub checks: CheckLimits,
}

/// What can be wrong with a description or a capture decoded with it.
#[derive(Debug, thiserror::Error)]
pub enum CaptureError {
    /// The description lists no frames.
    #[error("the capture description lists no frames")]
    EmptySequence,
    /// A fringe set with fewer than 3 steps.
    #[error("fringe set {set}: {steps} steps; phase shifting needs 3 to {MAX_STEPS}")]
    Steps {
        /// Index of the set in the sequence.
        set: usize,
        /// Steps given.
        steps: usize,
    },
    /// A period that is not a positive finite number, or a set without periods.
    #[error("fringe set {set}: periods {periods_px:?} must be 1 to {MAX_SET_PERIODS} positive numbers of projector pixels")]
    Periods {
        /// Index of the set in the sequence.
        set: usize,
        /// Periods given.
        periods_px: Vec<f64>,
    },
    /// A sign that is not +1 or -1, or an offset that is not finite.
    #[error("fringe set {set}: {field} is {value}; it must be {want}")]
    Convention {
        /// Index of the set in the sequence.
        set: usize,
        /// The field.
        field: &'static str,
        /// The value given.
        value: f64,
        /// What it must be.
        want: &'static str,
    },
    /// A Gray set whose blocks do not cover the projector, or with no bits.
    #[error("Gray set {set}: {bits} bits of {block_px} px blocks cover {covered} px, the projector's {axis:?} extent is {extent} px")]
    GrayCoverage {
        /// Index of the set in the sequence.
        set: usize,
        /// Bits.
        bits: u32,
        /// Finest block, pixels.
        block_px: u32,
        /// Pixels the code covers.
        covered: u64,
        /// The axis.
        axis: ProjectorAxis,
        /// Projector pixels along the axis.
        extent: u32,
    },
    /// The unwrapping cannot work with the frames the axis has.
    #[error("{axis:?}: {method} {reason}")]
    Unwrapping {
        /// The axis.
        axis: ProjectorAxis,
        /// The method.
        method: &'static str,
        /// What is missing or wrong.
        reason: String,
    },
    /// Gray bits without inverses need white and black frames or a fringe set whose
    /// mean serves as threshold.
    #[error("Gray set {set} has no inverse frames, and the capture has neither white + black frames nor a fringe set to threshold it against")]
    NoGrayThreshold {
        /// Index of the set in the sequence.
        set: usize,
    },
    /// A threshold outside [0, 1] (or NaN).
    #[error("threshold {name} = {value} must be in [0, 1]")]
    Threshold {
        /// Which.
        name: &'static str,
        /// Value.
        value: f64,
    },
    /// No fringe or Gray set at all.
    #[error("the capture has no fringe or Gray set: nothing encodes a projector coordinate")]
    NoAxis,
    /// A self-check limit outside (0, 1].
    #[error("self-check limit {name} = {value} must be in (0, 1]")]
    CheckLimit {
        /// Which.
        name: &'static str,
        /// Value.
        value: f64,
    },
    /// The folder does not hold as many frames as the description.
    #[error("the capture description ({breakdown}) needs {expected} frames, {found} were given")]
    FrameCount {
        /// Frames described.
        expected: usize,
        /// Frames found.
        found: usize,
        /// Frames per element, in words.
        breakdown: String,
    },
    /// A preset request that cannot be met.
    #[error(transparent)]
    Preset(#[from] presets::PresetError),
    /// Frames of different sizes, or not the camera's.
    #[error(transparent)]
    Phase(#[from] crate::phase::PhaseError),
    /// An unwrapping method refused its input.
    #[error(transparent)]
    Unwrap(#[from] UnwrapError),
    /// A convention self-check failed: the capture is refused instead of returning
    /// wrong points.
    #[error(
        "{axis:?}: {check}: {share:.1} % of the pixels (limit {limit:.1} %); likely cause: {cause}"
    )]
    SelfCheck {
        /// The axis.
        axis: ProjectorAxis,
        /// What was measured.
        check: &'static str,
        /// Share of pixels failing, percent.
        share: f64,
        /// Limit, percent.
        limit: f64,
        /// The likely cause, in words.
        cause: String,
    },
    /// Frames are not the calibrated camera's size.
    #[error("frames are {got:?} but the calibrated camera is {expected:?} (width, height)")]
    CameraSize {
        /// Calibrated size.
        expected: (usize, usize),
        /// Frame size.
        got: (usize, usize),
    },
}

impl FringeSet {
    /// Frames of this set.
    pub fn frames(&self) -> usize {
        self.steps * self.periods_px.len()
    }
}

impl GraySet {
    /// Frames of this set (with inverses).
    pub fn frames(&self) -> usize {
        self.bits as usize * if self.inverse { 2 } else { 1 }
    }
}

impl Frames {
    /// How many frames this element takes.
    pub fn count(&self) -> usize {
        match self {
            Frames::Fringes(f) => f.frames(),
            Frames::Gray(g) => g.frames(),
            Frames::White | Frames::Black => 1,
        }
    }

    /// The element in words, for messages ("12-step fringes, columns, periods [32]").
    pub fn describe(&self) -> String {
        match self {
            Frames::Fringes(f) => format!(
                "{} x {}-step {} fringes",
                f.periods_px.len(),
                f.steps,
                axis_name(f.axis)
            ),
            Frames::Gray(g) => format!(
                "{} {} Gray bits{}",
                g.bits,
                axis_name(g.axis),
                if g.inverse { " with inverses" } else { "" }
            ),
            Frames::White => "white".into(),
            Frames::Black => "black".into(),
        }
    }
}

/// "column" or "row".
pub fn axis_name(axis: ProjectorAxis) -> &'static str {
    match axis {
        ProjectorAxis::Column => "column",
        ProjectorAxis::Row => "row",
    }
}

impl Unwrapping {
    /// The method's name as manifests spell it.
    pub fn name(&self) -> &'static str {
        match self {
            Unwrapping::Heterodyne => "heterodyne",
            Unwrapping::Pdm => "pdm",
            Unwrapping::GrayCode => "gray-code",
            Unwrapping::ComplementaryGrayCode => "complementary-gray-code",
            Unwrapping::QualityGuided { .. } => "quality-guided",
            Unwrapping::None => "none",
        }
    }
}

impl CaptureSpec {
    /// Frames the description needs.
    pub fn frame_count(&self) -> usize {
        self.sequence.iter().map(Frames::count).sum()
    }

    /// The elements and their frame counts in words ("12 x 1-step ... (12) + ...").
    pub fn breakdown(&self) -> String {
        self.sequence
            .iter()
            .map(|f| format!("{} ({})", f.describe(), f.count()))
            .collect::<Vec<_>>()
            .join(" + ")
    }

    /// Refuses a folder whose frame count differs, before any frame is read.
    pub fn check_frame_count(&self, found: usize) -> Result<(), CaptureError> {
        let expected = self.frame_count();
        if found != expected {
            return Err(CaptureError::FrameCount {
                expected,
                found,
                breakdown: self.breakdown(),
            });
        }
        Ok(())
    }

    /// The axes the capture encodes, columns first.
    pub fn axes(&self) -> Vec<ProjectorAxis> {
        [ProjectorAxis::Column, ProjectorAxis::Row]
            .into_iter()
            .filter(|&a| {
                self.sequence.iter().any(|f| match f {
                    Frames::Fringes(s) => s.axis == a,
                    Frames::Gray(g) => g.axis == a,
                    _ => false,
                })
            })
            .collect()
    }

    /// The fringe sets of an axis with their sequence indices.
    pub fn fringe_sets(&self, axis: ProjectorAxis) -> Vec<(usize, &FringeSet)> {
        self.sequence
            .iter()
            .enumerate()
            .filter_map(|(i, f)| match f {
                Frames::Fringes(s) if s.axis == axis => Some((i, s)),
                _ => None,
            })
            .collect()
    }

    /// The Gray sets of an axis with their sequence indices.
    pub fn gray_sets(&self, axis: ProjectorAxis) -> Vec<(usize, &GraySet)> {
        self.sequence
            .iter()
            .enumerate()
            .filter_map(|(i, f)| match f {
                Frames::Gray(g) if g.axis == axis => Some((i, g)),
                _ => None,
            })
            .collect()
    }

    /// Whether both a white and a black frame are captured.
    pub fn has_white_and_black(&self) -> bool {
        self.sequence.contains(&Frames::White) && self.sequence.contains(&Frames::Black)
    }

    /// Everything that can be checked before a frame is read, for a projector of
    /// `projector` (width, height) pixels.
    pub fn validate(&self, projector: (u32, u32)) -> Result<(), CaptureError> {
        if self.sequence.is_empty() {
            return Err(CaptureError::EmptySequence);
        }
        self.validate_thresholds()?;
        let any_fringes = self
            .sequence
            .iter()
            .any(|f| matches!(f, Frames::Fringes(_)));
        for (i, f) in self.sequence.iter().enumerate() {
            match f {
                Frames::Fringes(s) => validate_fringes(i, s)?,
                Frames::Gray(g) => {
                    validate_gray(i, g, extent(g.axis, projector))?;
                    if !g.inverse && !self.has_white_and_black() && !any_fringes {
                        return Err(CaptureError::NoGrayThreshold { set: i });
                    }
                }
                Frames::White | Frames::Black => {}
            }
        }
        let axes = self.axes();
        if axes.is_empty() {
            return Err(CaptureError::NoAxis);
        }
        for axis in axes {
            self.validate_unwrapping(axis, extent(axis, projector))?;
        }
        Ok(())
    }

    fn validate_thresholds(&self) -> Result<(), CaptureError> {
        let t = &self.thresholds;
        for (name, value) in [
            ("min_modulation", t.min_modulation),
            ("min_mean", t.min_mean),
            ("saturation", t.saturation),
            ("min_code_contrast", t.min_code_contrast),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(CaptureError::Threshold {
                    name,
                    value: f64::from(value),
                });
            }
        }
        let c = &self.checks;
        for (name, value) in [
            ("max_half_period", c.max_half_period),
            ("max_wrong_order", c.max_wrong_order),
            ("max_outside", c.max_outside),
        ] {
            if !(value > 0.0 && value <= 1.0) {
                return Err(CaptureError::CheckLimit { name, value });
            }
        }
        Ok(())
    }

    /// Whether the axis's frames suit the unwrapping.
    fn validate_unwrapping(&self, axis: ProjectorAxis, extent_px: u32) -> Result<(), CaptureError> {
        let method = self.unwrapping.name();
        let fringes = self.fringe_sets(axis);
        let grays = self.gray_sets(axis);
        let periods: Vec<f64> = fringes
            .iter()
            .flat_map(|(_, s)| s.periods_px.iter().copied())
            .collect();
        let fail = |reason: String| CaptureError::Unwrapping {
            axis,
            method,
            reason,
        };
        let single_period = || -> Result<f64, CaptureError> {
            match periods.as_slice() {
                [p] => Ok(*p),
                _ => Err(fail(format!(
                    "needs exactly one fringe period, the {} frames have {}",
                    axis_name(axis),
                    periods.len()
                ))),
            }
        };
        let no_gray = || -> Result<(), CaptureError> {
            if grays.is_empty() {
                Ok(())
            } else {
                Err(fail(format!(
                    "does not use Gray codes, but the {} frames have {} Gray set(s)",
                    axis_name(axis),
                    grays.len()
                )))
            }
        };
        let one_gray = || -> Result<&GraySet, CaptureError> {
            match grays.as_slice() {
                [(_, g)] => Ok(*g),
                _ => Err(fail(format!(
                    "needs exactly one Gray set, the {} frames have {}",
                    axis_name(axis),
                    grays.len()
                ))),
            }
        };
        let range = f64::from(extent_px);
        match self.unwrapping {
            Unwrapping::Heterodyne => {
                no_gray()?;
                let mut sorted = periods.clone();
                sorted.sort_by(f64::total_cmp);
                crate::unwrap::heterodyne::Heterodyne::new(
                    &sorted,
                    range,
                    std::f64::consts::FRAC_PI_2,
                )?;
            }
            Unwrapping::Pdm => {
                no_gray()?;
                let ints = integer_periods(&periods)
                    .ok_or_else(|| fail(format!("needs whole-pixel periods, got {periods:?}")))?;
                crate::unwrap::pdm::Pdm::new(&ints, range)?;
            }
            Unwrapping::GrayCode => {
                let g = one_gray()?;
                if !fringes.is_empty() {
                    let p = single_period()?;
                    if f64::from(g.block_px) > p / 2.0 {
                        return Err(UnwrapError::BlockTooWide {
                            block_px: f64::from(g.block_px),
                            period_px: p,
                        }
                        .into());
                    }
                }
            }
            Unwrapping::ComplementaryGrayCode => {
                let g = one_gray()?;
                let p = single_period()?;
                if g.bits < 2 || (2.0 * f64::from(g.block_px) - p).abs() > 1e-9 {
                    return Err(fail(format!(
                        "needs n + 1 >= 2 Gray bits whose finest block is half the period: \
                         {} bits of {} px for a {p} px period",
                        g.bits, g.block_px
                    )));
                }
            }
            Unwrapping::QualityGuided { .. } => {
                no_gray()?;
                single_period()?;
            }
            Unwrapping::None => {
                no_gray()?;
                let p = single_period()?;
                if p < range {
                    return Err(fail(format!(
                        "needs a period at least as long as the projector ({range} px), got {p} px; choose an unwrapping"
                    )));
                }
            }
        }
        Ok(())
    }
}

/// The periods as whole pixels, if they all are.
pub(crate) fn integer_periods(periods: &[f64]) -> Option<Vec<u32>> {
    periods
        .iter()
        .map(|&p| (p.fract() == 0.0 && p >= 1.0 && p <= f64::from(u32::MAX)).then_some(p as u32))
        .collect()
}

/// Projector pixels along an axis.
pub fn extent(axis: ProjectorAxis, projector: (u32, u32)) -> u32 {
    match axis {
        ProjectorAxis::Column => projector.0,
        ProjectorAxis::Row => projector.1,
    }
}

/// Most steps a fringe set may have (a description is read from outside: its counts
/// must not overflow or allocate without bound).
pub const MAX_STEPS: usize = 256;
/// Most periods one fringe set may list.
pub const MAX_SET_PERIODS: usize = 16;

fn validate_fringes(set: usize, s: &FringeSet) -> Result<(), CaptureError> {
    if !(3..=MAX_STEPS).contains(&s.steps) {
        return Err(CaptureError::Steps {
            set,
            steps: s.steps,
        });
    }
    if s.periods_px.is_empty()
        || s.periods_px.len() > MAX_SET_PERIODS
        || s.periods_px.iter().any(|p| !(p.is_finite() && *p > 0.0))
    {
        return Err(CaptureError::Periods {
            set,
            periods_px: s.periods_px.clone(),
        });
    }
    for (field, value) in [("phase_sign", s.phase_sign), ("shift_sign", s.shift_sign)] {
        if value != 1 && value != -1 {
            return Err(CaptureError::Convention {
                set,
                field,
                value: f64::from(value),
                want: "+1 or -1",
            });
        }
    }
    if !s.phase_offset_rad.is_finite() {
        return Err(CaptureError::Convention {
            set,
            field: "phase_offset_rad",
            value: s.phase_offset_rad,
            want: "a finite angle",
        });
    }
    Ok(())
}

fn validate_gray(set: usize, g: &GraySet, extent: u32) -> Result<(), CaptureError> {
    let covered = if g.bits == 0 || g.bits > 24 {
        0
    } else {
        u64::from(g.block_px) << g.bits
    };
    if covered < u64::from(extent) || g.block_px == 0 {
        return Err(CaptureError::GrayCoverage {
            set,
            bits: g.bits,
            block_px: g.block_px,
            covered,
            axis: g.axis,
            extent,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests;
