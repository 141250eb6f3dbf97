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

/// tract panics on some malformed graphs (found by this target:
/// `tract-onnx` model.rs:187, "no entry found for key"); `Model::from_bytes`
/// catches those and returns `ModelError::Onnx`. libFuzzer's hook would
/// abort at the panic before that catch, so the hook is made silent: a
/// panic our own code lets escape still reaches libfuzzer-sys's catch and
/// aborts there, as a crash.
fn let_caught_panics_be_caught() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| std::panic::set_hook(Box::new(|_| {})));
}

fuzz_target!(|data: &[u8]| {
    let_caught_panics_be_caught();
    if let Ok(meta) = serde_json::from_slice::<ModelMeta>(data) {
        let _ = check_meta(&meta);
    }
    let _ = Model::from_bytes(data, shipped_meta().clone(), Path::new("fuzz.onnx"));
});
