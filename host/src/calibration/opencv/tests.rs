//! The readers on files typed as OpenCV writes them, the import's layouts and checks, and
//! rig -> YAML/XML -> rig round trips. Longer than our usual 600 lines: about 150 of them
//! are fixtures typed exactly as OpenCV writes them.

use nalgebra::{Rotation3, Vector3};

use super::storage::{parse, to_text, Depth};
use super::*;
use crate::calibration::{Head, PinholeModel, Pose, RigCalibration, StereoHead};

/// SLMaster's layout as `cv::FileStorage` writes it: data spread over lines, `0.`, `1.`.
const SLMASTER_YML: &str = "%YAML:1.0
---
M1: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 2.4001234567890123e+03, 0., 6.3950000000000000e+02, 0.,
       2.4005000000000000e+03, 5.1150000000000000e+02, 0., 0., 1. ]
D1: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ -8.1234567890123456e-02, 1.2345678901234567e-01,
       1.0000000000000000e-04, -2.0000000000000000e-04, 0. ]
M4: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 1.7503000000000000e+03, 0., 4.5600000000000000e+02, 0.,
       1.7498000000000000e+03, 1.1395000000000000e+03, 0., 0., 1. ]
D4: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ 2.9999999999999999e-02, 0., 0., 0., 0. ]
Rlp: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 9.5782628522115143e-01, 0., 2.8734788556634544e-01,
       5.7465745884753578e-03, 9.9980000666657776e-01,
       -1.9155248628251194e-02, -2.8729041790485921e-01,
       1.9998666693333080e-02, 9.5763472634953062e-01 ]
Tlp: !!opencv-matrix
   rows: 3
   cols: 1
   dt: d
   data: [ -1.4367394278317272e+02, 1.9134013945060254e+01,
       4.3493536019595545e+01 ]
calibration_time: \"Tue Dec  1 10:12:13 2026\"
";

/// The same head as XML, with the sizes and a `dt: f` projector matrix.
const SLMASTER_XML: &str = r#"<?xml version="1.0"?>
<opencv_storage>
<!-- written by cv::FileStorage -->
<cam_size>
  1280 1024</cam_size>
<proj_width>912</proj_width>
<proj_height>1140</proj_height>
<M1 type_id="opencv-matrix">
  <rows>3</rows>
  <cols>3</cols>
  <dt>d</dt>
  <data>
    2.4001234567890123e+03 0. 6.3950000000000000e+02 0.
    2.4005000000000000e+03 5.1150000000000000e+02 0. 0. 1.</data></M1>
<D1 type_id="opencv-matrix">
  <rows>1</rows>
  <cols>5</cols>
  <dt>d</dt>
  <data>
    -8.1234567890123456e-02 1.2345678901234567e-01 1.0000000000000000e-04
    -2.0000000000000000e-04 0.</data></D1>
<M4 type_id="opencv-matrix">
  <rows>3</rows>
  <cols>3</cols>
  <dt>f</dt>
  <data>
    1.75030005e+03 0. 456. 0. 1.74979993e+03 1.13950000e+03 0. 0. 1.</data></M4>
<D4 type_id="opencv-matrix">
  <rows>1</rows>
  <cols>4</cols>
  <dt>d</dt>
  <data>
    2.9999999999999999e-02 0. 0. 0.</data></D4>
<Rlp type_id="opencv-matrix">
  <rows>3</rows>
  <cols>3</cols>
  <dt>d</dt>
  <data>
    9.5782628522115143e-01 0. 2.8734788556634544e-01 5.7465745884753578e-03
    9.9980000666657776e-01 -1.9155248628251194e-02 -2.8729041790485921e-01
    1.9998666693333080e-02 9.5763472634953062e-01</data></Rlp>
<Tlp type_id="opencv-matrix">
  <rows>3</rows>
  <cols>1</cols>
  <dt>d</dt>
  <data>
    -1.4367394278317272e+02 1.9134013945060254e+01 4.3493536019595545e+01</data></Tlp>
</opencv_storage>
"#;

/// OpenCV's calibration sample (`camera_calibration.cpp`) output, abridged.
const SAMPLE_CAMERA_YML: &str = "%YAML:1.0
---
calibration_time: \"Tue 01 Dec 2026 10:00:00 CET\"
nr_of_frames: 25
image_width: 640
image_height: 480
board_width: 9
board_height: 6
square_size: 25.
fix_aspect_ratio: 1.
# flags:  +fix_aspect_ratio +fix_principal_point +zero_tangent_dist
flags: 14
fisheye_model: 0
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 6.5746697944293521e+02, 0., 3.1950000000000000e+02, 0.,
       6.5746697944293521e+02, 2.3950000000000000e+02, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ -4.1802327176423804e-01, 5.0715244063187526e-01, 0., 0.,
       -5.7843597214487474e-01 ]
avg_reprojection_error: 3.9299671947143459e-01
per_view_reprojection_errors: !!opencv-matrix
   rows: 2
   cols: 1
   dt: f
   data: [ 1.92965463e-01, 1.88131750e-01 ]
extrinsic_parameters: !!opencv-matrix
   rows: 2
   cols: 6
   dt: d
   data: [ -7.8563656198143308e-02, 2.7935777734657617e-01,
       1.5766101405574226e-02, -1.2327032932698318e+02,
       -5.5428592218155536e+01, 4.3862209183829474e+02,
       -7.8563656198143308e-02, 2.7935777734657617e-01,
       1.5766101405574226e-02, -1.2327032932698318e+02,
       -5.5428592218155536e+01, 4.3862209183829474e+02 ]
image_points: !!opencv-nd-matrix
   sizes: [ 2, 54 ]
   dt: \"2f\"
   data: [ 1., 2. ]
";

/// A number as the file types it (clippy refuses 17-digit literals).
fn exact(text: &str) -> f64 {
    text.parse().unwrap()
}

fn sizes() -> ImportOptions {
    ImportOptions {
        camera_size_px: Some((1280, 1024)),
        projector_size_px: Some((912, 1140)),
        ..ImportOptions::default()
    }
}

fn head_of(imported: Imported) -> Head {
    match imported {
        Imported::Head(h) => h,
        other => panic!("not a head: {other:?}"),
    }
}

fn stereo_of(imported: Imported) -> StereoHead {
    match imported {
        Imported::Stereo(h) => h,
        other => panic!("not a stereo head: {other:?}"),
    }
}

fn import_err(text: &str, options: &ImportOptions) -> ImportError {
    parse_opencv(text.as_bytes(), options).expect_err("should be refused")
}

#[test]
fn yaml_slmaster_file_reads_as_opencv_wrote_it() {
    let s = parse(SLMASTER_YML.as_bytes()).unwrap();
    let m1 = match &s.get("M1").unwrap().value {
        Value::Matrix(m) => m.clone(),
        other => panic!("{other:?}"),
    };
    assert_eq!((m1.rows, m1.cols, m1.depth), (3, 3, Depth::F64));
    assert_eq!(m1.data[0], 2.4001234567890123e+03);
    assert_eq!(m1.data[8], 1.0);
    assert_eq!(s.get("M1").unwrap().line, 3);
    assert_eq!(
        s.get("calibration_time").unwrap().value,
        Value::Str("Tue Dec  1 10:12:13 2026".into())
    );
    let head = head_of(parse_opencv(SLMASTER_YML.as_bytes(), &sizes()).unwrap());
    assert_eq!(head.name, "A");
    assert_eq!(head.camera.pose, Pose::identity());
    assert_eq!(head.camera.intrinsics.fx, 2.4001234567890123e+03);
    assert_eq!(head.camera.distortion.k1, exact("-8.1234567890123456e-02"));
    assert_eq!(
        head.projector.distortion.k1,
        exact("2.9999999999999999e-02")
    );
    assert_eq!(
        (head.projector.width_px, head.projector.height_px),
        (912, 1140)
    );
    // Tlp is in mm; the projector sits 150 mm to the right, 20 mm up.
    let c = head.projector.centre_m();
    assert!(
        (c - nalgebra::Point3::new(0.15, -0.02, 0.0)).norm() < 1e-12,
        "{c}"
    );
}

#[test]
fn xml_file_with_dt_f_and_sizes_in_the_file() {
    let head = head_of(parse_opencv(SLMASTER_XML.as_bytes(), &ImportOptions::default()).unwrap());
    let yml = head_of(parse_opencv(SLMASTER_YML.as_bytes(), &sizes()).unwrap());
    assert_eq!((head.camera.width_px, head.camera.height_px), (1280, 1024));
    assert_eq!(head.camera, yml.camera);
    // `dt: f` values are the f32 OpenCV held, widened exactly.
    assert_eq!(head.projector.intrinsics.fx, f64::from(1750.3f32));
    assert_eq!(head.projector.intrinsics.cx, 456.0);
    assert_eq!(head.projector.pose, yml.projector.pose);
    assert_eq!(head.projector.distortion, yml.projector.distortion);
}

#[test]
fn sample_camera_file_is_one_camera_and_no_rig() {
    let s = parse(SAMPLE_CAMERA_YML.as_bytes()).unwrap();
    assert_eq!(s.get("image_points").unwrap().value, Value::Skipped);
    assert_eq!(s.get("flags").unwrap().value, Value::Int(14));
    assert_eq!(s.get("square_size").unwrap().value, Value::Real(25.0));
    let cam = match parse_opencv(SAMPLE_CAMERA_YML.as_bytes(), &ImportOptions::default()).unwrap() {
        Imported::Camera(c) => c,
        other => panic!("{other:?}"),
    };
    assert_eq!((cam.width_px, cam.height_px), (640, 480));
    assert_eq!(cam.distortion.k3, exact("-5.7843597214487474e-01"));
    let err = Imported::Camera(cam).into_rig().unwrap_err();
    assert!(matches!(err, ImportError::CameraOnly), "{err}");
}

/// A head like the twin's: camera at the origin, projector to the right, toed in.
fn head() -> Head {
    let mut camera = PinholeModel::ideal(1280, 1024, 2400.123456789);
    camera.intrinsics.cy = 511.25;
    camera.distortion.k1 = -0.0812345;
    camera.distortion.p2 = 1.5e-4;
    let mut projector = PinholeModel::ideal(912, 1140, 1750.3);
    projector.intrinsics.cy = 1139.5;
    projector.distortion.k1 = 0.03;
    projector.distortion.k3 = -0.001;
    let rotation = Rotation3::from_euler_angles(0.02, 0.29, 0.003);
    let centre = Vector3::new(0.15, -0.02, 0.001);
    projector.pose = Pose {
        rotation: *rotation.matrix(),
        translation_m: -(rotation * centre),
    };
    Head {
        name: "A".into(),
        camera,
        projector,
        view_errors: vec![],
        port: None,
    }
}

fn stereo() -> StereoHead {
    let left = PinholeModel::ideal(1624, 1240, 2000.0);
    let mut right = PinholeModel::ideal(1624, 1240, 2010.5);
    right.distortion.k2 = 0.0123;
    let rotation = Rotation3::from_euler_angles(0.001, 0.2, -0.002);
    right.pose = Pose {
        rotation: *rotation.matrix(),
        translation_m: -(rotation * Vector3::new(0.2, 0.001, 0.02)),
    };
    StereoHead {
        name: "S".into(),
        left,
        right,
    }
}

/// Every number of two devices equal to `tol` relative (absolute near zero).
fn assert_close(a: &PinholeModel, b: &PinholeModel, tol: f64) {
    assert_eq!((a.width_px, a.height_px), (b.width_px, b.height_px));
    let nums = |m: &PinholeModel| {
        let (k, d) = (m.intrinsics, m.distortion);
        let mut v = vec![k.fx, k.fy, k.cx, k.cy, d.k1, d.k2, d.p1, d.p2, d.k3];
        v.extend(m.pose.rotation.iter());
        v.extend(m.pose.translation_m.iter());
        v
    };
    for (x, y) in nums(a).into_iter().zip(nums(b)) {
        assert!(
            (x - y).abs() <= tol * x.abs().max(y.abs()).max(1.0),
            "{x} vs {y}"
        );
    }
}

#[test]
fn rig_round_trips_through_yaml_and_xml_in_both_units() {
    for format in [Format::Yaml, Format::Xml] {
        for unit in [LengthUnit::Mm, LengthUnit::M] {
            let options = ImportOptions {
                unit,
                ..ImportOptions::default()
            };
            let rig = RigCalibration::single(head());
            let text = to_text(&rig_to_storage(&rig, None, unit).unwrap(), format);
            let back = parse_opencv(text.as_bytes(), &options)
                .unwrap()
                .into_rig()
                .unwrap();
            assert_close(&back.heads[0].camera, &rig.heads[0].camera, 1e-12);
            assert_close(&back.heads[0].projector, &rig.heads[0].projector, 1e-12);

            let rig = RigCalibration {
                heads: vec![],
                head_poses: vec![],
                stereo_heads: vec![stereo()],
            };
            let text = to_text(&rig_to_storage(&rig, None, unit).unwrap(), format);
            let options = ImportOptions {
                name: "S".into(),
                ..options
            };
            let back = parse_opencv(text.as_bytes(), &options)
                .unwrap()
                .into_rig()
                .unwrap();
            assert_eq!(back.stereo_heads[0].name, "S");
            assert_close(&back.stereo_heads[0].left, &rig.stereo_heads[0].left, 1e-12);
            assert_close(
                &back.stereo_heads[0].right,
                &rig.stereo_heads[0].right,
                1e-12,
            );
        }
    }
}

#[test]
fn storage_text_round_trip_is_exact() {
    let mut s = Storage::default();
    s.push(
        "M",
        Value::Matrix(Matrix::f64(
            2,
            3,
            vec![0.1, -1e-300, 3.0, 1e21, f64::MIN_POSITIVE, -0.0],
        )),
    );
    s.push("n", Value::Int(-7));
    s.push("x", Value::Real(0.30000000000000004));
    s.push("name", Value::Str("a \"quoted\" <b> & c\\d".into()));
    s.push("imageSize", Value::Seq(vec![640.0, 480.0]));
    for format in [Format::Yaml, Format::Xml] {
        let text = to_text(&s, format);
        let back = parse(text.as_bytes()).unwrap();
        let strip = |s: &Storage| {
            s.nodes
                .iter()
                .map(|n| (n.key.clone(), n.value.clone()))
                .collect::<Vec<_>>()
        };
        assert_eq!(strip(&back), strip(&s), "{text}");
    }
}

#[test]
fn second_projector_and_rectified_layouts() {
    let mut s = rig_to_storage(
        &RigCalibration {
            heads: vec![],
            head_poses: vec![],
            stereo_heads: vec![stereo()],
        },
        None,
        LengthUnit::Mm,
    )
    .unwrap();
    let options = ImportOptions {
        second: SecondDevice::Projector,
        projector_size_px: Some((912, 1140)),
        ..ImportOptions::default()
    };
    let head = head_of(import_storage(&s, &options).unwrap());
    assert_close(
        &head.projector,
        &PinholeModel {
            width_px: 912,
            height_px: 1140,
            ..stereo().right
        },
        1e-12,
    );

    // stereoRectify's output alone: P2 = K2 [I | (Tx, 0, 0)] with Tx = -120 mm.
    s = Storage::default();
    let ident = Matrix::f64(3, 3, vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
    s.push("R1", Value::Matrix(ident.clone()));
    s.push("R2", Value::Matrix(ident));
    s.push(
        "P1",
        Value::Matrix(Matrix::f64(
            3,
            4,
            vec![
                1900.0, 0.0, 800.0, 0.0, 0.0, 1900.0, 600.0, 0.0, 0.0, 0.0, 1.0, 0.0,
            ],
        )),
    );
    s.push(
        "P2",
        Value::Matrix(Matrix::f64(
            3,
            4,
            vec![
                1900.0,
                0.0,
                800.0,
                -1900.0 * 120.0,
                0.0,
                1900.0,
                600.0,
                0.0,
                0.0,
                0.0,
                1.0,
                0.0,
            ],
        )),
    );
    s.push("Q", Value::Matrix(Matrix::f64(4, 4, vec![0.0; 16])));
    s.push("imageSize", Value::Seq(vec![1624.0, 1240.0]));
    let head = stereo_of(import_storage(&s, &ImportOptions::default()).unwrap());
    assert_eq!(head.right.pose.translation_m, Vector3::new(-0.12, 0.0, 0.0));
    assert_eq!(head.right.centre_m().x, 0.12);
    assert_eq!((head.left.width_px, head.left.height_px), (1624, 1240));
    assert!(head.right.distortion.is_zero());
}

#[test]
fn missing_key_is_named_with_its_layout() {
    let text = SLMASTER_YML.replace("Tlp:", "Tlq:");
    let err = import_err(&text, &sizes());
    assert!(
        matches!(err, ImportError::MissingKey { key: "Tlp", .. }),
        "{err}"
    );
    assert!(err.to_string().contains("M1 D1 M4 D4 Rlp Tlp"), "{err}");
    let err = import_err("%YAML:1.0\nfoo: 1\n", &sizes());
    assert!(matches!(err, ImportError::NoCalibration { .. }), "{err}");
    assert!(err.to_string().contains("foo"), "{err}");
}

#[test]
fn a_non_rotation_is_refused_with_its_defect() {
    let text = SLMASTER_YML.replace(
        "data: [ 9.5782628522115143e-01",
        "data: [ 9.9782628522115143e-01",
    );
    match import_err(&text, &sizes()) {
        ImportError::NotARotation { key, defect } => {
            assert_eq!(key, "Rlp");
            assert!(defect > 0.03 && defect < 0.2, "{defect}");
        }
        other => panic!("{other}"),
    }
}

#[test]
fn half_inverted_extrinsics_are_refused_and_the_option_inverts() {
    let s = parse(SLMASTER_YML.as_bytes()).unwrap();
    let with = |f: &dyn Fn(&Pose) -> Pose| {
        let good = head_of(import_storage(&s, &sizes()).unwrap())
            .projector
            .pose;
        let bad = f(&good);
        let mut s = s.clone();
        for node in &mut s.nodes {
            match node.key.as_str() {
                "Rlp" => {
                    node.value = Value::Matrix(Matrix::f64(
                        3,
                        3,
                        bad.rotation.transpose().iter().copied().collect(),
                    ))
                }
                "Tlp" => {
                    node.value = Value::Matrix(Matrix::f64(
                        3,
                        1,
                        (bad.translation_m * 1e3).iter().copied().collect(),
                    ))
                }
                _ => {}
            }
        }
        s
    };
    // R transposed (the direction of R alone), T negated, T given as the projector's centre.
    let cases: [&dyn Fn(&Pose) -> Pose; 3] = [
        &|p| Pose {
            rotation: p.rotation.transpose(),
            ..*p
        },
        &|p| Pose {
            translation_m: -p.translation_m,
            ..*p
        },
        &|p| Pose {
            translation_m: -(p.rotation.transpose() * p.translation_m),
            ..*p
        },
    ];
    for case in cases {
        let err = import_storage(&with(case), &sizes()).unwrap_err();
        assert!(
            matches!(err, ImportError::InvertedExtrinsics { .. }),
            "{err}"
        );
        let text = err.to_string();
        assert!(
            text.contains("look inverted") && text.contains("--invert-extrinsics"),
            "{text}"
        );
    }
    // A file holding device 2 -> device 1, imported with invert_extrinsics, equals the original.
    let original = head_of(import_storage(&s, &sizes()).unwrap());
    let inverted = with(&|p| p.inverse());
    let options = ImportOptions {
        invert_extrinsics: true,
        ..sizes()
    };
    let back = head_of(import_storage(&inverted, &options).unwrap());
    assert_close(&back.projector, &original.projector, 1e-12);
}

#[test]
fn non_finite_wrong_size_unknown_dt_and_higher_terms_are_refused() {
    let nan = SLMASTER_YML.replace("2.4005000000000000e+03", ".Nan");
    match import_err(&nan, &sizes()) {
        ImportError::NonFinite { key, index, .. } => assert_eq!((key.as_str(), index), ("M1", 4)),
        other => panic!("{other}"),
    }
    let wrong = SLMASTER_YML.replacen("rows: 3\n   cols: 3", "rows: 1\n   cols: 9", 1);
    match import_err(&wrong, &sizes()) {
        ImportError::WrongSize {
            key,
            rows: 1,
            cols: 9,
            line: 3,
            ..
        } => assert_eq!(key, "M1"),
        other => panic!("{other}"),
    }
    let dt = SLMASTER_YML.replacen("dt: d", "dt: x", 1);
    let err = import_err(&dt, &sizes());
    assert!(
        matches!(err, ImportError::Storage(StorageError::UnknownDt { .. })),
        "{err}"
    );
    assert!(err.to_string().contains("M1 (line 3)"), "{err}");
    let k4 = SLMASTER_YML.replace(
        "rows: 5\n   cols: 1\n   dt: d\n   data: [ 2.9999999999999999e-02, 0., 0., 0., 0. ]",
        "rows: 8\n   cols: 1\n   dt: d\n   data: [ 0.03, 0., 0., 0., 0., 0.5, 0., 1e-3 ]",
    );
    match import_err(&k4, &sizes()) {
        ImportError::UnmodelledDistortion { key, terms } => {
            assert_eq!((key.as_str(), terms), ("D4", vec!["k4", "k6"]))
        }
        other => panic!("{other}"),
    }
    // Zero higher terms of a 14-coefficient vector are fine.
    let zeros = SLMASTER_YML.replace(
        "rows: 5\n   cols: 1\n   dt: d\n   data: [ 2.9999999999999999e-02, 0., 0., 0., 0. ]",
        "rows: 1\n   cols: 14\n   dt: d\n   data: [ 2.9999999999999999e-02, 0., 0., 0., 0., 0., 0., 0., 0., 0., 0., 0., 0., 0. ]",
    );
    assert!(parse_opencv(zeros.as_bytes(), &sizes()).is_ok());
    let skew = SLMASTER_YML.replacen(
        "data: [ 2.4001234567890123e+03, 0.,",
        "data: [ 2.4001234567890123e+03, 1.5,",
        1,
    );
    assert!(matches!(
        import_err(&skew, &sizes()),
        ImportError::BadCameraMatrix { .. }
    ));
    let negative = SLMASTER_YML.replacen("2.4001234567890123e+03", "-2.4e+03", 1);
    assert!(matches!(
        import_err(&negative, &sizes()),
        ImportError::BadCameraMatrix { .. }
    ));
}

#[test]
fn image_sizes_come_from_the_file_or_the_caller() {
    let err = import_err(SLMASTER_YML, &ImportOptions::default());
    assert!(
        matches!(
            err,
            ImportError::NoImageSize {
                device: "camera",
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("--camera-size"), "{err}");
    let options = ImportOptions {
        camera_size_px: Some((1280, 1024)),
        ..ImportOptions::default()
    };
    assert!(matches!(
        import_err(SLMASTER_YML, &options),
        ImportError::NoImageSize {
            device: "projector",
            ..
        }
    ));
    let options = ImportOptions {
        camera_size_px: Some((640, 480)),
        ..ImportOptions::default()
    };
    let err = parse_opencv(SLMASTER_XML.as_bytes(), &options).unwrap_err();
    assert!(
        matches!(
            err,
            ImportError::SizeConflict {
                file_w: 1280,
                given_w: 640,
                ..
            }
        ),
        "{err}"
    );
}

#[test]
fn claimed_sizes_never_allocate_and_bad_text_gets_a_line() {
    let huge = SLMASTER_YML.replacen("rows: 3", "rows: 100000000", 1);
    match import_err(&huge, &sizes()) {
        ImportError::Storage(StorageError::SizeMismatch {
            rows: 100_000_000,
            count: 9,
            ..
        }) => {}
        other => panic!("{other}"),
    }
    let overflow = SLMASTER_YML.replacen(
        "rows: 3\n   cols: 3",
        "rows: 18446744073709551615\n   cols: 18446744073709551615",
        1,
    );
    assert!(matches!(
        import_err(&overflow, &sizes()),
        ImportError::Storage(StorageError::SizeMismatch { .. })
    ));
    let unclosed = SLMASTER_YML.replacen("0., 0., 1. ]", "0., 0., 1.", 1);
    assert!(matches!(
        import_err(&unclosed, &sizes()),
        ImportError::Storage(StorageError::Syntax { line: 3, .. })
    ));
    let dup = format!("{SLMASTER_YML}M1: 3\n");
    let line = SLMASTER_YML.lines().count() + 1;
    assert!(
        matches!(import_err(&dup, &sizes()), ImportError::Storage(StorageError::DuplicateKey { line: l, .. }) if l == line)
    );
    let xml = SLMASTER_XML.replace("</Tlp>", "</Tl>");
    assert!(matches!(
        import_err(&xml, &sizes()),
        ImportError::Storage(StorageError::Syntax { .. })
    ));
    let deep = format!("<opencv_storage>{}", "<a>".repeat(100_000));
    assert!(matches!(
        parse(deep.as_bytes()),
        Err(StorageError::TooDeep { .. })
    ));
    assert!(matches!(
        parse(b"\xff\xfe"),
        Err(StorageError::NotUtf8 { line: 1 })
    ));
    assert!(matches!(
        parse(b"hello: 1"),
        Err(StorageError::UnknownFormat)
    ));
}

#[test]
fn any_bytes_are_an_error_or_a_storage_never_a_panic() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(16);
    let seeds = [
        SLMASTER_YML.as_bytes(),
        SLMASTER_XML.as_bytes(),
        SAMPLE_CAMERA_YML.as_bytes(),
    ];
    for i in 0..3000 {
        let mut bytes = seeds[i % 3].to_vec();
        for _ in 0..rng.random_range(1..8) {
            let at = rng.random_range(0..bytes.len());
            match rng.random_range(0..3) {
                0 => bytes[at] = rng.random(),
                1 => {
                    bytes.remove(at);
                }
                _ => bytes.insert(at, {
                    let alphabet = b"[]<>:,-\n 0.e";
                    alphabet[rng.random_range(0..alphabet.len())]
                }),
            }
        }
        let _ = parse_opencv(&bytes, &sizes());
    }
}

#[test]
fn export_picks_a_head_and_refuses_ambiguity() {
    let mut rig = RigCalibration::single(head());
    rig.stereo_heads.push(stereo());
    let err = rig_to_storage(&rig, None, LengthUnit::Mm).unwrap_err();
    assert!(err.to_string().contains("--head"), "{err}");
    assert!(rig_to_storage(&rig, Some("S"), LengthUnit::Mm)
        .unwrap()
        .get("M2")
        .is_some());
    assert!(rig_to_storage(&rig, Some("A"), LengthUnit::Mm)
        .unwrap()
        .get("Rlp")
        .is_some());
    assert!(matches!(
        rig_to_storage(&rig, Some("Z"), LengthUnit::Mm),
        Err(ExportError::UnknownHead { .. })
    ));
}
