//! `slscan register` and `slscan fuse` on PLY files as other tools write
//! them (ASCII with doubles in millimetres, Open3D-style; binary floats in
//! metres, slscan's own), against the library's registration of the same
//! clouds, and the errors bad clouds must give.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

use nalgebra::{Isometry3, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use slscan::fusion::synthetic::{perturbed, pose_error, two_head_scene};
use slscan::fusion::{estimate_normals, register, IcpParams, PointCloud};

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("slscan-register-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// An ASCII PLY of `cloud` in millimetres, doubles, as Open3D writes it.
fn write_ascii_mm(path: &Path, cloud: &PointCloud) {
    let mut f = std::fs::File::create(path).unwrap();
    write!(
        f,
        "ply\nformat ascii 1.0\ncomment Created by Open3D\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nend_header\n",
        cloud.points.len()
    )
    .unwrap();
    for p in &cloud.points {
        writeln!(
            f,
            "{:.17e} {:.17e} {:.17e}",
            p.x * 1e3,
            p.y * 1e3,
            p.z * 1e3
        )
        .unwrap();
    }
}

fn slscan(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_slscan"))
        .args(args)
        .output()
        .unwrap()
}

fn scene() -> (
    PointCloud,
    PointCloud,
    Isometry3<f64>,
    Isometry3<f64>,
    Vector3<f64>,
) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let s = two_head_scene(20_000, 20e-6, || StandardNormal.sample(&mut rng));
    let guess = perturbed(
        &s.b_to_a_m,
        &s.centre_m,
        &Vector3::new(0.3, 1.0, 0.2),
        1.0,
        &Vector3::new(1.0, -0.5, 0.3),
        2e-3,
    );
    (s.a, s.b, s.b_to_a_m, guess, s.centre_m)
}

#[test]
fn register_agrees_with_the_library_on_ascii_mm_files() {
    let dir = tmp("ascii");
    let (a, b, truth, guess, centre) = scene();
    write_ascii_mm(&dir.join("a.ply"), &a);
    write_ascii_mm(&dir.join("b.ply"), &b);
    // The guess as a 4x4 matrix in the files' unit.
    let m = guess.to_homogeneous();
    let rows: Vec<Vec<f64>> = (0..4)
        .map(|i| {
            (0..4)
                .map(|j| {
                    if j == 3 && i < 3 {
                        m[(i, j)] * 1e3
                    } else {
                        m[(i, j)]
                    }
                })
                .collect()
        })
        .collect();
    std::fs::write(
        dir.join("guess.json"),
        serde_json::to_string(&rows).unwrap(),
    )
    .unwrap();
    let d = |n: &str| dir.join(n).display().to_string();
    let out = slscan(&[
        "register",
        &d("a.ply"),
        &d("b.ply"),
        "--unit",
        "mm",
        "--initial-matrix",
        &d("guess.json"),
        "--out",
        &d("t.json"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("t.json")).unwrap()).unwrap();
    let rows = report["matrix_b_to_a_m"].as_array().unwrap();
    let m = nalgebra::Matrix4::from_fn(|i, j| rows[i][j].as_f64().unwrap());
    // The library path on the same points (read back from text: the files
    // carry 17 digits, so the points are the same to ~1e-16 m).
    let a_n = PointCloud {
        normals: Some(estimate_normals(&a.points, 12, &Vector3::zeros()).unwrap()),
        ..a.clone()
    };
    let lib = register(&b, &a_n, &guess, &IcpParams::default()).unwrap();
    let diff = (m - lib.transform.to_homogeneous()).abs().max();
    assert!(diff < 1e-9, "CLI vs library: {diff}");
    let (deg, metres) = pose_error(&lib.transform, &truth, &centre);
    println!("register vs truth: {deg:.5} deg / {:.2} um", metres * 1e6);
    assert!(deg < 0.01 && metres < 5e-6, "{deg} deg, {metres} m");
    assert!(report["converged"].as_bool().unwrap());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn fuse_writes_one_cloud_from_binary_files() {
    let dir = tmp("fuse");
    let (a, b, _, guess, _) = scene();
    let to_out = |c: &PointCloud| slscan::scan::clouds::from_fusion(c);
    slscan::io::ply::write_ply(&dir.join("a.ply"), &to_out(&a)).unwrap();
    slscan::io::ply::write_ply(&dir.join("b.ply"), &to_out(&b)).unwrap();
    let rig = slscan::calibration::RigCalibration {
        heads: vec![head("A"), head("B")],
        head_poses: vec![slscan::calibration::Pose::from_isometry(&guess.inverse())],
        stereo_heads: vec![],
    };
    slscan::calibration::write_rig(&dir.join("rig.json"), &rig).unwrap();
    let d = |n: &str| dir.join(n).display().to_string();
    let out = slscan(&[
        "fuse",
        &d("a.ply"),
        &d("b.ply"),
        "--initial-rig",
        &d("rig.json"),
        "--out",
        &d("merged.ply"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let merged = slscan::io::ply_read::read_ply(&dir.join("merged.ply"), 1.0).unwrap();
    let n = merged.cloud.points.len();
    // The overlap's duplicates merged: fewer than both, more than either.
    assert!(n > 20_000 && n < 40_000, "{n}");
    let _ = std::fs::remove_dir_all(&dir);
}

fn head(name: &str) -> slscan::calibration::Head {
    slscan::calibration::Head {
        name: name.into(),
        camera: slscan::calibration::PinholeModel::ideal(64, 48, 80.0),
        projector: slscan::calibration::PinholeModel::ideal(128, 80, 120.0),
        view_errors: vec![],
        port: None,
    }
}

#[test]
fn bad_clouds_and_guesses_are_clear_errors() {
    let dir = tmp("bad");
    let (a, _, _, _, _) = scene();
    write_ascii_mm(&dir.join("a.ply"), &a);
    std::fs::write(dir.join("empty.ply"), "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n").unwrap();
    std::fs::write(dir.join("faces.ply"), "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n3 0 1 2\n").unwrap();
    std::fs::write(dir.join("nan.ply"), "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 nan 3\n").unwrap();
    let mut cut = std::fs::read(dir.join("a.ply")).unwrap();
    cut.truncate(cut.len() / 2);
    std::fs::write(dir.join("cut.ply"), cut).unwrap();
    // Far apart: no overlap at all.
    let far = PointCloud {
        points: a
            .points
            .iter()
            .map(|p| p + Vector3::new(5.0, 0.0, 0.0))
            .collect(),
        ..a.clone()
    };
    write_ascii_mm(&dir.join("far.ply"), &far);
    std::fs::write(
        dir.join("skew.json"),
        "[[1,0,0,0],[0,1,0,0],[0,0,2,0],[0,0,0,1]]",
    )
    .unwrap();
    let d = |n: &str| dir.join(n).display().to_string();
    let cases: [(&[&str], &str); 6] = [
        (&[&d("empty.ply")], "no vertices"),
        (&[&d("faces.ply")], "no vertices"),
        (&[&d("nan.ply")], "non-finite"),
        // Cut mid-number or between lines: either way the body is named.
        (&[&d("cut.ply")], "PLY body"),
        (&[&d("far.ply")], "did not converge"),
        (
            &[&d("a.ply"), "--initial-matrix", &d("skew.json")],
            "not a rotation",
        ),
    ];
    let a_path = d("a.ply");
    let (transform, merged) = (d("transform.json"), d("merged.ply"));
    for (extra, want) in cases {
        for command in ["register", "fuse"] {
            let out_file = if command == "register" {
                &transform
            } else {
                &merged
            };
            // An earlier run's output must not survive a failed one.
            std::fs::write(out_file, b"an earlier run").unwrap();
            let mut args = vec![command, "--unit", "mm", "--out", out_file];
            let (b, rest) = extra.split_first().unwrap();
            args.push(&a_path);
            args.push(b);
            args.extend(rest.iter().copied());
            let out = slscan(&args);
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert!(!out.status.success(), "{args:?} should fail");
            assert!(stderr.contains(want), "{args:?}: {stderr} lacks {want}");
            assert!(!Path::new(out_file).exists(), "{args:?} left {out_file}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
