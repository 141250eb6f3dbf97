//! The capture manifest: a small JSON file beside the frames (`capture.json`) saying
//! what they are.
//!
//! ```json
//! {"format": "slscan-capture", "version": 1,
//!  "sequence": [
//!    {"kind": "fringes", "axis": "columns", "steps": 12, "periods_px": [32],
//!     "phase_offset_rad": -3.141592653589793, "phase_sign": 1, "shift_sign": 1},
//!    {"kind": "gray", "axis": "columns", "bits": 6, "block_px": 16, "inverse": false},
//!    {"kind": "white"}, {"kind": "black"}],
//!  "unwrapping": {"method": "complementary-gray-code"},
//!  "thresholds": {"min_modulation": 0.05, "min_mean": 0.02, "saturation": 0.995,
//!                 "min_code_contrast": 0.03},
//!  "self_check": {"max_half_period": 0.1, "max_wrong_order": 0.25, "max_outside": 0.1}}
//! ```
//!
//! or a preset with its options: `{"format": "slscan-capture", "version": 1,
//! "preset": "sinus-comple-gray", "steps": 12, "periods_px": [32], "both": false}`.
//! Fringe fields other than `axis`, `steps` and `periods_px` default to ours
//! (offset 0, signs +1); `unwrapping` methods: `heterodyne`, `pdm`, `gray-code`,
//! `complementary-gray-code`, `quality-guided` (with `"seed": [x, y], "order": k`),
//! `none`. Unknown fields are refused (a typo must not silently change the decoding).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::presets::{Preset, PresetOptions};
use super::{
    CaptureError, CaptureSpec, CheckLimits, Frames, FringeSet, GraySet, ProjectorAxis, Thresholds,
    Unwrapping,
};

/// The `format` string of a manifest.
pub const FORMAT: &str = "slscan-capture";
/// The version this code reads and writes.
pub const VERSION: u32 = 1;
/// The manifest's file name in a frame folder.
pub const FILE_NAME: &str = "capture.json";
/// Largest manifest read, bytes (a description is a few hundred bytes).
const MAX_BYTES: u64 = 1 << 20;

/// What can be wrong with a manifest.
#[derive(Debug, thiserror::Error)]
pub enum ManifestError {
    /// The file could not be read.
    #[error("capture manifest {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// Larger than any description.
    #[error("capture manifest {path} is {bytes} bytes; a description is at most {MAX_BYTES}")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size.
        bytes: u64,
    },
    /// Not JSON of the manifest's shape (serde names the field, line and column).
    #[error("capture manifest {path}: {source}")]
    Json {
        /// The file (empty for text).
        path: PathBuf,
        /// serde_json's error.
        source: serde_json::Error,
    },
    /// Another format or version.
    #[error("not a capture manifest this version reads: format {format:?} version {version} (want {FORMAT:?} {VERSION})")]
    Format {
        /// `format` found.
        format: String,
        /// `version` found.
        version: u32,
    },
    /// Both a preset and a sequence, or neither, or preset options with a sequence.
    #[error("capture manifest: {0}")]
    Shape(&'static str),
    /// The description is not decodable.
    #[error("capture manifest: {0}")]
    Capture(#[from] CaptureError),
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Doc {
    format: String,
    version: u32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    preset: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    steps: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    periods_px: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    both: Option<bool>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sequence: Option<Vec<ElementDoc>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    unwrapping: Option<UnwrappingDoc>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    thresholds: Option<ThresholdsDoc>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    self_check: Option<CheckDoc>,
}

#[derive(Clone, Copy, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
enum AxisDoc {
    Columns,
    Rows,
}

fn zero() -> f64 {
    0.0
}
fn plus() -> i8 {
    1
}

#[derive(Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
enum ElementDoc {
    Fringes {
        axis: AxisDoc,
        steps: usize,
        periods_px: Vec<f64>,
        #[serde(default = "zero")]
        phase_offset_rad: f64,
        #[serde(default = "plus")]
        phase_sign: i8,
        #[serde(default = "plus")]
        shift_sign: i8,
    },
    Gray {
        axis: AxisDoc,
        bits: u32,
        block_px: u32,
        #[serde(default)]
        inverse: bool,
    },
    White,
    Black,
}

#[derive(Serialize, Deserialize)]
#[serde(tag = "method", rename_all = "kebab-case", deny_unknown_fields)]
enum UnwrappingDoc {
    Heterodyne,
    Pdm,
    GrayCode,
    ComplementaryGrayCode,
    QualityGuided { seed: [usize; 2], order: i32 },
    None,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ThresholdsDoc {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    min_modulation: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    min_mean: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    saturation: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    min_code_contrast: Option<f32>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CheckDoc {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    max_half_period: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    max_wrong_order: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    max_outside: Option<f64>,
}

/// Reads and validates a manifest for a projector of `projector` (width, height).
pub fn read_manifest(path: &Path, projector: (u32, u32)) -> Result<CaptureSpec, ManifestError> {
    let io = |source| ManifestError::Io {
        path: path.to_path_buf(),
        source,
    };
    let bytes = std::fs::metadata(path).map_err(io)?.len();
    if bytes > MAX_BYTES {
        return Err(ManifestError::TooLarge {
            path: path.to_path_buf(),
            bytes,
        });
    }
    let text = std::fs::read_to_string(path).map_err(io)?;
    parse(&text, projector).map_err(|e| match e {
        ManifestError::Json { source, .. } => ManifestError::Json {
            path: path.to_path_buf(),
            source,
        },
        other => other,
    })
}

/// Parses and validates manifest text (see [`read_manifest`]).
pub fn parse(text: &str, projector: (u32, u32)) -> Result<CaptureSpec, ManifestError> {
    let doc: Doc = serde_json::from_str(text).map_err(|source| ManifestError::Json {
        path: PathBuf::new(),
        source,
    })?;
    if doc.format != FORMAT || doc.version != VERSION {
        return Err(ManifestError::Format {
            format: doc.format,
            version: doc.version,
        });
    }
    let mut spec = match (&doc.preset, doc.sequence) {
        (Some(_), Some(_)) => {
            return Err(ManifestError::Shape(
                "give either a preset or a sequence, not both",
            ))
        }
        (None, None) => return Err(ManifestError::Shape("give a preset or a sequence")),
        (Some(name), None) => {
            if doc.unwrapping.is_some() {
                return Err(ManifestError::Shape(
                    "a preset sets its own unwrapping; describe a sequence to choose another",
                ));
            }
            let preset = Preset::from_name(name).map_err(CaptureError::from)?;
            let options = PresetOptions {
                steps: doc.steps,
                periods_px: doc.periods_px,
                both: doc.both.unwrap_or(false),
            };
            preset.spec(&options, projector)?
        }
        (None, Some(sequence)) => {
            if doc.steps.is_some() || doc.periods_px.is_some() || doc.both.is_some() {
                return Err(ManifestError::Shape(
                    "steps, periods_px and both are preset options; a sequence gives them per fringe set",
                ));
            }
            let unwrapping = doc
                .unwrapping
                .ok_or(ManifestError::Shape("a sequence needs an unwrapping"))?;
            CaptureSpec {
                name: "manifest".into(),
                sequence: sequence.into_iter().map(element).collect(),
                unwrapping: unwrapping_from(unwrapping),
                thresholds: Thresholds::default(),
                checks: CheckLimits::default(),
            }
        }
    };
    if let Some(t) = doc.thresholds {
        let s = &mut spec.thresholds;
        s.min_modulation = t.min_modulation.unwrap_or(s.min_modulation);
        s.min_mean = t.min_mean.unwrap_or(s.min_mean);
        s.saturation = t.saturation.unwrap_or(s.saturation);
        s.min_code_contrast = t.min_code_contrast.unwrap_or(s.min_code_contrast);
    }
    if let Some(c) = doc.self_check {
        let s = &mut spec.checks;
        s.max_half_period = c.max_half_period.unwrap_or(s.max_half_period);
        s.max_wrong_order = c.max_wrong_order.unwrap_or(s.max_wrong_order);
        s.max_outside = c.max_outside.unwrap_or(s.max_outside);
    }
    spec.validate(projector)?;
    Ok(spec)
}

/// A description as manifest text (the sequence form, every field written).
pub fn to_json(spec: &CaptureSpec) -> String {
    let t = &spec.thresholds;
    let c = &spec.checks;
    let doc = Doc {
        format: FORMAT.into(),
        version: VERSION,
        preset: None,
        steps: None,
        periods_px: None,
        both: None,
        sequence: Some(spec.sequence.iter().map(element_doc).collect()),
        unwrapping: Some(unwrapping_doc(spec.unwrapping)),
        thresholds: Some(ThresholdsDoc {
            min_modulation: Some(t.min_modulation),
            min_mean: Some(t.min_mean),
            saturation: Some(t.saturation),
            min_code_contrast: Some(t.min_code_contrast),
        }),
        self_check: Some(CheckDoc {
            max_half_period: Some(c.max_half_period),
            max_wrong_order: Some(c.max_wrong_order),
            max_outside: Some(c.max_outside),
        }),
    };
    serde_json::to_string_pretty(&doc).expect("a manifest document always serialises")
}

fn axis(a: AxisDoc) -> ProjectorAxis {
    match a {
        AxisDoc::Columns => ProjectorAxis::Column,
        AxisDoc::Rows => ProjectorAxis::Row,
    }
}

fn axis_doc(a: ProjectorAxis) -> AxisDoc {
    match a {
        ProjectorAxis::Column => AxisDoc::Columns,
        ProjectorAxis::Row => AxisDoc::Rows,
    }
}

fn element(e: ElementDoc) -> Frames {
    match e {
        ElementDoc::Fringes {
            axis: a,
            steps,
            periods_px,
            phase_offset_rad,
            phase_sign,
            shift_sign,
        } => Frames::Fringes(FringeSet {
            axis: axis(a),
            steps,
            periods_px,
            phase_offset_rad,
            phase_sign,
            shift_sign,
        }),
        ElementDoc::Gray {
            axis: a,
            bits,
            block_px,
            inverse,
        } => Frames::Gray(GraySet {
            axis: axis(a),
            bits,
            block_px,
            inverse,
        }),
        ElementDoc::White => Frames::White,
        ElementDoc::Black => Frames::Black,
    }
}

fn element_doc(e: &Frames) -> ElementDoc {
    match e {
        Frames::Fringes(f) => ElementDoc::Fringes {
            axis: axis_doc(f.axis),
            steps: f.steps,
            periods_px: f.periods_px.clone(),
            phase_offset_rad: f.phase_offset_rad,
            phase_sign: f.phase_sign,
            shift_sign: f.shift_sign,
        },
        Frames::Gray(g) => ElementDoc::Gray {
            axis: axis_doc(g.axis),
            bits: g.bits,
            block_px: g.block_px,
            inverse: g.inverse,
        },
        Frames::White => ElementDoc::White,
        Frames::Black => ElementDoc::Black,
    }
}

fn unwrapping_from(u: UnwrappingDoc) -> Unwrapping {
    match u {
        UnwrappingDoc::Heterodyne => Unwrapping::Heterodyne,
        UnwrappingDoc::Pdm => Unwrapping::Pdm,
        UnwrappingDoc::GrayCode => Unwrapping::GrayCode,
        UnwrappingDoc::ComplementaryGrayCode => Unwrapping::ComplementaryGrayCode,
        UnwrappingDoc::QualityGuided { seed, order } => Unwrapping::QualityGuided {
            seed: (seed[0], seed[1]),
            order,
        },
        UnwrappingDoc::None => Unwrapping::None,
    }
}

fn unwrapping_doc(u: Unwrapping) -> UnwrappingDoc {
    match u {
        Unwrapping::Heterodyne => UnwrappingDoc::Heterodyne,
        Unwrapping::Pdm => UnwrappingDoc::Pdm,
        Unwrapping::GrayCode => UnwrappingDoc::GrayCode,
        Unwrapping::ComplementaryGrayCode => UnwrappingDoc::ComplementaryGrayCode,
        Unwrapping::QualityGuided { seed, order } => UnwrappingDoc::QualityGuided {
            seed: [seed.0, seed.1],
            order,
        },
        Unwrapping::None => UnwrappingDoc::None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PROJECTOR: (u32, u32) = (1280, 800);

    #[test]
    fn every_preset_round_trips_through_the_sequence_form() {
        for (_, preset) in super::super::presets::PRESETS {
            let options = PresetOptions {
                steps: Some(5),
                periods_px: Some(vec![20.0, 22.0, 24.0]),
                both: true,
            };
            let options = match preset {
                Preset::SinusCompleGray => PresetOptions {
                    periods_px: Some(vec![32.0]),
                    ..options
                },
                Preset::OpencvGrayCode => PresetOptions::default(),
                _ => options,
            };
            let spec = preset.spec(&options, PROJECTOR).unwrap();
            let back = parse(&to_json(&spec), PROJECTOR).unwrap();
            assert_eq!(back.sequence, spec.sequence);
            assert_eq!(back.unwrapping, spec.unwrapping);
            assert_eq!(back.thresholds, spec.thresholds);
        }
    }

    #[test]
    fn a_preset_manifest_reads() {
        let spec = parse(
            r#"{"format": "slscan-capture", "version": 1, "preset": "sinus-comple-gray",
                "steps": 8, "periods_px": [40]}"#,
            PROJECTOR,
        )
        .unwrap();
        assert_eq!(spec.unwrapping, Unwrapping::ComplementaryGrayCode);
        assert_eq!(spec.frame_count(), 8 + 6);
    }

    #[test]
    fn bad_manifests_say_what_is_wrong() {
        let cases = [
            (
                r#"{"format": "x", "version": 1, "preset": "slscan"}"#,
                "format",
            ),
            (
                r#"{"format": "slscan-capture", "version": 1, "preset": "slscan", "sequence": []}"#,
                "not both",
            ),
            (
                r#"{"format": "slscan-capture", "version": 1, "preset": "slscan", "stpes": 4}"#,
                "unknown field",
            ),
            (
                r#"{"format": "slscan-capture", "version": 1, "sequence": [
                    {"kind": "fringes", "axis": "columns", "steps": 2, "periods_px": [32]}],
                    "unwrapping": {"method": "none"}}"#,
                "3 to 256",
            ),
            (
                r#"{"format": "slscan-capture", "version": 1, "sequence": [
                    {"kind": "fringes", "axis": "columns", "steps": 4, "periods_px": [32]}],
                    "unwrapping": {"method": "heterodyne"}}"#,
                "heterodyne",
            ),
            (
                r#"{"format": "slscan-capture", "version": 1, "sequence": [
                    {"kind": "fringes", "axis": "columns", "steps": 4, "periods_px": [32],
                     "phase_sign": 2}],
                    "unwrapping": {"method": "none"}}"#,
                "+1 or -1",
            ),
            (
                r#"{"format": "slscan-capture", "version": 1, "preset": "slscan",
                    "thresholds": {"min_modulation": 2}}"#,
                "min_modulation",
            ),
        ];
        for (text, want) in cases {
            let err = parse(text, PROJECTOR).unwrap_err().to_string();
            assert!(err.contains(want), "{text}: {err}");
        }
    }
}
