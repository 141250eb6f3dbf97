//! Accuracy against ground truth on FORMULA-BASED synthetic images (`slscan::synth`), not
//! digital-twin renders: a plane and the two calibration spheres seen by a pinhole camera
//! and projector, Gaussian intensity noise of known sigma. Numbers are printed (run with
//! `--nocapture`) and held against the physical limit where one exists.

#[path = "support/formula_scene.rs"]
mod formula_scene;

use formula_scene::{light, rig, tilted_plane, SIGMA_I};

use nalgebra::Point3;
use slscan::fit::{fit_plane, fit_sphere};
use slscan::phase::{phase_noise_crb, wrap_pi, PhaseShift};
use slscan::raster::Raster;
use slscan::reconstruct::{Directions, ReconstructConfig, Reconstructor};
use slscan::synth::{self, GroundTruth, Surface};
use slscan::unwrap::PixelStatus;

const PERIODS: [f64; 3] = [20.0, 22.0, 24.0];

/// RMS over lit pixels of (measured - true wrapped phase) / CRB(true B).
fn crb_ratio(truth: &GroundTruth, steps: usize, period: f64, seed: u64) -> (f64, usize) {
    let frames = synth::render_fringe_set(truth, &[period], steps, true, &light(), seed);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let out = PhaseShift::new(steps)
        .unwrap()
        .wrapped_phase(&refs)
        .unwrap();
    let (mut sum, mut n) = (0.0f64, 0usize);
    for i in 0..out.phase.len() {
        let Some((u, _)) = truth.projector_px.data[i] else {
            continue;
        };
        let b_true = 0.5 * f64::from(light().gain * truth.shading.data[i]);
        if b_true < 0.1 {
            continue;
        }
        let want = (std::f64::consts::TAU * u / period) as f32;
        let e = f64::from(wrap_pi(out.phase.data[i] - want));
        let crb = phase_noise_crb(f64::from(SIGMA_I), steps, b_true);
        sum += (e / crb).powi(2);
        n += 1;
    }
    ((sum / n as f64).sqrt(), n)
}

#[test]
fn wrapped_phase_error_is_at_the_cramer_rao_bound_on_a_plane() {
    let (camera, projector) = rig();
    let truth = synth::trace(&tilted_plane(), &camera, &projector);
    for (steps, seed) in [(3usize, 1u64), (4, 2), (8, 3)] {
        let (ratio, n) = crb_ratio(&truth, steps, 20.0, seed);
        println!("N = {steps}: RMS phase error / CRB = {ratio:.4} over {n} pixels");
        // Within 1.1x of the bound, and not below it (which would mean a broken test).
        assert!(n > 50_000, "{n}");
        assert!((0.95..=1.1).contains(&ratio), "N = {steps}: ratio {ratio}");
    }
}

struct Run {
    truth: GroundTruth,
    rec: slscan::reconstruct::Reconstruction,
}

fn run(scene: &[Surface], periods: &[f64], seed: u64) -> Run {
    let (camera, projector) = rig();
    let truth = synth::trace(scene, &camera, &projector);
    let frames = synth::render_fringe_set(&truth, periods, 4, true, &light(), seed);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let mut config = ReconstructConfig::new(periods.to_vec());
    config.noise_sigma = SIGMA_I;
    let r = Reconstructor::new(&camera, &projector, config).unwrap();
    let rec = r.reconstruct(&refs, None).unwrap();
    Run { truth, rec }
}

/// (valid, lit, unwrapping errors): an error is a valid pixel whose absolute phase is more
/// than pi from the truth (a wrong fringe order).
fn unwrap_errors(run: &Run, period: f64) -> (usize, usize, usize) {
    let (mut valid, mut lit, mut errors) = (0, 0, 0);
    for (i, p) in run.rec.pixels.iter().enumerate() {
        let Some((u, _)) = run.truth.projector_px.data[i] else {
            continue;
        };
        if run.truth.shading.data[i] < 0.2 {
            continue; // grazing light: modulation near the mask threshold
        }
        lit += 1;
        if p.status == PixelStatus::Valid {
            valid += 1;
            let want = std::f64::consts::TAU * u / period;
            if (f64::from(p.phase_u) - want).abs() > std::f64::consts::PI {
                errors += 1;
            }
        }
    }
    (valid, lit, errors)
}

#[test]
fn plane_unwraps_without_errors_and_is_flat_to_the_predicted_noise() {
    let scene = tilted_plane();
    let r = run(&scene, &PERIODS, 11);
    let (valid, lit, errors) = unwrap_errors(&r, PERIODS[0]);
    println!("plane: {valid} valid of {lit} well-lit pixels, {errors} unwrapping errors");
    assert_eq!(errors, 0);
    assert!(valid as f64 >= 0.999 * lit as f64);

    let Surface::Plane { point_m, normal } = scene[0] else {
        unreachable!()
    };
    let pts: Vec<Point3<f64>> = r
        .rec
        .cloud
        .points_m
        .iter()
        .map(|p| Point3::new(p[0], p[1], p[2]).cast())
        .collect();
    let fit = fit_plane(&pts).unwrap();
    let to_truth: Vec<f64> = pts.iter().map(|p| normal.dot(&(p - point_m))).collect();
    let bias = to_truth.iter().sum::<f64>() / to_truth.len() as f64;
    let rms_truth = (to_truth.iter().map(|d| d * d).sum::<f64>() / to_truth.len() as f64).sqrt();
    // Predicted: per-point sigma along the ray projected on the normal.
    let (camera, _) = rig();
    let c = camera.centre_m();
    let predicted = (r
        .rec
        .cloud
        .quality_m
        .as_ref()
        .unwrap()
        .iter()
        .zip(&pts)
        .map(|(&s, p)| (f64::from(s) * normal.dot(&(p - c).normalize())).powi(2))
        .sum::<f64>()
        / pts.len() as f64)
        .sqrt();
    println!(
        "plane: flatness RMS {:.1} um (fit), {:.1} um to the true plane, bias {:.2} um, predicted {:.1} um",
        fit.rms_m * 1e6,
        rms_truth * 1e6,
        bias * 1e6,
        predicted * 1e6
    );
    let ratio = rms_truth / predicted;
    assert!(
        (0.85..1.2).contains(&ratio),
        "measured / predicted = {ratio}"
    );
    assert!(bias.abs() < 0.2 * predicted);
}

#[test]
fn calibration_spheres_fit_with_small_radius_and_distance_errors() {
    let scene = synth::two_spheres(0.5, 0.62);
    let r = run(&scene, &PERIODS, 21);
    let (valid, lit, errors) = unwrap_errors(&r, PERIODS[0]);
    println!("spheres: {valid} valid of {lit} well-lit pixels, {errors} unwrapping errors");
    assert_eq!(errors, 0);
    assert!(valid as f64 > 0.95 * lit as f64);
    let mut fits = Vec::new();
    for (id, sphere) in scene.iter().enumerate().take(2) {
        let pts: Vec<Point3<f64>> = r
            .rec
            .pixels
            .iter()
            .enumerate()
            .filter(|(i, p)| p.status == PixelStatus::Valid && r.truth.surface.data[*i] == Some(id))
            .map(|(_, p)| Point3::new(p.point_m[0], p.point_m[1], p.point_m[2]).cast())
            .collect();
        let fit = fit_sphere(&pts).unwrap();
        let Surface::Sphere { centre_m, radius_m } = *sphere else {
            unreachable!()
        };
        println!(
            "sphere {id}: {} points, radius {:.4} mm (true {:.4}, error {:+.1} um), centre error {:.1} um, RMSE {:.1} um",
            pts.len(),
            fit.radius_m * 1e3,
            radius_m * 1e3,
            (fit.radius_m - radius_m) * 1e6,
            (fit.centre_m - centre_m).norm() * 1e6,
            fit.rms_m * 1e6
        );
        assert!(pts.len() > 2000);
        assert!((fit.radius_m - radius_m).abs() < 20e-6);
        assert!(fit.rms_m < 100e-6, "seed 001 reached RMSE < 100 um");
        fits.push(fit);
    }
    let distance = (fits[0].centre_m - fits[1].centre_m).norm();
    println!(
        "centre distance {:.4} mm (true 100.1166, error {:+.1} um)",
        distance * 1e3,
        (distance - 0.100_116_6) * 1e6
    );
    assert!((distance - 0.100_116_6).abs() < 30e-6);
}

#[test]
fn two_and_four_frequency_sets_unwrap_without_errors() {
    let scene = synth::two_spheres(0.5, 0.62);
    for periods in [vec![60.0, 64.0], vec![20.0, 22.0, 24.0, 26.0]] {
        let r = run(&scene, &periods, 31);
        let (valid, lit, errors) = unwrap_errors(&r, periods[0]);
        println!("{periods:?}: {valid} valid of {lit} well-lit pixels, {errors} errors");
        assert_eq!(errors, 0);
        // The 2-period set amplifies noise ~22x, so dim sphere rims are refused.
        assert!(valid as f64 > 0.9 * lit as f64);
    }
}

#[test]
fn both_directions_triangulate_with_two_rays() {
    let (camera, projector) = rig();
    let scene = tilted_plane();
    let truth = synth::trace(&scene, &camera, &projector);
    let fu = synth::render_fringe_set(&truth, &PERIODS, 4, true, &light(), 41);
    let fv = synth::render_fringe_set(&truth, &PERIODS, 4, false, &light(), 42);
    let ru: Vec<&Raster<f32>> = fu.iter().collect();
    let rv: Vec<&Raster<f32>> = fv.iter().collect();
    let mut config = ReconstructConfig::new(PERIODS.to_vec());
    config.directions = Directions::Both;
    // 912 x 1140 DMD: the 1320 px beat covers the rows too.
    let rec = Reconstructor::new(&camera, &projector, config).unwrap();
    let out = rec.reconstruct(&ru, Some(&rv)).unwrap();
    let Surface::Plane { point_m, normal } = scene[0] else {
        unreachable!()
    };
    let d: Vec<f64> = out
        .cloud
        .points_m
        .iter()
        .map(|p| normal.dot(&(Point3::new(p[0], p[1], p[2]).cast() - point_m)))
        .collect();
    let rms = (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt();
    println!(
        "two-ray plane: {} points, RMS to true plane {:.1} um",
        d.len(),
        rms * 1e6
    );
    assert!(d.len() > 50_000);
    assert!(rms < 100e-6);
}
