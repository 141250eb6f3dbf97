//! Every shipped model (models/*.onnx) loads, validates and reproduces the
//! golden input/output pair its export wrote, within 1e-4, under tract;
//! broken model files are clear errors naming the file.

use std::path::{Path, PathBuf};

use slscan::infer::{Model, ModelError};

fn models_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../models")
}

fn shipped() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(models_dir())
        .expect("models/ exists")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "onnx"))
        .collect();
    v.sort();
    v
}

/// The golden tensors (name, values) in the order the metadata lists them.
fn golden(onnx: &Path) -> Vec<(String, Vec<f32>)> {
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(onnx.with_extension("json")).unwrap()).unwrap();
    let g = &meta["golden"];
    let bytes = std::fs::read(onnx.with_file_name(g["file"].as_str().unwrap())).unwrap();
    let mut floats = bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()));
    let tensors: Vec<(String, Vec<f32>)> = g["tensors"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            let n: u64 = t["shape"]
                .as_array()
                .unwrap()
                .iter()
                .map(|d| d.as_u64().unwrap())
                .product();
            let values: Vec<f32> = floats.by_ref().take(n as usize).collect();
            assert_eq!(values.len(), n as usize, "golden file too short");
            (t["name"].as_str().unwrap().to_string(), values)
        })
        .collect();
    assert!(floats.next().is_none(), "golden file too long");
    tensors
}

#[test]
fn shipped_models_match_their_golden_pairs() {
    let models = shipped();
    assert!(
        models.len() >= 2,
        "models/ should ship the one-step and the diffusion de-aliaser"
    );
    for onnx in models {
        let model = Model::load(&onnx).unwrap_or_else(|e| panic!("{}: {e}", onnx.display()));
        let mut tensors = golden(&onnx);
        let (_, want) = tensors.pop().unwrap();
        let inputs: Vec<&[f32]> = tensors.iter().map(|(_, v)| v.as_slice()).collect();
        let got = model.run(&inputs).unwrap();
        assert_eq!(got.len(), want.len());
        let worst = got
            .iter()
            .zip(&want)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(
            worst <= 1e-4,
            "{}: max |tract - torch| = {worst}",
            onnx.display()
        );
        let size = std::fs::metadata(&onnx).unwrap().len();
        assert!(size <= 20 << 20, "{}: {size} bytes > 20 MB", onnx.display());
    }
}

/// Copies a shipped model and its metadata into a temporary folder, with
/// `damage` applied to the ONNX bytes.
fn damaged(name: &str, damage: impl Fn(&mut Vec<u8>)) -> PathBuf {
    let src = shipped()[0].clone();
    let dir = std::env::temp_dir().join(format!("slscan-model-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let onnx = dir.join("m.onnx");
    let mut bytes = std::fs::read(&src).unwrap();
    damage(&mut bytes);
    std::fs::write(&onnx, bytes).unwrap();
    std::fs::copy(src.with_extension("json"), dir.join("m.json")).unwrap();
    onnx
}

#[test]
fn a_missing_model_is_an_error_naming_the_file() {
    let err = Model::load(Path::new("/nonexistent/dealias.onnx")).unwrap_err();
    assert!(matches!(err, ModelError::Read { .. }), "{err:?}");
    assert!(
        err.to_string().contains("/nonexistent/dealias.json"),
        "{err}"
    );
}

#[test]
fn a_truncated_model_is_an_error_naming_the_file() {
    let onnx = damaged("truncated", |b| b.truncate(b.len() / 3));
    let err = Model::load(&onnx).unwrap_err();
    assert!(matches!(err, ModelError::Onnx { .. }), "{err:?}");
    assert!(err.to_string().contains("m.onnx"), "{err}");
    std::fs::remove_dir_all(onnx.parent().unwrap()).unwrap();
}

#[test]
fn metadata_that_disagrees_with_the_graph_is_refused() {
    let onnx = damaged("shape", |_| {});
    let meta_path = onnx.with_extension("json");
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&meta_path).unwrap()).unwrap();
    meta["cond_channels"] = serde_json::json!(7);
    std::fs::write(&meta_path, meta.to_string()).unwrap();
    let err = Model::load(&onnx).unwrap_err();
    assert!(
        matches!(
            err,
            ModelError::Onnx { .. } | ModelError::Unsupported { .. }
        ),
        "{err:?}"
    );
    std::fs::write(&meta_path, b"{ not json").unwrap();
    let err = Model::load(&onnx).unwrap_err();
    assert!(matches!(err, ModelError::Meta { .. }), "{err:?}");
    std::fs::remove_dir_all(onnx.parent().unwrap()).unwrap();
}
