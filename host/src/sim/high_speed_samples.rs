//! Random twin scenes under seed 001's 24-pattern set, each with the truths a
//! high-speed decoder is measured against and its networks are trained on:
//! the colour long exposure as the scan's camera takes it, the LED flats the
//! scan measures crosstalk from, each pattern's true phase and depth at its
//! own instant, and each LED's clean fringe split into its AC and zero order.
//! The scenes are static, or (the moving stream) their objects spin or fly
//! during the exposure as the `rotor` and `falling` scenes' do.

use std::sync::Arc;

use hil_sim::twin::dataset::PLACE;
use hil_sim::twin::random_scene::random_scene;
use hil_sim::twin::scenes::{single_head, Detail};
use hil_sim::twin::sensor::Channels;
use hil_sim::twin::{
    render_exposure, CameraRays, Exposure, Illum, Image, Motion, Pattern, ProjectorTimeline,
    Renderer, Scene, SensorModel, TwinError, V3,
};
use rand::{Rng, SeedableRng};
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
    /// Per pattern, the true absolute phase at its instant (the middle of
    /// its slot), radians (NaN where unlit).
    pub phase: Vec<Vec<f32>>,
    /// Per pattern, the true depth (camera z) at its instant, metres.
    pub depth_m: Vec<Vec<f32>>,
    /// Per LED, the noise-free fringe light without its zero order: the sum
    /// over its 8 patterns of `B_m cos(phi_m)`, as LED `c` alone would give
    /// it in camera channel `c` (full scale, unclipped): the units the
    /// analytic unmixing (crosstalk diagonal 1) gives. ZOCR-Net's first target.
    pub ac: [Vec<f32>; 3],
    /// Per LED band, the zero order: the patterns' mean light (half the flat,
    /// the patterns being binary at half duty) plus the ambient light, same
    /// units. ZOCR-Net's second target. (In a moving scene both are the
    /// scene's at mid-exposure: an approximation, not ZOCR-Net's data.)
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

/// Whether a sample's objects stay put or move during the exposure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneMotion {
    /// Static scenes: every pattern's truth is the one pose.
    Static,
    /// Every object but the wall spins or flies through the exposure (see
    /// [`set_random_motions`]): the exposure sums the poses the 24 patterns
    /// light, and each pattern's truth is the scene where it was at that
    /// pattern's instant. The same layout as the static sample.
    Moving,
}

/// Scene `index` of the stream `seed` (the dataset exporter's placement:
/// objects 0.44-0.54 m away, a wall at 0.6 m), rendered through head A of
/// [`single_head`] with `set` at 5 kHz in one 4.8 ms exposure.
pub fn random_high_speed_sample(
    set: &PatternSet,
    detail: &Detail,
    seed: u64,
    index: u64,
    motion: SceneMotion,
) -> Result<HighSpeedSample, TwinError> {
    let moving = motion == SceneMotion::Moving;
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(1_000_003).wrapping_add(index));
    let mut scene = random_scene(&mut rng, &PLACE, true)?;
    if moving {
        // Drawn after the scene, so a moving sample has its static twin's layout.
        set_random_motions(&mut scene, &mut rng);
    }
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
    let timelines = std::slice::from_ref(&timeline);
    let slots = |n: usize| Exposure {
        start_s: 0.0,
        end_s: n as f64 * SLOT_S,
    };
    let exposure = slots(set.patterns().len());
    let sensor = high_speed_sensor();
    // Flats and zero-order truths: the scene at mid-exposure when it moves.
    let pose_s = if moving { 0.5 * exposure.end_s } else { 0.0 };
    let renderer = Renderer::new(&scene, &rig, 0, pose_s)?;
    let image = if moving {
        let mut noise = ChaCha8Rng::seed_from_u64(index + 17);
        render_exposure(&scene, &rig, 0, timelines, exposure, &sensor, &mut noise)?.image
    } else {
        renderer
            .frame(timelines, exposure, &sensor, index + 17)?
            .image
    };
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
    // Every instant's pose casts the same camera rays.
    let rays = moving.then(|| CameraRays::new(&rig, 0, 1)).transpose()?;
    let mut phase = Vec::with_capacity(set.patterns().len());
    let mut depth_m = Vec::with_capacity(set.patterns().len());
    for p in set.patterns() {
        let posed;
        let at_instant = match &rays {
            Some(rays) => {
                let instant_s = (p.index as f64 + 0.5) * SLOT_S;
                posed = Renderer::posed(&scene, &rig, rays, instant_s)?;
                posed.geometry()
            }
            None => renderer.geometry(),
        };
        let view = &at_instant.projectors[0];
        phase.push(
            view.uv_px
                .iter()
                .zip(&view.illum)
                .map(|(q, il)| match il {
                    Illum::Lit => PatternSet::phase_at(p, f64::from(q[0]), f64::from(q[1])) as f32,
                    _ => f32::NAN,
                })
                .collect(),
        );
        depth_m.push(at_instant.depth_m.clone());
    }
    Ok(HighSpeedSample {
        channels: planes(&image),
        flats: [f0?, f1?, f2?],
        phase,
        depth_m,
        ac,
        dc,
    })
}

/// Gives every object but the wall a motion like the built-in moving
/// scenes': half spin (2-20 rev/s, the `rotor` turns at 19.6, about a random
/// axis up to 3 cm off the object's centre, so parts sweep like blades),
/// half fly (0.2-2 m/s any way, under gravity along +y as in `falling`).
/// Over the 4.8 ms exposure a point moves up to a few centimetres.
fn set_random_motions(scene: &mut Scene, rng: &mut impl Rng) {
    for object in scene.objects.iter_mut().filter(|o| o.name != "wall") {
        let centre = object.pose.translation.vector;
        let (axis, offset, velocity) = (unit(rng), unit(rng), unit(rng));
        object.motion = if rng.random_bool(0.5) {
            Motion::Spin {
                centre_m: centre + offset * rng.random_range(0.0..0.03),
                axis,
                rate_rad_s: std::f64::consts::TAU * rng.random_range(2.0..20.0),
            }
        } else {
            Motion::Ballistic {
                velocity_m_s: velocity * rng.random_range(0.2..2.0),
                accel_m_s2: V3::new(0.0, 9.81, 0.0),
            }
        };
    }
}

/// A direction drawn evenly over the sphere (rejection from the cube).
fn unit(rng: &mut impl Rng) -> V3 {
    loop {
        let v = V3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let n = v.norm();
        if n > 0.1 && n <= 1.0 {
            return v / n;
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn changed(a: &[f32], b: &[f32]) -> usize {
        a.iter()
            .zip(b)
            .filter(|(x, y)| x.to_bits() != y.to_bits())
            .count()
    }

    #[test]
    fn a_moving_sample_has_each_patterns_truth_at_its_instant() {
        let detail = Detail {
            camera: (80, 60),
            projector: (1280, 800),
        };
        let set = PatternSet::seed001(detail.projector).unwrap();
        let still = random_high_speed_sample(&set, &detail, 5, 0, SceneMotion::Static).unwrap();
        let moving = random_high_speed_sample(&set, &detail, 5, 0, SceneMotion::Moving).unwrap();
        let n = still.depth_m[0].len();
        let last = set.patterns().len() - 1;
        // A static scene's 24 instants are one truth.
        for m in 1..=last {
            assert_eq!(changed(&still.depth_m[0], &still.depth_m[m]), 0);
            let lit = |phase: &[f32]| phase.iter().filter(|v| v.is_finite()).count();
            assert_eq!(lit(&still.phase[0]), lit(&still.phase[m]));
        }
        // A moving one's objects are elsewhere at the last instant than at
        // the first; the wall, where they are not, stays.
        let moved = changed(&moving.depth_m[0], &moving.depth_m[last]);
        assert!(moved > 0 && moved < n, "{moved} of {n} pixels moved");
        // The same pattern's truth follows: the static layout is the pose at 0.
        assert!(changed(&still.phase[last], &moving.phase[last]) > 0);
        // Motion blurs the exposure: its image is not the static scene's.
        assert!(changed(&still.channels[0].data, &moving.channels[0].data) > 0);
    }
}
