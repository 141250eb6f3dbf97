//! Any bytes as an OpenCV `cv::FileStorage` calibration file: through the YAML and the
//! XML reader directly (whatever the first bytes say), then through the whole import
//! (`slscan calibration import`'s path). The first byte picks a prefix so the fuzzer
//! starts inside each format (0: `%YAML:1.0` + a matrix head, 1: `<opencv_storage>` + a
//! matrix element): no panic; a matrix that comes back holds exactly rows x cols values
//! and no more values than the input has bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slscan::calibration::opencv::storage::parse;
use slscan::calibration::opencv::{import_storage, ImportOptions, Value};

fuzz_target!(|data: &[u8]| {
    let bytes = match data.split_first() {
        Some((0, rest)) => [
            b"%YAML:1.0\nM1: !!opencv-matrix\n   rows: ".as_slice(),
            rest,
        ]
        .concat(),
        Some((1, rest)) => [
            b"<?xml version=\"1.0\"?>\n<opencv_storage>\n<M1 type_id=\"opencv-matrix\"><rows>"
                .as_slice(),
            rest,
        ]
        .concat(),
        _ => data.to_vec(),
    };
    let options = ImportOptions {
        camera_size_px: Some((640, 480)),
        projector_size_px: Some((912, 1140)),
        ..ImportOptions::default()
    };
    if let Ok(storage) = parse(&bytes) {
        for node in &storage.nodes {
            if let Value::Matrix(m) = &node.value {
                assert_eq!(m.data.len(), m.rows * m.cols);
                assert!(m.data.len() <= bytes.len());
            }
        }
        let _ = import_storage(&storage, &options);
    }
    // Each reader on its own, whatever the bytes start with.
    if let Ok(text) = std::str::from_utf8(&bytes) {
        let _ = slscan::calibration::opencv::storage::parse_yaml(text);
        let _ = slscan::calibration::opencv::storage::parse_xml(text);
    }
});
