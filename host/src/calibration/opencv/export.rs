//! Our rig -> an OpenCV `cv::FileStorage` file (YAML or XML).
//!
//! A projector-camera [`Head`] becomes the SLMaster layout `M1 D1 M4 D4 Rlp Tlp`, a
//! [`StereoHead`] `cv::stereoCalibrate`'s `M1 D1 M2 D2 R T`; both get the image sizes as
//! extra keys (`image_width image_height`, and `proj_width proj_height` or, for a
//! right camera of another size, `image2_width image2_height`), which the importer
//! reads back. `R, T` map device 1 (the camera, the left camera) into device 2, as
//! OpenCV's do; `T` in the unit asked for. Distortion is written as OpenCV's five
//! coefficients. The world frame is not written: a head whose camera is not at the
//! world origin comes back with the camera as the world (the relative pose is kept).

use std::path::{Path, PathBuf};

use super::import::LengthUnit;
use super::storage::{self, Format, Matrix, Storage, Value};
use crate::calibration::{Head, PinholeModel, Pose, RigCalibration, RigFileError, StereoHead};

/// What can stop an export.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The rig fails its own checks.
    #[error(transparent)]
    Rig(#[from] RigFileError),
    /// The rig has several heads and none was chosen.
    #[error("the rig has {count} heads ({names}): choose one with --head NAME (an OpenCV file holds one)")]
    WhichHead {
        /// Heads and stereo heads.
        count: usize,
        /// Their names.
        names: String,
    },
    /// No head of that name.
    #[error("the rig has no head named {name:?} (it has {names})")]
    UnknownHead {
        /// The name asked for.
        name: String,
        /// The names there are.
        names: String,
    },
    /// The output name has no `.yml`, `.yaml` or `.xml` extension and no format was given.
    #[error("{path}: cannot tell the format from the name; use .yml, .yaml or .xml")]
    UnknownFormat {
        /// The output.
        path: PathBuf,
    },
    /// The file could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The output.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
}

/// The head an OpenCV file can hold.
enum Chosen<'a> {
    Head(&'a Head),
    Stereo(&'a StereoHead),
}

fn choose<'a>(rig: &'a RigCalibration, name: Option<&str>) -> Result<Chosen<'a>, ExportError> {
    let all: Vec<(&str, Chosen<'a>)> = rig
        .heads
        .iter()
        .map(|h| (h.name.as_str(), Chosen::Head(h)))
        .chain(
            rig.stereo_heads
                .iter()
                .map(|h| (h.name.as_str(), Chosen::Stereo(h))),
        )
        .collect();
    let names = all.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ");
    let count = all.len();
    match name {
        Some(name) => all
            .into_iter()
            .find(|(n, _)| *n == name)
            .map(|(_, c)| c)
            .ok_or_else(|| ExportError::UnknownHead {
                name: name.to_owned(),
                names,
            }),
        None if count == 1 => Ok(all.into_iter().next().map(|(_, c)| c).expect("one head")),
        None => Err(ExportError::WhichHead { count, names }),
    }
}

fn camera_matrix(m: &PinholeModel) -> Value {
    let k = &m.intrinsics;
    Value::Matrix(Matrix::f64(
        3,
        3,
        vec![k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0],
    ))
}

fn distortion(m: &PinholeModel) -> Value {
    let d = &m.distortion;
    Value::Matrix(Matrix::f64(1, 5, vec![d.k1, d.k2, d.p1, d.p2, d.k3]))
}

/// `R, T` of device 2 relative to device 1 (`X_2 = R X_1 + T`), `T` in `unit`.
fn relative(first: &PinholeModel, second: &PinholeModel, unit: LengthUnit) -> (Value, Value) {
    let p: Pose = second.pose.compose(&first.pose.inverse());
    let r = &p.rotation;
    let rotation = Matrix::f64(3, 3, (0..9).map(|i| r[(i / 3, i % 3)]).collect());
    let t = p.translation_m / unit.metres();
    (
        Value::Matrix(rotation),
        Value::Matrix(Matrix::f64(3, 1, vec![t.x, t.y, t.z])),
    )
}

/// The FileStorage nodes of one head of the rig (`name`, or the only one).
pub fn rig_to_storage(
    rig: &RigCalibration,
    name: Option<&str>,
    unit: LengthUnit,
) -> Result<Storage, ExportError> {
    rig.validate()?;
    let mut s = Storage::default();
    let (first, second, keys) = match choose(rig, name)? {
        Chosen::Head(h) => (&h.camera, &h.projector, ["M4", "D4", "Rlp", "Tlp"]),
        Chosen::Stereo(h) => (&h.left, &h.right, ["M2", "D2", "R", "T"]),
    };
    let (r, t) = relative(first, second, unit);
    s.push("M1", camera_matrix(first));
    s.push("D1", distortion(first));
    s.push(keys[0], camera_matrix(second));
    s.push(keys[1], distortion(second));
    s.push(keys[2], r);
    s.push(keys[3], t);
    s.push("image_width", Value::Int(first.width_px.into()));
    s.push("image_height", Value::Int(first.height_px.into()));
    let second_size = (second.width_px, second.height_px);
    if keys[0] == "M4" {
        s.push("proj_width", Value::Int(second.width_px.into()));
        s.push("proj_height", Value::Int(second.height_px.into()));
    } else if second_size != (first.width_px, first.height_px) {
        s.push("image2_width", Value::Int(second.width_px.into()));
        s.push("image2_height", Value::Int(second.height_px.into()));
    }
    Ok(s)
}

/// Writes one head of the rig as an OpenCV file, YAML or XML as `format` says or, when
/// `None`, as the extension says; atomically (never a partial file).
pub fn write_opencv(
    path: &Path,
    rig: &RigCalibration,
    name: Option<&str>,
    unit: LengthUnit,
    format: Option<Format>,
) -> Result<(), ExportError> {
    let format =
        format
            .or_else(|| storage::format_of(path))
            .ok_or_else(|| ExportError::UnknownFormat {
                path: path.to_owned(),
            })?;
    let text = storage::to_text(&rig_to_storage(rig, name, unit)?, format);
    crate::io::write_atomically(path, |w| w.write_all(text.as_bytes())).map_err(|source| {
        ExportError::Io {
            path: path.to_owned(),
            source,
        }
    })
}
