//! The analytic high-speed decoder on a formula-rendered multiplexed exposure
//! (synth: two calibration spheres before a plane, every pattern at its exact
//! projector coordinate, Gaussian noise): each of the 24 instants' depth against
//! the traced truth, and the bad inputs it must refuse (exposures, sets, and
//! ZOCR-Nets that do not fit).

use std::path::{Path, PathBuf};

use slscan::calibration::Head;
use slscan::highspeed::learned::set_periods;
use slscan::highspeed::{Decoder, DecoderConfig, FddNet, HighSpeedError, PatternSet, ZocrNet};
use slscan::raster::Raster;
use slscan::simd::Simd;
use slscan::synth::high_speed::{high_speed_exposure, high_speed_head};
use slscan::synth::{trace, two_spheres, GroundTruth};

const DMD: (u32, u32) = (1280, 800);

fn scene(width: u32, height: u32) -> (Head, GroundTruth) {
    let head = high_speed_head(width, height, DMD);
    let truth = trace(&two_spheres(0.5, 0.6), &head.camera, &head.projector);
    (head, truth)
}

/// The single demodulation (the default) and one pass of sibling
/// cancellation: measured 0.0852 / 0.0735 rad, decoded 0.958 / 0.959,
/// right 0.9926 / 0.9934, depth RMSE 1,690 / 1,393 um, median 110.5 /
/// 43.8 um.
#[test]
fn each_instant_lands_on_the_traced_surface() {
    for cancellations in [0, 1] {
        each_instant_lands_on_the_traced_surface_with(cancellations);
    }
}

fn each_instant_lands_on_the_traced_surface_with(cancellations: u32) {
    let (head, truth) = scene(320, 240);
    let set = PatternSet::seed001(DMD).unwrap();
    let planes = high_speed_exposure(&set, &truth, 0.002, 7);
    let mut config = DecoderConfig::default();
    config.demux.cancellations = cancellations;
    let decoder = Decoder::new(set.clone(), &head, config).unwrap();
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
        "320x240 synth, two spheres + plane, noise 0.002, {cancellations} sibling cancellation pass(es): wrapped-phase MAE {mae:.4} rad, \
         decoded {coverage:.3} of lit, unwrapped right {right_share:.4}, depth RMSE {rmse_um:.1} um, \
         median {median_um:.1} um, 95th percentile {p95_um:.1} um"
    );
    assert!(mae < 0.15, "wrapped-phase MAE {mae}");
    assert!(coverage > 0.8, "coverage {coverage}");
    assert!(right_share > 0.99, "right share {right_share}");
    assert!(median_um < 1000.0, "median depth error {median_um} um");
    assert!(rmse_um < 2500.0, "depth RMSE {rmse_um} um");
}

/// The per-pixel demultiplexing and unwrapping built for AVX2 (rounding as
/// instructions, 8 lanes) and for baseline x86-64 (libm calls) give the same bits.
#[test]
fn both_builds_of_the_unwrapping_give_the_same_bits() {
    let (head, truth) = scene(160, 120);
    let set = PatternSet::seed001(DMD).unwrap();
    let planes = high_speed_exposure(&set, &truth, 0.002, 11);
    let decode = |simd: Simd| {
        let config = DecoderConfig {
            simd,
            ..DecoderConfig::default()
        };
        Decoder::new(set.clone(), &head, config)
            .unwrap()
            .decode([&planes[0], &planes[1], &planes[2]])
            .unwrap()
    };
    let (baseline, avx2) = (decode(Simd::Baseline), decode(Simd::Avx2));
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let mut decoded = 0;
    for (a, b) in baseline.instants.iter().zip(&avx2.instants) {
        assert_eq!(bits(&a.absolute_phase), bits(&b.absolute_phase));
        assert_eq!(bits(&a.depth_m), bits(&b.depth_m));
        decoded += a.depth_m.iter().filter(|d| d.is_finite()).count();
    }
    assert!(decoded > 10_000, "only {decoded} depths to compare");
}

#[test]
fn fewer_epipolar_samples_where_the_chords_allow_give_the_same_orders_and_depths() {
    let (head, truth) = scene(160, 120);
    let set = PatternSet::seed001(DMD).unwrap();
    let planes = high_speed_exposure(&set, &truth, 0.002, 5);
    let decoder = |max_chord_px: f64| {
        let config = DecoderConfig {
            max_chord_px,
            ..DecoderConfig::default()
        };
        Decoder::new(set.clone(), &head, config).unwrap()
    };
    // A tolerance no chord meets keeps every sample the config allows.
    let (few, all) = (decoder(0.05), decoder(1e-12));
    assert_eq!(all.samples(), DecoderConfig::default().samples);
    assert!(few.samples() < all.samples(), "{} samples", few.samples());
    let (n_few, n_all) = (few.samples(), all.samples());
    let [a, b] = [few, all].map(|d| d.decode([&planes[0], &planes[1], &planes[2]]).unwrap());
    let (mut both, mut only_one, mut worst_um) = (0usize, 0usize, 0.0f64);
    for (x, y) in a.instants.iter().zip(&b.instants) {
        for i in 0..x.depth_m.len() {
            match (x.depth_m[i].is_finite(), y.depth_m[i].is_finite()) {
                (true, true) => {
                    both += 1;
                    assert_eq!(x.absolute_phase[i], y.absolute_phase[i], "pixel {i}");
                    let d = 1e6 * f64::from((x.depth_m[i] - y.depth_m[i]).abs());
                    worst_um = worst_um.max(d);
                }
                (false, false) => {}
                _ => only_one += 1,
            }
        }
    }
    println!(
        "{n_few} against {n_all} samples: {both} depths in both, {only_one} in one only, largest difference {worst_um:.3} um"
    );
    assert!(both > 10_000, "only {both} depths to compare");
    assert!(
        only_one * 1000 < both,
        "{only_one} of {both} decoded by one only"
    );
    assert!(worst_um < 1.0, "depths differ by up to {worst_um} um");
}

#[test]
fn bad_exposures_are_refused_with_what_is_wrong() {
    let (head, truth) = scene(96, 72);
    let set = PatternSet::seed001(DMD).unwrap();
    let decoder = Decoder::new(set.clone(), &head, DecoderConfig::default()).unwrap();
    let planes = high_speed_exposure(&set, &truth, 0.0, 1);
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
        Decoder::new(set.clone(), &head, config),
        Err(HighSpeedError::BadConfig { .. })
    ));
    // Sample counts and chord tolerances that are not ones.
    for (samples, max_chord_px) in [(1, 0.05), (65, 0.05), (16, 0.0), (16, f64::NAN)] {
        let config = DecoderConfig {
            samples,
            max_chord_px,
            ..DecoderConfig::default()
        };
        assert!(
            matches!(
                Decoder::new(set.clone(), &head, config),
                Err(HighSpeedError::BadConfig { .. })
            ),
            "{samples} samples within {max_chord_px} px"
        );
    }
}

/// `models/NAME.onnx` and its metadata copied into a scratch folder, the
/// metadata changed by `edit`; returns the copy's ONNX path.
fn edited_model(name: &str, tag: &str, edit: impl Fn(&mut serde_json::Value)) -> PathBuf {
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models");
    let dir = std::env::temp_dir().join(format!("slscan-zocr-{}-{tag}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let onnx = dir.join("net.onnx");
    std::fs::copy(models.join(format!("{name}.onnx")), &onnx).unwrap();
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(models.join(format!("{name}.json"))).unwrap())
            .unwrap();
    edit(&mut meta);
    std::fs::write(dir.join("net.json"), meta.to_string()).unwrap();
    onnx
}

#[test]
fn a_zocr_net_that_does_not_fit_the_set_is_refused_at_load() {
    let set = PatternSet::seed001(DMD).unwrap();
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/highspeed_zocr.onnx");
    ZocrNet::load(&shipped, &set).expect("the shipped ZOCR-Net fits seed 001's set");
    // Trained for other periods.
    let other = edited_model("highspeed_zocr", "periods", |m| {
        m["periods_px"][0] = serde_json::json!(m["periods_px"][0].as_f64().unwrap() * 1.1);
    });
    let err = ZocrNet::load(&other, &set).unwrap_err();
    assert!(
        matches!(err, HighSpeedError::BadPatternSet { .. })
            && err.to_string().contains("trained for pattern periods"),
        "{err}"
    );
    // Another network (the underwater restorer, 5 -> 4 channels) with this
    // set's periods written into its metadata.
    let periods = set_periods(&set);
    let underwater = edited_model("underwater_onestep", "channels", |m| {
        m["periods_px"] = serde_json::json!(periods);
        m["steps_per_period"] = serde_json::json!(1);
    });
    let err = ZocrNet::load(&underwater, &set).unwrap_err();
    assert!(
        matches!(err, HighSpeedError::BadConfig { .. }) && err.to_string().contains("5 -> 4"),
        "{err}"
    );
    // A truncated file.
    let truncated = edited_model("highspeed_zocr", "truncated", |_| {});
    let bytes = std::fs::read(&truncated).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let err = ZocrNet::load(&truncated, &set).unwrap_err();
    assert!(matches!(err, HighSpeedError::Model(_)), "{err}");
    assert!(err.to_string().contains("net.onnx"), "{err}");
    for path in [other, underwater, truncated] {
        std::fs::remove_dir_all(path.parent().unwrap()).unwrap();
    }
}

/// FDD-Net learnt the single-pass demodulation's errors: a decoder that
/// refines its demodulation or cancels siblings refuses it, with the reason.
#[test]
fn an_fdd_net_is_refused_by_a_refining_or_cancelling_decoder() {
    let set = PatternSet::seed001(DMD).unwrap();
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/highspeed_fdd.onnx");
    let net = FddNet::load(&shipped, &set).unwrap();
    let head = high_speed_head(64, 48, DMD);
    let decoder = |refinements, cancellations| {
        let mut config = DecoderConfig::default();
        config.demux.refinements = refinements;
        config.demux.cancellations = cancellations;
        Decoder::new(set.clone(), &head, config).unwrap()
    };
    assert!(decoder(0, 0).with_fdd(net.clone()).is_ok());
    for (refinements, cancellations, why) in [
        (1, 0, "refines them 1 time(s)"),
        (0, 1, "cancels siblings 1 time(s)"),
    ] {
        let err = decoder(refinements, cancellations)
            .with_fdd(net.clone())
            .err()
            .expect("refused");
        assert!(
            matches!(err, HighSpeedError::BadConfig { .. }) && err.to_string().contains(why),
            "{err}"
        );
    }
}

#[test]
fn an_fdd_net_that_does_not_fit_the_set_is_refused_at_load() {
    let set = PatternSet::seed001(DMD).unwrap();
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/highspeed_fdd.onnx");
    FddNet::load(&shipped, &set).expect("the shipped FDD-Net fits seed 001's set");
    let other = edited_model("highspeed_fdd", "fdd-periods", |m| {
        m["periods_px"][5] = serde_json::json!(m["periods_px"][5].as_f64().unwrap() * 0.9);
    });
    let err = FddNet::load(&other, &set).unwrap_err();
    assert!(
        matches!(err, HighSpeedError::BadPatternSet { .. })
            && err.to_string().contains("trained for pattern periods"),
        "{err}"
    );
    // ZOCR-Net, trained for the same set, is not a third stage.
    let zocr = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/highspeed_zocr.onnx");
    let err = FddNet::load(&zocr, &set).unwrap_err();
    assert!(
        matches!(err, HighSpeedError::BadConfig { .. }) && err.to_string().contains("3 -> 6"),
        "{err}"
    );
    std::fs::remove_dir_all(other.parent().unwrap()).unwrap();
}

/// Mean absolute wrapped-phase error of all 24 patterns against the traced truth.
fn wrapped_mae(truth: &GroundTruth, set: &PatternSet, wrapped: &[Vec<f32>]) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for p in set.patterns() {
        for (i, uv) in truth.projector_px.data.iter().enumerate() {
            let (Some((u, v)), w) = (uv, wrapped[p.index][i]) else {
                continue;
            };
            if w.is_finite() {
                let e = f64::from(w) - PatternSet::phase_at(p, *u, *v);
                sum += (e - std::f64::consts::TAU * (e / std::f64::consts::TAU).round()).abs();
                n += 1;
            }
        }
    }
    sum / n.max(1) as f64
}

/// A consensus pass whose holes at the spheres' outlines are settled on the
/// surface that explains their fringes (`settle_edges`) against one that
/// fills them smoothly, and the ceiling of both: a pass on the traced depth.
/// Measured: single pass 0.0852, consensus pass 0.0580, settled 0.0514, on
/// the true depth 0.0334 rad (settled 0.0565 with the first version's
/// candidates, the nearest and farthest in a square; 0.0534 with the
/// closest surface each way as a constant, not extrapolated).
#[test]
fn settled_edges_and_the_true_depth_bring_the_consensus_pass_closer_to_the_truth() {
    let (head, truth) = scene(320, 240);
    let set = PatternSet::seed001(DMD).unwrap();
    let planes = high_speed_exposure(&set, &truth, 0.002, 7);
    let channels = [&planes[0], &planes[1], &planes[2]];
    let decode = |passes: u32, settle_edges: bool| {
        let config = DecoderConfig {
            consensus_passes: passes,
            settle_edges,
            ..DecoderConfig::default()
        };
        let decoder = Decoder::new(set.clone(), &head, config).unwrap();
        let out = decoder.decode(channels).unwrap();
        (decoder, out)
    };
    let (first, single) = decode(0, false);
    let smooth = wrapped_mae(&truth, &set, &decode(1, false).1.fringes.wrapped);
    let settled = wrapped_mae(&truth, &set, &decode(1, true).1.fringes.wrapped);
    let depth = Raster {
        width: 320,
        height: 240,
        data: truth
            .point_m
            .data
            .iter()
            .map(|p| p.map_or(f32::NAN, |p| p.z as f32))
            .collect(),
    };
    let at = first.dmd_at_depths(&depth).unwrap();
    let cleaned = first.demultiplexer().remove_zero_order([
        &planes[0].data[..],
        &planes[1].data,
        &planes[2].data,
    ]);
    let mut oracle = single.fringes.wrapped.clone();
    first.demultiplexer().demodulate_at(
        &cleaned.fringes,
        &at,
        &mut oracle,
        &single.fringes.modulation,
    );
    let oracle = wrapped_mae(&truth, &set, &oracle);
    let single = wrapped_mae(&truth, &set, &single.fringes.wrapped);
    println!(
        "wrapped-phase MAE: single pass {single:.4}, consensus pass {smooth:.4}, settled {settled:.4}, on the true depth {oracle:.4} rad"
    );
    assert!(smooth < single, "{smooth} against {single}");
    assert!(settled < smooth, "{settled} against {smooth}");
    assert!(oracle < settled, "{oracle} against {settled}");
    // A depth map of another size is refused, not read past its end.
    let small = Raster {
        width: 32,
        height: 24,
        data: vec![0.5f32; 32 * 24],
    };
    assert!(matches!(
        first.dmd_at_depths(&small),
        Err(HighSpeedError::WrongSize { .. })
    ));
}
