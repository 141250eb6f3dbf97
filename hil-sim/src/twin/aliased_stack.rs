//! Seed 000's training sample as the simultaneous scan captures it: both
//! projectors show the same K-period x N-step fringe sequence at once, and
//! each camera records the K x N aliased frames plus three flat fields
//! (both projectors dark, its own projector full on, the other full on).
//! The target is what a single-head run records: ambient plus the camera's
//! own projector alone, noise-free. The truth is the own projector's DMD
//! column at every pixel (phase of period p: 2 pi u / p).
//!
//! The fringes are the host's (`I = 0.5 + 0.5 cos(2 pi u / p + 2 pi n / N)`,
//! unquantised, as `slscan::patterns::phase_shift_set` makes them) and the
//! sensor is exposed as the simulated scan's is, so a network trained on
//! these samples sees what the scan shows it.

use std::f64::consts::TAU;
use std::sync::Arc;

use super::device::Rig;
use super::error::TwinError;
use super::pattern::{Exposure, Pattern, ProjectorTimeline};
use super::render::Renderer;
use super::scene::Scene;
use super::sensor::SensorModel;
use super::truth::Truth;
use super::Illum;

/// One camera's aliased capture and its targets; every image is row-major
/// `width x height`, full-scale units.
#[derive(Clone, Debug)]
pub struct AliasedStack {
    /// The camera (and its own projector: head `camera`).
    pub camera: usize,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Noisy aliased frames, period-major (`K x N`).
    pub aliased: Vec<Vec<f32>>,
    /// Noise-free frames of ambient + the own projector alone (`K x N`).
    pub clean_own: Vec<Vec<f32>>,
    /// Noisy flat fields: [both dark, own projector on, other projector on].
    pub flats: [Vec<f32>; 3],
    /// Own projector's DMD column per pixel; NaN where it does not light it.
    pub own_u_px: Vec<f32>,
    /// Lit by both projectors (the twin's overlap).
    pub overlap: Vec<bool>,
}

/// The fringe sequence and the sensor of an aliased capture.
#[derive(Clone, Debug)]
pub struct AliasedCapture {
    /// Fringe periods, DMD pixels (K).
    pub periods_px: Vec<f64>,
    /// Phase steps per period (N).
    pub steps: usize,
    /// Sensor; its exposure scale is set by [`scan_sensor`].
    pub sensor: SensorModel,
    /// Exposure of each frame, seconds.
    pub exposure_s: f64,
}

/// The 12-bit mono sensor as the simulated scan exposes it (a full-on
/// pattern on a white diffuser fills 70 % of the well in `exposure_s`),
/// with its shot and read noise scaled by `noise_scale` (1 = the scan's).
pub fn scan_sensor(exposure_s: f64, noise_scale: f64) -> SensorModel {
    let mut sensor = SensorModel::mono12();
    // sigma/full-scale goes as sqrt(well)/well for shot, read/well for read.
    let s = noise_scale.max(1e-3);
    sensor.full_well_e /= s * s;
    sensor.read_noise_e /= s;
    sensor.electrons_per_unit = 0.7 * sensor.full_well_e / exposure_s;
    sensor
}

/// The host's N-step fringe of period `period_px` at step `n`, unquantised.
fn host_fringe(width: u32, height: u32, period_px: f64, n: usize, steps: usize) -> Pattern {
    let delta = TAU * n as f64 / steps as f64;
    let row: Vec<f32> = (0..width)
        .map(|u| (0.5 + 0.5 * (TAU * u as f64 / period_px + delta).cos()) as f32)
        .collect();
    let mut values = Vec::with_capacity(width as usize * height as usize);
    for _ in 0..height {
        values.extend_from_slice(&row);
    }
    Pattern {
        width,
        height,
        values,
    }
}

/// Each projector's timeline: `pattern` on the listed projectors, dark on the rest.
fn timelines(
    rig: &Rig,
    on: &[(usize, Arc<Pattern>)],
    exposure: &Exposure,
) -> Vec<ProjectorTimeline> {
    (0..rig.projectors.len())
        .map(|p| match on.iter().find(|(q, _)| *q == p) {
            Some((_, pattern)) => {
                ProjectorTimeline::single(pattern.clone(), exposure.start_s, exposure.end_s)
            }
            None => ProjectorTimeline::dark(),
        })
        .collect()
}

/// Renders camera `camera`'s aliased capture of `scene` on the two-head
/// `rig`; noise streams start at `noise_seed`.
pub fn render_aliased_stack(
    scene: &Scene,
    rig: &Rig,
    camera: usize,
    capture: &AliasedCapture,
    noise_seed: u64,
) -> Result<AliasedStack, TwinError> {
    if rig.projectors.len() != 2 || camera > 1 {
        return Err(TwinError::BadParameter {
            name: "aliased capture heads",
            value: rig.projectors.len() as f64,
            why: "needs a two-head rig and camera 0 or 1",
        });
    }
    if capture
        .periods_px
        .iter()
        .any(|p| !(p.is_finite() && *p > 0.0))
        || capture.steps < 3
    {
        return Err(TwinError::BadParameter {
            name: "aliased capture",
            value: capture.steps as f64,
            why: "periods must be > 0 and steps >= 3",
        });
    }
    let (own, other) = (camera, 1 - camera);
    let renderer = Renderer::new(scene, rig, camera, 0.0)?;
    let exposure = Exposure {
        start_s: 0.0,
        end_s: capture.exposure_s,
    };
    let k = &rig.projectors[own].model.intrinsics;
    let (dw, dh) = (k.width, k.height);
    let mut seed = noise_seed;
    let mut next_seed = || {
        seed = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
        seed
    };
    let mut aliased = Vec::new();
    let mut clean_own = Vec::new();
    let mut truth: Option<Truth> = None;
    for &p in &capture.periods_px {
        for n in 0..capture.steps {
            let pattern = Arc::new(host_fringe(dw, dh, p, n, capture.steps));
            let t = timelines(rig, &[(0, pattern.clone()), (1, pattern)], &exposure);
            let frame = renderer.frame(&t, exposure, &capture.sensor, next_seed())?;
            aliased.push(frame.image.data);
            clean_own.push(frame.per_projector_clean[own].data.clone());
            truth.get_or_insert(frame.truth);
        }
    }
    let white = Arc::new(Pattern::flat(dw, dh, 1.0));
    let mut flat = |on: &[(usize, Arc<Pattern>)]| -> Result<Vec<f32>, TwinError> {
        let t = timelines(rig, on, &exposure);
        Ok(renderer
            .frame(&t, exposure, &capture.sensor, next_seed())?
            .image
            .data)
    };
    let flats = [
        flat(&[])?,
        flat(&[(own, white.clone())])?,
        flat(&[(other, white)])?,
    ];
    let truth = truth.ok_or(TwinError::BadParameter {
        name: "aliased capture periods",
        value: 0.0,
        why: "needs at least one period",
    })?;
    let own_u_px = truth
        .projector_uv_px(own)
        .iter()
        .zip(truth.illum(own))
        .map(|(uv, il)| if *il == Illum::Lit { uv[0] } else { f32::NAN })
        .collect();
    Ok(AliasedStack {
        camera,
        width: truth.width(),
        height: truth.height(),
        aliased,
        clean_own,
        flats,
        own_u_px,
        overlap: truth.overlap().to_vec(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::random_scene::{random_scene, Placement};
    use crate::twin::scenes::{dual_head, Detail};
    use rand::SeedableRng;

    /// Objects near the middle, where the two heads' light overlaps.
    const PLACE_NEAR: Placement = Placement {
        x_m: (-0.02, 0.02),
        y_m: (-0.02, 0.02),
        z_m: (0.48, 0.5),
        wall_z_m: 0.6,
    };

    fn stack(camera: usize) -> AliasedStack {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let scene = random_scene(&mut rng, &PLACE_NEAR, false).unwrap();
        let rig = dual_head(&Detail {
            camera: (96, 72),
            projector: (320, 200),
        });
        let capture = AliasedCapture {
            periods_px: vec![16.0, 20.0],
            steps: 4,
            sensor: scan_sensor(1e-3, 0.05),
            exposure_s: 1e-3,
        };
        render_aliased_stack(&scene, &rig, camera, &capture, 9).unwrap()
    }

    /// The phase of the N target frames of period p, by the N-step formula.
    fn phase(frames: &[Vec<f32>], i: usize) -> f64 {
        let n = frames.len();
        let (mut s, mut c) = (0.0, 0.0);
        for (k, f) in frames.iter().enumerate() {
            let d = TAU * k as f64 / n as f64;
            s += f64::from(f[i]) * d.sin();
            c += f64::from(f[i]) * d.cos();
        }
        (-s).atan2(c)
    }

    #[test]
    fn targets_carry_the_own_projectors_phase_and_the_overlap_is_summed() {
        for camera in [0, 1] {
            let st = stack(camera);
            assert_eq!(st.aliased.len(), 8);
            assert_eq!(st.clean_own.len(), 8);
            let pixels = (st.width * st.height) as usize;
            let (mut checked, mut summed) = (0, 0);
            for i in 0..pixels {
                let u = st.own_u_px[i];
                if !u.is_finite() {
                    continue;
                }
                for (k, p) in [16.0, 20.0].iter().enumerate() {
                    let want = TAU * f64::from(u) / p;
                    let got = phase(&st.clean_own[4 * k..4 * k + 4], i);
                    let err = (got - want + TAU / 2.0).rem_euclid(TAU) - TAU / 2.0;
                    // Defocus and pixel footprint blur the fringe, not its phase.
                    assert!(err.abs() < 0.3, "camera {camera} pixel {i}: {err} rad");
                    checked += 1;
                }
                // In the overlap the other projector adds its light.
                let other = st.flats[2][i] - st.flats[0][i];
                if st.overlap[i] && other > 0.05 {
                    let mean_aliased: f32 = st.aliased[..4].iter().map(|f| f[i]).sum::<f32>() / 4.0;
                    let mean_own: f32 = st.clean_own[..4].iter().map(|f| f[i]).sum::<f32>() / 4.0;
                    assert!((mean_aliased - mean_own - 0.5 * other).abs() < 0.02 + 0.1 * other);
                    summed += 1;
                }
            }
            assert!(
                checked > 500,
                "camera {camera}: {checked} lit pixels checked"
            );
            assert!(
                summed > 50,
                "camera {camera}: {summed} overlap pixels checked"
            );
        }
    }

    #[test]
    fn a_one_head_rig_is_refused() {
        let mut rig = dual_head(&Detail {
            camera: (8, 8),
            projector: (32, 20),
        });
        rig.projectors.pop();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let scene = random_scene(&mut rng, &PLACE_NEAR, false).unwrap();
        let capture = AliasedCapture {
            periods_px: vec![16.0],
            steps: 4,
            sensor: scan_sensor(1e-3, 1.0),
            exposure_s: 1e-3,
        };
        assert!(render_aliased_stack(&scene, &rig, 0, &capture, 0).is_err());
    }
}
