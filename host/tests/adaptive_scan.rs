//! Adaptive projection (seeds 003 and 004) and the multi-exposure scan on
//! the twin's high-dynamic-range scene, `hdr-part` (a polished
//! half-cylinder whose highlight saturates beside a matte black block too
//! dark to decode at the standard exposure), and on its painted plate,
//! `colour-part` (red, green, blue and white quarters under a mono camera),
//! at 200x150, against a plain scan of the same scene: what each recovers,
//! and that nothing it recovers is invented.

use slscan::adaptive::colour::{ColourChoice, ColourParams};
use slscan::adaptive::hdr::HdrParams;
use slscan::scan::{Exposures, HeadResult};
use slscan::sim::scan::{run_sim, SimScanConfig};

fn scan(exposures: Exposures) -> HeadResult {
    scan_scene("hdr-part", exposures)
}

fn scan_scene(scene: &str, exposures: Exposures) -> HeadResult {
    let mut config = SimScanConfig::new(scene);
    config.scan.camera_px = (200, 150);
    config.scan.exposures = exposures;
    let mut result = run_sim(&config, &mut |_| {}).expect("scan runs");
    result.heads.remove(0)
}

fn describe(name: &str, h: &HeadResult) -> (f64, f64, f64) {
    let t = h.truth.as_ref().expect("measured");
    let e = &h.exposure;
    let saturated = e.saturated_px as f64 / e.pixels as f64;
    eprintln!(
        "{name}: {} images, RMSE {:.1} um (predicted {:.1} um), coverage {:.3}, {} over 1 mm, saturated {:.2} %, below floor {:.2} %",
        e.images,
        t.accuracy.rmse_m * 1e6,
        t.accuracy.predicted_rms_m * 1e6,
        t.coverage,
        t.accuracy.outliers,
        100.0 * saturated,
        100.0 * e.below_floor_px as f64 / e.pixels as f64
    );
    // Whatever a method recovers, it does not invent: the error is the
    // noise its own modulation predicts, and (almost) nothing lands a
    // millimetre off (the colour mode's 3-step fringes on the dim wall have
    // a predicted sigma near 250 um, so a 4-sigma noise sample is 1 mm).
    assert!(
        t.accuracy.outliers * 10_000 <= t.accuracy.points,
        "{name}: {} outliers",
        t.accuracy.outliers
    );
    assert!(
        t.accuracy.rmse_m < 1.15 * t.accuracy.predicted_rms_m,
        "{name}: {:?}",
        t.accuracy
    );
    (t.coverage, saturated, t.accuracy.rmse_m)
}

#[test]
fn adaptive_projection_recovers_highlights_and_dark_parts_in_31_images() {
    let plain = scan(Exposures::Single);
    let adaptive = scan(Exposures::AdaptiveHdr(HdrParams::default()));
    let (plain_coverage, plain_saturated, _) = describe("plain", &plain);
    let (coverage, saturated, _) = describe("adaptive", &adaptive);
    assert_eq!(plain.exposure.images, 12);
    assert_eq!(adaptive.exposure.images, 31);
    assert!(plain_saturated > 0.02, "the scene saturates a plain scan");
    let a = adaptive.exposure.adaptive.expect("adaptive figures");
    // Its own full-intensity set saw what the plain scan saw.
    let before = a.before_saturated_px as f64 / adaptive.exposure.pixels as f64;
    assert!(
        (before - plain_saturated).abs() < 0.005,
        "{before} vs {plain_saturated}"
    );
    assert!(saturated < 0.5 * plain_saturated, "{saturated}");
    assert!(a.stats.lowered_px > 0 && a.stats.mapped_by_homography_px > 0);
    assert!(a.exposure.scale > 1.0, "{a:?}");
    assert!(
        coverage > 3.0 * plain_coverage,
        "{coverage} vs {plain_coverage}"
    );
}

#[test]
fn multi_exposure_takes_each_pixel_from_its_best_exposure() {
    let plain = scan(Exposures::Single);
    let multi = scan(Exposures::Multi(vec![8.0, 1.0, 0.125]));
    let (plain_coverage, _, _) = describe("plain", &plain);
    let (coverage, saturated, _) = describe("multi-exposure", &multi);
    assert_eq!(multi.exposure.images, 36);
    assert_eq!(multi.exposure.scales, [8.0, 1.0, 0.125]);
    // The shortest exposure holds even the highlight's peak.
    assert_eq!(saturated, 0.0);
    assert!(
        coverage > 3.0 * plain_coverage,
        "{coverage} vs {plain_coverage}"
    );
}

#[test]
fn adaptive_colour_projection_runs_seed_004s_chain_on_the_painted_plate() {
    let plain = scan_scene("colour-part", Exposures::Single);
    let (plain_coverage, ..) = describe("plain", &plain);
    let mut coverages = Vec::new();
    for choice in [ColourChoice::Texture, ColourChoice::White] {
        let h = scan_scene(
            "colour-part",
            Exposures::AdaptiveColour(ColourParams {
                choice,
                ..ColourParams::default()
            }),
        );
        let (coverage, ..) = describe(&format!("colour {choice:?}"), &h);
        // 5 floods, 68 matching images (9 column and 8 row bits, each at 4
        // shifts), 9 fringe images (3 steps x 3 pitches).
        assert_eq!(h.exposure.images, 5 + 68 + 9);
        let a = h.exposure.adaptive.expect("adaptive figures");
        assert!(a.stats.mapped_by_phase_px > a.stats.lowered_px / 2, "{a:?}");
        coverages.push(coverage);
    }
    // Both recover the colours a plain scan leaves too dark; white, on a
    // mono camera, at least as much as the surface's own colour.
    assert!(
        coverages.iter().all(|&c| c > plain_coverage + 0.05),
        "{coverages:?} vs {plain_coverage}"
    );
    assert!(coverages[1] >= coverages[0] - 0.01, "{coverages:?}");
}
