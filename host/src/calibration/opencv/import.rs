//! OpenCV calibration files -> our device models.
//!
//! Layouts recognised, first complete one wins:
//!
//! | keys | what | becomes |
//! |---|---|---|
//! | `M1 D1 M4 D4 Rlp Tlp` | camera, projector, camera -> projector (SLMaster) | [`Head`] |
//! | `M1 D1 M2 D2 R T` | `cv::stereoCalibrate`: camera 1, device 2, 1 -> 2 | [`StereoHead`], or a [`Head`] with [`SecondDevice::Projector`] |
//! | `R1 R2 P1 P2 Q` | `cv::stereoRectify` only | [`StereoHead`] of the rectified cameras |
//! | `camera_matrix distortion_coefficients` | OpenCV's calibration sample | one [`CameraModel`] |
//!
//! OpenCV's convention is `X_2 = R X_1 + T`: `R, T` map camera-1 coordinates into
//! device 2. Our poses map the head's world frame into each device (`x_d = R x_w + t`),
//! and the world is camera 1's frame, so camera 1 gets the identity and device 2 gets
//! `(R, T)` with `T` scaled to metres.
//!
//! A rectified-only file (`R1 R2 P1 P2 Q`) is taken to describe images that are already
//! rectified (`cv::initUndistortRectifyMap` with `R1, P1` and `R2, P2`): the devices are
//! the rectified cameras, intrinsics `P_i[:, 0..3]`, no distortion, pose
//! `(I, K_i^-1 P_i[:, 3])` in rectified camera 1's frame, both of the camera image
//! size. `R1`, `R2` (rotation checks) and `Q` (present, finite) are only checked.
//!
//! Checks before anything is returned: every number finite, camera matrices of the form
//! `[fx 0 cx; 0 fy cy; 0 0 1]` with positive focal lengths, distortion vectors of 4, 5,
//! 8, 12 or 14 terms whose terms past `k3` are zero (we model `k1 k2 p1 p2 k3`), proper
//! rotations, and the direction of `R, T`: the closest points of the two principal rays
//! must lie in front of both devices. A file whose `R, T` map device 2 into device 1
//! gets [`ImportError::InvertedExtrinsics`] when only one of `R`, `T` is inverted (`R`
//! transposed, or `T` negated or given as device 2's centre): the axes then diverge or
//! meet behind a device. A *consistently* inverted pair `(R^T, -R^T T)` describes the
//! mirror rig, congruent to the true one with the two devices' places swapped; no test
//! on the file alone can tell it apart, so that case is not caught here.

use std::path::Path;

use nalgebra::{Matrix3, Vector3};

pub use super::error::ImportError;
use super::storage::{self, Matrix, Storage, Value};
use crate::calibration::rodrigues::rotation_from_rodrigues;
use crate::calibration::{
    CameraModel, Distortion, Head, Intrinsics, PinholeModel, Pose, RigCalibration, StereoHead,
};

/// Length unit of the file's translations.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LengthUnit {
    /// Millimetres (OpenCV calibrations with board squares in mm; the default).
    #[default]
    Mm,
    /// Metres.
    M,
}

impl std::str::FromStr for LengthUnit {
    type Err = String;

    /// `mm` or `m`.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "mm" => Ok(Self::Mm),
            "m" => Ok(Self::M),
            _ => Err(format!("unit {s:?}: expected mm or m")),
        }
    }
}

impl std::str::FromStr for SecondDevice {
    type Err = String;

    /// `camera` or `projector`.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "camera" => Ok(Self::Camera),
            "projector" => Ok(Self::Projector),
            _ => Err(format!("second device {s:?}: expected camera or projector")),
        }
    }
}

impl LengthUnit {
    /// Metres per unit.
    pub fn metres(self) -> f64 {
        match self {
            Self::Mm => 1e-3,
            Self::M => 1.0,
        }
    }
}

/// What the second device of an `M1 D1 M2 D2 R T` file is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SecondDevice {
    /// A second camera: a stereo head (the default; what `cv::stereoCalibrate` writes).
    #[default]
    Camera,
    /// A projector: a projector-camera head.
    Projector,
}

/// How to read a file.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportOptions {
    /// Unit of `T`, `Tlp` and `P2`'s last column.
    pub unit: LengthUnit,
    /// Camera image size `(width, height)`, pixels, when the file lacks it.
    pub camera_size_px: Option<(u32, u32)>,
    /// Projector DMD size `(width, height)`, pixels, when the file lacks it.
    pub projector_size_px: Option<(u32, u32)>,
    /// Name of the head.
    pub name: String,
    /// What device 2 of an `M1 D1 M2 D2 R T` file is.
    pub second: SecondDevice,
    /// Invert `R, T` (the file maps device 2 into device 1) before anything else.
    pub invert_extrinsics: bool,
}

impl Default for ImportOptions {
    fn default() -> Self {
        Self {
            unit: LengthUnit::Mm,
            camera_size_px: None,
            projector_size_px: None,
            name: "A".into(),
            second: SecondDevice::Camera,
            invert_extrinsics: false,
        }
    }
}

/// What a file held.
#[derive(Clone, Debug, PartialEq)]
pub enum Imported {
    /// A camera and a projector.
    Head(Head),
    /// Two cameras.
    Stereo(StereoHead),
    /// One camera.
    Camera(CameraModel),
}

type Result<T> = std::result::Result<T, ImportError>;

const PROJECTOR_CAMERA: &[&str] = &["M1", "D1", "M4", "D4", "Rlp", "Tlp"];
const STEREO: &[&str] = &["M1", "D1", "M2", "D2", "R", "T"];
const RECTIFIED: &[&str] = &["R1", "R2", "P1", "P2", "Q"];
const CAMERA: &[&str] = &["camera_matrix", "distortion_coefficients"];
/// Each layout: keys, name, keys as one text.
const LAYOUTS: [(&[&str], &str, &str); 4] = [
    (PROJECTOR_CAMERA, "projector-camera", "M1 D1 M4 D4 Rlp Tlp"),
    (STEREO, "stereo", "M1 D1 M2 D2 R T"),
    (RECTIFIED, "rectified stereo", "R1 R2 P1 P2 Q"),
    (
        CAMERA,
        "single-camera",
        "camera_matrix distortion_coefficients",
    ),
];

/// Keys holding a camera's size: `[w, h]` nodes, then `(width, height)` pairs.
const CAMERA_SIZE_KEYS: (&[&str], &[(&str, &str)], &str) = (
    &["imageSize", "image_size", "cam_size", "camera_size"],
    &[("image_width", "image_height"), ("cam_width", "cam_height")],
    "imageSize, image_size, cam_size, camera_size, image_width/image_height, cam_width/cam_height",
);
const PROJECTOR_SIZE_KEYS: (&[&str], &[(&str, &str)], &str) = (
    &["proj_size", "projector_size", "projSize"],
    &[
        ("proj_width", "proj_height"),
        ("projector_width", "projector_height"),
    ],
    "proj_size, projector_size, projSize, proj_width/proj_height, projector_width/projector_height",
);

/// A right camera whose size differs from the left's (as `export` writes it).
const RIGHT_SIZE_KEYS: (&[&str], &[(&str, &str)], &str) = (
    &[],
    &[("image2_width", "image2_height")],
    "image2_width/image2_height",
);

/// Reads and imports a FileStorage file (YAML or XML).
pub fn read_opencv(path: &Path, options: &ImportOptions) -> Result<Imported> {
    let bytes = std::fs::read(path).map_err(|source| ImportError::Io {
        path: path.to_owned(),
        source,
    })?;
    parse_opencv(&bytes, options)
}

/// Imports FileStorage bytes (YAML or XML).
pub fn parse_opencv(bytes: &[u8], options: &ImportOptions) -> Result<Imported> {
    import_storage(&storage::parse(bytes)?, options)
}

/// Imports the nodes of a FileStorage file (see the module doc for layouts and checks).
pub fn import_storage(s: &Storage, options: &ImportOptions) -> Result<Imported> {
    let has = |keys: &[&str]| keys.iter().filter(|k| s.get(k).is_some()).count();
    let Some(&(keys, layout, needs)) = LAYOUTS
        .iter()
        .find(|(keys, ..)| has(keys) == keys.len())
        .or_else(|| {
            LAYOUTS
                .iter()
                .filter(|(k, ..)| has(k) > 0)
                .max_by_key(|(k, ..)| has(k) * 100 / k.len())
        })
    else {
        let found: Vec<&str> = s.nodes.iter().map(|n| n.key.as_str()).collect();
        return Err(ImportError::NoCalibration {
            found: found.join(" "),
        });
    };
    if let Some(key) = keys.iter().find(|k| s.get(k).is_none()) {
        return Err(ImportError::MissingKey { key, layout, needs });
    }
    let metres = options.unit.metres();
    let camera_size = || {
        image_size(
            s,
            "camera",
            CAMERA_SIZE_KEYS,
            options.camera_size_px,
            "--camera-size",
        )
    };
    match keys[0] {
        "M1" => {
            let (m2, d2, r, t) = if keys == PROJECTOR_CAMERA {
                ("M4", "D4", "Rlp", "Tlp")
            } else {
                ("M2", "D2", "R", "T")
            };
            let is_projector =
                keys == PROJECTOR_CAMERA || options.second == SecondDevice::Projector;
            let mut pose = pose(s, r, t, metres)?;
            if options.invert_extrinsics {
                pose = pose.inverse();
            }
            let first = device(s, "M1", "D1", camera_size()?, Pose::identity())?;
            let second_size = if is_projector {
                image_size(
                    s,
                    "projector",
                    PROJECTOR_SIZE_KEYS,
                    options.projector_size_px,
                    "--projector-size",
                )?
            } else if s.get("image2_width").is_some() {
                image_size(s, "right camera", RIGHT_SIZE_KEYS, None, "--camera-size")?
            } else {
                camera_size()?
            };
            let second = device(s, m2, d2, second_size, pose)?;
            check_direction(&pose, r, t)?;
            warn_on_baseline(&second);
            Ok(if is_projector {
                Imported::Head(Head {
                    name: options.name.clone(),
                    camera: first,
                    projector: second,
                    view_errors: vec![],
                    port: None,
                })
            } else {
                Imported::Stereo(StereoHead {
                    name: options.name.clone(),
                    left: first,
                    right: second,
                })
            })
        }
        "R1" => {
            for key in ["R1", "R2"] {
                rotation(s, key)?;
            }
            let q = matrix(s, "Q")?;
            shape(s, &q, "Q", &[(4, 4)], "4x4")?;
            let size = camera_size()?;
            let left = rectified(s, "P1", size, metres)?;
            let right = rectified(s, "P2", size, metres)?;
            warn_on_baseline(&right);
            Ok(Imported::Stereo(StereoHead {
                name: options.name.clone(),
                left,
                right,
            }))
        }
        _ => Ok(Imported::Camera(device(
            s,
            "camera_matrix",
            "distortion_coefficients",
            camera_size()?,
            Pose::identity(),
        )?)),
    }
}

impl Imported {
    /// A one-head rig of what was imported, validated as the rig file is.
    pub fn into_rig(self) -> Result<RigCalibration> {
        let rig = match self {
            Self::Head(head) => RigCalibration::single(head),
            Self::Stereo(stereo) => RigCalibration {
                heads: vec![],
                head_poses: vec![],
                stereo_heads: vec![stereo],
            },
            Self::Camera(_) => return Err(ImportError::CameraOnly),
        };
        rig.validate()?;
        Ok(rig)
    }
}

/// The node `key` as a matrix (a number sequence counts as a column), all finite.
fn matrix(s: &Storage, key: &str) -> Result<Matrix> {
    let node = s.get(key).ok_or_else(|| ImportError::NotAMatrix {
        key: key.to_owned(),
        line: 0,
    })?;
    let m = match &node.value {
        Value::Matrix(m) => m.clone(),
        Value::Seq(v) => Matrix::f64(v.len(), 1, v.clone()),
        _ => {
            return Err(ImportError::NotAMatrix {
                key: key.to_owned(),
                line: node.line,
            })
        }
    };
    if let Some((index, &value)) = m.data.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(ImportError::NonFinite {
            key: key.to_owned(),
            line: node.line,
            index,
            value,
        });
    }
    Ok(m)
}

fn line_of(s: &Storage, key: &str) -> usize {
    s.get(key).map_or(0, |n| n.line)
}

fn shape(
    s: &Storage,
    m: &Matrix,
    key: &str,
    ok: &[(usize, usize)],
    expected: &'static str,
) -> Result<()> {
    if ok.contains(&(m.rows, m.cols)) {
        return Ok(());
    }
    Err(ImportError::WrongSize {
        key: key.to_owned(),
        line: line_of(s, key),
        rows: m.rows,
        cols: m.cols,
        expected,
    })
}

/// A vector of `n` values given as a row or a column.
fn vector(s: &Storage, key: &str, n: usize, expected: &'static str) -> Result<Vec<f64>> {
    let m = matrix(s, key)?;
    shape(s, &m, key, &[(n, 1), (1, n)], expected)?;
    Ok(m.data)
}

fn intrinsics(s: &Storage, key: &str) -> Result<Intrinsics> {
    let m = matrix(s, key)?;
    shape(s, &m, key, &[(3, 3)], "3x3")?;
    let bad = |problem| ImportError::BadCameraMatrix {
        key: key.to_owned(),
        problem,
    };
    let (fx, fy) = (m.at(0, 0), m.at(1, 1));
    if fx <= 0.0 || fy <= 0.0 {
        return Err(bad("a focal length is not positive"));
    }
    if m.at(0, 1).abs() > 1e-9 * fx {
        return Err(bad("nonzero skew M[0][1] (not modelled)"));
    }
    if m.at(1, 0) != 0.0 || m.at(2, 0) != 0.0 || m.at(2, 1) != 0.0 || m.at(2, 2) != 1.0 {
        return Err(bad("the last row is not 0 0 1 or M[1][0] is not 0"));
    }
    Ok(Intrinsics {
        fx,
        fy,
        cx: m.at(0, 2),
        cy: m.at(1, 2),
    })
}

fn distortion(s: &Storage, key: &str) -> Result<Distortion> {
    const NAMES: [&str; 14] = [
        "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "tau_x", "tau_y",
    ];
    let m = matrix(s, key)?;
    let n = m.data.len();
    if m.rows.min(m.cols) != 1 || ![4, 5, 8, 12, 14].contains(&n) {
        return Err(ImportError::WrongSize {
            key: key.to_owned(),
            line: line_of(s, key),
            rows: m.rows,
            cols: m.cols,
            expected: "a row or column of 4, 5, 8, 12 or 14 coefficients",
        });
    }
    let terms: Vec<&'static str> = (5..n)
        .filter(|&i| m.data[i] != 0.0)
        .map(|i| NAMES[i])
        .collect();
    if !terms.is_empty() {
        return Err(ImportError::UnmodelledDistortion {
            key: key.to_owned(),
            terms,
        });
    }
    let d = &m.data;
    Ok(Distortion {
        k1: d[0],
        k2: d[1],
        p1: d[2],
        p2: d[3],
        k3: d.get(4).copied().unwrap_or(0.0),
    })
}

/// A 3x3 rotation, or a Rodrigues 3-vector, checked proper.
fn rotation(s: &Storage, key: &str) -> Result<Matrix3<f64>> {
    let m = matrix(s, key)?;
    shape(
        s,
        &m,
        key,
        &[(3, 3), (3, 1), (1, 3)],
        "3x3 (or a 3-element Rodrigues vector)",
    )?;
    let r = if m.rows == 3 && m.cols == 3 {
        Matrix3::from_row_slice(&m.data)
    } else {
        rotation_from_rodrigues(&Vector3::from_column_slice(&m.data))
    };
    let defect = Pose {
        rotation: r,
        translation_m: Vector3::zeros(),
    }
    .rotation_defect();
    if defect > 1e-6 || !defect.is_finite() {
        return Err(ImportError::NotARotation {
            key: key.to_owned(),
            defect,
        });
    }
    Ok(r)
}

fn pose(s: &Storage, r_key: &str, t_key: &str, metres: f64) -> Result<Pose> {
    let rotation = rotation(s, r_key)?;
    let t = vector(s, t_key, 3, "3x1 or 1x3")?;
    Ok(Pose {
        rotation,
        translation_m: Vector3::from_column_slice(&t) * metres,
    })
}

fn device(s: &Storage, m: &str, d: &str, size: (u32, u32), pose: Pose) -> Result<PinholeModel> {
    Ok(PinholeModel {
        width_px: size.0,
        height_px: size.1,
        intrinsics: intrinsics(s, m)?,
        distortion: distortion(s, d)?,
        pose,
    })
}

/// A rectified camera from its 3x4 projection matrix (see the module doc).
fn rectified(s: &Storage, key: &str, size: (u32, u32), metres: f64) -> Result<PinholeModel> {
    let p = matrix(s, key)?;
    shape(s, &p, key, &[(3, 4)], "3x4")?;
    let k = Matrix::f64(3, 3, (0..9).map(|i| p.at(i / 3, i % 3)).collect());
    let mut tmp = Storage::default();
    tmp.push(key, Value::Matrix(k.clone()));
    let intrinsics = intrinsics(&tmp, key)?;
    let k = Matrix3::from_row_slice(&k.data);
    let last = Vector3::new(p.at(0, 3), p.at(1, 3), p.at(2, 3));
    // K is upper triangular with positive diagonal (checked): invertible.
    let t = k.try_inverse().map_or(Vector3::zeros(), |ki| ki * last) * metres;
    Ok(PinholeModel {
        width_px: size.0,
        height_px: size.1,
        intrinsics,
        distortion: Distortion::none(),
        pose: Pose {
            rotation: Matrix3::identity(),
            translation_m: t,
        },
    })
}

/// The caller's size, the file's, or an error; both given and different is an error.
fn image_size(
    s: &Storage,
    device: &'static str,
    (single, pairs, keys): (&[&str], &[(&str, &str)], &'static str),
    given: Option<(u32, u32)>,
    flag: &'static str,
) -> Result<(u32, u32)> {
    let side = |key: &str, v: f64| {
        if v.fract() == 0.0 && (1.0..=65_536.0).contains(&v) {
            Ok(v as u32)
        } else {
            Err(ImportError::BadImageSize {
                key: key.to_owned(),
                line: line_of(s, key),
            })
        }
    };
    let number = |key: &str| match s.get(key).map(|n| &n.value) {
        Some(Value::Int(i)) => Some(*i as f64),
        Some(Value::Real(v)) => Some(*v),
        _ => None,
    };
    let mut file = None;
    for key in single {
        if s.get(key).is_some() {
            let v = vector(s, key, 2, "2 values: width, height").map_err(|_| {
                ImportError::BadImageSize {
                    key: (*key).to_owned(),
                    line: line_of(s, key),
                }
            })?;
            file = Some((side(key, v[0])?, side(key, v[1])?));
            break;
        }
    }
    if file.is_none() {
        for (w, h) in pairs {
            if let (Some(wv), Some(hv)) = (number(w), number(h)) {
                file = Some((side(w, wv)?, side(h, hv)?));
                break;
            }
        }
    }
    match (file, given) {
        (Some(f), Some(g)) if f != g => Err(ImportError::SizeConflict {
            device,
            file_w: f.0,
            file_h: f.1,
            given_w: g.0,
            given_h: g.1,
        }),
        (Some(size), _) | (None, Some(size)) => Ok(size),
        (None, None) => Err(ImportError::NoImageSize { device, keys, flag }),
    }
}

/// Closest points of the two principal rays, as distances along each: `None` when the
/// axes are within 2 degrees of parallel (the closest point is then ill-defined).
pub fn principal_ray_closest(device2: &Pose) -> Option<(f64, f64)> {
    let d1 = Vector3::z();
    let rt = device2.rotation.transpose();
    let c2 = -(rt * device2.translation_m);
    let d2 = rt * Vector3::z();
    let b = d1.dot(&d2);
    let denom = 1.0 - b * b;
    if denom < (2f64.to_radians().sin()).powi(2) {
        return None;
    }
    let w0 = -c2;
    let (d, e) = (d1.dot(&w0), d2.dot(&w0));
    Some(((b * e - d) / denom, (e - b * d) / denom))
}

fn check_direction(device2: &Pose, r_key: &'static str, t_key: &'static str) -> Result<()> {
    match principal_ray_closest(device2) {
        Some((s1_m, s2_m)) if s1_m <= 0.0 || s2_m <= 0.0 => Err(ImportError::InvertedExtrinsics {
            r_key,
            t_key,
            s1_m,
            s2_m,
        }),
        _ => Ok(()),
    }
}

fn warn_on_baseline(second: &PinholeModel) {
    let baseline_m = second.centre_m().coords.norm();
    if !(1e-3..=10.0).contains(&baseline_m) {
        tracing::warn!(
            baseline_mm = baseline_m * 1e3,
            "the baseline is {:.4} mm: is --unit right (mm or m)?",
            baseline_m * 1e3
        );
    }
}
