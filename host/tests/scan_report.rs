//! A simulated scan's outputs as a user meets them: the calibration's
//! self-checks on deliberately wrong rig files (no truth used), and
//! `report.html` opened in a real headless browser (Chromium).

use std::path::{Path, PathBuf};
use std::process::Command;

use slscan::calibration::write_rig;
use slscan::io::report::ScanReport;
use slscan::sim::calibration_source::CalibrationSource;
use slscan::sim::scan::{scan_to_dir, SimScanConfig};
use slscan::sim::twin::Detail;

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("slscan-report-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `large-part`'s true rig file with head A's camera fx scaled by `fx_scale`.
fn rig_file(dir: &Path, fx_scale: f64) -> PathBuf {
    let mut rig = slscan::sim::truth::scene_calibration("large-part", &Detail::default()).unwrap();
    rig.heads[0].camera.intrinsics.fx *= fx_scale;
    let path = dir.join("rig.json");
    write_rig(&path, &rig).unwrap();
    path
}

fn scan(dir: &Path, fx_scale: f64) -> ScanReport {
    let mut config = SimScanConfig::new("large-part");
    config.calibration = CalibrationSource::File(rig_file(dir, fx_scale));
    scan_to_dir(&config, &dir.join("out"), &mut |_| {}).expect("the scan returns a report")
}

#[test]
fn a_true_calibration_passes_and_a_half_percent_focal_length_error_is_named_with_its_size() {
    let dir = tmp("fx");
    let good = scan(&dir, 1.0);
    let check = good.fused.self_check.as_ref().expect("two heads, ICP ran");
    assert_eq!(check.verdict, "consistent", "{check:?}");
    assert!(good.warnings.is_empty(), "{:?}", good.warnings);

    let off = scan(&dir, 1.005);
    let check = off.fused.self_check.as_ref().unwrap();
    assert_eq!(check.verdict, "camera intrinsics or projector model off");
    let shape = check.shape_disagreement_um.unwrap();
    assert!(shape > 50.0, "{check:?}");
    assert!(check.pose_correction_deg > 0.5, "{check:?}");
    let warning = off
        .warnings
        .iter()
        .find(|w| w.contains("calibration inconsistent"))
        .expect("warned");
    assert!(
        warning.contains("intrinsics") && warning.contains(&format!("{shape:.0} um RMS")),
        "{warning}"
    );
    // The same warning on the report page, in a browser.
    let out = dir.join("out");
    let pictures = std::fs::read_dir(&out)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "png")
        })
        .count();
    check_page_in_browser(
        &out.join("report.html"),
        pictures,
        "calibration inconsistent",
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_two_percent_focal_length_error_writes_the_head_clouds_and_a_report_that_says_why() {
    let dir = tmp("fx2");
    let report = scan(&dir, 1.02);
    let failure = report.fused.failure.as_deref().expect("fusion failed");
    assert!(failure.contains("ICP diverged"), "{failure}");
    assert!(failure.contains("calibration is likely wrong"), "{failure}");
    let out = dir.join("out");
    for file in [
        "head_a.ply",
        "head_b.ply",
        "report.json",
        "report.html",
        "depth_a.png",
    ] {
        assert!(out.join(file).is_file(), "{file} written");
    }
    assert!(!out.join("scan.ply").exists(), "no fused scan");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert!(json["fused"]["failure"]
        .as_str()
        .unwrap()
        .contains("ICP diverged"));
    // The head figures are still measured.
    assert!(
        json["heads"][1]["rmse_um"].as_f64().unwrap() < 150.0,
        "{}",
        json["heads"][1]
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Loads `page` in headless Chromium and checks it rendered `pictures`
/// images, none broken, and shows `text`. Without a browser the check says
/// so; CI sets SLSCAN_REQUIRE_BROWSER so that a missing one fails.
fn check_page_in_browser(page: &Path, pictures: usize, text: &str) {
    let Some(browser) = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|b| {
            Command::new(b)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
    else {
        assert!(
            std::env::var_os("SLSCAN_REQUIRE_BROWSER").is_none(),
            "SLSCAN_REQUIRE_BROWSER is set but no Chromium is installed"
        );
        eprintln!(
            "SKIPPED the browser check of {}: no Chromium installed",
            page.display()
        );
        return;
    };
    let out = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--virtual-time-budget=10000",
            "--dump-dom",
        ])
        .arg(format!("file://{}", page.canonicalize().unwrap().display()))
        .output()
        .expect("the browser runs");
    let dom = String::from_utf8_lossy(&out.stdout);
    assert!(
        dom.contains(&format!("data-images=\"{pictures}\"")),
        "the page's script counted every picture: {}",
        dom.lines()
            .find(|l| l.contains("<body"))
            .unwrap_or("no body")
    );
    assert!(
        dom.contains("data-broken-images=\"0\""),
        "no broken picture"
    );
    assert!(dom.contains(text), "the page shows {text:?}");
}
