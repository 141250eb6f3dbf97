//! PDM, Gray code + phase, quality-guided unwrapping and FTP on FORMULA-BASED renders
//! (`slscan::synth`, not twin renders) of a tilted plane and the calibration spheres,
//! checked against the projector coordinate each camera pixel truly sees.

#[path = "support/formula_scene.rs"]
mod formula_scene;

use formula_scene::{light, rig, tilted_plane};

use slscan::phase::ftp::{ftp_phase, FringeAxis};
use slscan::phase::{modulation_mask, wrap_pi, PhaseShift, WrappedPhase};
use slscan::raster::Raster;
use slscan::synth::{self, GroundTruth};
use slscan::unwrap::gray_code::{binary_to_gray, decode_with_inverse, unwrap_with_blocks};
use slscan::unwrap::pdm::Pdm;
use slscan::unwrap::quality_guided::{unwrap_quality_guided, Seed};
use slscan::unwrap::{AbsolutePhase, PixelStatus};

const TAU: f64 = std::f64::consts::TAU;

fn wrapped(truth: &GroundTruth, period: f64, seed: u64) -> WrappedPhase {
    let frames = synth::render_fringe_set(truth, &[period], 4, true, &light(), seed);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    PhaseShift::new(4).unwrap().wrapped_phase(&refs).unwrap()
}

/// (valid, lit, wrong orders, largest |offset| in orders) against `u_true + offset_px`.
fn score(truth: &GroundTruth, abs: &AbsolutePhase, offset_orders: f64) -> (usize, usize, usize) {
    let (mut valid, mut lit, mut wrong) = (0, 0, 0);
    for i in 0..abs.phase.len() {
        let Some((u, _)) = truth.projector_px.data[i] else {
            continue;
        };
        if truth.shading.data[i] < 0.2 {
            continue;
        }
        lit += 1;
        if abs.status.data[i] == PixelStatus::Valid {
            valid += 1;
            let want = TAU * u / abs.period_px + TAU * offset_orders;
            if (f64::from(abs.phase.data[i]) - want).abs() > std::f64::consts::PI {
                wrong += 1;
            }
        }
    }
    (valid, lit, wrong)
}

#[test]
fn pdm_unwraps_seed_001_periods_on_spheres() {
    let (camera, projector) = rig();
    let truth = synth::trace(&synth::two_spheres(0.5, 0.62), &camera, &projector);
    let periods = [18u32, 21, 23];
    let sets: Vec<WrappedPhase> = periods
        .iter()
        .enumerate()
        .map(|(k, &p)| wrapped(&truth, f64::from(p), 100 + k as u64))
        .collect();
    let pdm = Pdm::new(&periods, 912.0).unwrap();
    // Modulation at which the CRB phase noise reaches PDM's 5-sigma limit.
    let sigma_max = pdm.max_phase_sigma_rad(5.0);
    let b_min = (0.01 * 0.5f64.sqrt() / sigma_max) as f32;
    let min_b = Raster::from_fn(320, 240, |x, y| {
        sets.iter()
            .map(|s| *s.modulation.at(x, y))
            .fold(f32::INFINITY, f32::min)
    });
    let mask = modulation_mask(&min_b, b_min);
    let maps: Vec<&Raster<f32>> = sets.iter().map(|s| &s.phase).collect();
    let abs = pdm.unwrap(&maps, Some(&mask)).unwrap();
    let (valid, lit, wrong) = score(&truth, &abs, 0.0);
    println!(
        "PDM 18/21/23: {valid} valid of {lit} lit, {wrong} wrong orders, {} unreliable (separation {:.4} cycles, needs B >= {b_min:.3} at sigma_I 0.01)",
        abs.count(PixelStatus::Unreliable),
        pdm.separation_cycles()
    );
    assert_eq!(wrong, 0);
    // 18/21/23 sit only 0.0216 cycles from a wrong order: dim pixels are refused.
    assert!(valid as f64 > 0.5 * lit as f64);
}

#[test]
fn gray_code_plus_phase_on_spheres() {
    let (camera, projector) = rig();
    let truth = synth::trace(&synth::two_spheres(0.5, 0.62), &camera, &projector);
    let (period, block) = (20.0, 8u32);
    let bits = 7; // 114 blocks of 8 px over 912 columns
    let bit_of = |u: f64, b: u32| {
        let column = (u + 0.5).floor().max(0.0) as u32; // pixel centres at integers
        (binary_to_gray(column / block) >> (bits - 1 - b)) & 1
    };
    let mut on = Vec::new();
    let mut off = Vec::new();
    for b in 0..bits {
        let seed = 200 + u64::from(b);
        on.push(synth::render(
            &truth,
            |u, _| f64::from(bit_of(u, b)),
            &light(),
            seed,
        ));
        off.push(synth::render(
            &truth,
            |u, _| f64::from(1 - bit_of(u, b)),
            &light(),
            seed + 50,
        ));
    }
    let on_refs: Vec<&Raster<f32>> = on.iter().collect();
    let off_refs: Vec<&Raster<f32>> = off.iter().collect();
    let decoded = decode_with_inverse(&on_refs, &off_refs, 0.1).unwrap();
    let w = wrapped(&truth, period, 300);
    let mask = modulation_mask(&w.modulation, 0.1);
    let abs =
        unwrap_with_blocks(&w.phase, &decoded, f64::from(block), period, Some(&mask)).unwrap();
    let (valid, lit, wrong) = score(&truth, &abs, 0.0);
    println!("Gray + phase: {valid} valid of {lit} lit, {wrong} wrong orders");
    assert_eq!(wrong, 0);
    assert!(valid as f64 > 0.95 * lit as f64);
}

#[test]
fn quality_guided_unwraps_a_plane_up_to_one_constant_order() {
    let (camera, projector) = rig();
    let truth = synth::trace(&tilted_plane(), &camera, &projector);
    let period = 20.0;
    let w = wrapped(&truth, period, 400);
    let seed = Seed {
        at: Some((160, 120)),
        order: 0,
    };
    let abs = unwrap_quality_guided(&w.phase, &w.modulation, 0.1, seed, period).unwrap();
    // The seed's true order fixes the constant the spatial method cannot know.
    let (u0, _) = truth.projector_px.at(160, 120).unwrap();
    let seed_order = ((TAU * u0 / period - f64::from(*w.phase.at(160, 120))) / TAU).round();
    let (valid, lit, wrong) = score(&truth, &abs, -seed_order);
    println!("quality-guided: {valid} valid of {lit} lit, {wrong} wrong orders (seed order {seed_order})");
    assert_eq!(wrong, 0);
    assert!(valid as f64 > 0.99 * lit as f64);
}

#[test]
fn ftp_single_shot_phase_error_on_a_plane() {
    let (camera, projector) = rig();
    let truth = synth::trace(&tilted_plane(), &camera, &projector);
    let period_proj = 20.0;
    let img = synth::render(
        &truth,
        |u, _| 0.5 + 0.5 * (TAU * u / period_proj).cos(),
        &light(),
        500,
    );
    // Camera-side carrier: projector px per camera px along x, measured from the truth.
    let (ua, _) = truth.projector_px.at(100, 120).unwrap();
    let (ub, _) = truth.projector_px.at(220, 120).unwrap();
    let period_cam = period_proj / ((ub - ua) / 120.0);
    let out = ftp_phase(&img, period_cam, FringeAxis::X).unwrap();
    let (mut sum, mut n) = (0.0f64, 0usize);
    for y in 20..220 {
        for x in 40..280 {
            let (u, _) = truth.projector_px.at(x, y).unwrap();
            let e = wrap_pi(*out.phase.at(x, y) - (TAU * u / period_proj) as f32);
            sum += f64::from(e).powi(2);
            n += 1;
        }
    }
    let rms = (sum / n as f64).sqrt();
    let n_step = wrapped(&truth, period_proj, 501);
    let mut sum4 = 0.0f64;
    for y in 20..220 {
        for x in 40..280 {
            let (u, _) = truth.projector_px.at(x, y).unwrap();
            let e = wrap_pi(*n_step.phase.at(x, y) - (TAU * u / period_proj) as f32);
            sum4 += f64::from(e).powi(2);
        }
    }
    let rms4 = (sum4 / n as f64).sqrt();
    println!(
        "FTP (one image, camera period {period_cam:.2} px): RMS phase error {rms:.4} rad; 4-step: {rms4:.4} rad"
    );
    assert!(rms < 0.1, "{rms}");
}
