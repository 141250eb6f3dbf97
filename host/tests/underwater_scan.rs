//! `scan --medium water` on the simulated rig (issue 18): the `spheres`
//! scene under the twin's water behind 30 mm flat ports, each fringe set
//! restored (or not) before decoding, every pixel triangulated through the
//! ports, measured against the twin's truth. Run with
//! `cargo test -p slscan --test underwater_scan -- --nocapture`.

use hil_sim::twin::scenes::{built_in, Detail};
use slscan::scan::underwater::{water_periods_px, Medium, Restorer, Turbidity, WaterScan};
use slscan::scan::{Exposures, ScanError, ScanResult};
use slscan::sim::scan::{run_sim, SimScanConfig, SimScanError};
use slscan::sim::underwater::{exposure_scale, nominal_psf_sigma_px};

/// A 320x240 water scan of `spheres` at `level` with `restorer`.
fn config(level: Turbidity, restorer: Restorer) -> SimScanConfig {
    let mut config = SimScanConfig::new("spheres");
    let scan = &mut config.scan;
    scan.camera_px = (320, 240);
    scan.periods_px = water_periods_px(scan.projector_px.0);
    scan.exposures = Exposures::Multi(vec![exposure_scale(level)]);
    scan.medium = Medium::Water(WaterScan {
        turbidity: Some(level),
        restorer,
        psf_sigma_px: nominal_psf_sigma_px(level),
        edge_margin_sigmas: slscan::underwater::edges::EDGE_MARGIN_SIGMAS,
    });
    config
}

/// A file of the repository's `models/` folder.
fn shipped_model(file: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../models")
        .join(file)
}

/// (coverage, RMSE um) of head A against the truth, printed.
fn figures(label: &str, r: &ScanResult) -> (f64, f64) {
    let t = r.heads[0].truth.as_ref().expect("the twin has a truth");
    let radius_um: Vec<String> = t
        .spheres
        .iter()
        .map(|s| format!("{:+.0}", s.radius_error_m() * 1e6))
        .collect();
    println!(
        "{label}: {} points, coverage {:.3}, RMSE {:.0} um, median {:.0} um, sphere radius errors {} um",
        t.accuracy.points,
        t.coverage,
        t.accuracy.rmse_m * 1e6,
        t.accuracy.median_m * 1e6,
        radius_um.join(" / ")
    );
    (t.coverage, t.accuracy.rmse_m * 1e6)
}

#[test]
fn restoring_turbid_fringes_and_triangulating_through_the_ports_measures_the_spheres() {
    let level = Turbidity::T3;
    let none = run_sim(&config(level, Restorer::None), &mut |_| {}).unwrap();
    let classical = run_sim(&config(level, Restorer::Classical), &mut |_| {}).unwrap();
    let (cov_none, rmse_none) = figures("T3, no restoration", &none);
    let (cov_classical, rmse_classical) = figures("T3, classical", &classical);
    // Measured here (320x240, the twin's blur as many pixels as at 640x480,
    // so the silhouette margin takes a larger share): none 0.222 / 759 um,
    // classical 0.422 / 249 um (without the margin 0.734 / 491 um); at
    // 640x480 (README): none 0.573 / 401 um, classical 0.617 / 145 um.
    assert!(cov_classical > 0.35, "{cov_classical}");
    assert!(cov_classical >= cov_none, "{cov_classical} vs {cov_none}");
    assert!(
        rmse_classical < 0.8 * rmse_none,
        "{rmse_classical} vs {rmse_none}"
    );
    // Through the ports the depth is right to a fraction of a millimetre
    // (with in-air triangulation it would be off by centimetres).
    assert!(rmse_classical < 600.0, "{rmse_classical} um");
    let w = classical.underwater.as_ref().expect("water figures");
    assert_eq!((w.sets, w.frames, w.evaluations), (3, 12, 0));
    assert_eq!(w.port_misses, vec![0]);

    // The pixels within 2 PSF sigmas of a silhouette, where the blur mixes
    // the other side's fringe in, are left out: fewer points, more accurate.
    let mut kept = config(level, Restorer::Classical);
    if let Medium::Water(w) = &mut kept.scan.medium {
        w.edge_margin_sigmas = 0.0;
    }
    let kept = run_sim(&kept, &mut |_| {}).unwrap();
    let (cov_kept, rmse_kept) = figures("T3, classical, silhouette margin 0", &kept);
    assert_eq!(kept.underwater.as_ref().unwrap().blur_edge_px, vec![0]);
    assert!(w.blur_edge_px[0] > 0, "{:?}", w.blur_edge_px);
    assert!(cov_classical < cov_kept, "{cov_classical} vs {cov_kept}");
    assert!(
        rmse_classical < rmse_kept,
        "{rmse_classical} vs {rmse_kept} um"
    );
    assert_eq!(w.samples.len(), 1);
    // The simulator adds the clear-water reference of the same frame.
    assert_eq!(w.references.len(), 1);
    assert_eq!(w.references[0].len(), w.samples[0].0.len());
    let unrestored = none.underwater.as_ref().expect("water figures");
    assert_eq!(unrestored.sets, 0);
    // Restored frames differ from the captured ones; unrestored do not.
    assert_ne!(w.samples[0].0, w.samples[0].1);
    assert_eq!(unrestored.samples[0].0, unrestored.samples[0].1);

    // The outputs: the three frames side by side and the report's figures.
    let dir = std::env::temp_dir().join(format!("slscan-underwater-out-{}", std::process::id()));
    let report = slscan::scan::output::write_scan(&dir, &classical, &mut |_| {}).unwrap();
    let picture = image::open(dir.join("underwater_a.png")).unwrap();
    assert_eq!(picture.width(), 3 * 320 + 2 * 8);
    let page = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(page.contains("<h2>Under water</h2>"), "no water table");
    assert!(page.contains("2 PSF sigmas"), "no silhouette margin row");
    std::fs::remove_dir_all(&dir).unwrap();
    let u = report.underwater.expect("water report");
    assert_eq!(
        (u.turbidity.as_deref(), u.restorer.as_str(), u.evaluations),
        (Some("T3"), "classical", 0)
    );
    assert_eq!(u.picture_files, vec!["underwater_a.png".to_string()]);
    assert_eq!((u.restorer_model, u.sampler_steps), (None, None));
    assert_eq!(u.edge_margin_sigmas, 2.0);
    assert_eq!(u.blur_edge_pixels, w.blur_edge_px);
}

#[test]
fn t4_water_decodes_with_frames_averaged_or_the_network_not_from_one_classical_frame() {
    // T4 needs ~27x the standard exposure for its attenuation and the plan
    // holds 8x: one frame per pattern leaves the fringes under the order
    // check's noise floor; averaging 4 halves the noise. At 640x480: at
    // 320x240 the 5 px forward-scatter blur leaves the finest fringe no
    // modulation, averaged or not (measured: coverage 0.02 with 16 frames).
    let level = Turbidity::T4;
    // What decodes, so the silhouette margin is off here (with it the
    // 4-frame coverage is 0.172, RMSE 98 um: README).
    let at_vga = |frames: usize| {
        let mut c = config(level, Restorer::Classical);
        c.scan.camera_px = (640, 480);
        c.scan.frames_per_pattern = frames;
        if let Medium::Water(w) = &mut c.scan.medium {
            w.edge_margin_sigmas = 0.0;
        }
        c
    };
    let one = run_sim(&at_vga(1), &mut |_| {}).unwrap();
    let four = run_sim(&at_vga(4), &mut |_| {}).unwrap();
    let (cov_one, _) = figures("T4, classical, 1 frame", &one);
    let (cov_four, rmse_four) = figures("T4, classical, 4 frames averaged", &four);
    // Measured here: 1 frame coverage 0.000, 4 frames 0.367 / 134 um.
    assert!(cov_one < 0.05, "{cov_one}");
    assert!(cov_four > 0.25, "{cov_four}");
    assert!(rmse_four < 300.0, "{rmse_four} um");
    assert_eq!(four.heads[0].exposure.images, 4 * 12);
    assert_eq!(one.heads[0].exposure.images, 12);

    // The shipped network decodes T4 from one frame per pattern (trained on
    // unclipped clear-water targets; the first, clipped-target networks kept
    // coverage 0.002 here).
    let onnx = shipped_model("underwater_onestep.onnx");
    let net =
        slscan::underwater::learned::LearnedRestorer::load(&onnx, &water_periods_px(1280), 4, 1)
            .unwrap();
    let mut learned = at_vga(1);
    if let Medium::Water(w) = &mut learned.scan.medium {
        w.restorer = Restorer::Learned(std::sync::Arc::new(net));
    }
    let learned = run_sim(&learned, &mut |_| {}).unwrap();
    let (cov_learned, _) = figures("T4, one-step network, 1 frame", &learned);
    // Measured here: coverage 0.855, sphere radius errors +123 / -233 um.
    assert!(cov_learned > 0.6, "{cov_learned}");
    for sphere in &learned.heads[0].truth.as_ref().expect("truth").spheres {
        let e = sphere.radius_error_m().abs();
        assert!(e < 0.6e-3, "{} radius off by {e} m", sphere.name);
    }
}

#[test]
fn a_water_scan_needs_a_level_in_the_simulator_and_a_port_on_every_head() {
    let mut no_level = config(Turbidity::T1, Restorer::Classical);
    if let Medium::Water(w) = &mut no_level.scan.medium {
        w.turbidity = None;
    }
    let err = run_sim(&no_level, &mut |_| {}).expect_err("refused");
    assert!(matches!(err, SimScanError::NoTurbidity), "{err}");
    // A rig file of the same scene in air has no ports: refused before capture.
    let dir = std::env::temp_dir().join(format!("slscan-underwater-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let rig_file = dir.join("rig.json");
    let detail = Detail {
        camera: (320, 240),
        projector: (1280, 800),
    };
    let (_, rig) = built_in("spheres", &detail).unwrap();
    let air = slscan::sim::truth::twin_calibration(&rig, 1);
    assert!(air.heads[0].port.is_none());
    slscan::calibration::write_rig(&rig_file, &air).unwrap();
    let mut with_file = config(Turbidity::T1, Restorer::Classical);
    with_file.calibration = slscan::sim::calibration_source::CalibrationSource::File(rig_file);
    let err = run_sim(&with_file, &mut |_| {}).expect_err("refused");
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(
        matches!(err, SimScanError::Scan(ScanError::NoPort { head: "A" })),
        "{err}"
    );
}

#[test]
fn a_restorer_model_for_other_fringes_is_refused_before_capture() {
    use slscan::underwater::learned::{LearnedRestoreError, LearnedRestorer};
    let onnx = shipped_model("underwater_onestep.onnx");
    let periods = water_periods_px(1280);
    LearnedRestorer::load(&onnx, &periods, 4, 1).unwrap();
    let err = LearnedRestorer::load(&onnx, &[59.0, 64.0, 70.0], 4, 1).unwrap_err();
    assert!(matches!(err, LearnedRestoreError::Patterns { .. }), "{err}");
    let err = LearnedRestorer::load(&onnx, &periods, 3, 1).unwrap_err();
    assert!(matches!(err, LearnedRestoreError::Patterns { .. }), "{err}");
    // The de-aliaser (another job, other fringes) is refused as well.
    let dealias = onnx.with_file_name("dealias_onestep.onnx");
    let err = LearnedRestorer::load(&dealias, &[17.5, 20.0], 4, 1).unwrap_err();
    assert!(matches!(err, LearnedRestoreError::Patterns { .. }), "{err}");
}

/// The physics correction reaches the diffusion restorer's sampler: with
/// it the restored set moves towards the observation (a blurred fringe, so
/// a sharper one is restored differently), without it the sample is the
/// same as before; a one-step network has no sampler and is left alone.
#[test]
fn the_physics_correction_changes_the_diffusion_sample_only() {
    use slscan::raster::Raster;
    use slscan::underwater::learned::{LearnedRestorer, PhysicsCorrection};
    let periods = water_periods_px(1280);
    let set: Vec<Raster<f32>> = (0..4)
        .map(|k| {
            Raster::from_fn(64, 64, |x, _| {
                let phase = std::f32::consts::TAU * x as f32 / 12.0;
                0.2 + 0.05 * (phase + k as f32 * std::f32::consts::FRAC_PI_2).cos()
            })
        })
        .collect();
    let refs: Vec<&Raster<f32>> = set.iter().collect();
    let physics = Some(PhysicsCorrection {
        strength: 4.0,
        ..PhysicsCorrection::seed(1.5)
    });
    let diffusion =
        LearnedRestorer::load(&shipped_model("underwater_diffusion.onnx"), &periods, 4, 2).unwrap();
    let (plain, run) = diffusion.restore_set(&refs, 7).unwrap();
    let corrected = diffusion.clone().with_physics(physics);
    let (moved, run_corrected) = corrected.restore_set(&refs, 7).unwrap();
    assert_eq!(
        run, run_corrected,
        "the correction adds no network evaluation"
    );
    let (again, _) = diffusion.with_physics(None).restore_set(&refs, 7).unwrap();
    let change = |a: &[Raster<f32>], b: &[Raster<f32>]| {
        a.iter()
            .zip(b)
            .flat_map(|(a, b)| a.data.iter().zip(&b.data).map(|(x, y)| (x - y).abs()))
            .fold(0.0f32, f32::max)
    };
    assert_eq!(change(&plain, &again), 0.0);
    assert!(change(&plain, &moved) > 1e-4, "{}", change(&plain, &moved));
    let onestep =
        LearnedRestorer::load(&shipped_model("underwater_onestep.onnx"), &periods, 4, 1).unwrap();
    let (a, _) = onestep.restore_set(&refs, 7).unwrap();
    let (b, _) = onestep.with_physics(physics).restore_set(&refs, 7).unwrap();
    assert_eq!(change(&a, &b), 0.0);
}
