//! Unit tests of the classical restorer (beside it, to keep `restore.rs` short).

use super::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A vertical fringe of `period_px` on two albedos (a step at a third of the width).
fn fringe(w: usize, h: usize, period_px: f32, shift_rad: f32) -> Raster<f32> {
    Raster::from_fn(w, h, |x, _| {
        let albedo = if x < w / 3 { 0.5 } else { 0.9 };
        let t = std::f32::consts::TAU * x as f32 / period_px + shift_rad;
        0.4 * albedo * (1.0 + t.cos())
    })
}

/// Reference blur: sampled unit-sum Gaussian, separable, mirrored borders.
fn blur_reference(img: &Raster<f32>, sigma_px: f64) -> Raster<f32> {
    let r = (4.0 * sigma_px).ceil() as i64;
    let k: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma_px * sigma_px)).exp())
        .collect();
    let sum: f64 = k.iter().sum();
    let (w, h) = img.size();
    let mirror = |i: i64, n: usize| -> usize {
        let n = n as i64;
        let m = i.rem_euclid(2 * n);
        (if m < n { m } else { 2 * n - 1 - m }) as usize
    };
    let pass = |src: &Raster<f32>, horizontal: bool| {
        Raster::from_fn(w, h, |x, y| {
            let mut acc = 0.0;
            for (j, kv) in k.iter().enumerate() {
                let d = j as i64 - r;
                let v = if horizontal {
                    *src.at(mirror(x as i64 + d, w), y)
                } else {
                    *src.at(x, mirror(y as i64 + d, h))
                };
                acc += kv * f64::from(v);
            }
            (acc / sum) as f32
        })
    };
    pass(&pass(img, true), false)
}

fn add_noise(img: &mut Raster<f32>, sigma: f32, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let normal = Normal::new(0.0, sigma).unwrap();
    img.data
        .iter_mut()
        .for_each(|v| *v += normal.sample(&mut rng));
}

/// RMS error after the best gain and offset (what the figures compare).
fn affine_rms(est: &Raster<f32>, truth: &Raster<f32>) -> f64 {
    let pairs: Vec<(f64, f64)> = est
        .data
        .iter()
        .zip(&truth.data)
        .filter(|(e, _)| e.is_finite())
        .map(|(&e, &t)| (f64::from(e), f64::from(t)))
        .collect();
    let n = pairs.len() as f64;
    let (me, mt) = pairs
        .iter()
        .fold((0.0, 0.0), |(a, b), (e, t)| (a + e / n, b + t / n));
    let (cov, var) = pairs.iter().fold((0.0, 0.0), |(c, v), (e, t)| {
        (c + (e - me) * (t - mt), v + (e - me) * (e - me))
    });
    let gain = cov / var;
    let sse: f64 = pairs
        .iter()
        .map(|(e, t)| (gain * (e - me) + mt - t).powi(2))
        .sum();
    (sse / n).sqrt()
}

#[test]
fn a_blurred_veiled_fringe_comes_back_sharper() {
    let (w, h) = (96, 64);
    let clean = fringe(w, h, 16.0, 0.3);
    let mut seen = blur_reference(&clean, 3.0);
    seen.data.iter_mut().for_each(|v| *v = 0.6 * *v + 0.15);
    add_noise(&mut seen, 0.002, 7);
    let mut params = RestoreParams::new(3.0);
    params.veil_block_px = 32;
    let out = restore_classical(&seen, &params, Veil::Floor).unwrap();
    let (before, after) = (affine_rms(&seen, &clean), affine_rms(&out.image, &clean));
    assert!(
        after < 0.5 * before,
        "RMS after gain/offset: degraded {before:.4}, restored {after:.4}"
    );
    // The veil (0.15) is removed: the restored troughs sit near zero.
    let floor = out.veil.data.iter().sum::<f32>() / out.veil.len() as f32;
    assert!((floor - 0.15).abs() < 0.03, "floor {floor}");
}

#[test]
fn one_veil_per_set_keeps_the_phase() {
    // A four-step set, blurred, under a veil, with the ambient light of a
    // dark frame: one veil for all four frames leaves the restored set's
    // wrapped phase as it was without it, and the veil found above the
    // dark frame is the veil.
    let (w, h) = (96, 64);
    let ambient = 0.05f32;
    let frames: Vec<Raster<f32>> = (0..4)
        .map(|n| {
            let shift = std::f32::consts::FRAC_PI_2 * n as f32;
            let mut f = blur_reference(&fringe(w, h, 16.0, shift), 2.0);
            f.data.iter_mut().for_each(|v| *v += 0.1 + ambient);
            f
        })
        .collect();
    let dark = Raster::filled(w, h, ambient);
    let mut params = RestoreParams::new(2.0);
    params.veil_block_px = 32;
    params.veil_percentile = 0.0;
    let r = ClassicalRestorer::new(w, h, params).unwrap();
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let out = r.restore_set(&refs, Veil::AboveDark(&dark)).unwrap();
    let kept = r.restore_set(&refs, Veil::Keep).unwrap();
    let phase = |f: &[&Raster<f32>], i: usize| {
        (f[3].data[i] - f[1].data[i]).atan2(f[0].data[i] - f[2].data[i])
    };
    let restored: Vec<&Raster<f32>> = out.iter().map(|o| &o.image).collect();
    let unveiled: Vec<&Raster<f32>> = kept.iter().map(|o| &o.image).collect();
    let pi = std::f32::consts::PI;
    let worst = (0..w * h)
        .map(|i| (phase(&restored, i) - phase(&unveiled, i) + pi).rem_euclid(2.0 * pi) - pi)
        .fold(0.0f32, |m, d| m.max(d.abs()));
    assert!(worst < 1e-4, "phase moved by {worst} rad");
    let veil = out[0].veil.data.iter().sum::<f32>() / (w * h) as f32;
    assert!((veil - 0.1).abs() < 0.02, "veil {veil}");
    assert!(out.iter().all(|o| o.veil == out[0].veil));
}

#[test]
fn flagged_pixels_come_out_nan_and_only_they() {
    let (w, h) = (48, 40);
    let mut img = blur_reference(&fringe(w, h, 12.0, 0.0), 1.5);
    img.data[5 * w + 7] = f32::NAN;
    img.data[20 * w + 30] = 1.0;
    img.data[30 * w + 2] = f32::INFINITY;
    let out = restore_classical(&img, &RestoreParams::new(1.5), Veil::Floor).unwrap();
    assert_eq!(out.masked, 3);
    for (i, v) in out.image.data.iter().enumerate() {
        let flagged = [5 * w + 7, 20 * w + 30, 30 * w + 2].contains(&i);
        assert_eq!(v.is_nan(), flagged, "pixel {i}: {v}");
    }
}

#[test]
fn bad_input_is_a_typed_error() {
    let img = Raster::filled(16, 16, 0.5f32);
    for sigma in [-1.0, f64::NAN, f64::INFINITY, 40.0] {
        assert!(matches!(
            restore_classical(&img, &RestoreParams::new(sigma), Veil::Keep),
            Err(RestoreError::BadPsfSigma { .. })
        ));
    }
    let p = RestoreParams::new(2.0);
    let nan = Raster::filled(16, 16, f32::NAN);
    assert_eq!(
        restore_classical(&nan, &p, Veil::Floor),
        Err(RestoreError::NoValidPixels { pixels: 256 })
    );
    let short = Raster {
        width: 16,
        height: 16,
        data: vec![0.5; 255],
    };
    assert!(matches!(
        restore_classical(&short, &p, Veil::Floor),
        Err(RestoreError::BufferSize { len: 255, .. })
    ));
    assert!(matches!(
        restore_classical(&Raster::filled(4, 16, 0.5), &p, Veil::Floor),
        Err(RestoreError::TooSmall { .. })
    ));
    let r = ClassicalRestorer::new(16, 16, p).unwrap();
    assert_eq!(
        r.restore(&Raster::filled(16, 20, 0.5), Veil::Floor),
        Err(RestoreError::SizeMismatch {
            expected: (16, 16),
            got: (16, 20)
        })
    );
    assert_eq!(r.restore_set(&[], Veil::Keep), Err(RestoreError::NoFrames));
    let wrong_dark = Raster::filled(8, 8, 0.0f32);
    assert!(matches!(
        r.restore(&img, Veil::AboveDark(&wrong_dark)),
        Err(RestoreError::SizeMismatch { .. })
    ));
    let mut q = p;
    q.noise_to_signal = 0.0;
    assert!(matches!(
        q.validate(),
        Err(RestoreError::BadParameter {
            name: "noise_to_signal",
            ..
        })
    ));
    q = p;
    q.veil_percentile = 70.0;
    assert!(q.validate().is_err());
}

#[test]
fn no_blur_no_noise_keeps_the_fringe() {
    let clean = fringe(64, 48, 16.0, 1.0);
    let out = restore_classical(&clean, &RestoreParams::new(0.0), Veil::Keep).unwrap();
    // K = 0.03 with H = 1: the gain is exactly 1.
    let worst = out
        .image
        .data
        .iter()
        .zip(&clean.data)
        .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
    assert!(worst < 1e-5, "{worst}");
}
