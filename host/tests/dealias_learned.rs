//! The learned de-aliaser with the shipped networks: NaN or clipped input
//! comes out masked (never an invented fringe), a model trained for other
//! fringes is refused at load (before any capture), and `scan --dealias
//! learned` with a missing model fails naming the file and writes nothing.

use std::path::{Path, PathBuf};

use slscan::dealias::dealias_frames_learned;
use slscan::dealias::learned::{LearnedDealiaser, LearnedError};
use slscan::raster::Raster;
use slscan::scan::aliasing::{camera_lighting, AliasParams, FlatFields};

fn model(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../models")
        .join(name)
}

fn periods() -> Vec<f64> {
    slscan::scan::dealias_periods_px(1280)
}

/// A 70 x 50 capture that both projectors light everywhere, with two
/// aliased fringes of different columns.
fn aliased_capture() -> (Vec<Raster<f32>>, FlatFields) {
    let (w, h) = (70, 50);
    let p = periods();
    let frames = (0..16)
        .map(|k| {
            let (period, n) = (p[k / 4], k % 4);
            Raster::from_fn(w, h, |x, _| {
                let d = std::f64::consts::TAU * n as f64 / 4.0;
                let a = (std::f64::consts::TAU * 2.0 * x as f64 / period + d).cos();
                let b = (std::f64::consts::TAU * (2.0 * x as f64 + 300.0) / period + d).cos();
                (0.05 + 0.2 * (1.0 + a) + 0.1 * (1.0 + b)) as f32
            })
        })
        .collect();
    let flat = FlatFields {
        dark: Raster::filled(w, h, 0.05),
        lit_a: Raster::filled(w, h, 0.45),
        lit_b: Raster::filled(w, h, 0.25),
    };
    (frames, flat)
}

#[test]
fn nan_and_saturated_pixels_are_masked_never_invented() {
    for (file, steps) in [("dealias_onestep.onnx", 1), ("dealias_diffusion.onnx", 2)] {
        let net = LearnedDealiaser::load(&model(file), &periods(), 4, steps).unwrap();
        let (mut frames, flat) = aliased_capture();
        let w = flat.dark.width;
        let (nan_px, clipped_px) = (10 * w + 20, 30 * w + 40);
        frames[3].data[nan_px] = f32::NAN;
        frames[9].data[clipped_px] = 1.0;
        let lit = camera_lighting(&flat, 0, &AliasParams::default());
        let stats = dealias_frames_learned(&mut frames, &flat, 0, &lit, &net, 7).unwrap();
        assert_eq!(stats.bad_input, 2, "{file}");
        assert_eq!(stats.separated, stats.attempted - 2, "{file}");
        for px in [nan_px, clipped_px] {
            assert!(
                frames.iter().all(|f| f.data[px] == 0.0),
                "{file}: pixel {px} not masked"
            );
        }
        let run = stats.network.unwrap();
        assert_eq!(run.evaluations, run.tiles * steps, "{file}");
        // Every written pixel holds finite values.
        assert!(frames.iter().all(|f| f.data.iter().all(|v| v.is_finite())));
    }
}

#[test]
fn a_model_for_other_fringes_is_refused() {
    let err = LearnedDealiaser::load(
        &model("dealias_onestep.onnx"),
        &[100.0, 110.0, 120.0, 130.0],
        4,
        1,
    )
    .unwrap_err();
    assert!(matches!(err, LearnedError::Patterns { .. }), "{err:?}");
    assert!(err.to_string().contains("dealias_onestep.onnx"), "{err}");
    let err = LearnedDealiaser::load(&model("dealias_onestep.onnx"), &periods(), 3, 1).unwrap_err();
    assert!(matches!(err, LearnedError::Patterns { .. }), "{err:?}");
    let err =
        LearnedDealiaser::load(&model("dealias_diffusion.onnx"), &periods(), 4, 0).unwrap_err();
    assert!(matches!(err, LearnedError::NoSteps), "{err:?}");
}

#[cfg(feature = "sim")]
#[test]
fn scan_with_a_missing_model_names_it_and_writes_nothing() {
    let out = std::env::temp_dir().join(format!("slscan-learned-missing-{}", std::process::id()));
    let result = std::process::Command::new(env!("CARGO_BIN_EXE_slscan"))
        .args([
            "scan",
            "--sim",
            "--mode",
            "simultaneous",
            "--dealias",
            "learned",
        ])
        .args([
            "--dealias-model",
            "/nonexistent/net.onnx",
            "--width",
            "64",
            "--height",
            "48",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(!result.status.success());
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert!(stderr.contains("/nonexistent/net.json"), "{stderr}");
    assert!(!out.join("scan.ply").exists());
    let _ = std::fs::remove_dir_all(&out);
}
