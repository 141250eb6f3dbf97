//! The model loader must turn any ONNX bytes (truncated, corrupt, hostile)
//! and any metadata text into a model or a ModelError, never a panic or a
//! hang: the ONNX bytes are loaded against the shipped one-step network's
//! metadata, and the same input is parsed as metadata.
#![no_main]

use std::path::Path;
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use slscan::infer::{check_meta, Model, ModelMeta};

fn shipped_meta() -> &'static ModelMeta {
    static META: OnceLock<ModelMeta> = OnceLock::new();
    META.get_or_init(|| {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/dealias_onestep.json");
        serde_json::from_slice(&std::fs::read(path).expect("shipped metadata")).expect("valid")
    })
}

fuzz_target!(|data: &[u8]| {
    if let Ok(meta) = serde_json::from_slice::<ModelMeta>(data) {
        let _ = check_meta(&meta);
    }
    let _ = Model::from_bytes(data, shipped_meta().clone(), Path::new("fuzz.onnx"));
});
