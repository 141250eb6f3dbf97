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
use slscan::dealias::DealiasMethod;
use slscan::io::report::ScanReport;
use slscan::rig::RigError;
use slscan::scan::{dealias_periods_px, output, Mode, ScanError};
use slscan::sim::scan::{scan_to_dir, SimScanConfig, SimScanError};

fn small(scene: &str) -> SimScanConfig {
    let mut config = SimScanConfig::new(scene);
    config.scan.camera_px = (200, 150);
    config
}

/// A figure against the twin's truth: a simulated scan always has it.
fn truth(figure: Option<f64>) -> f64 {
    figure.expect("a simulated scan is measured against the twin")
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
    config.scan.mode = mode;
    let report = scan_to_dir(&config, &dir, &mut |_| {}).expect("scan runs");
    for head in &report.heads {
        // Noise-limited: the phase noise of a 12-bit sensor through the
        // S = 64 three-pitch set gives about 80-95 um RMS; the report's
        // predicted_rms_um carries each pixel's phase-noise bound (at its
        // own shot + read noise) to metres, so the two agree. A wrong
        // pattern in any exposure, or the other head's light leaking
        // through the demultiplexer, gives millimetres.
        assert!(truth(head.rmse_um) < 200.0, "head {}: {head:?}", head.name);
        let ratio = truth(head.rmse_um) / head.predicted_rms_um;
        assert!(
            (0.9..1.1).contains(&ratio),
            "head {}: measured / predicted {ratio:.3}: {head:?}",
            head.name
        );
        assert_eq!(head.outliers_over_1mm, Some(0), "head {}", head.name);
        assert!(
            truth(head.own_pixel_coverage) > 0.9,
            "head {}: {head:?}",
            head.name
        );
        assert!(truth(head.coverage) > 0.5, "head {}: {head:?}", head.name);
    }
    let fused = &report.fused;
    let best_head = report
        .heads
        .iter()
        .map(|h| truth(h.coverage))
        .fold(0.0, f64::max);
    assert!(
        truth(fused.coverage) > best_head + 0.15,
        "fused {:?} vs best head {best_head}",
        fused.coverage
    );
    assert!(truth(fused.rmse_um) < 200.0, "{fused:?}");
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
        "error_vs_truth_a.png",
        "report.html",
        "cloud_front.png",
        "cloud_oblique.png",
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
    config.scan.mode = Mode::Simultaneous;
    config.scan.dealias = DealiasMethod::Mask;
    let report = scan_to_dir(&config, &dir, &mut |_| {}).expect("scan runs");
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains("--dealias mask") && w.contains("MASKED")),
        "{:?}",
        report.warnings
    );
    for head in &report.heads {
        // The overlap is measured by the flat-field exposures, not taken
        // from the twin: compare it with the twin's truth.
        let mask = head.aliased_mask.as_ref().expect("flat fields measured");
        eprintln!("head {}: measured overlap vs truth {mask:?}", head.name);
        assert!(mask.true_overlap_pixels > 1_000, "{mask:?}");
        assert!(mask.iou > 0.95 && mask.recall > 0.99, "{mask:?}");
        assert_eq!(head.overlap_points, Some(0), "{head:?}");
        let d = head.dealias.as_ref().expect("masking figures");
        assert!(d.picture.is_none() && d.error_vs_clean_rms_8bit.is_none());
        // What is left (outside the overlap) is as good as ever ...
        assert!(truth(head.rmse_um) < 200.0, "head {}: {head:?}", head.name);
        assert_eq!(head.outliers_over_1mm, Some(0), "head {}", head.name);
    }
    // ... but the overlap is gone, so far less of the part is measured.
    assert!(truth(report.fused.coverage) < 0.6, "{:?}", report.fused);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A simultaneous scan of `large-part` at 320x240 with `method`; checks
/// the figures every de-aliaser must give and returns the report.
fn simultaneous_scan(method: DealiasMethod) -> ScanReport {
    let dir = out_dir(method.name());
    let mut config = SimScanConfig::new("large-part");
    config.scan.camera_px = (320, 240);
    config.scan.mode = Mode::Simultaneous;
    config.scan.dealias = method;
    config.scan.periods_px = dealias_periods_px(config.scan.projector_px.0);
    let report = scan_to_dir(&config, &dir, &mut |_| {}).expect("scan runs");
    for head in &report.heads {
        let d = head.dealias.as_ref().expect("simultaneous mode de-aliases");
        assert_eq!(d.method, method.name());
        eprintln!(
            "head {}: {:?} of {:?} overlap pixels recovered (RMSE {:?} um), median error {:?} um, \
             {:?} over 1 mm of {} points, coverage {:?}; {d:?}",
            head.name,
            head.overlap_points,
            head.overlap_pixels,
            head.overlap_rmse_um,
            head.median_error_um,
            head.outliers_over_1mm,
            head.points,
            head.coverage,
        );
        assert!(
            truth(head.median_error_um) < 1.2 * head.predicted_rms_um,
            "{head:?}"
        );
        // The picture of the separation, and its fringe error against the
        // twin's frame of the own projector alone: about the camera's noise
        // (1.1 on the 8-bit scale at 640x480; seed 000's MSE 1.85 is 1.36).
        let picture = d.picture.as_ref().expect("de-aliasing picture");
        assert!(dir.join(picture).is_file(), "{picture}");
        let error = d
            .error_vs_clean_rms_8bit
            .expect("error against the clean frame");
        assert!(error > 0.1 && error < 3.0, "head {}: {error}", head.name);
    }
    let _ = std::fs::remove_dir_all(&dir);
    report
}

#[test]
fn simultaneous_epipolar_dealiasing_recovers_the_whole_overlap() {
    let report = simultaneous_scan(DealiasMethod::Epipolar);
    for head in &report.heads {
        let (overlap, recovered) = (head.overlap_pixels.unwrap(), head.overlap_points.unwrap());
        // 99.3 / 99.2 % at 640x480; sequential reconstructs 99.99 %.
        assert!(
            recovered * 100 > overlap * 97,
            "head {}: {recovered} of {overlap}",
            head.name
        );
        assert_eq!(head.outliers_over_1mm, Some(0), "{head:?}");
        // Both projectors' fringes and all four periods fix the range: the
        // overlap comes out better than a sequential scan's (~92 um).
        assert!(truth(head.overlap_rmse_um) < 92.0 * 1.1, "{head:?}");
    }
    // 0.961 here; at 640x480 0.978, sequential 0.979, masking 0.370.
    assert!(truth(report.fused.coverage) > 0.95, "{:?}", report.fused);
}

#[test]
fn simultaneous_analytic_dealiasing_recovers_much_of_the_overlap() {
    let report = simultaneous_scan(DealiasMethod::Analytic);
    for head in &report.heads {
        let (overlap, recovered) = (head.overlap_pixels.unwrap(), head.overlap_points.unwrap());
        assert!(
            recovered * 3 > overlap,
            "head {}: {recovered} of {overlap}",
            head.name
        );
        // A wrong separation is a point millimetres off: nearly none get through.
        assert!(
            head.outliers_over_1mm.unwrap() * 1000 < head.points,
            "{head:?}"
        );
    }
    // Masking leaves the fused coverage under 0.6 (the test above; 0.37 at
    // 640x480), sequential scans cover 0.98; here 0.71 at 320x240.
    assert!(truth(report.fused.coverage) > 0.65, "{:?}", report.fused);
}

/// Also: an earlier run's outputs in the folder are gone afterwards (a user
/// would take them for this run's result); files the scan never writes stay.
#[test]
fn board_going_silent_mid_scan_is_a_clear_error_and_leaves_no_scan() {
    let dir = out_dir("silent");
    std::fs::create_dir_all(&dir).unwrap();
    for name in output::output_files() {
        std::fs::write(dir.join(&name), b"an earlier run").unwrap();
    }
    std::fs::write(dir.join("notes.txt"), b"the user's").unwrap();
    let mut config = small("large-part");
    config.scan.client = ClientConfig {
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
        matches!(err, SimScanError::Scan(ScanError::Rig(RigError::Board(ref e))) if e.is_link_failure()),
        "{err:?}"
    );
    let left: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(left, ["notes.txt"], "only the user's file is left");
    let _ = std::fs::remove_dir_all(&dir);
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
        matches!(
            err,
            SimScanError::Scan(ScanError::Rig(RigError::NotClean { .. }))
        ),
        "{err:?}"
    );
    assert!(!dir.join("scan.ply").exists());
}

/// Head A alone on a fresh simulated rig with DMD table `table` (the
/// plan's trigger k shows `table[k]`); returns its per-pixel accuracy.
fn head_a_with_table(
    reorder: impl Fn(Vec<slscan::raster::Raster<f32>>) -> Vec<slscan::raster::Raster<f32>>,
) -> slscan::scan::metrics::PixelAccuracy {
    use hil_sim::twin::scenes::{built_in, Detail};
    use hil_sim::twin::TwinRig;
    use slscan::reconstruct::{ReconstructConfig, Reconstructor};
    use slscan::rig::{Board, Camera, Projector};
    use slscan::scan::{default_periods_px, metrics, plan};
    use slscan::sim::rig::{SimRig, SimRigConfig};
    use slscan::sim::scan::{noise_sigma, sim_sensor};
    use slscan::sim::truth::{ground_truth, twin_calibration};
    use std::sync::Arc;

    let config = small("large-part").scan;
    let detail = Detail {
        camera: config.camera_px,
        projector: config.projector_px,
    };
    let (scene, rig) = built_in("large-part", &detail).unwrap();
    let twin = Arc::new(TwinRig::new(scene, rig).unwrap());
    let sensor = sim_sensor();
    let mut sim = SimRig::start(
        twin.clone(),
        SimRigConfig {
            board: SimBoardConfig::default(),
            client: config.client,
            sensor,
            noise_seed: 5,
            board_limits: protocol::BoardLimits::STM32G474,
        },
    )
    .unwrap();
    let periods = default_periods_px(config.projector_px.0);
    let patterns = plan::fringe_sequence(config.projector_px, &periods, 4);
    let count = patterns.len();
    sim.load_sequence(0, &reorder(patterns)).unwrap();
    sim.run_plan(&plan::one_pattern_per_exposure(protocol::HeadSet::A, count).unwrap())
        .expect("the board's timing is fine either way");
    let frames = sim.take_frames(0).unwrap();
    let cal = twin_calibration(twin.rig(), 2);
    let mut rc_config = ReconstructConfig::new(periods);
    rc_config.noise_sigma = noise_sigma(&sensor);
    let rc = Reconstructor::from_head(&cal.heads[0], rc_config).unwrap();
    let refs: Vec<_> = frames.iter().collect();
    let recon = rc.reconstruct(&refs, None).unwrap();
    let truth = ground_truth(&twin, 1).unwrap();
    metrics::pixel_accuracy(&recon, &truth.cameras[0], &truth.head_from_world(0))
}

#[test]
fn a_dmd_table_off_by_one_shows_in_the_rendered_images() {
    // The cameras render what the DMD really showed, so a host that loads
    // its pattern table one step out of turn gets wrong phases, though the
    // board's trigger timing is perfect.
    let good = head_a_with_table(|p| p);
    let rotated = head_a_with_table(|mut p| {
        p.rotate_left(1);
        p
    });
    eprintln!("DMD table in order: {good:?}\nDMD table off by one: {rotated:?}");
    assert!(good.rmse_m < 200e-6 && good.own_coverage > 0.9, "{good:?}");
    assert!(
        rotated.own_coverage < 0.5 * good.own_coverage || rotated.rmse_m > 10.0 * good.rmse_m,
        "good {good:?}, rotated {rotated:?}"
    );
}
