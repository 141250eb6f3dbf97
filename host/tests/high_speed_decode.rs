//! The analytic high-speed decoder on a formula-rendered multiplexed exposure
//! (synth: two calibration spheres before a plane, every pattern at its exact
//! projector coordinate, Gaussian noise): each of the 24 instants' depth against
//! the traced truth, and the bad inputs it must refuse.

use slscan::calibration::{Head, PinholeModel};
use slscan::highspeed::{Decoder, DecoderConfig, HighSpeedError, PatternSet};
use slscan::raster::Raster;
use slscan::synth::{render, stereo_rig, trace, two_spheres, GroundTruth, Lighting};

const DMD: (u32, u32) = (1280, 800);

fn head(width: u32, height: u32) -> Head {
    let camera = PinholeModel::ideal(width, height, 833.0 * f64::from(width) / 640.0);
    let mut projector = PinholeModel::ideal(DMD.0, DMD.1, 1203.0);
    projector.intrinsics.cy = 0.5 * f64::from(DMD.1);
    let (camera, projector) = stereo_rig(camera, projector, 0.12, 0.5);
    Head {
        name: "A".into(),
        camera,
        projector,
        view_errors: vec![],
        port: None,
    }
}

/// Each LED's eight patterns summed in one exposure, scaled so the brightest
/// possible pixel stays below full scale.
fn exposure(set: &PatternSet, truth: &GroundTruth, noise: f32, seed: u64) -> [Raster<f32>; 3] {
    let lighting = Lighting {
        ambient: 0.03,
        gain: 0.9,
        noise_sigma: noise,
    };
    [0, 1, 2].map(|c| {
        let pats: Vec<_> = set
            .patterns()
            .iter()
            .filter(|p| p.colour == c)
            .copied()
            .collect();
        let n = pats.len() as f64;
        render(
            truth,
            |u, v| {
                pats.iter()
                    .map(|p| 0.5 + 0.5 * PatternSet::phase_at(p, u, v).cos())
                    .sum::<f64>()
                    / n
            },
            &lighting,
            seed + c as u64,
        )
    })
}

fn scene(width: u32, height: u32) -> (Head, GroundTruth) {
    let head = head(width, height);
    let truth = trace(&two_spheres(0.5, 0.6), &head.camera, &head.projector);
    (head, truth)
}

#[test]
fn each_instant_lands_on_the_traced_surface() {
    let (head, truth) = scene(320, 240);
    let set = PatternSet::seed001(DMD).unwrap();
    let planes = exposure(&set, &truth, 0.002, 7);
    let decoder = Decoder::new(set.clone(), &head, DecoderConfig::default()).unwrap();
    let out = decoder
        .decode([&planes[0], &planes[1], &planes[2]])
        .unwrap();
    assert_eq!(out.instants.len(), 24);
    let (mut lit, mut decoded, mut right, mut sq) = (0usize, 0usize, 0usize, 0.0f64);
    let mut abs_um: Vec<f64> = Vec::new();
    let mut wrapped_err = 0.0f64;
    for instant in &out.instants {
        let p = &instant.pattern;
        for i in 0..truth.point_m.data.len() {
            let (Some((u, v)), Some(point)) = (truth.projector_px.data[i], truth.point_m.data[i])
            else {
                continue;
            };
            lit += 1;
            let phase = PatternSet::phase_at(p, u, v);
            let w = f64::from(out.fringes.wrapped[p.index][i]) - phase;
            wrapped_err += (w - std::f64::consts::TAU * (w / std::f64::consts::TAU).round()).abs();
            let a = instant.absolute_phase[i];
            if !a.is_finite() {
                continue;
            }
            decoded += 1;
            if (f64::from(a) - phase).abs() < std::f64::consts::PI {
                right += 1;
                let e = f64::from(instant.depth_m[i]) - point.z;
                sq += e * e;
                abs_um.push(1e6 * e.abs());
            }
        }
    }
    let mae = wrapped_err / lit as f64;
    let coverage = decoded as f64 / lit as f64;
    let right_share = right as f64 / decoded as f64;
    let rmse_um = 1e6 * (sq / right as f64).sqrt();
    abs_um.sort_by(f64::total_cmp);
    let median_um = abs_um[abs_um.len() / 2];
    let p95_um = abs_um[abs_um.len() * 95 / 100];
    println!(
        "320x240 synth, two spheres + plane, noise 0.002: wrapped-phase MAE {mae:.4} rad, \
         decoded {coverage:.3} of lit, unwrapped right {right_share:.4}, depth RMSE {rmse_um:.1} um, \
         median {median_um:.1} um, 95th percentile {p95_um:.1} um"
    );
    assert!(mae < 0.15, "wrapped-phase MAE {mae}");
    assert!(coverage > 0.8, "coverage {coverage}");
    assert!(right_share > 0.99, "right share {right_share}");
    assert!(median_um < 1000.0, "median depth error {median_um} um");
    assert!(rmse_um < 2500.0, "depth RMSE {rmse_um} um");
}

#[test]
fn bad_exposures_are_refused_with_what_is_wrong() {
    let (head, truth) = scene(96, 72);
    let set = PatternSet::seed001(DMD).unwrap();
    let decoder = Decoder::new(set.clone(), &head, DecoderConfig::default()).unwrap();
    let planes = exposure(&set, &truth, 0.0, 1);
    // Wrong size.
    let small = Raster::filled(64, 72, 0.2f32);
    let err = decoder
        .decode([&small, &planes[1], &planes[2]])
        .unwrap_err();
    assert!(
        matches!(err, HighSpeedError::WrongSize { got: (64, 72), .. }),
        "{err}"
    );
    // A NaN.
    let mut nan = planes[1].clone();
    nan.data[10] = f32::NAN;
    assert!(matches!(
        decoder.decode([&planes[0], &nan, &planes[2]]),
        Err(HighSpeedError::NotFinite)
    ));
    // Saturated: a quarter of the image clipped.
    let mut clipped = planes[0].clone();
    let n = clipped.data.len() / 4;
    clipped.data[..n].iter_mut().for_each(|v| *v = 1.0);
    let err = decoder
        .decode([&clipped, &planes[1], &planes[2]])
        .unwrap_err();
    assert!(err.to_string().contains("saturated"), "{err}");
    // A set made for another DMD.
    let other = PatternSet::seed001((912, 1140)).unwrap();
    let err = Decoder::new(other, &head, DecoderConfig::default())
        .err()
        .unwrap();
    assert!(err.to_string().contains("912x1140"), "{err}");
    // A depth range that is not one.
    let config = DecoderConfig {
        depth_range_m: (0.6, 0.4),
        ..DecoderConfig::default()
    };
    assert!(matches!(
        Decoder::new(set, &head, config),
        Err(HighSpeedError::BadConfig { .. })
    ));
}
