//! Dual-head scans end to end: slscan's scan pipeline -> host serial client
//! -> simulated board on a pty -> simulated DMDs and cameras -> digital-twin
//! images of what each DMD displayed while each shutter was open ->
//! reconstruction per head -> ICP fusion -> figures against the twin's
//! ground truth. Small images keep it to seconds.

use std::path::PathBuf;
use std::time::Duration;

use hil_sim::board::SimBoardConfig;
use hil_sim::faults::FaultPlan;
use slscan::board::ClientConfig;
use slscan::io::report::ScanReport;
use slscan::rig::RigError;
use slscan::scan::{scan_to_dir, Mode, ScanConfig, ScanError};

fn small(scene: &str) -> ScanConfig {
    let mut config = ScanConfig::new(scene);
    config.camera_px = (200, 150);
    config
}

fn out_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("slscan-dual-head-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Checks a scan of `large-part` whose heads both measured the overlap:
/// per-head accuracy near the noise limit, fused coverage above either
/// head's, ICP barely moving the (true) calibration; all files written.
fn check_fused_scan(mode: Mode, name: &str) -> ScanReport {
    let dir = out_dir(name);
    let mut config = small("large-part");
    config.mode = mode;
    let report = scan_to_dir(&config, &dir, &mut |_| {}).expect("scan runs");
    for head in &report.heads {
        // Noise-limited: the phase noise of a 12-bit sensor through the
        // S = 64 three-pitch set gives about 80-95 um RMS; the report's
        // predicted_rms_um carries the phase-noise bound (at half-scale
        // noise, so it errs high) to metres. A wrong pattern in any
        // exposure, or the other head's light leaking through the
        // demultiplexer, gives millimetres.
        assert!(head.rmse_um < 200.0, "head {}: {head:?}", head.name);
        assert!(
            head.rmse_um <= head.predicted_rms_um,
            "head {}: {head:?}",
            head.name
        );
        assert_eq!(head.outliers_over_1mm, 0, "head {}", head.name);
        assert!(
            head.own_pixel_coverage > 0.9,
            "head {}: {head:?}",
            head.name
        );
        assert!(head.coverage > 0.5, "head {}: {head:?}", head.name);
    }
    let fused = &report.fused;
    let best_head = report.heads.iter().map(|h| h.coverage).fold(0.0, f64::max);
    assert!(
        fused.coverage > best_head + 0.15,
        "fused {} vs best head {best_head}",
        fused.coverage
    );
    assert!(fused.rmse_um < 200.0, "{fused:?}");
    // The calibration is the twin's truth: ICP should change it by no more
    // than the noise can pull it.
    let icp = fused.icp.as_ref().expect("ICP ran");
    assert!(icp.converged);
    assert!(icp.rotation_deg < 0.05, "{icp:?}");
    assert!(icp.translation_um < 100.0, "{icp:?}");
    for file in [
        "scan.ply",
        "head_a.ply",
        "head_b.ply",
        "report.json",
        "error_a.png",
    ] {
        assert!(dir.join(file).is_file(), "{file} written");
    }
    let _ = std::fs::remove_dir_all(&dir);
    report
}

#[test]
fn sequential_scan_of_a_part_wider_than_one_head() {
    let report = check_fused_scan(Mode::Sequential, "sequential");
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
}

#[test]
fn temporally_multiplexed_heads_separate_and_fuse_like_sequential_runs() {
    let report = check_fused_scan(Mode::SimultaneousMultiplexed, "multiplexed");
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
}

#[test]
fn simultaneous_identical_sequences_mask_the_aliased_overlap_loudly() {
    let dir = out_dir("simultaneous");
    let mut config = small("large-part");
    config.mode = Mode::Simultaneous;
    let report = scan_to_dir(&config, &dir, &mut |_| {}).expect("scan runs");
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains("PLACEHOLDER") && w.contains("MASKED")),
        "{:?}",
        report.warnings
    );
    for head in &report.heads {
        // What is left (outside the overlap) is as good as ever ...
        assert!(head.rmse_um < 200.0, "head {}: {head:?}", head.name);
        assert_eq!(head.outliers_over_1mm, 0, "head {}", head.name);
    }
    // ... but the overlap is gone, so far less of the part is measured.
    assert!(report.fused.coverage < 0.6, "{:?}", report.fused);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn board_going_silent_mid_scan_is_a_clear_error_and_writes_no_scan() {
    let dir = out_dir("silent");
    let mut config = small("large-part");
    config.client = ClientConfig {
        attempt_timeout: Duration::from_millis(200),
        attempts: 2,
    };
    // Head A's run starts at tick 170_000 and lasts 12 x 34 ms; the board
    // vanishes about 100 ms in.
    config.board = SimBoardConfig {
        seed: 1,
        faults: FaultPlan {
            vanish_at_tick: Some(170_000 + 17_000_000),
            ..FaultPlan::none()
        },
    };
    let err = scan_to_dir(&config, &dir, &mut |_| {}).expect_err("the board vanished");
    assert!(
        matches!(err, ScanError::Rig(RigError::Board(ref e)) if e.is_link_failure()),
        "{err:?}"
    );
    assert!(!dir.join("scan.ply").exists());
    assert!(!dir.exists() || std::fs::read_dir(&dir).unwrap().next().is_none());
}

#[test]
fn a_late_projector_is_caught_by_the_board_and_no_scan_is_written() {
    let dir = out_dir("late");
    let mut config = small("large-part");
    // Head B's DMD lights its patterns 8 ms late: past its 12 ms exposure.
    config.board = SimBoardConfig {
        seed: 1,
        faults: FaultPlan {
            projector_lag_ns: [(1u8, 8_000_000u64)].into(),
            ..FaultPlan::none()
        },
    };
    let err = scan_to_dir(&config, &dir, &mut |_| {}).expect_err("late patterns");
    assert!(
        matches!(err, ScanError::Rig(RigError::NotClean { .. })),
        "{err:?}"
    );
    assert!(!dir.join("scan.ply").exists());
}
