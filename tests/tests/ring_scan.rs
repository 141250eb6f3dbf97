//! Scans of three and four heads end to end (issue 21): the `ring-4` twin
//! scene through the same pipeline as one and two heads (board on a pty
//! with 8 lines, twin cameras, per-head reconstruction, joint registration
//! of every head's pose, one merged cloud), and the refusals before any
//! capture: a board with lines for two heads, and identical sequences on
//! more than two projectors.

use std::path::PathBuf;

use slscan::io::report::ScanReport;
use slscan::scan::{Exposures, Mode, ScanError};
use slscan::sim::scan::{scan_to_dir, SimScanConfig, SimScanError};

fn out_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("slscan-ring-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Runs `ring-4` at 320x240 in `mode` and checks what every K-head scan
/// must give: each head a part of the blade, the joint registration
/// converged near the true poses with a consistent self-check, a fused
/// cloud well above any head's coverage, every pair within a few noise
/// sigma. Returns the report.
fn ring_4(mode: Mode, exposures: Exposures, name: &str) -> ScanReport {
    let mut config = SimScanConfig::new("ring-4");
    config.scan.camera_px = (320, 240);
    config.scan.mode = mode;
    config.scan.exposures = exposures;
    let dir = out_dir(name);
    let report = scan_to_dir(&config, &dir, &mut |_| {}).expect("ring-4 scans");
    assert_eq!(report.heads.len(), 4);
    let registration = report
        .fused
        .registration
        .as_ref()
        .expect("joint registration");
    println!(
        "ring-4 {name}: fused coverage {:.3}, RMSE {:.1} um, {} iterations",
        report.fused.coverage.unwrap(),
        report.fused.rmse_um.unwrap(),
        registration.iterations
    );
    assert!(registration.converged, "{registration:?}");
    // The true devices pass the calibration self-check.
    assert_eq!(registration.verdict, "consistent", "{registration:?}");
    let fused_coverage = report.fused.coverage.unwrap();
    for h in &report.heads {
        let coverage = h.coverage.unwrap();
        println!(
            "head {}: coverage {coverage:.3}, RMSE {:.1} um, overlap pixels {:.1} um, exposure {:?}, correction {:?}, pose vs truth {:.4} deg / {:.1} um",
            h.name,
            h.rmse_um.unwrap(),
            h.overlap_rmse_um.unwrap(),
            h.exposure.exposure_scales,
            h.registration,
            h.pose_error_vs_truth_deg.unwrap_or(0.0),
            h.pose_error_vs_truth_um.unwrap_or(0.0)
        );
        // The part is one that no head sees whole.
        assert!(coverage < 0.6, "head {} covers {coverage}", h.name);
        assert!(fused_coverage > coverage + 0.3, "head {}", h.name);
        // Registration from the true poses stays near them (ICP noise:
        // tens of micrometres, hundredths of a degree).
        if h.name != "A" {
            assert!(h.pose_error_vs_truth_deg.unwrap() < 0.2, "head {}", h.name);
            assert!(
                h.pose_error_vs_truth_um.unwrap() < 1000.0,
                "head {}",
                h.name
            );
        }
        assert_eq!(h.outliers_over_1mm, Some(0), "head {}", h.name);
    }
    assert!(fused_coverage > 0.85, "fused coverage {fused_coverage}");
    // Neighbours overlap; every pair's overlap agrees within a few noise sigma.
    assert!(registration.pairs.len() >= 4, "{:?}", registration.pairs);
    for p in &registration.pairs {
        println!(
            "pair {}: {} inliers, {:.1} um",
            p.heads, p.inliers, p.overlap_rmse_um
        );
        assert!(p.overlap_rmse_um < 300.0, "{p:?}");
    }
    for file in ["scan.ply", "head_a.ply", "head_d.ply", "report.json"] {
        assert!(dir.join(file).is_file(), "{file}");
    }
    // The page shows the registration and its check as report.json has them.
    let page = std::fs::read_to_string(dir.join("report.html")).expect("report.html");
    assert!(
        page.contains("calibration self-check (no truth needed): consistent"),
        "no registration row on the page"
    );
    assert!(page.contains("overlap A-B"), "no pair rows on the page");
    let _ = std::fs::remove_dir_all(&dir);
    report
}

/// Both ways of sharing time on four heads: one head after another (each
/// at the exposure its white flood calls for: at the standard exposure the
/// blade's steep flanks stay under the fringe-order noise floor and the
/// heads share too little to register), and all at once on gamma-safe
/// temporal bins (N = 15). Multiplexing must cost at most 10 % of depth
/// noise against sequential where the projectors overlap.
#[test]
fn four_heads_sequential_and_multiplexed_register_jointly_and_fuse() {
    let auto = Exposures::Auto(slscan::scan::AutoExposure::default());
    let sequential = ring_4(Mode::Sequential, auto, "sequential-auto");
    let multiplexed = ring_4(
        Mode::SimultaneousMultiplexed,
        Exposures::Single,
        "multiplexed",
    );
    for (s, m) in sequential.heads.iter().zip(&multiplexed.heads) {
        let ratio = m.overlap_rmse_um.unwrap() / s.overlap_rmse_um.unwrap();
        println!(
            "head {}: multiplexed / sequential RMSE where projectors overlap {ratio:.3}",
            s.name
        );
        assert!(ratio <= 1.10, "head {}: {ratio}", s.name);
        assert_eq!(s.exposure.kind, "auto");
        assert_eq!(s.exposure.images, 13, "one white flood and 12 fringes");
    }
}

#[test]
fn a_board_with_lines_for_two_heads_refuses_a_four_head_rig_before_capture() {
    let mut config = SimScanConfig::new("ring-4");
    config.scan.camera_px = (160, 120);
    config.board_lines = Some(4);
    let dir = out_dir("ring-4-four-lines");
    let mut stages = Vec::new();
    let err = scan_to_dir(&config, &dir, &mut |p| {
        if let slscan::scan::Progress::Stage { name, .. } = p {
            stages.push(name);
        }
    })
    .expect_err("4 heads on 4 lines");
    assert!(
        matches!(
            err,
            SimScanError::Scan(ScanError::TooManyHeadsForBoard {
                heads: 4,
                max_heads: 2,
                ..
            })
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("4 trigger lines"), "{err}");
    assert!(
        !stages.iter().any(|s| s.starts_with("capture")),
        "{stages:?}"
    );
    assert!(!dir.join("report.json").exists());
}

#[test]
fn identical_sequences_on_four_projectors_are_refused_before_capture() {
    let mut config = SimScanConfig::new("ring-4");
    config.scan.camera_px = (160, 120);
    config.scan.mode = Mode::Simultaneous;
    config.scan.periods_px = slscan::scan::dealias_periods_px(config.scan.projector_px.0);
    let err = scan_to_dir(&config, &out_dir("ring-4-simultaneous"), &mut |_| {})
        .expect_err("simultaneous on four heads");
    assert!(
        matches!(
            err,
            SimScanError::Scan(ScanError::SimultaneousNeedsTwo { heads: 4 })
        ),
        "{err:?}"
    );
}

/// Adaptive projection takes the heads one after another, so it runs on
/// four heads as on two: each head gets its own floods, adaptation and
/// exposure (the capture once stopped at head B and indexed past it).
#[test]
fn adaptive_projection_adapts_each_of_four_heads() {
    let mut config = SimScanConfig::new("ring-4");
    config.scan.camera_px = (160, 120);
    config.scan.exposures = Exposures::AdaptiveHdr(slscan::adaptive::hdr::HdrParams::default());
    let result = slscan::sim::scan::run_sim(&config, &mut |_| {}).expect("ring-4 adaptive");
    assert_eq!(result.heads.len(), 4);
    for h in &result.heads {
        let adaptive = h.adaptive.as_ref().expect("every head adapted");
        assert!(adaptive.exposure.scale > 0.0, "head {}", h.name);
        assert!(!h.reconstruction.cloud.is_empty(), "head {}", h.name);
    }
}
