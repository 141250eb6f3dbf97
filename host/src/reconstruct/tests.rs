//! The one-pass reconstruction against its staged reference: typed errors, every SIMD build, bad samples, per-pixel noise, integer frames.

use super::*;
use crate::calibration::PinholeModel;
use crate::synth;

/// Fringe periods of the small rig's frames, projector pixels.
const PERIODS: [f64; 3] = [9.0, 10.0, 11.0];

/// The two calibration spheres seen by the small rig in 4-step fringes of [`PERIODS`]
/// along projector columns (or rows), noise seeded by `seed`.
fn sphere_frames(
    camera: &CameraModel,
    projector: &ProjectorModel,
    columns: bool,
    seed: u64,
) -> Vec<Raster<f32>> {
    let truth = synth::trace(&synth::two_spheres(0.5, 0.6), camera, projector);
    let light = synth::Lighting {
        ambient: 0.1,
        gain: 0.7,
        noise_sigma: 0.005,
    };
    synth::render_fringe_set(&truth, &PERIODS, 4, columns, &light, seed)
}

/// Every map's bits (NaNs compare equal, unlike `PartialEq` on the floats).
fn map_bits(r: &Reconstruction) -> Vec<u32> {
    let m = &r.pixels;
    let floats = [
        &m.phase_u,
        &m.depth_m,
        &m.sigma_m,
        &m.modulation,
        &m.background,
    ];
    let status = m.status.iter().map(|&s| s as u32);
    floats
        .into_iter()
        .chain(&m.point_m)
        .flat_map(|v| v.iter().map(|x| x.to_bits()))
        .chain(status)
        .collect()
}

fn small_rig() -> (CameraModel, ProjectorModel) {
    synth::stereo_rig(
        PinholeModel::ideal(64, 48, 160.0),
        PinholeModel::ideal(228, 285, 450.0),
        0.15,
        0.5,
    )
}

#[test]
fn fused_and_staged_agree_and_errors_are_typed() {
    let (camera, projector) = small_rig();
    let frames = sphere_frames(&camera, &projector, true, 7);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let rec =
        Reconstructor::new(&camera, &projector, ReconstructConfig::new(PERIODS.into())).unwrap();
    let fused = rec.reconstruct(&refs, None).unwrap();
    let (staged, _) = rec.reconstruct_staged(&refs).unwrap();
    assert!(fused.cloud.len() > 500, "{}", fused.cloud.len());
    assert_eq!(fused.cloud, staged.cloud);
    assert!(map_bits(&fused) == map_bits(&staged), "staged maps differ");
    // Reusing the buffers of another capture's result gives the same result.
    let other = sphere_frames(&camera, &projector, true, 8);
    let other: Vec<&Raster<f32>> = other.iter().collect();
    let mut reused = rec.reconstruct(&other, None).unwrap();
    assert_ne!(reused.cloud, fused.cloud);
    rec.reconstruct_into(&refs, None, &mut reused).unwrap();
    assert_eq!(reused.cloud, fused.cloud);
    assert!(map_bits(&reused) == map_bits(&fused), "reused maps differ");
    assert_eq!(reused.status(), fused.status());

    assert!(matches!(
        rec.reconstruct(&refs[..11], None),
        Err(ReconstructError::FrameCount {
            expected: 12,
            got: 11,
            ..
        })
    ));
    assert!(matches!(
        rec.reconstruct(&refs, Some(&refs)),
        Err(ReconstructError::RowFrames { .. })
    ));
    let small = Raster::filled(32, 24, 0.5f32);
    let wrong: Vec<&Raster<f32>> = vec![&small; 12];
    assert!(matches!(
        rec.reconstruct(&wrong, None),
        Err(ReconstructError::CameraSize { .. })
    ));
}

#[test]
fn every_simd_build_gives_the_same_bits() {
    // A distorted projector, so the Newton path is compared too.
    let (camera, mut projector) = small_rig();
    projector.distortion.k1 = 0.03;
    projector.distortion.p1 = 3e-4;
    let frames = sphere_frames(&camera, &projector, true, 3);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let rec =
        Reconstructor::new(&camera, &projector, ReconstructConfig::new(PERIODS.into())).unwrap();
    let best = rec.clone().with_simd(Simd::best());
    let baseline = rec.with_simd(Simd::Baseline);
    let (a, b) = (
        best.reconstruct(&refs, None).unwrap(),
        baseline.reconstruct(&refs, None).unwrap(),
    );
    assert!(a.cloud.len() > 500, "{}", a.cloud.len());
    assert!(map_bits(&a) == map_bits(&b), "maps differ");
    assert_eq!(a.cloud, b.cloud);
    // Both directions (the two-ray row path) too.
    let rows = sphere_frames(&camera, &projector, false, 4);
    let rows: Vec<&Raster<f32>> = rows.iter().collect();
    let mut config = ReconstructConfig::new(PERIODS.into());
    config.directions = Directions::Both;
    let rec = Reconstructor::new(&camera, &projector, config).unwrap();
    let (a, b) = (
        rec.clone()
            .with_simd(Simd::best())
            .reconstruct(&refs, Some(&rows)),
        rec.with_simd(Simd::Baseline)
            .reconstruct(&refs, Some(&rows)),
    );
    let (a, b) = (a.unwrap(), b.unwrap());
    assert!(a.cloud.len() > 500, "{}", a.cloud.len());
    assert!(map_bits(&a) == map_bits(&b), "two-ray maps differ");
}

#[test]
fn nan_and_infinite_samples_are_masked_not_triangulated() {
    let (camera, projector) = small_rig();
    let mut columns = sphere_frames(&camera, &projector, true, 7);
    let mut rows = sphere_frames(&camera, &projector, false, 8);
    // A patch of corrupt samples in one frame of each direction.
    let patch: Vec<usize> = (10..20)
        .flat_map(|y| (20..30).map(move |x| y * 64 + x))
        .collect();
    for &i in &patch {
        columns[5].data[i] = f32::NAN;
        rows[2].data[i] = if i % 2 == 0 { f32::INFINITY } else { f32::NAN };
    }
    let (cu, cv): (Vec<&Raster<f32>>, Vec<&Raster<f32>>) =
        (columns.iter().collect(), rows.iter().collect());
    for both in [false, true] {
        let mut config = ReconstructConfig::new(PERIODS.into());
        if both {
            config.directions = Directions::Both;
        }
        let rec = Reconstructor::new(&camera, &projector, config).unwrap();
        let out = rec.reconstruct(&cu, both.then_some(&cv[..])).unwrap();
        for &i in &patch {
            let p = out.pixels.get(i);
            assert_eq!(
                p.status,
                PixelStatus::Masked,
                "both={both} pixel {i}: {p:?}"
            );
            assert!(p.point_m[0].is_nan() && p.sigma_m.is_nan());
        }
        assert!(out.cloud.len() > 500, "both={both}: {}", out.cloud.len());
        assert!(out.cloud.points_m.iter().flatten().all(|v| v.is_finite()));
        assert!(out
            .cloud
            .quality_m
            .as_ref()
            .unwrap()
            .iter()
            .all(|v| v.is_finite()));
    }
}

#[test]
fn shot_noise_makes_each_points_sigma_follow_its_level() {
    let (camera, projector) = small_rig();
    let frames = sphere_frames(&camera, &projector, true, 7);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let mut config = ReconstructConfig::new(PERIODS.into());
    let run = |config: &ReconstructConfig| {
        Reconstructor::new(&camera, &projector, config.clone())
            .unwrap()
            .reconstruct(&refs, None)
            .unwrap()
    };
    let flat = run(&config);
    config.shot_noise_share = 0.5;
    let shot = run(&config);
    // The same points; each sigma scaled by sqrt(1 - s + 2 s A) at its level A.
    let mut compared = 0;
    for (a, b) in flat.pixels.iter().zip(shot.pixels.iter()) {
        assert_eq!(a.status, b.status);
        if a.status == PixelStatus::Valid {
            let want = a.sigma_m * (0.5 + a.background.max(0.0)).sqrt();
            assert!((b.sigma_m - want).abs() <= 1e-6 * want, "{b:?} vs {want}");
            assert!(
                b.background < 0.5 && b.sigma_m < a.sigma_m,
                "dim pixels: less noise"
            );
            compared += 1;
        }
    }
    assert!(compared > 500, "{compared}");
    for bad in [1.5, -0.1, f32::NAN] {
        config.shot_noise_share = bad;
        assert!(matches!(
            Reconstructor::new(&camera, &projector, config.clone()),
            Err(ReconstructError::ShotNoiseShare(_))
        ));
    }
}

#[test]
fn integer_frames_give_the_float_result() {
    let (camera, projector) = small_rig();
    let frames = sphere_frames(&camera, &projector, true, 7);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let config = ReconstructConfig::new(PERIODS.into());
    let rec = Reconstructor::new(&camera, &projector, config.clone()).unwrap();
    let want = rec.reconstruct(&refs, None).unwrap();
    // 12-bit samples in u16 words, and 8-bit ones, quantised from the same frames.
    let quantise = |scale: f32| -> Vec<Raster<u16>> {
        frames
            .iter()
            .map(|f| Raster {
                width: f.width,
                height: f.height,
                data: f.data.iter().map(|&v| (v * scale + 0.5) as u16).collect(),
            })
            .collect()
    };
    let q12 = quantise(4095.0);
    let mut c12 = config.clone();
    c12.full_scale = Some(4095.0);
    let rec12 = Reconstructor::new(&camera, &projector, c12).unwrap();
    let r12: Vec<&Raster<u16>> = q12.iter().collect();
    let got = rec12.reconstruct(&r12, None).unwrap();
    let (staged, _) = rec12.reconstruct_staged(&r12).unwrap();
    assert_eq!(got.cloud, staged.cloud);
    let q8: Vec<Raster<u8>> = quantise(255.0)
        .into_iter()
        .map(|f| Raster {
            width: f.width,
            height: f.height,
            data: f.data.iter().map(|&v| v as u8).collect(),
        })
        .collect();
    let r8: Vec<&Raster<u8>> = q8.iter().collect();
    let got8 = rec.reconstruct(&r8, None).unwrap();
    for (out, tol_m) in [(&got, 2e-4f32), (&got8, 3e-3)] {
        let mut compared = 0;
        for (a, b) in out.pixels.iter().zip(want.pixels.iter()) {
            if a.status == PixelStatus::Valid && b.status == PixelStatus::Valid {
                assert!(
                    (a.depth_m - b.depth_m).abs() < tol_m,
                    "{} vs {}",
                    a.depth_m,
                    b.depth_m
                );
                assert!((a.background - b.background).abs() < 3e-3);
                compared += 1;
            }
        }
        assert!(
            compared * 100 > want.cloud.len() * 98,
            "{compared} of {}",
            want.cloud.len()
        );
    }
}
