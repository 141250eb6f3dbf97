//! A scan that fails leaves no earlier run's `scan.ply` or `report.json`
//! in its output folder, where a user would take them for its result;
//! files the scan does not write stay.

use std::time::Duration;

use hil_sim::board::SimBoardConfig;
use hil_sim::faults::FaultPlan;
use slscan::board::ClientConfig;
use slscan::scan::{output, scan_to_dir, ScanConfig, ScanError};

#[test]
fn a_failed_scan_removes_the_previous_runs_scan_and_report() {
    let dir = std::env::temp_dir().join(format!("slscan-stale-scan-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for name in output::output_files() {
        std::fs::write(dir.join(&name), b"an earlier run").unwrap();
    }
    std::fs::write(dir.join("notes.txt"), b"the user's").unwrap();

    let mut config = ScanConfig::new("large-part");
    config.camera_px = (200, 150);
    config.client = ClientConfig {
        attempt_timeout: Duration::from_millis(200),
        attempts: 2,
    };
    // The board vanishes about 100 ms into head A's run (as in dual_head).
    config.board = SimBoardConfig {
        seed: 1,
        faults: FaultPlan {
            vanish_at_tick: Some(170_000 + 17_000_000),
            ..FaultPlan::none()
        },
    };
    let err = scan_to_dir(&config, &dir, &mut |_| {}).expect_err("the board vanished");
    assert!(matches!(err, ScanError::Rig(_)), "{err:?}");
    let left: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(left, ["notes.txt"], "only the user's file is left");
    std::fs::remove_dir_all(&dir).unwrap();
}
