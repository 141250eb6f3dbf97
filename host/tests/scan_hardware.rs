//! The hardware scan path without hardware: hil-sim's board on a pty stands
//! in for the sync board (passed as `--port`), and a thread plays the two
//! vendor tools a real rig needs: the DMD GUI (it reads the pattern PNGs
//! slscan writes) and the camera software (for every exposure the simulated
//! board's cameras took, it renders the digital twin lit by the patterns the
//! simulated DMDs displayed then, and saves the frame into the frames
//! folder with a temporary name and a rename). The scan then reads frames
//! exactly as on a real rig. Small images keep each scan to seconds.

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use slscan::adaptive::colour::ColourParams;
use slscan::adaptive::hdr::HdrParams;
use slscan::board::ClientConfig;
use slscan::calibration::{write_rig, RigCalibration};
use slscan::dealias::DealiasMethod;
use slscan::rig::folder_camera::{FolderCamera, FolderCameraConfig, FolderHead};
use slscan::rig::folder_projector::{
    pattern_file_name, FolderProjector, FolderProjectorHead, PatternDelivery, LED_FILE,
};
use slscan::rig::hardware::HardwareRig;
use slscan::rig::serial_board::SerialBoard;
use slscan::rig::RigError;
use slscan::scan::{run_on_rig, Exposures, Mode, ScanConfig, ScanError, ScanResult};
use slscan::sim::scan::{noise_sigma, shot_noise_share, sim_sensor};
use slscan::sim::truth::ground_truth;

#[path = "support/vendor_tools.rs"]
mod vendor_tools;

use vendor_tools::{
    twin, with_vendor_tools, with_vendor_tools_on, Fault, Folders, VendorRig, CAMERA_PX, HEADS,
};

/// A scan config for the twin's sizes.
fn config(mode: Mode) -> ScanConfig {
    let mut config = ScanConfig::new("hardware");
    config.mode = mode;
    config.camera_px = CAMERA_PX;
    // Three periods: the simultaneous mode masks (analytic needs four).
    config.dealias = DealiasMethod::Mask;
    // The camera noise the twin's sensor has, as a user gives it for theirs.
    config.noise_sigma = noise_sigma(&sim_sensor());
    config.shot_noise_share = shot_noise_share(&sim_sensor());
    config
}

/// The hardware rig of `calibration`'s heads on `port` with the test's folders.
fn hardware_rig(
    port: &Path,
    folders: &Folders,
    timeout: Duration,
    calibration: &RigCalibration,
) -> Result<HardwareRig, RigError> {
    let cameras = FolderCamera::new(FolderCameraConfig {
        root: folders.frames.clone(),
        heads: FolderHead::of_rig(calibration),
        bit_depth: None,
        timeout,
        poll_interval: Duration::from_millis(20),
        settle: Duration::from_millis(300),
    })?;
    let projector = FolderProjector::new(
        folders.patterns.clone(),
        FolderProjectorHead::of_rig(calibration),
        PatternDelivery::Write,
    );
    let board = SerialBoard::open(port, ClientConfig::default())?;
    Ok(HardwareRig::new(
        board,
        projector,
        cameras,
        calibration.heads.len(),
    ))
}

/// A library-level hardware scan; measured against the twin when `truth`.
fn hardware_scan(
    name: &str,
    mode: Mode,
    fault: Fault,
    truth: bool,
) -> (Result<ScanResult, ScanError>, Folders) {
    // A missing frame is only known after the whole timeout; other faults
    // end the wait at once, so theirs only needs to outlast a slow machine.
    let timeout = match fault {
        // Long enough for a slow, loaded CI machine to render the rest.
        Fault::Drop { .. } => 10,
        _ => 30,
    };
    with_vendor_tools(name, fault, |port, folders| {
        let (twin, calibration) = twin();
        let mut rig = hardware_rig(port, folders, Duration::from_secs(timeout), calibration)?;
        let truth = truth.then(|| ground_truth(twin, 2).expect("twin truth"));
        run_on_rig(
            &mut rig,
            calibration,
            "twin truth written as a rig file",
            truth.as_ref(),
            &config(mode),
            &mut |_| {},
        )
    })
}

/// Head A of the twin's rig as a one-head rig (the board triggers its
/// camera and projector only, the folder camera reads A/ only), scanned with
/// `config` and measured against the twin.
fn one_head_hardware_scan(
    name: &str,
    config: &ScanConfig,
) -> (Result<ScanResult, ScanError>, Folders) {
    with_vendor_tools(name, Fault::None, |port, folders| {
        let (twin, calibration) = twin();
        let one = RigCalibration::single(calibration.heads[0].clone());
        let mut rig = hardware_rig(port, folders, Duration::from_secs(30), &one)?;
        let truth = ground_truth(twin, 1).expect("twin truth");
        run_on_rig(
            &mut rig,
            &one,
            "head A of the twin truth as a rig file",
            Some(&truth),
            config,
            &mut |_| {},
        )
    })
}

/// Frames in order, each from its own trigger: per-head accuracy at the
/// noise limit (a frame out of turn gives millimetres, see dual_head's
/// off-by-one DMD table test) and the fused cloud covering more.
fn check_accurate(result: &ScanResult) {
    for head in &result.heads {
        let t = head.truth.as_ref().expect("measured");
        assert!(
            t.accuracy.rmse_m < 200e-6,
            "head {}: {:?}",
            head.name,
            t.accuracy
        );
        assert_eq!(t.accuracy.outliers, 0, "head {}", head.name);
        assert!(
            t.accuracy.own_coverage > 0.9,
            "head {}: {:?}",
            head.name,
            t.accuracy
        );
    }
    let fused = result.fused.truth.as_ref().expect("measured");
    for head in &result.heads {
        let t = head.truth.as_ref().expect("measured");
        eprintln!(
            "{:?} head {}: RMSE {:.1} um (predicted {:.1} um), coverage {:.3}",
            result.config.mode,
            head.name,
            t.accuracy.rmse_m * 1e6,
            t.accuracy.predicted_rms_m * 1e6,
            t.coverage
        );
    }
    eprintln!(
        "{:?} fused: RMSE {:.1} um, coverage {:.3}",
        result.config.mode,
        fused.plane_rmse_m * 1e6,
        fused.coverage
    );
    let best = result
        .heads
        .iter()
        .map(|h| h.truth.as_ref().map_or(0.0, |t| t.coverage))
        .fold(0.0, f64::max);
    assert!(
        fused.coverage > best + 0.15,
        "fused {fused:?} vs best head {best}"
    );
    assert!(result.fused.icp.as_ref().is_some_and(|icp| icp.converged));
}

#[test]
fn sequential_hardware_scan_reads_every_frame_in_order() {
    let (result, folders) = hardware_scan("sequential", Mode::Sequential, Fault::None, true);
    let result = result.expect("scan runs");
    check_accurate(&result);
    // The pattern sets were handed over as 12 numbered PNGs per head.
    for head in HEADS {
        assert!(folders
            .patterns
            .join(head)
            .join(pattern_file_name(11))
            .is_file());
        assert!(!folders
            .patterns
            .join(head)
            .join(pattern_file_name(12))
            .exists());
    }
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn a_one_head_hardware_rig_scans_with_its_head_alone() {
    let (result, folders) = one_head_hardware_scan("one-head", &config(Mode::Sequential));
    let result = result.expect("scan runs");
    assert_eq!(result.heads.len(), 1);
    let t = result.heads[0].truth.as_ref().expect("measured");
    eprintln!(
        "one head: RMSE {:.1} um (predicted {:.1} um), coverage {:.3}",
        t.accuracy.rmse_m * 1e6,
        t.accuracy.predicted_rms_m * 1e6,
        t.coverage
    );
    assert!(t.accuracy.rmse_m < 200e-6, "{:?}", t.accuracy);
    assert_eq!(t.accuracy.outliers, 0);
    assert!(t.accuracy.own_coverage > 0.9, "{:?}", t.accuracy);
    // The head's cloud is the scan; head B was never triggered.
    assert_eq!(result.fused.cloud.len(), result.heads[0].cloud_in_a.len());
    assert!(result.fused.icp.is_none());
    assert!(!folders.patterns.join("B").exists());
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn adaptive_projection_runs_its_three_board_runs_through_the_hardware_path() {
    // Head A alone: floods + the full set in one run, then the adapted set
    // (patterns written anew for the DMD GUI) at the exposure it chose.
    let mut config = config(Mode::Sequential);
    config.exposures = Exposures::AdaptiveHdr(HdrParams::default());
    let (result, folders) = one_head_hardware_scan("adaptive", &config);
    let result = result.expect("scan runs");
    let head = &result.heads[0];
    let t = head.truth.as_ref().expect("measured");
    let a = head.exposure.adaptive.expect("adaptive figures");
    eprintln!(
        "adaptive, one head: RMSE {:.1} um (predicted {:.1} um), coverage {:.3}, exposure {:.2} ({})",
        t.accuracy.rmse_m * 1e6,
        t.accuracy.predicted_rms_m * 1e6,
        t.coverage,
        a.exposure.scale,
        a.exposure.limit.name()
    );
    assert_eq!(head.exposure.images, 7 + 12 + 12);
    assert_eq!(head.exposure.scales, [a.exposure.scale]);
    assert!(t.accuracy.rmse_m < 200e-6, "{:?}", t.accuracy);
    assert_eq!(t.accuracy.outliers, 0);
    assert!(t.accuracy.own_coverage > 0.9, "{:?}", t.accuracy);
    // The DMD folder holds the adapted set alone, not the 19 preliminaries.
    let dir = folders.patterns.join("A");
    assert!(dir.join(pattern_file_name(11)).is_file());
    assert!(!dir.join(pattern_file_name(12)).exists());
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn adaptive_colour_projection_hands_its_leds_to_the_dmd_tool() {
    // Head A alone, seed 004's chain: five floods and the matching set as
    // three-LED images, then the coloured fringes; the DMD tool lights each
    // pattern with the LEDs of pattern_leds.json.
    let mut config = config(Mode::Sequential);
    config.exposures = Exposures::AdaptiveColour(ColourParams::default());
    let (result, folders) = one_head_hardware_scan("adaptive-colour", &config);
    let result = result.expect("scan runs");
    let head = &result.heads[0];
    let t = head.truth.as_ref().expect("measured");
    eprintln!(
        "adaptive colour, one head: RMSE {:.1} um (predicted {:.1} um), coverage {:.3}",
        t.accuracy.rmse_m * 1e6,
        t.accuracy.predicted_rms_m * 1e6,
        t.coverage
    );
    assert_eq!(head.exposure.images, 5 + 68 + 9);
    assert!(
        t.accuracy.rmse_m < 1.15 * t.accuracy.predicted_rms_m,
        "{:?}",
        t.accuracy
    );
    assert_eq!(t.accuracy.outliers, 0);
    assert!(t.accuracy.own_coverage > 0.9, "{:?}", t.accuracy);
    // The last set handed over: 27 planes (9 images x red, green, blue).
    let dir = folders.patterns.join("A");
    assert!(dir.join(pattern_file_name(26)).is_file());
    assert!(!dir.join(pattern_file_name(27)).exists());
    let leds: Vec<[f32; 3]> =
        serde_json::from_slice(&std::fs::read(dir.join(LED_FILE)).unwrap()).unwrap();
    assert_eq!(leds.len(), 27);
    assert_eq!(leds[4], [0.0, 1.0, 0.0]);
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn multiplexed_hardware_scan_separates_the_heads() {
    let (result, folders) = hardware_scan(
        "multiplexed",
        Mode::SimultaneousMultiplexed,
        Fault::None,
        true,
    );
    check_accurate(&result.expect("scan runs"));
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn simultaneous_mode_masks_the_overlap_it_measures_without_a_twin() {
    // No ground truth: the aliased overlap comes from the flat-field
    // exposures the plan adds, which the vendor tools play like any other.
    let (result, folders) = hardware_scan("simultaneous", Mode::Simultaneous, Fault::None, false);
    // `config` masks: the analytic de-aliaser needs four periods.
    let result = result.expect("simultaneous mode runs on hardware");
    assert!(
        result
            .warnings
            .iter()
            .any(|w| w.contains("flat fields") && w.contains("MASKED")),
        "{:?}",
        result.warnings
    );
    for head in &result.heads {
        assert!(head.truth.is_none());
        // What is outside the other projector's light is reconstructed.
        assert!(
            head.reconstruction.cloud.len() > 1_000,
            "head {}",
            head.name
        );
    }
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn a_board_vanishing_mid_scan_is_a_link_error() {
    // Head A's run starts at tick 170_000 and lasts 12 x 34 ms; the board
    // vanishes about 100 ms in.
    let fault = Fault::BoardVanishes {
        at_tick: 170_000 + 17_000_000,
    };
    let (result, folders) = hardware_scan("vanish", Mode::Sequential, fault, false);
    let err = result.expect_err("the board vanished");
    assert!(
        matches!(err, ScanError::Rig(RigError::Board(ref e)) if e.is_link_failure()),
        "{err:?}"
    );
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn a_missing_frame_is_a_frame_count_error() {
    let fault = Fault::Drop { head: 0, index: 5 };
    let (result, folders) = hardware_scan("missing", Mode::Sequential, fault, false);
    let err = result.expect_err("a frame is missing");
    assert!(
        matches!(
            err,
            ScanError::Rig(RigError::FrameCount {
                head: 0,
                expected: 12,
                got: 11,
                ..
            })
        ),
        "{err:?}"
    );
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn an_extra_frame_is_a_frame_count_error() {
    // Head B runs second in sequential mode: head A's frames were fine.
    // (An extra frame mid-run is caught too when the settle time outlasts
    // the gap between two saves; this slow test renderer has no fixed gap.)
    let fault = Fault::Extra { head: 1, index: 11 };
    let (result, folders) = hardware_scan("extra", Mode::Sequential, fault, false);
    let err = result.expect_err("one frame too many");
    assert!(
        matches!(
            err,
            ScanError::Rig(RigError::FrameCount {
                head: 1,
                expected: 12,
                got: 13,
                ..
            })
        ),
        "{err:?}"
    );
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn a_wrong_size_frame_is_a_size_error() {
    let fault = Fault::WrongSize { head: 0, index: 3 };
    let (result, folders) = hardware_scan("size", Mode::Sequential, fault, false);
    let err = result.expect_err("a half-size frame");
    assert!(
        matches!(
            err,
            ScanError::Rig(RigError::FrameSize {
                head: 0,
                frame: 3,
                expected: (200, 150),
                got: (100, 75),
                ..
            })
        ),
        "{err:?}"
    );
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn a_corrupt_frame_is_a_decode_error() {
    let fault = Fault::Corrupt { head: 1, index: 4 };
    let (result, folders) = hardware_scan("corrupt", Mode::SimultaneousMultiplexed, fault, false);
    let err = result.expect_err("a truncated PNG");
    assert!(
        matches!(
            err,
            ScanError::Rig(RigError::FrameDecode {
                head: 1,
                frame: 4,
                ..
            })
        ),
        "{err:?}"
    );
    let _ = std::fs::remove_dir_all(&folders.root);
}

fn slscan_scan(port: &Path, folders: &Folders, extra: &[&str]) -> std::process::Output {
    let (_, calibration) = twin();
    let rig_file = folders.root.join("rig.json");
    write_rig(&rig_file, calibration).expect("rig file");
    let path = |p: &Path| p.to_string_lossy().into_owned();
    let mut args = vec![
        "scan".to_string(),
        "--port".into(),
        path(port),
        "--frames-from".into(),
        path(&folders.frames),
        "--calibration".into(),
        path(&rig_file),
        "--patterns-dir".into(),
        path(&folders.patterns),
        "--out".into(),
        path(&folders.out),
        "--frame-poll-ms".into(),
        "20".into(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    Command::new(env!("CARGO_BIN_EXE_slscan"))
        .args(&args)
        .output()
        .expect("slscan runs")
}

#[test]
fn slscan_scan_on_a_port_writes_clouds_and_a_report_without_truth() {
    let (out, folders) = with_vendor_tools("cli", Fault::None, |port, folders| {
        slscan_scan(port, folders, &["--mode", "sequential"])
    });
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("PLACEHOLDER: no DMD driver uploads patterns"),
        "{stderr}"
    );
    // A redirected log: no colour codes, and the warning once per head.
    assert!(!stderr.contains('\u{1b}'), "{stderr}");
    let placeholder = stderr.matches("PLACEHOLDER: no DMD driver").count();
    assert_eq!(placeholder, 2, "once per head: {stderr}");
    for file in [
        "scan.ply",
        "head_a.ply",
        "head_b.ply",
        "report.json",
        "report.html",
        "projector_column_a.png",
        "camera_mean_b.png",
    ] {
        assert!(folders.out.join(file).is_file(), "{file} written");
    }
    assert!(
        !folders.out.join("error_vs_truth_a.png").exists(),
        "no truth, no error map"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(folders.out.join("report.json")).unwrap())
            .unwrap();
    for head in 0..2 {
        let h = &report["heads"][head];
        assert!(h["points"].as_u64().unwrap() > 5_000, "{h}");
        assert!(h["rmse_um"].is_null() && h["coverage"].is_null(), "{h}");
        // The noise prediction needs no truth: 12-bit sensor noise through
        // the S = 64 three-pitch set, about 130 um at the part.
        let predicted = h["predicted_rms_um"].as_f64().unwrap();
        assert!(predicted > 50.0 && predicted < 300.0, "{h}");
    }
    let fused = &report["fused"];
    assert!(
        fused["rmse_um"].is_null() && fused["coverage"].is_null(),
        "{fused}"
    );
    assert!(fused["points"].as_u64().unwrap() > report["heads"][0]["points"].as_u64().unwrap());
    assert!(fused["icp"]["converged"].as_bool().unwrap(), "{fused}");
    assert!(report["calibration"].as_str().unwrap().contains("rig.json"));
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn slscan_scan_with_a_missing_frame_fails_and_writes_no_scan() {
    let fault = Fault::Drop { head: 1, index: 0 };
    let (out, folders) = with_vendor_tools("cli-missing", fault, |port, folders| {
        // An earlier run's results in the output folder must not survive.
        seed_earlier_run(&folders.out);
        slscan_scan(port, folders, &["--frame-timeout-s", "10"])
    });
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("head 1: camera took 11 frames for 12 triggers"),
        "{stderr}"
    );
    assert_no_outputs(&folders.out);
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn slscan_scan_at_every_fault_leaves_no_output_old_or_new() {
    let faults = [
        (
            "vanish",
            Fault::BoardVanishes {
                at_tick: 170_000 + 17_000_000,
            },
            "sync board",
        ),
        (
            "extra",
            Fault::Extra { head: 1, index: 11 },
            "camera took 13 frames",
        ),
        ("size", Fault::WrongSize { head: 0, index: 3 }, "(100, 75)"),
        ("corrupt", Fault::Corrupt { head: 1, index: 4 }, "frame"),
    ];
    for (name, fault, want) in faults {
        let (out, folders) = with_vendor_tools(&format!("cli-{name}"), fault, |port, folders| {
            seed_earlier_run(&folders.out);
            slscan_scan(port, folders, &["--frame-timeout-s", "30"])
        });
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{name}: {stderr}");
        assert!(stderr.contains(want), "{name}: {stderr}");
        assert_no_outputs(&folders.out);
        let _ = std::fs::remove_dir_all(&folders.root);
    }
}

/// Every file a scan writes, each as an earlier run's.
fn seed_earlier_run(out: &Path) {
    std::fs::create_dir_all(out).unwrap();
    for name in slscan::scan::output::output_files() {
        std::fs::write(out.join(name), b"an earlier run").unwrap();
    }
}

/// No file of a scan in `out`, neither this run's nor an earlier one's.
fn assert_no_outputs(out: &Path) {
    for name in slscan::scan::output::output_files() {
        assert!(!out.join(&name).exists(), "{name} left behind");
    }
}

/// Folders of a run that never reaches the board.
fn offline_folders(name: &str) -> Folders {
    let root = std::env::temp_dir().join(format!("slscan-hw-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(root.join("frames/A")).unwrap();
    std::fs::create_dir_all(root.join("frames/B")).unwrap();
    Folders {
        frames: root.join("frames"),
        patterns: root.join("patterns"),
        out: root.join("out"),
        root,
    }
}

#[test]
fn a_link_failing_at_connect_leaves_no_output_old_or_new() {
    let folders = offline_folders("connect");
    seed_earlier_run(&folders.out);
    let out = slscan_scan(&folders.root.join("no-such-port"), &folders, &[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("connecting to the sync board"), "{stderr}");
    assert_no_outputs(&folders.out);
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[cfg(unix)]
#[test]
fn an_output_name_that_is_a_symlink_is_refused_before_the_board_is_touched() {
    let folders = offline_folders("symlink");
    std::fs::create_dir_all(&folders.out).unwrap();
    std::fs::write(folders.root.join("keep.txt"), b"not ours").unwrap();
    std::os::unix::fs::symlink(folders.root.join("keep.txt"), folders.out.join("scan.ply"))
        .unwrap();
    std::fs::write(folders.out.join("report.json"), b"an earlier run").unwrap();
    let out = slscan_scan(&folders.root.join("no-such-port"), &folders, &[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("is a symlink, not a regular file"),
        "{stderr}"
    );
    assert!(
        !stderr.contains("connecting"),
        "refused before the board: {stderr}"
    );
    let link = std::fs::symlink_metadata(folders.out.join("scan.ply")).unwrap();
    assert!(link.file_type().is_symlink(), "the link is left as it was");
    assert_eq!(
        std::fs::read(folders.root.join("keep.txt")).unwrap(),
        b"not ours"
    );
    assert!(
        folders.out.join("report.json").exists(),
        "nothing removed before the check"
    );
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn slscan_scan_names_the_missing_hardware_options() {
    let out = Command::new(env!("CARGO_BIN_EXE_slscan"))
        .args([
            "scan",
            "--port",
            "/dev/ttyACM9",
            "--out",
            "/tmp/slscan-never",
        ])
        .output()
        .expect("slscan runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("--frames-from or --camera, --calibration") && stderr.contains("--sim"),
        "{stderr}"
    );
}

/// Seed 001's high-speed mode on a hardware rig of one colour camera: the
/// 24 binary patterns and the LED flats are written for the DMD GUI with
/// each pattern's LEDs, the camera software saves each colour long exposure
/// as a 16-bit RGB PNG, and the scan reads them as R, G, B planes and
/// decodes 24 instants per frame, measured against the twin's truth at
/// each instant as on the simulated rig (`high_speed_scan.rs`).
#[test]
fn high_speed_mode_runs_on_a_colour_camera_through_the_vendor_tools() {
    use hil_sim::twin::scenes::{built_in, Detail};
    use hil_sim::twin::TwinRig;
    use slscan::scan::high_speed::{run_high_speed, HighSpeedConfig};
    use slscan::sim::high_speed::{high_speed_sensor, SimHighSpeedConfig};
    use slscan::sim::truth::{camera_truth_at, spheres_at, twin_calibration};
    use std::sync::Arc;

    let sim = SimHighSpeedConfig::new("spheres");
    let detail = Detail {
        camera: (320, 240),
        projector: sim.projector_px,
    };
    let (scene, rig) = built_in("spheres", &detail).expect("scene");
    let twin = Arc::new(TwinRig::new(scene, rig).expect("twin"));
    let calibration = twin_calibration(twin.rig(), 1);
    let vendor = VendorRig {
        twin: twin.clone(),
        heads: 1,
        sensor: high_speed_sensor(),
    };
    let (result, folders) =
        with_vendor_tools_on(&vendor, "high-speed", Fault::None, |port, folders| {
            let mut rig = hardware_rig(port, folders, Duration::from_secs(30), &calibration)?;
            let mut config = HighSpeedConfig::new("hardware");
            config.frames = 1;
            let truth_at = |t: f64| {
                let truth = camera_truth_at(&twin, 0, t).ok()?;
                Some((truth, spheres_at(twin.scene(), t)))
            };
            run_high_speed(
                &mut rig,
                &config,
                &calibration,
                Some(&truth_at),
                &mut |_| {},
            )
        });
    let result = result.expect("the high-speed scan runs on the hardware path");
    // What the DMD GUI was handed: the 24 patterns with their LEDs.
    let leds: Vec<[f32; 3]> = serde_json::from_slice(
        &std::fs::read(folders.patterns.join("A").join(LED_FILE)).expect("LED table"),
    )
    .expect("LED table reads");
    assert_eq!(leds.len(), 24);
    assert_eq!(result.frames.len(), 1);
    let instants = &result.frames[0].instants;
    assert_eq!(instants.len(), 24);
    let mut medians: Vec<f64> = instants
        .iter()
        .map(|i| {
            let t = i.truth.as_ref().expect("measured against the twin");
            assert!(
                t.coverage > 0.5,
                "pattern {}: coverage {}",
                i.pattern.index,
                t.coverage
            );
            t.depth_median_m
        })
        .collect();
    medians.sort_by(f64::total_cmp);
    println!(
        "hardware path, colour PNGs: instants' median depth error {:.0}-{:.0} um (median {:.0})",
        medians[0] * 1e6,
        medians[23] * 1e6,
        medians[12] * 1e6
    );
    // The simulated rig's bound for the same scene and size.
    assert!(medians[12] < 5e-3, "median of medians {} m", medians[12]);
    let _ = std::fs::remove_dir_all(&folders.root);
}
