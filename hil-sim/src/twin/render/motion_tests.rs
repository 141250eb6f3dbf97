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
    for (k, s) in slices.iter().enumerate() {
        let want = 0.01 + k as f64 * 0.01 / MOTION_SAMPLES as f64;
        assert!((s.start_s - want).abs() < 1e-15, "{k}: {s:?}");
        assert!((s.duration_s() - 0.01 / MOTION_SAMPLES as f64).abs() < 1e-15);
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
    // A second projector with one pattern whose edges are 0.3 us off head
    // A's (jitter: no extra slice) and one edge of its own.
    let b = ProjectorTimeline {
        shown: vec![shown(t0 + 3.0 * SLOT_S + 0.3e-6, t0 + 4.5 * SLOT_S)],
    };
    let exposure = Exposure {
        start_s: t0 - 50e-6,
        end_s: t0 + 24.0 * SLOT_S + 50e-6,
    };
    let slices = motion_slices(&[a, b], exposure);
    // Before, 24 patterns (one cut in two by B's end), after.
    assert_eq!(slices.len(), 1 + 25 + 1);
    assert_eq!(slices[0].start_s, exposure.start_s);
    assert_eq!(slices[slices.len() - 1].end_s, exposure.end_s);
    for w in slices.windows(2) {
        assert_eq!(w[0].end_s, w[1].start_s);
    }
    assert_eq!(slices[1].start_s, t0);
    assert_eq!(slices[4].start_s, t0 + 3.0 * SLOT_S);
    assert_eq!(slices[5].start_s, t0 + 4.0 * SLOT_S);
    assert_eq!(slices[6].start_s, t0 + 4.5 * SLOT_S);
    assert!(slices.iter().all(|s| s.duration_s() >= MIN_MOTION_SLICE_S));
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
