//! Random static twin scenes under seed 001's 24-pattern set, each with the
//! truths a high-speed decoder is measured against and its zero-order network
//! is trained on: the colour long exposure as the scan's camera takes it, the
//! LED flats the scan measures crosstalk from, each pattern's true phase, the
//! depth, and each LED's clean fringe split into its AC and zero order.

use std::sync::Arc;

use hil_sim::twin::dataset::PLACE;
use hil_sim::twin::random_scene::random_scene;
use hil_sim::twin::scenes::{single_head, Detail};
use hil_sim::twin::sensor::Channels;
use hil_sim::twin::{
    Exposure, Illum, Image, Pattern, ProjectorTimeline, Renderer, SensorModel, TwinError,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::high_speed::high_speed_sensor;
use crate::highspeed::PatternSet;
use crate::raster::Raster;

/// Each pattern's slot, seconds (5 kHz, as the board plays the set).
pub const SLOT_S: f64 = 200e-6;

/// One rendered exposure and its truths (all maps row-major, camera size).
pub struct HighSpeedSample {
    /// The camera's R, G, B planes (full scale 1): crosstalk, noise, 8 bits.
    pub channels: [Raster<f32>; 3],
    /// Per LED, its flat minus a dark frame, as camera R, G, B planes.
    pub flats: [[Vec<f32>; 3]; 3],
    /// Per pattern, the true absolute phase, radians (NaN where unlit).
    pub phase: Vec<Vec<f32>>,
    /// True depth (camera z), metres.
    pub depth_m: Vec<f32>,
    /// Per LED, the noise-free fringe light without its zero order: the sum
    /// over its 8 patterns of `B_m cos(phi_m)`, as LED `c` alone would give
    /// it in camera channel `c` (full scale, unclipped): the units the
    /// analytic unmixing (crosstalk diagonal 1) gives. ZOCR-Net's first target.
    pub ac: [Vec<f32>; 3],
    /// Per LED band, the zero order: the patterns' mean light (half the flat,
    /// the patterns being binary at half duty) plus the ambient light, same
    /// units. ZOCR-Net's second target.
    pub dc: [Vec<f32>; 3],
}

/// The camera image's planes.
fn planes(image: &Image) -> [Raster<f32>; 3] {
    let (w, h) = (image.width as usize, image.height as usize);
    [0, 1, 2].map(|c| Raster {
        width: w,
        height: h,
        data: image.data.chunks(3).map(|p| p[c]).collect(),
    })
}

/// Scene `index` of the stream `seed` (the dataset exporter's placement:
/// objects 0.44-0.54 m away, a wall at 0.6 m), rendered through head A of
/// [`single_head`] with `set` at 5 kHz in one 4.8 ms exposure.
pub fn random_high_speed_sample(
    set: &PatternSet,
    detail: &Detail,
    seed: u64,
    index: u64,
) -> Result<HighSpeedSample, TwinError> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(1_000_003).wrapping_add(index));
    let scene = random_scene(&mut rng, &PLACE, true)?;
    let rig = single_head(detail);
    let (dw, dh) = set.dmd_px();
    let to_twin = |r: &Raster<f32>| {
        Arc::new(Pattern {
            width: dw,
            height: dh,
            values: r.data.clone(),
        })
    };
    let items: Vec<_> = set
        .binary_frames()
        .iter()
        .map(to_twin)
        .zip(set.leds())
        .collect();
    let timeline = ProjectorTimeline::sequence(items, 0.0, SLOT_S);
    let slots = |n: usize| Exposure {
        start_s: 0.0,
        end_s: n as f64 * SLOT_S,
    };
    let exposure = slots(set.patterns().len());
    let sensor = high_speed_sensor();
    let renderer = Renderer::new(&scene, &rig, 0, 0.0)?;
    let frame = renderer.frame(
        std::slice::from_ref(&timeline),
        exposure,
        &sensor,
        index + 17,
    )?;
    let white = to_twin(&Raster::filled(dw as usize, dh as usize, 1.0));
    // As the scan does: each LED's flat minus a dark frame (the ambient light).
    let flat = |colour: [f32; 3], noise: u64| {
        let t = ProjectorTimeline::sequence([(white.clone(), colour)], 0.0, slots(7).end_s);
        renderer
            .frame(&[t], slots(7), &sensor, noise)
            .map(|f| planes(&f.image).map(|p| p.data))
    };
    let dark = flat([0.0; 3], index + 99)?;
    let flats = [0, 1, 2].map(|led| {
        let mut colour = [0.0f32; 3];
        colour[led] = 1.0;
        flat(colour, index + 100 + led as u64).map(|mut planes| {
            for (plane, d) in planes.iter_mut().zip(&dark) {
                plane.iter_mut().zip(d).for_each(|(v, d)| *v -= d);
            }
            planes
        })
    });
    let [f0, f1, f2] = flats;
    let (ac, dc) = zero_order_truth(&renderer, &timeline, &white, set, &sensor)?;
    let uv = frame.truth.projector_uv_px(0);
    let lit = frame.truth.illum(0);
    let phase = set
        .patterns()
        .iter()
        .map(|p| {
            uv.iter()
                .zip(lit)
                .map(|(q, il)| match il {
                    Illum::Lit => PatternSet::phase_at(p, f64::from(q[0]), f64::from(q[1])) as f32,
                    _ => f32::NAN,
                })
                .collect()
        })
        .collect();
    Ok(HighSpeedSample {
        channels: planes(&frame.image),
        flats: [f0?, f1?, f2?],
        phase,
        depth_m: frame.truth.depth_m().to_vec(),
        ac,
        dc,
    })
}

/// Each LED band's AC and zero order, noise-free: the set's light minus half
/// of each LED's flat over the same eight slots (a binary pattern at half duty
/// averages to half the flat), and that half plus the ambient light.
#[allow(clippy::type_complexity)]
fn zero_order_truth(
    renderer: &Renderer,
    timeline: &ProjectorTimeline,
    white: &Arc<Pattern>,
    set: &PatternSet,
    sensor: &SensorModel,
) -> Result<([Vec<f32>; 3], [Vec<f32>; 3]), TwinError> {
    let n = set.patterns().len();
    let exposure = Exposure {
        start_s: 0.0,
        end_s: n as f64 * SLOT_S,
    };
    let lit = renderer.exposed(std::slice::from_ref(timeline), exposure)?;
    // Every LED on for half of each of its patterns' slots: n / 3 / 2 slots
    // of white, all three LEDs at once (they fall in separate bands).
    let half = Exposure {
        start_s: 0.0,
        end_s: n as f64 / 6.0 * SLOT_S,
    };
    let white_timeline = ProjectorTimeline::sequence([(white.clone(), [1.0; 3])], 0.0, half.end_s);
    let mean = renderer.exposed(&[white_timeline], half)?;
    let scale = (sensor.electrons_per_unit * sensor.gain / sensor.full_well_e) as f32;
    // Band c as camera channel c sees it (the sensor's own-band sensitivity).
    let own = |c: usize| match sensor.channels {
        Channels::Rgb(m) => m[c][c] as f32,
        Channels::Mono(s) => s[c] as f32,
    };
    let band = |c: usize, f: &dyn Fn(usize) -> f32| -> Vec<f32> {
        let k = scale * own(c);
        (0..lit.ambient.len()).map(|i| f(i) * k).collect()
    };
    let ac = [0, 1, 2].map(|c| {
        band(c, &|i| {
            lit.per_projector[0][i][c] - mean.per_projector[0][i][c]
        })
    });
    let dc = [0, 1, 2].map(|c| band(c, &|i| mean.per_projector[0][i][c] + lit.ambient[i][c]));
    Ok((ac, dc))
}
