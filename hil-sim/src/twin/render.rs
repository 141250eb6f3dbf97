//! Image formation: integrate what each projector displayed during the
//! exposure over the cached geometry, add ambient, apply the medium, then
//! the sensor (seed 000 eq. 4-7: in the overlap a camera sees the sum of
//! both projectors; seed 001 eq. 6: a long exposure sums its patterns).

use std::sync::{Arc, Mutex};

use rand::Rng;
use rayon::prelude::*;

use super::cache::{CameraGeometry, CameraRays};
use super::device::Rig;
use super::error::TwinError;
use super::medium::Medium;
use super::pattern::{bit_plane_intervals, Display, Exposure, Pattern, ProjectorTimeline, Tap};
use super::scatter::blur_varying;
use super::scene::Scene;
use super::sensor::{Image, SensorModel};
use super::truth::Truth;

/// Rays per pixel and axis for checkerboard (calibration) renders: an edge's area
/// share on a 1/16 grid. Measured on 12 twin board views at 640x480 (slscan's
/// `twin_accuracy` test): detected corners 0.032 px RMS from the truth, against
/// 0.16 px with one ray per pixel.
pub const CALIBRATION_PIXEL_SAMPLES: u32 = 4;

/// Fewest time slices per exposure of a moving scene (geometry is recomputed
/// per slice): an exposure is also cut at every pattern edge, see [`motion_slices`].
pub const MOTION_SAMPLES: usize = 8;

/// Shortest slice [`motion_slices`] cuts at a pattern edge, seconds: edges
/// closer than this to the previous cut (a DMD's trigger jitter, back-to-back
/// patterns a few nanoseconds apart) get no ray cast of their own.
pub const MIN_MOTION_SLICE_S: f64 = 1e-6;

/// Linear band exposures (twin units x seconds) of one camera frame, kept
/// apart per source so that sums can be checked and clean targets written.
#[derive(Clone, Debug, PartialEq)]
pub struct Exposed {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Ambient light (surface ambient + direct stray light) per pixel and band.
    pub ambient: Vec<[f32; 3]>,
    /// Each projector's light (including its backscatter veil in water).
    pub per_projector: Vec<Vec<[f32; 3]>>,
}

impl Exposed {
    /// Ambient plus every projector.
    pub fn total(&self) -> Vec<[f32; 3]> {
        let mut out = self.ambient.clone();
        for p in &self.per_projector {
            add_into(&mut out, p);
        }
        out
    }

    /// Ambient plus projector `p` alone (what a single-head reference run sees).
    pub fn single(&self, p: usize) -> Vec<[f32; 3]> {
        let mut out = self.ambient.clone();
        add_into(&mut out, &self.per_projector[p]);
        out
    }

    fn accumulate(&mut self, other: &Exposed) {
        add_into(&mut self.ambient, &other.ambient);
        for (a, b) in self.per_projector.iter_mut().zip(&other.per_projector) {
            add_into(a, b);
        }
    }
}

fn add_into(acc: &mut [[f32; 3]], x: &[[f32; 3]]) {
    for (a, b) in acc.iter_mut().zip(x) {
        for c in 0..3 {
            a[c] += b[c];
        }
    }
}

/// A rendered camera frame with everything that goes with it.
#[derive(Clone, Debug)]
pub struct Frame {
    /// The sensor image, with noise.
    pub image: Image,
    /// The same image without noise (still clipped, gamma'd, quantised).
    pub clean: Image,
    /// Noise-free image of ambient + each projector alone (de-aliasing targets).
    pub per_projector_clean: Vec<Image>,
    /// Ground truth at mid-exposure.
    pub truth: Truth,
    /// The linear exposures the images came from.
    pub exposed: Exposed,
}

/// Cached geometry of one camera for one scene pose: build once, then
/// render any number of pattern sequences cheaply.
#[derive(Debug)]
pub struct Renderer {
    rig: Rig,
    /// One ray per pixel centre: the truth and, at one sample per pixel, the image.
    geometry: Arc<CameraGeometry>,
    /// With more than one sample per pixel: the sub-pixel rays the image is rendered
    /// from (`pixel_samples` times as wide and high as `geometry`).
    sampled: Option<Arc<CameraGeometry>>,
    /// Rays per pixel and axis.
    pixel_samples: u32,
    /// Defocused patterns by (displayed pattern, projector), so a sequence
    /// shown again is not blurred again. Holding the source `Arc` keeps its
    /// address from being reused while cached.
    defocus_cache: Mutex<Vec<DefocusEntry>>,
}

/// (shown pattern, projector index, bit plane or whole, its defocused image).
type DefocusEntry = (Arc<Pattern>, usize, Option<u8>, Arc<Pattern>);

/// Defocused patterns kept per renderer (a 24-pattern sequence for two projectors fits).
const DEFOCUS_CACHE: usize = 64;

impl Renderer {
    /// Casts the camera's rays into `scene` frozen at `time_s` (expensive), one per
    /// pixel centre: fast, but a sharp edge inside a pixel is all or nothing (aliased).
    pub fn new(
        scene: &Scene,
        rig: &Rig,
        camera: usize,
        time_s: f64,
    ) -> Result<Renderer, TwinError> {
        Self::with_pixel_samples(scene, rig, camera, time_s, 1)
    }

    /// As [`Self::new`], but every image pixel integrates `samples` x `samples` rays
    /// over its area (see [`CameraGeometry::sampled`]), as a real pixel integrates
    /// light: edges inside a pixel give the grey level of their area share, which
    /// sub-pixel corner and edge detection need. Costs `samples`^2 the ray casting and
    /// pattern look-ups; the truth stays one ray per pixel centre.
    /// [`CALIBRATION_PIXEL_SAMPLES`] suits checkerboard renders; smooth fringes on
    /// smooth surfaces are fine with 1.
    pub fn with_pixel_samples(
        scene: &Scene,
        rig: &Rig,
        camera: usize,
        time_s: f64,
        samples: u32,
    ) -> Result<Renderer, TwinError> {
        let posed = scene.at(time_s);
        let geometry = Arc::new(CameraGeometry::new(&posed, rig, camera)?);
        let sampled = if samples == 1 {
            None
        } else {
            Some(Arc::new(CameraGeometry::sampled(
                &posed, rig, camera, samples,
            )?))
        };
        Ok(Self::with_geometry(rig, geometry, sampled, samples))
    }

    /// As [`Self::new`] with the camera's rays already computed for this rig
    /// (one per pixel): a moving scene seen by a fixed rig pays for the rays
    /// once, and each new pose only for casting them.
    pub fn posed(
        scene: &Scene,
        rig: &Rig,
        rays: &CameraRays,
        time_s: f64,
    ) -> Result<Renderer, TwinError> {
        if rays.samples() != 1 {
            return Err(TwinError::BadParameter {
                name: "camera rays per pixel and axis",
                value: f64::from(rays.samples()),
                why: "a posed renderer takes one ray per pixel",
            });
        }
        let geometry = CameraGeometry::from_rays(&scene.at(time_s), rig, rays)?;
        Ok(Self::with_geometry(rig, Arc::new(geometry), None, 1))
    }

    fn with_geometry(
        rig: &Rig,
        geometry: Arc<CameraGeometry>,
        sampled: Option<Arc<CameraGeometry>>,
        pixel_samples: u32,
    ) -> Renderer {
        Renderer {
            rig: rig.clone(),
            geometry,
            sampled,
            pixel_samples,
            defocus_cache: Mutex::new(Vec::new()),
        }
    }

    /// Rays per pixel and axis the image is rendered with.
    pub fn pixel_samples(&self) -> u32 {
        self.pixel_samples
    }

    /// The cached geometry.
    pub fn geometry(&self) -> &CameraGeometry {
        &self.geometry
    }

    /// Linear exposures for what each projector displayed during `exposure`
    /// (cheap: pattern look-ups only, no ray casting).
    pub fn exposed(
        &self,
        timelines: &[ProjectorTimeline],
        exposure: Exposure,
    ) -> Result<Exposed, TwinError> {
        exposure.validate()?;
        if timelines.len() != self.rig.projectors.len() {
            return Err(TwinError::TimelineCount {
                given: timelines.len(),
                expected: self.rig.projectors.len(),
            });
        }
        // Light is gathered per ray (sub-pixel sample), then averaged per pixel.
        let g = self.sampled.as_ref().unwrap_or(&self.geometry);
        let (w, h) = (g.width as usize, g.height as usize);
        let secs = exposure.duration_s() as f32;
        let mut ambient: Vec<[f32; 3]> = g.ambient.iter().map(|a| a.map(|v| v * secs)).collect();
        let mut per_projector = Vec::with_capacity(timelines.len());
        for (pi, tl) in timelines.iter().enumerate() {
            let proj = &self.rig.projectors[pi];
            let mut active: Vec<(Arc<Pattern>, [f32; 3])> = Vec::new();
            let mut mean_drive = [0.0f64; 3];
            for s in &tl.shown {
                if !(s.start_s.is_finite() && s.end_s.is_finite() && s.end_s >= s.start_s) {
                    return Err(TwinError::BadInterval {
                        start_s: s.start_s,
                        end_s: s.end_s,
                    });
                }
                let k = &proj.model.intrinsics;
                if s.pattern.width != k.width || s.pattern.height != k.height {
                    return Err(TwinError::PatternSize {
                        projector: pi,
                        got_w: s.pattern.width,
                        got_h: s.pattern.height,
                        want_w: k.width,
                        want_h: k.height,
                    });
                }
                // Fields are public: a hand-made pattern may not match its size.
                if s.pattern.values.len() != k.width as usize * k.height as usize {
                    return Err(TwinError::PatternBuffer {
                        len: s.pattern.values.len(),
                        width: k.width,
                        height: k.height,
                    });
                }
                if s.led.iter().any(|l| !(l.is_finite() && *l >= 0.0)) {
                    return Err(TwinError::BadParameter {
                        name: "LED drive",
                        value: s.led.iter().map(|&l| l as f64).fold(f64::NAN, f64::min),
                        why: "must be finite and >= 0",
                    });
                }
                // (plane, interval): the whole pattern, or each of its bit planes.
                let parts: Vec<(Option<u8>, f64, f64)> = match s.display {
                    Display::Steady => vec![(None, s.start_s, s.end_s)],
                    Display::BitPlanes => bit_plane_intervals(s.start_s, s.end_s)
                        .iter()
                        .map(|&(k, a, b)| (Some(k), a, b))
                        .collect(),
                };
                for (plane, a, b) in parts {
                    let dt = exposure.overlap_s(a, b);
                    if dt > 0.0 {
                        let weight = s.led.map(|l| l * dt as f32);
                        let lit = self.defocused(&s.pattern, pi, plane);
                        let mean = lit.mean() as f64;
                        for b in 0..3 {
                            mean_drive[b] += weight[b] as f64 * mean;
                        }
                        active.push((lit, weight));
                    }
                }
            }
            let view = &g.projectors[pi];
            let k = &proj.model.intrinsics;
            let mut img = vec![[0.0f32; 3]; w * h];
            img.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                let gains = &view.gain[y * w..(y + 1) * w];
                let uvs = &view.uv_px[y * w..(y + 1) * w];
                // One bilinear tap per lit pixel, shared by every pattern.
                let taps: Vec<Option<Tap>> = gains
                    .iter()
                    .zip(uvs)
                    .map(|(g, [u, v])| {
                        if *g == [0.0; 3] {
                            None
                        } else {
                            Tap::new(k.width, k.height, *u, *v)
                        }
                    })
                    .collect();
                // Pattern-major within a row: one pattern's few DMD lines stay
                // in cache while the row samples them (24 patterns of 1 MP do not fit).
                for (pat, wgt) in &active {
                    for (out, tap) in row.iter_mut().zip(&taps) {
                        if let Some(tap) = tap {
                            let s = pat.sample_tap(tap);
                            for b in 0..3 {
                                out[b] += wgt[b] * s;
                            }
                        }
                    }
                }
                for (out, gain) in row.iter_mut().zip(gains) {
                    for b in 0..3 {
                        out[b] *= gain[b];
                    }
                }
            });
            if let Medium::Water(water) = &self.rig.medium {
                // Backscatter: light the projector puts into the water the camera looks through.
                let veil_drive = [0, 1, 2].map(|b| proj.led_power[b] * mean_drive[b]);
                for (o, &path) in img.iter_mut().zip(&g.water_path_m) {
                    let veil = water.veil(path as f64);
                    for b in 0..3 {
                        o[b] += (veil * veil_drive[b]) as f32;
                    }
                }
            }
            per_projector.push(img);
        }
        let g = &self.geometry;
        let (w, h) = (g.width as usize, g.height as usize);
        if self.pixel_samples > 1 {
            let k = self.pixel_samples as usize;
            ambient = box_average(&ambient, w, h, k);
            for p in per_projector.iter_mut() {
                *p = box_average(p, w, h, k);
            }
        }
        if let Medium::Water(water) = &self.rig.medium {
            let sigma: Vec<f32> = g
                .water_path_m
                .iter()
                .map(|&p| p * water.forward_sigma_px_per_m as f32)
                .collect();
            ambient = blur_varying(&ambient, w, h, &sigma);
            for p in per_projector.iter_mut() {
                *p = blur_varying(p, w, h, &sigma);
            }
        }
        Ok(Exposed {
            width: g.width,
            height: g.height,
            ambient,
            per_projector,
        })
    }

    /// The pattern as projector `pi` puts it on the scene: its gamma, then
    /// its lens defocus (cached).
    fn defocused(&self, pattern: &Arc<Pattern>, pi: usize, plane: Option<u8>) -> Arc<Pattern> {
        let mut cache = self.defocus_cache.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, _, _, d)) = cache
            .iter()
            .find(|(p, i, k, _)| *i == pi && *k == plane && Arc::ptr_eq(p, pattern))
        {
            return d.clone();
        }
        let proj = &self.rig.projectors[pi];
        // Gamma acts on the displayed grey level, before the lens blurs it.
        let mut shown = match plane {
            Some(k) => pattern.bit_plane(k),
            None => (**pattern).clone(),
        };
        if proj.gamma != 1.0 {
            shown
                .values
                .iter_mut()
                .for_each(|v| *v = v.max(0.0).powf(proj.gamma as f32));
        }
        let d = Arc::new(shown.defocused(proj.defocus_sigma_px));
        if cache.len() >= DEFOCUS_CACHE {
            cache.remove(0);
        }
        cache.push((pattern.clone(), pi, plane, d.clone()));
        d
    }

    /// Only the noisy sensor image and its saturation mask: the fast path
    /// of a simulated camera.
    pub fn image(
        &self,
        timelines: &[ProjectorTimeline],
        exposure: Exposure,
        sensor: &SensorModel,
        noise_seed: u64,
    ) -> Result<(Image, Vec<bool>), TwinError> {
        sensor.validate()?;
        let e = self.exposed(timelines, exposure)?;
        Ok(sensor.expose(e.width, e.height, &e.total(), Some(noise_seed)))
    }

    /// A full frame: exposures, sensor image with noise from `noise_seed`,
    /// clean images and truth.
    pub fn frame(
        &self,
        timelines: &[ProjectorTimeline],
        exposure: Exposure,
        sensor: &SensorModel,
        noise_seed: u64,
    ) -> Result<Frame, TwinError> {
        let exposed = self.exposed(timelines, exposure)?;
        finish(self.geometry.clone(), exposed, sensor, noise_seed)
    }
}

/// Mean of each `k` x `k` block of a `w k` x `h k` image: the `w` x `h` image.
fn box_average(fine: &[[f32; 3]], w: usize, h: usize, k: usize) -> Vec<[f32; 3]> {
    let fine_w = w * k;
    let scale = 1.0 / (k * k) as f32;
    let mut out = vec![[0.0f32; 3]; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for sy in 0..k {
            let line = &fine[(y * k + sy) * fine_w..(y * k + sy + 1) * fine_w];
            for (o, block) in row.iter_mut().zip(line.chunks_exact(k)) {
                for v in block {
                    for b in 0..3 {
                        o[b] += v[b];
                    }
                }
            }
        }
        for o in row.iter_mut() {
            for v in o.iter_mut() {
                *v *= scale;
            }
        }
    });
    out
}

fn finish(
    geometry: Arc<CameraGeometry>,
    exposed: Exposed,
    sensor: &SensorModel,
    noise_seed: u64,
) -> Result<Frame, TwinError> {
    sensor.validate()?;
    let (w, h) = (exposed.width, exposed.height);
    let total = exposed.total();
    let (image, _) = sensor.expose(w, h, &total, Some(noise_seed));
    let (clean, saturated) = sensor.expose(w, h, &total, None);
    let per_projector_clean = (0..exposed.per_projector.len())
        .map(|p| sensor.expose(w, h, &exposed.single(p), None).0)
        .collect();
    Ok(Frame {
        image,
        clean,
        per_projector_clean,
        truth: Truth {
            geometry,
            saturated,
        },
        exposed,
    })
}

/// One time slice of a moving scene's exposure and the instant its scene
/// is posed at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionSlice {
    /// The part of the exposure it integrates.
    pub exposure: Exposure,
    /// When its scene is posed, seconds: the middle of the projector light
    /// it holds (of the whole slice when it holds none).
    pub pose_s: f64,
}

/// The time slices a moving scene's `exposure` is rendered in, in time
/// order. The exposure is cut at every start and end of a pattern any
/// projector showed inside it, so each displayed pattern's light is posed at
/// that pattern's own middle and lands where the surface was while it was
/// on (seed 001: 24 patterns of 200 us in one 4.8 ms exposure, each
/// triangulated at its own instant). A stretch lit by no pattern goes half
/// to each lit neighbour (only ambient light, which needs no ray cast of its
/// own). Then the slices with the longest light are halved until there are
/// [`MOTION_SAMPLES`], so one long pattern still blurs. Cuts closer than
/// [`MIN_MOTION_SLICE_S`] to the previous one are skipped. The slices tile
/// the exposure exactly.
pub fn motion_slices(timelines: &[ProjectorTimeline], exposure: Exposure) -> Vec<MotionSlice> {
    let (start, end) = (exposure.start_s, exposure.end_s);
    let mut cuts: Vec<f64> = timelines
        .iter()
        .flat_map(|tl| &tl.shown)
        .flat_map(|s| [s.start_s, s.end_s])
        // Also drops NaN.
        .filter(|&t| t > start && t < end)
        .collect();
    cuts.sort_by(f64::total_cmp);
    let mut edges = vec![start];
    for t in cuts {
        let last = edges[edges.len() - 1];
        if t - last >= MIN_MOTION_SLICE_S && end - t >= MIN_MOTION_SLICE_S {
            edges.push(t);
        }
    }
    edges.push(end);
    let lit = |a: f64, b: f64| {
        let piece = Exposure {
            start_s: a,
            end_s: b,
        };
        timelines
            .iter()
            .flat_map(|tl| &tl.shown)
            .any(|s| piece.overlap_s(s.start_s, s.end_s) > 0.0)
    };
    // (slice start, slice end, light start, light end).
    let mut slices: Vec<[f64; 4]> = Vec::new();
    // Start of a dark stretch not yet given to a slice.
    let mut dark_from: Option<f64> = None;
    for w in edges.windows(2) {
        let (a, b) = (w[0], w[1]);
        if !lit(a, b) {
            dark_from.get_or_insert(a);
            continue;
        }
        let mut from = a;
        if let Some(d) = dark_from.take() {
            match slices.last_mut() {
                // Between two lit slices: half to each.
                Some(prev) => {
                    let mid = 0.5 * (d + a);
                    prev[1] = mid;
                    from = mid;
                }
                // Before the first light: all to it.
                None => from = d,
            }
        }
        slices.push([from, b, a, b]);
    }
    match (dark_from, slices.last_mut()) {
        // After the last light: all to it.
        (Some(_), Some(last)) => last[1] = end,
        // No light at all: ambient over the whole exposure.
        (_, None) => slices.push([start, end, start, end]),
        (None, Some(_)) => {}
    }
    while slices.len() < MOTION_SAMPLES {
        // The first of the longest lights, so that one halves into 8 equal ones.
        let mut i = 0;
        for (k, s) in slices.iter().enumerate() {
            if s[3] - s[2] > slices[i][3] - slices[i][2] {
                i = k;
            }
        }
        let [a, b, la, lb] = slices[i];
        let mid = 0.5 * (la + lb);
        slices[i] = [a, mid, la, mid];
        slices.insert(i + 1, [mid, b, mid, lb]);
    }
    slices
        .into_iter()
        .map(|[a, b, la, lb]| MotionSlice {
            exposure: Exposure {
                start_s: a,
                end_s: b,
            },
            pose_s: 0.5 * (la + lb),
        })
        .collect()
}

/// Renders what camera `camera` records during `exposure` while each
/// projector shows its timeline: the entry point for simulated cameras.
/// A static scene is ray-cast once; a moving one once per slice of
/// [`motion_slices`] (at least [`MOTION_SAMPLES`], and one per displayed
/// pattern), posed at the middle of the slice's light, whose exposures add
/// up. The truth is at mid-exposure. Noise comes from `rng`.
pub fn render_exposure(
    scene: &Scene,
    rig: &Rig,
    camera: usize,
    timelines: &[ProjectorTimeline],
    exposure: Exposure,
    sensor: &SensorModel,
    rng: &mut impl Rng,
) -> Result<Frame, TwinError> {
    exposure.validate()?;
    let mid = 0.5 * (exposure.start_s + exposure.end_s);
    // Every pose (the truth's and each slice's) casts the same rays.
    let rays = CameraRays::new(rig, camera, 1)?;
    let truth_renderer = Renderer::posed(scene, rig, &rays, mid)?;
    let exposed = if scene.is_dynamic() {
        let mut acc: Option<Exposed> = None;
        for slice in motion_slices(timelines, exposure) {
            let r = Renderer::posed(scene, rig, &rays, slice.pose_s)?;
            let e = r.exposed(timelines, slice.exposure)?;
            match acc.as_mut() {
                None => acc = Some(e),
                Some(a) => a.accumulate(&e),
            }
        }
        acc.expect("motion_slices gives at least MOTION_SAMPLES > 0 slices")
    } else {
        truth_renderer.exposed(timelines, exposure)?
    };
    finish(
        truth_renderer.geometry.clone(),
        exposed,
        sensor,
        rng.random(),
    )
}

#[cfg(test)]
mod motion_tests;
