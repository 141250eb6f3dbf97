//! A moving scene in one long exposure: the exposure is cut at every
//! displayed pattern's edges, so each pattern's light lands where the
//! surface was while that pattern was on (seed 001's 24 patterns).

use std::f64::consts::PI;
use std::sync::Arc;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::*;
use crate::twin::pattern::{BitDepth, Fringe, Shown};
use crate::twin::scenes::{built_in, Detail};

const SLOT_S: f64 = 200e-6;

fn shown(start_s: f64, end_s: f64) -> Shown {
    Shown {
        pattern: Arc::new(Pattern::flat(4, 4, 1.0)),
        start_s,
        end_s,
        led: [1.0; 3],
        display: Display::Steady,
    }
}

#[test]
fn one_long_pattern_still_gets_motion_samples_equal_slices() {
    let exposure = Exposure {
        start_s: 0.01,
        end_s: 0.02,
    };
    let tl = [ProjectorTimeline {
        shown: vec![shown(0.0, 1.0)],
    }];
    let slices = motion_slices(&tl, exposure);
    assert_eq!(slices.len(), MOTION_SAMPLES);
    let dt = 0.01 / MOTION_SAMPLES as f64;
    for (k, s) in slices.iter().enumerate() {
        let want = 0.01 + k as f64 * dt;
        assert!((s.exposure.start_s - want).abs() < 1e-15, "{k}: {s:?}");
        assert!((s.exposure.duration_s() - dt).abs() < 1e-15);
        assert!((s.pose_s - (want + 0.5 * dt)).abs() < 1e-15);
    }
    // Dark throughout: still MOTION_SAMPLES slices of ambient light.
    let dark = motion_slices(&[ProjectorTimeline::dark()], exposure);
    assert_eq!(dark, slices);
}

fn assert_tiles(slices: &[MotionSlice], exposure: Exposure) {
    assert_eq!(slices[0].exposure.start_s, exposure.start_s);
    assert_eq!(slices[slices.len() - 1].exposure.end_s, exposure.end_s);
    for w in slices.windows(2) {
        assert_eq!(w[0].exposure.end_s, w[1].exposure.start_s);
    }
    for s in slices {
        assert!(s.exposure.duration_s() >= MIN_MOTION_SLICE_S);
        assert!(s.exposure.start_s <= s.pose_s && s.pose_s <= s.exposure.end_s);
    }
}

#[test]
fn slices_cut_at_every_pattern_edge_of_every_projector_and_tile_the_exposure() {
    let t0 = 0.003;
    // 24 patterns back to back, the shutter open 50 us before and after.
    let a = ProjectorTimeline {
        shown: (0..24)
            .map(|k| shown(t0 + k as f64 * SLOT_S, t0 + (k + 1) as f64 * SLOT_S))
            .collect(),
    };
    // A second projector with one pattern whose start is 0.3 us off head
    // A's edge (jitter: no slice of its own) and whose end cuts a slice.
    let b = ProjectorTimeline {
        shown: vec![shown(t0 + 3.0 * SLOT_S + 0.3e-6, t0 + 4.5 * SLOT_S)],
    };
    let exposure = Exposure {
        start_s: t0 - 50e-6,
        end_s: t0 + 24.0 * SLOT_S + 50e-6,
    };
    let slices = motion_slices(&[a, b], exposure);
    assert_tiles(&slices, exposure);
    // 24 patterns, one cut in two by B's end; the dark ends join the first
    // and last pattern, posed at their patterns' middles.
    assert_eq!(slices.len(), 25);
    assert_eq!(slices[0].exposure.end_s, t0 + SLOT_S);
    assert!((slices[0].pose_s - (t0 + 0.5 * SLOT_S)).abs() < 1e-15);
    assert_eq!(slices[3].exposure.start_s, t0 + 3.0 * SLOT_S);
    assert_eq!(slices[4].exposure.start_s, t0 + 4.0 * SLOT_S);
    assert_eq!(slices[5].exposure.start_s, t0 + 4.5 * SLOT_S);
    assert_eq!(slices[24].exposure.start_s, t0 + 23.0 * SLOT_S);
    assert!((slices[24].pose_s - (t0 + 23.5 * SLOT_S)).abs() < 1e-15);
}

#[test]
fn dark_gaps_between_patterns_go_half_to_each_neighbour() {
    // Three 180 us patterns 200 us apart, the shutter open from 100 us
    // before the first to 100 us after the last.
    let t0 = 0.001;
    let tl = [ProjectorTimeline {
        shown: (0..3)
            .map(|k| {
                let a = t0 + k as f64 * SLOT_S;
                shown(a, a + 180e-6)
            })
            .collect(),
    }];
    let exposure = Exposure {
        start_s: t0 - 100e-6,
        end_s: t0 + 2.0 * SLOT_S + 180e-6 + 100e-6,
    };
    let slices = motion_slices(&tl, exposure);
    assert_tiles(&slices, exposure);
    assert_eq!(slices.len(), MOTION_SAMPLES);
    // Each pattern's light halves until there are 8 slices; every pose is
    // the middle of the light it holds.
    let poses: Vec<f64> = slices.iter().map(|s| s.pose_s).collect();
    let q = 180e-6 / 4.0;
    let want = [
        t0 + 0.5 * q,
        t0 + 1.5 * q,
        t0 + 2.5 * q,
        t0 + 3.5 * q,
        t0 + SLOT_S + 45e-6,
        t0 + SLOT_S + 135e-6,
        t0 + 2.0 * SLOT_S + 45e-6,
        t0 + 2.0 * SLOT_S + 135e-6,
    ];
    for (got, want) in poses.iter().zip(want) {
        assert!((got - want).abs() < 1e-12, "{poses:?}");
    }
    // The first slice holds the dark lead-in, the 20 us gaps split 10/10.
    assert_eq!(slices[0].exposure.start_s, exposure.start_s);
    assert!((slices[4].exposure.start_s - (t0 + 190e-6)).abs() < 1e-12);
    assert!((slices[6].exposure.start_s - (t0 + 390e-6)).abs() < 1e-12);
}

/// Seed 001's multiplexed sequence: 8 directions x R/G/B binary fringes,
/// back to back from `t0_s`, one `SLOT_S` each.
fn multiplexed(t0_s: f64, w: u32, h: u32) -> ProjectorTimeline {
    let leds = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let items = (0..24).map(|k| {
        let f = Fringe {
            period_px: [11.0, 9.0, 7.0][k % 3],
            angle_rad: (k / 3) as f64 * PI / 8.0 + 0.31,
            shift_rad: 0.0,
        };
        (
            Arc::new(Pattern::fringe(w, h, &f, BitDepth::One)),
            leds[k % 3],
        )
    });
    ProjectorTimeline::sequence(items, t0_s, SLOT_S)
}

#[test]
fn each_of_24_patterns_lands_where_the_rotor_was_while_it_was_shown() {
    let detail = Detail {
        camera: (128, 96),
        projector: (160, 100),
    };
    let (scene, rig) = built_in("rotor", &detail).unwrap();
    let t0 = 0.0123;
    let tl = [multiplexed(t0, 160, 100)];
    let exposure = Exposure {
        start_s: t0,
        end_s: t0 + 24.0 * SLOT_S,
    };
    let sensor = SensorModel::ideal();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let frame = render_exposure(&scene, &rig, 0, &tl, exposure, &sensor, &mut rng).unwrap();
    // Reference: each pattern's slot rendered alone at its own instant, summed.
    let slot_sum = |slots: &[Exposure]| {
        let mut acc: Option<Exposed> = None;
        for s in slots {
            let r = Renderer::new(&scene, &rig, 0, 0.5 * (s.start_s + s.end_s)).unwrap();
            let e = r.exposed(&tl, *s).unwrap();
            match acc.as_mut() {
                None => acc = Some(e),
                Some(a) => a.accumulate(&e),
            }
        }
        acc.unwrap().total()
    };
    let per_pattern: Vec<Exposure> = (0..24)
        .map(|k| Exposure {
            start_s: t0 + k as f64 * SLOT_S,
            end_s: t0 + (k + 1) as f64 * SLOT_S,
        })
        .collect();
    let want = slot_sum(&per_pattern);
    let got = frame.exposed.total();
    let peak = want.iter().flatten().fold(0.0f32, |m, &v| m.max(v));
    let worst = got
        .iter()
        .flatten()
        .zip(want.iter().flatten())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(worst <= 1e-6 * peak, "worst {worst} of peak {peak}");
    // Through the noise-free sensor too.
    let (clean, _) = sensor.expose(128, 96, &want, None);
    let worst_px = frame
        .clean
        .data
        .iter()
        .zip(&clean.data)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(worst_px <= 1e-5, "{worst_px}");
    // The test can tell: 8 equal slices (3 patterns each, posed at the
    // middle one's instant) put the outer patterns' light up to 2 x 2.3 mm
    // off on blade edges.
    let coarse: Vec<Exposure> = (0..MOTION_SAMPLES)
        .map(|k| {
            let dt = exposure.duration_s() / MOTION_SAMPLES as f64;
            Exposure {
                start_s: t0 + k as f64 * dt,
                end_s: t0 + (k + 1) as f64 * dt,
            }
        })
        .collect();
    let old = slot_sum(&coarse);
    let off = old
        .iter()
        .flatten()
        .zip(want.iter().flatten())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(off > 0.05 * peak, "8 slices differ by only {off} of {peak}");
}

#[test]
fn with_dark_gaps_each_patterns_light_is_still_posed_at_its_own_middle() {
    let detail = Detail {
        camera: (96, 72),
        projector: (160, 100),
    };
    let (scene, rig) = built_in("rotor", &detail).unwrap();
    let t0 = 0.0071;
    // 180 us of light every 200 us, the shutter open 30 us before and after.
    let mut tl = multiplexed(t0, 160, 100);
    for s in tl.shown.iter_mut() {
        s.end_s = s.start_s + 180e-6;
    }
    let tl = [tl];
    let exposure = Exposure {
        start_s: t0 - 30e-6,
        end_s: t0 + 23.0 * SLOT_S + 180e-6 + 30e-6,
    };
    assert_eq!(motion_slices(&tl, exposure).len(), 24);
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let frame = render_exposure(
        &scene,
        &rig,
        0,
        &tl,
        exposure,
        &SensorModel::ideal(),
        &mut rng,
    )
    .unwrap();
    let mut want: Option<Exposed> = None;
    for s in &tl[0].shown {
        let r = Renderer::new(&scene, &rig, 0, 0.5 * (s.start_s + s.end_s)).unwrap();
        let e = r
            .exposed(
                &tl,
                Exposure {
                    start_s: s.start_s,
                    end_s: s.end_s,
                },
            )
            .unwrap();
        match want.as_mut() {
            None => want = Some(e),
            Some(a) => a.accumulate(&e),
        }
    }
    let want = want.unwrap();
    let peak = want.per_projector[0]
        .iter()
        .flatten()
        .fold(0.0f32, |m, &v| m.max(v));
    let worst = frame.exposed.per_projector[0]
        .iter()
        .flatten()
        .zip(want.per_projector[0].iter().flatten())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(worst <= 1e-6 * peak, "worst {worst} of peak {peak}");
}

/// A posed renderer on rays computed once for the rig gives the geometry of
/// a renderer that computes them itself, bit for bit, at every pose; rays of
/// another rig, or sub-pixel rays, are refused.
#[test]
fn shared_camera_rays_give_the_same_geometry_and_belong_to_one_rig() {
    let detail = Detail {
        camera: (96, 64),
        projector: (120, 80),
    };
    let (scene, rig) = built_in("rotor", &detail).unwrap();
    let rays = CameraRays::new(&rig, 0, 1).unwrap();
    for t in [0.0, 0.0042, 0.0137] {
        let own = Renderer::new(&scene, &rig, 0, t).unwrap();
        let shared = Renderer::posed(&scene, &rig, &rays, t).unwrap();
        let (a, b) = (own.geometry(), shared.geometry());
        let bits = |v: &[[f32; 3]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a.point_m), bits(&b.point_m), "t = {t}");
        assert_eq!(bits(&a.normal), bits(&b.normal), "t = {t}");
        assert_eq!(a.object, b.object);
        assert_eq!(a.projectors[0].illum, b.projectors[0].illum, "t = {t}");
        assert_eq!(bits(&a.projectors[0].gain), bits(&b.projectors[0].gain));
    }
    let mut moved = rig.clone();
    moved.cameras[0].model.intrinsics.fx *= 1.01;
    assert!(matches!(
        Renderer::posed(&scene, &moved, &rays, 0.0),
        Err(TwinError::BadParameter {
            name: "camera rays",
            ..
        })
    ));
    let sub_pixel = CameraRays::new(&rig, 0, 2).unwrap();
    assert!(matches!(
        Renderer::posed(&scene, &rig, &sub_pixel, 0.0),
        Err(TwinError::BadParameter { .. })
    ));
}
