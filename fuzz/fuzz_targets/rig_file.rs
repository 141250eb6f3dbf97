//! Any bytes as a rig file (`slscan-rig` JSON, what `scan --calibration`,
//! `register` and `reconstruct` read): straight into
//! `slscan::calibration::rig_file::parse_rig`, or (first byte 0) spliced into a valid
//! three-head rig in place of its head poses, so the fuzzer starts inside a
//! document that parses. No panic; a rig that comes back validates, has a
//! pose from head A for every further head, and writes to text that reads
//! back to the same rig.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slscan::calibration::rig_file::{parse_rig, to_json};
use slscan::calibration::{Head, PinholeModel, Pose, RigCalibration};

/// A valid three-head rig's text, split where its `head_poses` list starts.
fn three_head_text() -> (String, String) {
    let head = |name: &str| Head {
        name: name.into(),
        camera: PinholeModel::ideal(64, 48, 80.0),
        projector: PinholeModel::ideal(128, 80, 120.0),
        view_errors: vec![],
        port: None,
    };
    let rig = RigCalibration {
        heads: vec![head("A"), head("B"), head("C")],
        head_poses: vec![Pose::identity(), Pose::identity()],
        stereo_heads: vec![],
    };
    let text = to_json(&rig).expect("a valid rig");
    let at = text
        .find("\"head_poses\"")
        .expect("three heads write head_poses");
    (text[..at].to_string(), text[at..].to_string())
}

fuzz_target!(|data: &[u8]| {
    let text = match data.split_first() {
        Some((0, rest)) => {
            let (head, _) = three_head_text();
            format!("{head}{}", String::from_utf8_lossy(rest))
        }
        _ => String::from_utf8_lossy(data).into_owned(),
    };
    if let Ok(rig) = parse_rig(&text) {
        rig.validate().expect("a parsed rig validates");
        assert_eq!(rig.head_poses.len(), rig.heads.len().saturating_sub(1));
        let again = to_json(&rig).expect("writes");
        assert_eq!(parse_rig(&again).expect("reads back"), rig);
    }
});
