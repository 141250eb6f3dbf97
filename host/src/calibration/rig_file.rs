//! The rig calibration file: one JSON document per rig, OpenCV field names.
//!
//! ```json
//! {
//!   "format": "slscan-rig", "version": 1,
//!   "heads": [{
//!     "name": "A",
//!     "camera":    {"width_px": 3072, "height_px": 2048,
//!                   "fx": 4000.0, "fy": 4000.0, "cx": 1535.5, "cy": 1023.5,
//!                   "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0, "k3": 0.0,
//!                   "rotation": [[1,0,0],[0,1,0],[0,0,1]], "translation_m": [0,0,0]},
//!     "projector": {"width_px": 912, "height_px": 1140, "...": "same fields"},
//!     "view_errors": [{"view": "pose_00", "camera_rms_px": 0.08, "projector_rms_px": 0.12}],
//!     "port": {"distance_m": 0.03, "normal": [0, 0, 1], "thickness_m": 0.008,
//!              "glass_index": 1.49, "water_index": 1.33}
//!   }],
//!   "head_to_head": null,
//!   "stereo_heads": [{"name": "S", "left": {"...": "camera fields"}, "right": {"...": "camera fields"}}]
//! }
//! ```
//!
//! `stereo_heads` is optional (absent in older files, and not written when empty); a rig
//! has 1 to 4 projector heads (`protocol::limits::MAX_HEADS`), or none when it has a
//! stereo head. Names are unique across both lists. Each head after the first has its
//! pose from head 0's world frame: a two-head rig writes it as `head_to_head` (as every
//! earlier file does), a rig of three or four as `head_poses` (one per head after the
//! first, in order); a two-head file may give either, never both.
//!
//! A head's `port` is optional (absent in files of heads that work in air, and not written
//! then): the flat window its camera and its projector each look through under water,
//! `distance_m` in front of the device along its optical axis, `normal` in the device's
//! frame (`[0, 0, 1]` when left out; scaled to unit length on reading), glass
//! `thickness_m` (0: a thin port) and the glass's and the water's refractive indices
//! (see `triangulation::flat_port`).
//!
//! `rotation` is row-major and, with `translation_m`, maps the head's world frame into the
//! device (`x_d = R x_w + t`), as OpenCV's `R`/`T`. Reading parses the text (serde names a
//! missing or mistyped field with its line), then validates it into a [`RigCalibration`]
//! the rest of the code trusts; writing validates first and never leaves a partial file.

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use super::{
    Distortion, Head, Intrinsics, PinholeModel, Pose, RigCalibration, StereoHead, ViewError,
};
use crate::triangulation::flat_port::{FlatPort, FlatPortError};

/// The `format` string every rig file carries.
pub const FORMAT: &str = "slscan-rig";
/// The file version this code reads and writes.
pub const VERSION: u32 = 1;
/// Largest image side accepted, pixels (guards against garbage sizes).
pub const MAX_SIDE_PX: u32 = 65_536;

/// What can be wrong with a rig file.
#[derive(Debug, thiserror::Error)]
pub enum RigFileError {
    /// The file could not be read or written.
    #[error("rig file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The text is not valid JSON for a rig (missing field, wrong type, wrong array length).
    #[error("rig file {path}: {source}")]
    Json {
        /// The file (empty for in-memory text).
        path: PathBuf,
        /// serde_json's error, with line and column.
        source: serde_json::Error,
    },
    /// `format` or `version` is not one this code reads.
    #[error("not a rig file this version reads: format {format:?} version {version} (want {FORMAT:?} {VERSION})")]
    UnsupportedFormat {
        /// The `format` found.
        format: String,
        /// The `version` found.
        version: u32,
    },
    /// A number is NaN or infinite.
    #[error("{field} is {value}, not a finite number")]
    NonFinite {
        /// Where, e.g. `heads[0].camera.k1`.
        field: String,
        /// The value.
        value: f64,
    },
    /// A focal length is zero or negative.
    #[error("{device}: focal lengths must be positive, got fx = {fx}, fy = {fy}")]
    NonPositiveFocal {
        /// Which device, e.g. `heads[0].projector`.
        device: String,
        /// fx found, pixels.
        fx: f64,
        /// fy found, pixels.
        fy: f64,
    },
    /// An image size is zero or absurdly large.
    #[error("{device}: image size {width_px}x{height_px} is not in 1..={MAX_SIDE_PX}")]
    BadImageSize {
        /// Which device.
        device: String,
        /// Width found.
        width_px: u32,
        /// Height found.
        height_px: u32,
    },
    /// A rotation matrix is not orthonormal with determinant +1.
    #[error("{device}: rotation is not a proper rotation (defect {defect:.3e} > 1e-6)")]
    NotARotation {
        /// Which transform.
        device: String,
        /// `max|R^T R - I| + |det R - 1|`.
        defect: f64,
    },
    /// A rig needs one to four heads (or none, with a stereo head).
    #[error(
        "a rig has 1 to {} projector heads (or none with a stereo head), this one has {count}",
        protocol::limits::MAX_HEADS
    )]
    HeadCount {
        /// Heads found.
        count: usize,
    },
    /// Every head after the first needs its pose from head 0 (`head_to_head`
    /// or `head_poses`), and only those.
    #[error("{heads} head(s) need {} head pose(s) from head 0 (head_to_head for two heads, head_poses for more), the file gives {poses}", heads.saturating_sub(1))]
    HeadPoses {
        /// Heads found.
        heads: usize,
        /// Poses given.
        poses: usize,
    },
    /// A file gives both `head_to_head` and `head_poses`.
    #[error("give a two-head rig's pose as head_to_head or as head_poses, not both")]
    BothHeadPoseFields,
    /// Two heads (projector or stereo) share a name.
    #[error("two heads are both named {name:?}")]
    DuplicateHeadName {
        /// The name.
        name: String,
    },
    /// A reprojection error is negative.
    #[error("{field} = {value} px: a reprojection error cannot be negative")]
    NegativeError {
        /// Where.
        field: String,
        /// The value.
        value: f64,
    },
    /// A head's flat port is not physical (non-finite number, index below 1, ...).
    #[error("{field}: {source}")]
    Port {
        /// Where, e.g. `heads[0].port`.
        field: String,
        /// What is wrong with it (boxed: it would double the size of every other error).
        source: Box<FlatPortError>,
    },
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RigDoc {
    format: String,
    version: u32,
    heads: Vec<HeadDoc>,
    #[serde(default)]
    head_to_head: Option<PoseDoc>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    head_poses: Vec<PoseDoc>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    stereo_heads: Vec<StereoHeadDoc>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct StereoHeadDoc {
    name: String,
    left: DeviceDoc,
    right: DeviceDoc,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct HeadDoc {
    name: String,
    camera: DeviceDoc,
    projector: DeviceDoc,
    #[serde(default)]
    view_errors: Vec<ViewErrorDoc>,
    /// Written for people reading the file; recomputed from `view_errors`, ignored on read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    camera_rms_px: Option<f64>,
    /// As `camera_rms_px`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    projector_rms_px: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    port: Option<PortDoc>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PortDoc {
    distance_m: f64,
    #[serde(default = "port_axis")]
    normal: [f64; 3],
    thickness_m: f64,
    glass_index: f64,
    water_index: f64,
}

/// A port square to the optical axis.
fn port_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct DeviceDoc {
    width_px: u32,
    height_px: u32,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    k1: f64,
    k2: f64,
    p1: f64,
    p2: f64,
    k3: f64,
    rotation: [[f64; 3]; 3],
    translation_m: [f64; 3],
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PoseDoc {
    rotation: [[f64; 3]; 3],
    translation_m: [f64; 3],
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ViewErrorDoc {
    view: String,
    camera_rms_px: f64,
    #[serde(default)]
    projector_rms_px: Option<f64>,
}

/// Reads and validates a rig file.
pub fn read_rig(path: &Path) -> Result<RigCalibration, RigFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| RigFileError::Io {
        path: path.to_owned(),
        source,
    })?;
    parse_rig(&text).map_err(|e| match e {
        RigFileError::Json { source, .. } => RigFileError::Json {
            path: path.to_owned(),
            source,
        },
        other => other,
    })
}

/// Parses and validates rig JSON text.
pub fn parse_rig(text: &str) -> Result<RigCalibration, RigFileError> {
    let doc: RigDoc = serde_json::from_str(text).map_err(|source| RigFileError::Json {
        path: PathBuf::new(),
        source,
    })?;
    if doc.format != FORMAT || doc.version != VERSION {
        return Err(RigFileError::UnsupportedFormat {
            format: doc.format,
            version: doc.version,
        });
    }
    if doc.head_to_head.is_some() && !doc.head_poses.is_empty() {
        return Err(RigFileError::BothHeadPoseFields);
    }
    let rig = RigCalibration {
        heads: doc.heads.into_iter().map(head_from_doc).collect(),
        head_poses: doc
            .head_to_head
            .iter()
            .chain(&doc.head_poses)
            .map(|p| pose_from_doc(&p.rotation, &p.translation_m))
            .collect(),
        stereo_heads: doc
            .stereo_heads
            .iter()
            .map(|h| StereoHead {
                name: h.name.clone(),
                left: device_from_doc(&h.left),
                right: device_from_doc(&h.right),
            })
            .collect(),
    };
    validate(&rig)?;
    Ok(rig)
}

/// Validates, then renders the rig as pretty JSON text.
pub fn to_json(rig: &RigCalibration) -> Result<String, RigFileError> {
    validate(rig)?;
    let doc = RigDoc {
        format: FORMAT.to_owned(),
        version: VERSION,
        heads: rig.heads.iter().map(head_to_doc).collect(),
        // Two heads keep the field every earlier file has.
        head_to_head: rig.head_to_head().as_ref().map(pose_doc),
        head_poses: match rig.heads.len() {
            2 => Vec::new(),
            _ => rig.head_poses.iter().map(pose_doc).collect(),
        },
        stereo_heads: rig
            .stereo_heads
            .iter()
            .map(|h| StereoHeadDoc {
                name: h.name.clone(),
                left: device_to_doc(&h.left),
                right: device_to_doc(&h.right),
            })
            .collect(),
    };
    serde_json::to_string_pretty(&doc).map_err(|source| RigFileError::Json {
        path: PathBuf::new(),
        source,
    })
}

/// Validates and writes a rig file (temp file, then rename: never a partial file).
pub fn write_rig(path: &Path, rig: &RigCalibration) -> Result<(), RigFileError> {
    let text = to_json(rig)?;
    crate::io::write_atomically(path, |w| w.write_all(text.as_bytes())).map_err(|source| {
        RigFileError::Io {
            path: path.to_owned(),
            source,
        }
    })
}

/// Checks a rig: 1-4 heads (or 0 with a stereo head), unique names, finite numbers,
/// positive focal lengths, sane sizes, proper rotations, one pose from head 0 per
/// further head, non-negative errors.
pub fn validate(rig: &RigCalibration) -> Result<(), RigFileError> {
    let count = rig.heads.len();
    let min = if rig.stereo_heads.is_empty() { 1 } else { 0 };
    if !(min..=protocol::limits::MAX_HEADS).contains(&count) {
        return Err(RigFileError::HeadCount { count });
    }
    if rig.head_poses.len() != count.saturating_sub(1) {
        return Err(RigFileError::HeadPoses {
            heads: count,
            poses: rig.head_poses.len(),
        });
    }
    let mut names = std::collections::HashSet::new();
    let all_names = rig.heads.iter().map(|h| &h.name);
    for name in all_names.chain(rig.stereo_heads.iter().map(|h| &h.name)) {
        if !names.insert(name) {
            return Err(RigFileError::DuplicateHeadName { name: name.clone() });
        }
    }
    for (i, head) in rig.heads.iter().enumerate() {
        validate_device(&format!("heads[{i}].camera"), &head.camera)?;
        validate_device(&format!("heads[{i}].projector"), &head.projector)?;
        for (j, v) in head.view_errors.iter().enumerate() {
            let field = format!("heads[{i}].view_errors[{j}]");
            check_error(&format!("{field}.camera_rms_px"), v.camera_rms_px)?;
            if let Some(p) = v.projector_rms_px {
                check_error(&format!("{field}.projector_rms_px"), p)?;
            }
        }
        if let Some(port) = &head.port {
            port.validate().map_err(|source| RigFileError::Port {
                field: format!("heads[{i}].port"),
                source: Box::new(source),
            })?;
        }
    }
    for (i, head) in rig.stereo_heads.iter().enumerate() {
        validate_device(&format!("stereo_heads[{i}].left"), &head.left)?;
        validate_device(&format!("stereo_heads[{i}].right"), &head.right)?;
    }
    for (i, p) in rig.head_poses.iter().enumerate() {
        let field = match count {
            2 => "head_to_head".to_owned(),
            _ => format!("head_poses[{i}]"),
        };
        validate_pose(&field, p)?;
    }
    Ok(())
}

fn check_error(field: &str, value: f64) -> Result<(), RigFileError> {
    finite(field, value)?;
    if value < 0.0 {
        return Err(RigFileError::NegativeError {
            field: field.to_owned(),
            value,
        });
    }
    Ok(())
}

fn finite(field: &str, value: f64) -> Result<(), RigFileError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(RigFileError::NonFinite {
            field: field.to_owned(),
            value,
        })
    }
}

fn validate_device(device: &str, m: &PinholeModel) -> Result<(), RigFileError> {
    let k = &m.intrinsics;
    let d = &m.distortion;
    let named = [
        ("fx", k.fx),
        ("fy", k.fy),
        ("cx", k.cx),
        ("cy", k.cy),
        ("k1", d.k1),
        ("k2", d.k2),
        ("p1", d.p1),
        ("p2", d.p2),
        ("k3", d.k3),
    ];
    for (name, value) in named {
        finite(&format!("{device}.{name}"), value)?;
    }
    if k.fx <= 0.0 || k.fy <= 0.0 {
        return Err(RigFileError::NonPositiveFocal {
            device: device.to_owned(),
            fx: k.fx,
            fy: k.fy,
        });
    }
    let side_ok = |s: u32| (1..=MAX_SIDE_PX).contains(&s);
    if !side_ok(m.width_px) || !side_ok(m.height_px) {
        return Err(RigFileError::BadImageSize {
            device: device.to_owned(),
            width_px: m.width_px,
            height_px: m.height_px,
        });
    }
    validate_pose(device, &m.pose)
}

fn validate_pose(device: &str, p: &Pose) -> Result<(), RigFileError> {
    for (i, v) in p.rotation.iter().enumerate() {
        finite(&format!("{device}.rotation[{}][{}]", i % 3, i / 3), *v)?;
    }
    for (i, v) in p.translation_m.iter().enumerate() {
        finite(&format!("{device}.translation_m[{i}]"), *v)?;
    }
    let defect = p.rotation_defect();
    if defect > 1e-6 {
        return Err(RigFileError::NotARotation {
            device: device.to_owned(),
            defect,
        });
    }
    Ok(())
}

fn pose_from_doc(r: &[[f64; 3]; 3], t: &[f64; 3]) -> Pose {
    Pose {
        rotation: Matrix3::from_fn(|i, j| r[i][j]),
        translation_m: Vector3::from(*t),
    }
}

fn pose_doc(p: &Pose) -> PoseDoc {
    let (rotation, translation_m) = pose_to_doc(p);
    PoseDoc {
        rotation,
        translation_m,
    }
}

fn pose_to_doc(p: &Pose) -> ([[f64; 3]; 3], [f64; 3]) {
    let r = &p.rotation;
    let rotation = [0, 1, 2].map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]);
    (rotation, p.translation_m.into())
}

fn device_from_doc(d: &DeviceDoc) -> PinholeModel {
    PinholeModel {
        width_px: d.width_px,
        height_px: d.height_px,
        intrinsics: Intrinsics {
            fx: d.fx,
            fy: d.fy,
            cx: d.cx,
            cy: d.cy,
        },
        distortion: Distortion {
            k1: d.k1,
            k2: d.k2,
            p1: d.p1,
            p2: d.p2,
            k3: d.k3,
        },
        pose: pose_from_doc(&d.rotation, &d.translation_m),
    }
}

fn device_to_doc(m: &PinholeModel) -> DeviceDoc {
    let (rotation, translation_m) = pose_to_doc(&m.pose);
    let (k, d) = (&m.intrinsics, &m.distortion);
    DeviceDoc {
        width_px: m.width_px,
        height_px: m.height_px,
        fx: k.fx,
        fy: k.fy,
        cx: k.cx,
        cy: k.cy,
        k1: d.k1,
        k2: d.k2,
        p1: d.p1,
        p2: d.p2,
        k3: d.k3,
        rotation,
        translation_m,
    }
}

fn head_from_doc(h: HeadDoc) -> Head {
    Head {
        name: h.name,
        camera: device_from_doc(&h.camera),
        projector: device_from_doc(&h.projector),
        view_errors: h
            .view_errors
            .into_iter()
            .map(|v| ViewError {
                view: v.view,
                camera_rms_px: v.camera_rms_px,
                projector_rms_px: v.projector_rms_px,
            })
            .collect(),
        port: h.port.as_ref().map(port_from_doc),
    }
}

fn port_from_doc(p: &PortDoc) -> FlatPort {
    let normal = Vector3::from(p.normal);
    let length = normal.norm();
    // A normal written by hand need not have unit length; one this code wrote has, and is
    // kept bit for bit (a zero or non-finite one is left for validation to name).
    let unit = length.is_finite() && length > 0.0 && (length - 1.0).abs() > 1e-12;
    FlatPort {
        distance_m: p.distance_m,
        normal: if unit { normal / length } else { normal },
        thickness_m: p.thickness_m,
        glass_index: p.glass_index,
        water_index: p.water_index,
    }
}

fn port_to_doc(p: &FlatPort) -> PortDoc {
    PortDoc {
        distance_m: p.distance_m,
        normal: p.normal.into(),
        thickness_m: p.thickness_m,
        glass_index: p.glass_index,
        water_index: p.water_index,
    }
}

fn head_to_doc(h: &Head) -> HeadDoc {
    HeadDoc {
        name: h.name.clone(),
        camera: device_to_doc(&h.camera),
        projector: device_to_doc(&h.projector),
        view_errors: h
            .view_errors
            .iter()
            .map(|v| ViewErrorDoc {
                view: v.view.clone(),
                camera_rms_px: v.camera_rms_px,
                projector_rms_px: v.projector_rms_px,
            })
            .collect(),
        camera_rms_px: h.camera_rms_px(),
        projector_rms_px: h.projector_rms_px(),
        port: h.port.as_ref().map(port_to_doc),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn head(name: &str) -> Head {
        let camera = PinholeModel::ideal(320, 240, 400.0);
        let mut projector = PinholeModel::ideal(912, 1140, 1500.0);
        projector.distortion.k1 = 0.03;
        projector.pose = Pose {
            rotation: *Rotation3::from_euler_angles(0.0, -0.2, 0.0).matrix(),
            translation_m: Vector3::new(-0.1, 0.0, 0.01),
        };
        Head {
            name: name.to_owned(),
            camera,
            projector,
            view_errors: vec![ViewError {
                view: "pose_00".into(),
                camera_rms_px: 0.08,
                projector_rms_px: Some(0.12),
            }],
            port: None,
        }
    }

    fn two_heads() -> RigCalibration {
        RigCalibration {
            heads: vec![head("A"), head("B")],
            head_poses: vec![Pose {
                rotation: *Rotation3::from_euler_angles(0.0, 1.2, 0.0).matrix(),
                translation_m: Vector3::new(0.5, 0.0, 0.2),
            }],
            stereo_heads: vec![],
        }
    }

    fn four_heads() -> RigCalibration {
        let pose = |k: f64| Pose {
            rotation: *Rotation3::from_euler_angles(0.0, k * std::f64::consts::FRAC_PI_2, 0.0)
                .matrix(),
            translation_m: Vector3::new(0.5 * k.sin(), 0.0, 0.5 - 0.5 * k.cos()),
        };
        RigCalibration {
            heads: ["A", "B", "C", "D"].map(head).to_vec(),
            head_poses: vec![pose(1.0), pose(2.0), pose(3.0)],
            stereo_heads: vec![],
        }
    }

    #[test]
    fn rigs_of_three_and_four_heads_round_trip_with_head_poses() {
        let four = four_heads();
        let mut three = four.clone();
        three.heads.pop();
        three.head_poses.pop();
        for rig in [three, four] {
            let text = to_json(&rig).expect("valid");
            assert!(text.contains("\"head_poses\""), "{text}");
            let back = parse_rig(&text).expect("parses");
            assert_eq!(back, rig);
            assert_eq!(back.pose_from_first(0), Some(Pose::identity()));
            assert_eq!(back.pose_from_first(2), Some(rig.head_poses[1]));
            assert_eq!(back.pose_from_first(rig.heads.len()), None);
            assert_eq!(back.head_to_head(), None);
        }
    }

    #[test]
    fn two_heads_write_head_to_head_and_read_either_field_but_not_both() {
        let text = to_json(&two_heads()).unwrap();
        assert!(text.contains("\"head_to_head\": {"), "{text}");
        assert!(!text.contains("head_poses"), "{text}");
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let pose = v["head_to_head"].take();
        v["head_poses"] = serde_json::json!([pose.clone()]);
        let rig = parse_rig(&v.to_string()).expect("head_poses serves two heads too");
        assert_eq!(rig.head_to_head(), two_heads().head_to_head());
        v["head_to_head"] = pose;
        assert!(matches!(
            parse_rig(&v.to_string()),
            Err(RigFileError::BothHeadPoseFields)
        ));
    }

    #[test]
    fn a_head_without_its_pose_or_a_fifth_head_is_refused() {
        let mut rig = four_heads();
        rig.head_poses.pop();
        let err = to_json(&rig).unwrap_err();
        assert!(matches!(
            err,
            RigFileError::HeadPoses { heads: 4, poses: 2 }
        ));
        assert!(err.to_string().contains("need 3 head pose(s)"), "{err}");
        let mut rig = four_heads();
        rig.heads.push(head("E"));
        rig.head_poses.push(Pose::identity());
        assert!(matches!(
            to_json(&rig),
            Err(RigFileError::HeadCount { count: 5 })
        ));
    }

    #[test]
    fn json_round_trip_is_exact() {
        for rig in [RigCalibration::single(head("A")), two_heads()] {
            let text = to_json(&rig).expect("valid");
            let back = parse_rig(&text).expect("parses");
            assert_eq!(back, rig);
        }
    }

    #[test]
    fn file_round_trip_and_no_temp_left() {
        let dir = std::env::temp_dir().join(format!("slscan-rig-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("rig.json");
        write_rig(&path, &two_heads()).expect("writes");
        assert_eq!(read_rig(&path).expect("reads"), two_heads());
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert_eq!(names.len(), 1, "only rig.json remains");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn missing_field_is_named() {
        let text = to_json(&RigCalibration::single(head("A"))).unwrap();
        let broken = text.replacen("\"fy\"", "\"fyy\"", 1);
        let err = parse_rig(&broken).unwrap_err();
        assert!(matches!(err, RigFileError::Json { .. }));
        assert!(err.to_string().contains("fyy"), "{err}");
        let missing = text.replacen("\"k3\": 0.0,", "", 1);
        let err = parse_rig(&missing).unwrap_err().to_string();
        assert!(err.contains("missing field `k3`"), "{err}");
    }

    #[test]
    fn wrong_array_length_is_a_json_error() {
        let text = to_json(&RigCalibration::single(head("A"))).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let mut v = v;
        v["heads"][0]["camera"]["translation_m"] = serde_json::json!([0.0, 0.0]);
        let err = parse_rig(&v.to_string()).unwrap_err();
        assert!(err.to_string().contains("length"), "{err}");
    }

    #[test]
    fn bad_values_get_typed_errors() {
        let mut rig = RigCalibration::single(head("A"));
        rig.heads[0].camera.intrinsics.fx = -1.0;
        assert!(matches!(
            to_json(&rig),
            Err(RigFileError::NonPositiveFocal { fx, .. }) if fx == -1.0
        ));

        let mut rig = RigCalibration::single(head("A"));
        rig.heads[0].projector.distortion.k2 = f64::NAN;
        match to_json(&rig) {
            Err(RigFileError::NonFinite { field, .. }) => {
                assert_eq!(field, "heads[0].projector.k2")
            }
            other => panic!("{other:?}"),
        }

        let mut rig = RigCalibration::single(head("A"));
        rig.heads[0].camera.width_px = 0;
        assert!(matches!(
            to_json(&rig),
            Err(RigFileError::BadImageSize { width_px: 0, .. })
        ));

        let mut rig = RigCalibration::single(head("A"));
        rig.heads[0].camera.pose.rotation[(0, 0)] = 1.1;
        assert!(matches!(
            to_json(&rig),
            Err(RigFileError::NotARotation { .. })
        ));

        let mut rig = two_heads();
        rig.head_poses.clear();
        assert!(matches!(
            to_json(&rig),
            Err(RigFileError::HeadPoses { heads: 2, poses: 0 })
        ));

        let mut rig = two_heads();
        rig.heads[1].name = "A".into();
        assert!(matches!(
            to_json(&rig),
            Err(RigFileError::DuplicateHeadName { .. })
        ));

        let rig = RigCalibration {
            heads: vec![],
            head_poses: vec![],
            stereo_heads: vec![],
        };
        assert!(matches!(
            to_json(&rig),
            Err(RigFileError::HeadCount { count: 0 })
        ));
    }

    #[test]
    fn nan_and_wrong_format_in_text_are_rejected() {
        let text = to_json(&RigCalibration::single(head("A"))).unwrap();
        let nan = text.replacen("\"fx\": 400.0", "\"fx\": NaN", 1);
        assert!(matches!(parse_rig(&nan), Err(RigFileError::Json { .. })));
        let null = text.replacen("\"fx\": 400.0", "\"fx\": null", 1);
        assert!(matches!(parse_rig(&null), Err(RigFileError::Json { .. })));
        let other = text.replacen("slscan-rig", "something-else", 1);
        assert!(matches!(
            parse_rig(&other),
            Err(RigFileError::UnsupportedFormat { .. })
        ));
    }

    fn stereo(name: &str) -> StereoHead {
        let mut right = PinholeModel::ideal(320, 240, 410.0);
        right.distortion.k2 = -0.01;
        right.pose = Pose {
            rotation: *Rotation3::from_euler_angles(0.01, -0.1, 0.0).matrix(),
            translation_m: Vector3::new(-0.12, 0.001, 0.004),
        };
        StereoHead {
            name: name.to_owned(),
            left: PinholeModel::ideal(320, 240, 400.0),
            right,
        }
    }

    #[test]
    fn stereo_heads_round_trip_alone_or_beside_heads() {
        let alone = RigCalibration {
            heads: vec![],
            head_poses: vec![],
            stereo_heads: vec![stereo("S")],
        };
        let mut beside = two_heads();
        beside.stereo_heads = vec![stereo("S"), stereo("T")];
        for rig in [alone, beside] {
            let text = to_json(&rig).expect("valid");
            assert!(text.contains("\"stereo_heads\""));
            assert_eq!(parse_rig(&text).expect("parses"), rig);
        }
        // Files without stereo heads are written as before: no `stereo_heads` key.
        let text = to_json(&two_heads()).unwrap();
        assert!(!text.contains("stereo_heads"), "{text}");
    }

    #[test]
    fn stereo_heads_are_validated() {
        let mut rig = RigCalibration::single(head("A"));
        rig.stereo_heads = vec![stereo("A")];
        assert!(matches!(
            to_json(&rig),
            Err(RigFileError::DuplicateHeadName { name }) if name == "A"
        ));
        rig.stereo_heads = vec![stereo("S")];
        rig.stereo_heads[0].right.pose.rotation[(1, 1)] = 0.5;
        match to_json(&rig) {
            Err(RigFileError::NotARotation { device, .. }) => {
                assert_eq!(device, "stereo_heads[0].right")
            }
            other => panic!("{other:?}"),
        }
        rig.stereo_heads = vec![stereo("S")];
        rig.stereo_heads[0].left.intrinsics.fy = f64::NAN;
        assert!(matches!(to_json(&rig), Err(RigFileError::NonFinite { .. })));
        let text = to_json(&RigCalibration::single(head("A"))).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let mut v = v;
        v["stereo_heads"] = serde_json::json!([{"name": "S"}]);
        let err = parse_rig(&v.to_string()).unwrap_err().to_string();
        assert!(err.contains("missing field `left`"), "{err}");
    }

    /// A thick port tilted off the optical axis.
    fn port() -> FlatPort {
        FlatPort::new(0.031, [0.02, -0.05, 1.0], 0.008, 1.49, 1.335).unwrap()
    }

    #[test]
    fn ports_round_trip_and_stay_out_of_files_without_them() {
        let mut rig = two_heads();
        rig.heads[1].port = Some(port());
        let text = to_json(&rig).unwrap();
        assert_eq!(text.matches("\"port\"").count(), 1, "{text}");
        assert_eq!(parse_rig(&text).unwrap(), rig);
        // Files of heads in air are written as before: no `port` key.
        assert!(!to_json(&two_heads()).unwrap().contains("port"));
        // By hand: the normal may be left out (square to the axis) or not unit length.
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        v["heads"][1]["port"] = serde_json::json!({
            "distance_m": 0.03, "thickness_m": 0.0, "glass_index": 1.5, "water_index": 1.33
        });
        let read = parse_rig(&v.to_string()).unwrap();
        assert_eq!(
            read.heads[1].port,
            Some(FlatPort::thin(0.03, 1.33).unwrap())
        );
        v["heads"][1]["port"]["normal"] = serde_json::json!([0.0, 0.0, 2.0]);
        let read = parse_rig(&v.to_string()).unwrap();
        assert_eq!(read.heads[1].port.unwrap().normal, Vector3::z());
    }

    /// The field and the port error of a [`RigFileError::Port`].
    fn port_error(err: RigFileError) -> (String, FlatPortError) {
        match err {
            RigFileError::Port { field, source } => (field, *source),
            other => panic!("not a port error: {other:?}"),
        }
    }

    #[test]
    fn bad_ports_get_typed_errors_naming_the_head() {
        let with = |f: fn(&mut FlatPort)| {
            let mut rig = two_heads();
            let mut p = port();
            f(&mut p);
            rig.heads[1].port = Some(p);
            to_json(&rig).unwrap_err()
        };
        let err = with(|p| p.water_index = 0.8);
        assert!(err.to_string().starts_with("heads[1].port: "), "{err}");
        assert_eq!(
            port_error(err),
            (
                "heads[1].port".into(),
                FlatPortError::Index {
                    field: "water_index",
                    value: 0.8
                }
            )
        );
        assert!(matches!(
            port_error(with(|p| p.distance_m = f64::INFINITY)).1,
            FlatPortError::NotFinite {
                field: "distance_m",
                ..
            }
        ));
        assert_eq!(
            port_error(with(|p| p.thickness_m = -0.001)).1,
            FlatPortError::Thickness(-0.001)
        );
        // In text: a zero normal, a port facing sideways, a missing index.
        let mut rig = two_heads();
        rig.heads[0].port = Some(port());
        let mut v: serde_json::Value = serde_json::from_str(&to_json(&rig).unwrap()).unwrap();
        v["heads"][0]["port"]["normal"] = serde_json::json!([0.0, 0.0, 0.0]);
        let parsed = |v: &serde_json::Value| port_error(parse_rig(&v.to_string()).unwrap_err()).1;
        assert!(matches!(parsed(&v), FlatPortError::NormalLength { .. }));
        v["heads"][0]["port"]["normal"] = serde_json::json!([1.0, 0.0, 0.1]);
        assert!(matches!(parsed(&v), FlatPortError::NormalTilt { .. }));
        v["heads"][0]["port"]
            .as_object_mut()
            .unwrap()
            .remove("water_index");
        let err = parse_rig(&v.to_string()).unwrap_err().to_string();
        assert!(err.contains("missing field `water_index`"), "{err}");
    }

    #[test]
    fn missing_file_is_an_io_error() {
        let err = read_rig(Path::new("/nonexistent/rig.json")).unwrap_err();
        assert!(matches!(err, RigFileError::Io { .. }));
    }
}
