//! One colour long exposure -> 24 absolute phase maps and 24 depth maps, each
//! at its own pattern's instant.
//!
//! After demultiplexing ([`super::demux`]), every pixel is unwrapped on its own
//! by projection distance minimisation along its epipolar segment: the camera
//! ray, sampled between the nearest and farthest depth of the working range,
//! crosses each direction's three fringes (R, G, B) at known phases, and the
//! one depth where all three wrapped phases agree wins (seed 001's PDM, eq. 4,
//! with the calibration's geometry in place of the full DMD: the whole DMD is
//! ambiguous for these 2-D patterns, 2898 x 1170 covers each axis, not their
//! mix). Each pattern's absolute phase then gives its own depth along the ray,
//! so the 24 depth maps are 24 instants 200 us apart, not one average.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::demux::{Demultiplexed, Demultiplexer, DemuxOptions};
use super::fdd::FddNet;
use super::set::{PatternSet, SetPattern};
use super::zocr::ZocrNet;
use super::HighSpeedError;
use crate::calibration::{Head, Pose, ProjectorModel};
use crate::huge_pages::filled_vec;
use crate::raster::Raster;
use crate::simd::{simd_run, Simd};

/// How one exposure is decoded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DecoderConfig {
    /// Nearest and farthest surface depth (camera z), metres: the epipolar segment.
    pub depth_range_m: (f64, f64),
    /// Most samples of each pixel's epipolar segment (evenly in inverse depth,
    /// at most [`MAX_SAMPLES`]): the decoder takes the fewest (at least 2)
    /// whose straight segments stay within `max_chord_px` of the DMD curve.
    pub samples: usize,
    /// Largest distance, DMD pixels, between a segment's chord and the DMD
    /// curve it stands for (the camera ray through the projector's lens):
    /// at 0.05 px a pattern's predicted phase is off by at most 0.004
    /// cycles at the shortest period here (13 px), far inside
    /// `max_rms_cycles`, and each depth is refined on the exact curve anyway.
    pub max_chord_px: f64,
    /// Largest RMS disagreement of a direction's three phases, cycles.
    pub max_rms_cycles: f64,
    /// Smallest modulation of a pattern, as a share of its LED's mean background
    /// (zero order / directions).
    pub min_modulation_ratio: f32,
    /// Camera value (full scale 1) from which a channel counts as saturated.
    pub saturation_level: f32,
    /// Largest share of saturated pixels before the exposure is refused.
    pub max_saturated_share: f64,
    /// The demultiplexer's stages.
    pub demux: DemuxOptions,
    /// Which build of the per-pixel unwrapping runs (both give the same bits;
    /// the AVX2 one is faster where the CPU has it).
    pub simd: Simd,
}

impl Default for DecoderConfig {
    fn default() -> Self {
        Self {
            depth_range_m: (0.38, 0.66),
            samples: 16,
            max_chord_px: 0.05,
            max_rms_cycles: 0.08,
            min_modulation_ratio: 0.25,
            saturation_level: 0.995,
            max_saturated_share: 0.05,
            demux: DemuxOptions::default(),
            simd: Simd::best(),
        }
    }
}

/// The most samples of an epipolar segment ([`DecoderConfig::samples`]).
pub const MAX_SAMPLES: usize = 64;

/// One pattern's instant.
#[derive(Clone, Debug, PartialEq)]
pub struct InstantMap {
    /// The pattern.
    pub pattern: SetPattern,
    /// Absolute phase, radians (NaN where not decoded).
    pub absolute_phase: Vec<f32>,
    /// Depth (camera z), metres (NaN where not decoded).
    pub depth_m: Vec<f32>,
}

/// A decoded exposure.
#[derive(Clone, Debug, PartialEq)]
pub struct Decoded {
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// The demultiplexed fringes (wrapped phases, modulations, zero orders).
    pub fringes: Demultiplexed,
    /// The 24 instants in projection order.
    pub instants: Vec<InstantMap>,
    /// Pixels saturated in some channel (left undecoded).
    pub saturated: usize,
}

/// The decoder of one head (calibrated camera and projector) and one set.
pub struct Decoder {
    set: PatternSet,
    /// Camera frame -> projector frame.
    camera_to_projector: Pose,
    projector: ProjectorModel,
    width: usize,
    height: usize,
    /// Per pixel, the undistorted normalised ray (x, y); NaN where undistortion fails.
    rays: Vec<[f64; 2]>,
    /// Samples of each epipolar segment in use (see [`DecoderConfig::samples`]).
    samples: usize,
    demux: Demultiplexer,
    /// ZOCR-Net in place of the analytic zero-order and crosstalk removal.
    zocr: Option<ZocrNet>,
    /// FDD-Net correcting the demodulated phases.
    fdd: Option<FddNet>,
    config: DecoderConfig,
}

impl Decoder {
    /// Sets up for `head`'s camera images and `set` on its projector.
    pub fn new(
        set: PatternSet,
        head: &Head,
        config: DecoderConfig,
    ) -> Result<Self, HighSpeedError> {
        let (near, far) = config.depth_range_m;
        let range_ok = near.is_finite() && far.is_finite() && near > 0.0 && far > near;
        let samples_ok = (2..=MAX_SAMPLES).contains(&config.samples);
        // NaN fails this too.
        let chord_ok = config.max_chord_px > 0.0;
        if !(range_ok && samples_ok && chord_ok) {
            return Err(HighSpeedError::BadConfig {
                why: format!(
                    "depth range {near}..{far} m with {} samples within {} px: need 0 < near < far, 2 to {MAX_SAMPLES} samples and a tolerance above 0",
                    config.samples, config.max_chord_px
                ),
            });
        }
        let dmd = (head.projector.width_px, head.projector.height_px);
        if dmd != set.dmd_px() {
            return Err(HighSpeedError::BadPatternSet {
                why: format!(
                    "the set is made for a {}x{} DMD, head {}'s projector has {}x{}",
                    set.dmd_px().0,
                    set.dmd_px().1,
                    head.name,
                    dmd.0,
                    dmd.1
                ),
            });
        }
        let camera = head.camera;
        let projector = head.projector;
        let (width, height) = (camera.width_px as usize, camera.height_px as usize);
        let rays = camera.normalised_grid();
        let camera_to_projector = projector.pose.compose(&camera.pose.inverse());
        let z_ref = 2.0 / (1.0 / near + 1.0 / far);
        let reference: Vec<[f64; 2]> = rays
            .par_iter()
            .map(|r| {
                let along = ray_in_projector(&camera_to_projector, r);
                dmd_on_ray(&camera_to_projector, &projector, &along, 1.0 / z_ref)
                    .unwrap_or([f64::NAN; 2])
            })
            .collect();
        let demux = Demultiplexer::new(&set, width, height, reference, config.demux)?
            .with_simd(config.simd);
        let samples = fewest_samples(&rays, width, &camera_to_projector, &projector, &config);
        Ok(Self {
            set,
            camera_to_projector,
            projector,
            width,
            height,
            rays,
            samples,
            demux,
            zocr: None,
            fdd: None,
            config,
        })
    }

    /// The same decoder with ZOCR-Net removing the zero order and the colour
    /// crosstalk (the demultiplexer's analytic steps 1 and 2 then unused).
    pub fn with_zocr(mut self, net: ZocrNet) -> Self {
        self.zocr = Some(net);
        self
    }

    /// The ZOCR-Net in use, if any.
    pub fn zocr(&self) -> Option<&ZocrNet> {
        self.zocr.as_ref()
    }

    /// The same decoder with FDD-Net correcting every pattern's
    /// demodulated phase before unwrapping. Refused after refined
    /// demodulations: the network learnt the single pass's errors.
    pub fn with_fdd(mut self, net: FddNet) -> Result<Self, HighSpeedError> {
        let refinements = self.config.demux.refinements;
        if refinements > 0 {
            return Err(HighSpeedError::BadConfig {
                why: format!(
                    "FDD-Net corrects the single-pass demodulation's phases; this decoder refines them {refinements} time(s)"
                ),
            });
        }
        self.fdd = Some(net);
        Ok(self)
    }

    /// The FDD-Net in use, if any.
    pub fn fdd(&self) -> Option<&FddNet> {
        self.fdd.as_ref()
    }

    /// The same decoder undoing the camera's colour crosstalk `m` (measured
    /// from LED flats after the decoder was checked against the rig): only
    /// the demultiplexer's unmixing changes; the rays and the reference
    /// plane, the costly part of [`Decoder::new`], are kept.
    pub fn with_crosstalk(mut self, m: nalgebra::Matrix3<f64>) -> Result<Self, HighSpeedError> {
        self.demux = self.demux.with_crosstalk(m)?;
        self.config.demux.crosstalk = Some(m);
        Ok(self)
    }

    /// The pattern set.
    pub fn set(&self) -> &PatternSet {
        &self.set
    }

    /// The demultiplexer.
    pub fn demultiplexer(&self) -> &Demultiplexer {
        &self.demux
    }

    /// Image size (width, height).
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Samples of each pixel's epipolar segment in use.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// The point at depth `z_m` on pixel `i`'s ray, in the camera frame (metres).
    pub fn point(&self, i: usize, z_m: f32) -> [f32; 3] {
        let r = self.rays[i];
        [r[0] as f32 * z_m, r[1] as f32 * z_m, z_m]
    }

    /// Decodes one exposure: camera channels R, G, B, full scale 1.
    pub fn decode(&self, channels: [&Raster<f32>; 3]) -> Result<Decoded, HighSpeedError> {
        for c in channels {
            if c.size() != (self.width, self.height) || c.data.len() != self.width * self.height {
                return Err(HighSpeedError::WrongSize {
                    what: "colour exposure".into(),
                    expected: (self.width, self.height),
                    got: c.size(),
                });
            }
            if c.data.iter().any(|v| !v.is_finite()) {
                return Err(HighSpeedError::NotFinite);
            }
        }
        let level = self.config.saturation_level;
        let saturated_px: Vec<bool> = (0..self.width * self.height)
            .map(|i| channels.iter().any(|c| c.data[i] >= level))
            .collect();
        let saturated = saturated_px.iter().filter(|&&s| s).count();
        let share = saturated as f64 / saturated_px.len() as f64;
        if share > self.config.max_saturated_share {
            return Err(HighSpeedError::Saturated {
                share,
                limit: self.config.max_saturated_share,
            });
        }
        let planes = [&channels[0].data[..], &channels[1].data, &channels[2].data];
        let cleaned = match &self.zocr {
            Some(net) => net.remove_zero_order(planes, self.width, self.height)?,
            None => self.demux.remove_zero_order(planes),
        };
        let mut fringes = self.demux.demodulate_all(cleaned);
        if let Some(net) = &self.fdd {
            fringes.wrapped =
                net.correct(&self.demux, &self.set, &fringes, self.width, self.height)?;
        }
        let p = self.set.patterns().len();
        let (w, h) = (self.width, self.height);
        // Maps 0..p: absolute phase of pattern m; p..2p: its depth. Filled in
        // bands of rows, each band's slice of every map written by one task, so
        // no per-pixel record is gathered into 48 maps afterwards.
        // NaN where not decoded; on huge pages and filled by all cores: the
        // 48 maps are 250 MB at 1280x1024, ~61,000 faults on 4 KiB pages.
        let mut maps: Vec<Vec<f32>> = (0..2 * p).map(|_| filled_vec(w * h, f32::NAN)).collect();
        const BAND_ROWS: usize = 4;
        let mut bands: Vec<Vec<&mut [f32]>> = (0..h.div_ceil(BAND_ROWS))
            .map(|_| Vec::with_capacity(2 * p))
            .collect();
        for map in &mut maps {
            for (band, rows) in bands.iter_mut().zip(map.chunks_mut(BAND_ROWS * w)) {
                band.push(rows);
            }
        }
        // Built for AVX2 where the CPU has it: round, floor and ceil become
        // instructions instead of libm calls (same bits).
        let simd = self.config.simd;
        bands.into_par_iter().enumerate().for_each(|(b, mut out)| {
            simd_run!(simd, {
                // One scratch per band, written where read: it was a fresh
                // NaN-filled 1.5 KB per direction, eight times a pixel.
                let mut scratch = ChunkScratch {
                    dmd: vec![[f64::NAN; 2]; CHUNK * self.samples],
                    along: [Vector3::zeros(); CHUNK],
                    phases: [[f64::NAN; MAX_SAMPLES]; 3],
                    newton: [[NewtonStep::NONE; CHUNK]; 3],
                };
                let first = b * BAND_ROWS * w;
                let len = out[0].len();
                for start in (0..len).step_by(CHUNK) {
                    let chunk = start..(start + CHUNK).min(len);
                    self.decode_chunk(
                        first,
                        chunk,
                        &saturated_px,
                        &fringes,
                        &mut out,
                        &mut scratch,
                    );
                }
            })
        });
        let instants = self
            .set
            .patterns()
            .iter()
            .map(|pattern| {
                let m = pattern.index;
                InstantMap {
                    pattern: *pattern,
                    absolute_phase: std::mem::take(&mut maps[m]),
                    depth_m: std::mem::take(&mut maps[p + m]),
                }
            })
            .collect();
        Ok(Decoded {
            width: w,
            height: h,
            fringes,
            instants,
            saturated,
        })
    }

    /// The pixels `first + chunk`: per pattern `m` its absolute phase into
    /// `out[m][at]` and its depth into `out[p + m][at]` (p patterns, `at` in
    /// `chunk`); untouched where not decoded. Direction by direction over the
    /// chunk, not pixel by pixel: a pixel's directions read 51 maps and write
    /// 48, more streams than the caches follow, a direction's only 15.
    #[inline(always)]
    fn decode_chunk(
        &self,
        first: usize,
        chunk: std::ops::Range<usize>,
        saturated: &[bool],
        fringes: &Demultiplexed,
        out: &mut [&mut [f32]],
        scratch: &mut ChunkScratch,
    ) {
        let (s0, ds) = self.segment_steps();
        let j_count = self.samples;
        let ChunkScratch {
            dmd,
            along,
            phases: buffers,
            newton,
        } = scratch;
        // Each pixel's samples on the DMD; a NaN ray marks a pixel that is
        // not decoded (saturated, or no ray).
        for (k, at) in chunk.clone().enumerate() {
            let i = first + at;
            let ray = self.rays[i];
            if saturated[i] || !ray[0].is_finite() {
                along[k] = Vector3::from_element(f64::NAN);
                continue;
            }
            let samples = &mut dmd[k * j_count..(k + 1) * j_count];
            along[k] = ray_in_projector(&self.camera_to_projector, &ray);
            for (j, d) in samples.iter_mut().enumerate() {
                let s = s0 + j as f64 * ds;
                *d = dmd_on_ray_or_nan(&self.camera_to_projector, &self.projector, &along[k], s);
            }
        }
        let directions = self.set.directions();
        let p = self.set.patterns().len();
        for n in 1..=directions as u32 {
            let pats = [0, 1, 2].map(|c| self.set.pattern(n, c));
            for steps in newton.iter_mut() {
                steps.fill(NewtonStep::NONE);
            }
            for (k, at) in chunk.clone().enumerate() {
                if !along[k].x.is_finite() {
                    continue;
                }
                let i = first + at;
                let dmd = &dmd[k * j_count..(k + 1) * j_count];
                let mut wrapped = [0.0f64; 3];
                let mut good = true;
                for (c, pat) in pats.iter().enumerate() {
                    let m = pat.index;
                    let zero = fringes.zero_order[c][i] / directions as f32;
                    let modulation = fringes.modulation[m][i];
                    good &= zero > 0.0 && modulation >= self.config.min_modulation_ratio * zero;
                    wrapped[c] = f64::from(fringes.wrapped[m][i]) / std::f64::consts::TAU;
                }
                if !good {
                    continue;
                }
                for (buffer, pat) in buffers.iter_mut().zip(&pats) {
                    for (b, p) in buffer[..j_count].iter_mut().zip(dmd) {
                        *b = pat.frequency[0] * p[0] + pat.frequency[1] * p[1];
                    }
                }
                let phases = [
                    &buffers[0][..j_count],
                    &buffers[1][..j_count],
                    &buffers[2][..j_count],
                ];
                let Some((j, tau, rms)) = pdm_along(&phases, &wrapped) else {
                    continue;
                };
                if rms > self.config.max_rms_cycles {
                    continue;
                }
                for (c, ph) in phases.iter().enumerate() {
                    let predicted = ph[j] + tau * (ph[j + 1] - ph[j]);
                    let absolute = wrapped[c] + (predicted - wrapped[c]).round();
                    if let Some(step) = self.depth_step(ph, dmd, absolute, j, s0, ds) {
                        newton[c][k] = step;
                    }
                }
            }
            // The Newton steps of the chunk's pixels, colour by colour: one
            // projection each, in a loop without branches over the pixels
            // (vector lanes); a pixel without a step gets NaN, which its maps
            // already hold.
            for (steps, pat) in newton.iter().zip(&pats) {
                let f = pat.frequency;
                let (phase_out, depth_out) = out_pair(out, pat.index, p + pat.index);
                let lanes = phase_out[chunk.clone()]
                    .iter_mut()
                    .zip(&mut depth_out[chunk.clone()])
                    .zip(steps.iter().zip(along.iter()));
                for ((phase, depth), (step, along)) in lanes {
                    let s = step.solve(&self.camera_to_projector, &self.projector, along, f);
                    // NaN (no step, or behind the projector) fails this too.
                    let ok = s > 0.0;
                    *phase = if ok {
                        (std::f64::consts::TAU * step.absolute) as f32
                    } else {
                        f32::NAN
                    };
                    *depth = if ok { (1.0 / s) as f32 } else { f32::NAN };
                }
            }
        }
    }

    /// The first sample's inverse depth and the step between samples.
    #[inline(always)]
    fn segment_steps(&self) -> (f64, f64) {
        segment_steps(self.config.depth_range_m, self.samples)
    }

    /// Where the Newton step toward the inverse depth at which a pattern's phase
    /// along the ray is `absolute` cycles starts: the samples' segment that
    /// brackets it, searched outward from segment `near` (where PDM put the
    /// pixel: the bracket is there or next to it), and the point on its chord.
    /// `None` off the segment or the DMD (judged on the segment's DMD points, a
    /// fraction of a pixel from exact).
    #[inline(always)]
    fn depth_step(
        &self,
        ph: &[f64],
        dmd: &[[f64; 2]],
        absolute: f64,
        near: usize,
        s0: f64,
        ds: f64,
    ) -> Option<NewtonStep> {
        let brackets = |j: usize| {
            let (a, b) = (ph[j], ph[j + 1]);
            a.is_finite() && b.is_finite() && (a - absolute) * (b - absolute) <= 0.0 && a != b
        };
        let segments = ph.len() - 1;
        let j = (0..segments).find_map(|d| {
            if d <= near && brackets(near - d) {
                Some(near - d)
            } else {
                (near + d < segments && brackets(near + d)).then_some(near + d)
            }
        })?;
        let slope = (ph[j + 1] - ph[j]) / ds;
        let tau = (absolute - ph[j]) / (ph[j + 1] - ph[j]);
        let s = s0 + j as f64 * ds + tau * ds;
        let (w, h) = self.set.dmd_px();
        let (a, b) = (dmd[j], dmd[j + 1]);
        let u = a[0] + tau * (b[0] - a[0]);
        let v = a[1] + tau * (b[1] - a[1]);
        let inside = u >= -0.5 && v >= -0.5 && u < w as f64 - 0.5 && v < h as f64 - 0.5;
        inside.then_some(NewtonStep { s, slope, absolute })
    }
}

/// One pattern's depth at one pixel before its Newton step: the inverse depth
/// on the chord, the phase's slope there (cycles per unit inverse depth) and
/// the absolute phase (cycles) it solves for; `s` NaN where there is none.
#[derive(Clone, Copy)]
struct NewtonStep {
    s: f64,
    slope: f64,
    absolute: f64,
}

impl NewtonStep {
    const NONE: NewtonStep = NewtonStep {
        s: f64::NAN,
        slope: f64::NAN,
        absolute: f64::NAN,
    };

    /// The inverse depth after one Newton step on the exact projection of the
    /// ray `along` ([`ray_in_projector`]) for a pattern of spatial `frequency`;
    /// NaN without a step or behind the projector. No branch: the decoder runs
    /// it over a chunk's pixels in vector lanes.
    #[inline(always)]
    fn solve(
        &self,
        camera_to_projector: &Pose,
        projector: &ProjectorModel,
        along: &Vector3<f64>,
        frequency: [f64; 2],
    ) -> f64 {
        let q = dmd_on_ray_or_nan(camera_to_projector, projector, along, self.s);
        self.s - (frequency[0] * q[0] + frequency[1] * q[1] - self.absolute) / self.slope
    }
}

/// Maps `a` and `b` of `out` at once (`a < b`).
fn out_pair<'a>(out: &'a mut [&mut [f32]], a: usize, b: usize) -> (&'a mut [f32], &'a mut [f32]) {
    debug_assert!(a < b);
    let (low, high) = out.split_at_mut(b);
    (&mut *low[a], &mut *high[0])
}

/// Pixels decoded together by [`Decoder::decode_chunk`].
const CHUNK: usize = 64;

/// One band's scratch for [`Decoder::decode_chunk`]: a chunk's pixels' rays in
/// the projector frame and their samples' DMD points (pixel-major), and one
/// direction's three phases at one pixel's samples.
struct ChunkScratch {
    dmd: Vec<[f64; 2]>,
    along: [Vector3<f64>; CHUNK],
    phases: [[f64; MAX_SAMPLES]; 3],
    newton: [[NewtonStep; CHUNK]; 3],
}

/// `samples` points evenly in inverse depth over `depth_range_m` (near, far):
/// the first one's inverse depth (1 / far) and the step between them.
#[inline(always)]
fn segment_steps(depth_range_m: (f64, f64), samples: usize) -> (f64, f64) {
    let (near, far) = depth_range_m;
    let (s0, s1) = (1.0 / far, 1.0 / near);
    (s0, (s1 - s0) / (samples - 1) as f64)
}

/// The fewest samples (2 to `config.samples`) whose segments' chords stay
/// within `config.max_chord_px` of the DMD curve, judged at the segments'
/// middles on a grid of pixels (every 16th row and column): the curve is a
/// projective line bent by the projector's distortion, so its chords are
/// farthest from it there.
fn fewest_samples(
    rays: &[[f64; 2]],
    width: usize,
    camera_to_projector: &Pose,
    projector: &ProjectorModel,
    config: &DecoderConfig,
) -> usize {
    let grid: Vec<Vector3<f64>> = rays
        .iter()
        .enumerate()
        .filter(|(i, r)| {
            (i % width).is_multiple_of(16) && (i / width).is_multiple_of(16) && r[0].is_finite()
        })
        .map(|(_, r)| ray_in_projector(camera_to_projector, r))
        .collect();
    let at = |along: &Vector3<f64>, s: f64| dmd_on_ray(camera_to_projector, projector, along, s);
    let within = |n: usize| {
        let (s0, ds) = segment_steps(config.depth_range_m, n);
        grid.par_iter().all(|along| {
            (0..n - 1).all(|j| {
                let s = s0 + j as f64 * ds;
                match (at(along, s), at(along, s + ds), at(along, s + 0.5 * ds)) {
                    (Some(a), Some(b), Some(m)) => {
                        let chord = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
                        (chord[0] - m[0]).hypot(chord[1] - m[1]) <= config.max_chord_px
                    }
                    // Behind the projector: nothing to decode there either.
                    _ => true,
                }
            })
        })
    };
    (2..config.samples)
        .find(|&n| within(n))
        .unwrap_or(config.samples)
}

/// PDM along one pixel's epipolar samples: `phases[c][j]` is colour `c`'s phase
/// (cycles) at sample `j`, `wrapped[c]` its measured wrapped phase (cycles). Each
/// integer order of the colour with the most cycles gives a position (segment `j`,
/// fraction `tau`); the position where the other two agree best wins. Returns
/// (j, tau, RMS disagreement in cycles).
#[inline(always)]
pub fn pdm_along(phases: &[&[f64]; 3], wrapped: &[f64; 3]) -> Option<(usize, f64, f64)> {
    let len = phases[0].len();
    let span = |c: usize| (phases[c][len - 1] - phases[c][0]).abs();
    let r = (0..3).max_by(|&a, &b| span(a).total_cmp(&span(b)))?;
    let others = match r {
        0 => [1, 2],
        1 => [0, 2],
        _ => [0, 1],
    };
    // Colour c's squared distance to its nearest order at (j, tau).
    let miss = |c: usize, j: usize, tau: f64| {
        let at = phases[c][j] + tau * (phases[c][j + 1] - phases[c][j]);
        let d = at - wrapped[c];
        let e = d - d.round();
        e * e
    };
    let mut best: Option<(usize, f64)> = None;
    let mut best_score = f64::INFINITY;
    for j in 0..len - 1 {
        let (a, b) = (phases[r][j], phases[r][j + 1]);
        if !(a.is_finite() && b.is_finite()) || a == b {
            continue;
        }
        let per_cycle = 1.0 / (b - a);
        let (lo, hi) = (a.min(b), a.max(b));
        // Orders as floats: a float-to-int cast is a scalar conversion with checks.
        let mut k = (lo - wrapped[r]).ceil();
        let last = (hi - wrapped[r]).floor();
        while k <= last {
            let tau = (wrapped[r] + k - a) * per_cycle;
            k += 1.0;
            // Half-open segments, so a sample's order is counted once.
            if tau >= 1.0 && j + 2 < len {
                continue;
            }
            // Most orders miss already on the first colour: the second can
            // only add, so they are out without it (the same winner).
            let first = miss(others[0], j, tau);
            if first >= best_score {
                continue;
            }
            let score = first + miss(others[1], j, tau);
            if score < best_score {
                best_score = score;
                best = Some((j, tau));
            }
        }
    }
    best.map(|(j, tau)| (j, tau, (best_score / 2.0).sqrt()))
}

/// The camera ray `(x, y, 1)` turned into the projector frame: with `t` the
/// pose's translation, the point at inverse depth `s` on the ray is
/// `(along + s t) / s` there.
#[inline(always)]
fn ray_in_projector(camera_to_projector: &Pose, ray: &[f64; 2]) -> Vector3<f64> {
    camera_to_projector.rotation * Vector3::new(ray[0], ray[1], 1.0)
}

/// The DMD pixel (u, v) that lights the point at inverse depth `s` (1 / camera
/// z) on the ray `along` ([`ray_in_projector`]); NaN behind the projector.
/// Without a branch, for loops over many points (vector lanes).
#[inline(always)]
fn dmd_on_ray_or_nan(
    camera_to_projector: &Pose,
    projector: &ProjectorModel,
    along: &Vector3<f64>,
    s: f64,
) -> [f64; 2] {
    // The point times s > 0: the same projection, no division by s.
    let d = along + camera_to_projector.translation_m * s;
    let p = projector.normalised_to_pixel(d.x / d.z, d.y / d.z);
    // One select per coordinate: a select of the pair kept the compiler
    // from vectorising the loops over pixels.
    let front = d.z > 0.0;
    [p.x, p.y].map(|c| if front { c } else { f64::NAN })
}

/// [`dmd_on_ray_or_nan`] as an option: `None` behind the projector.
#[inline(always)]
fn dmd_on_ray(
    camera_to_projector: &Pose,
    projector: &ProjectorModel,
    along: &Vector3<f64>,
    s: f64,
) -> Option<[f64; 2]> {
    let p = dmd_on_ray_or_nan(camera_to_projector, projector, along, s);
    (!p[0].is_nan()).then_some(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::Distortion;
    use crate::synth::high_speed::high_speed_head;

    #[test]
    fn the_depth_step_lands_within_a_micrometre_of_the_exact_depth() {
        let dmd_px = (1280, 800);
        let lens = Distortion {
            k1: -0.2,
            k2: 0.05,
            p1: 0.001,
            p2: -0.001,
            k3: 0.0,
        };
        for distortion in [Distortion::none(), lens] {
            let mut head = high_speed_head(320, 240, dmd_px);
            head.projector.distortion = distortion;
            let set = PatternSet::seed001(dmd_px).unwrap();
            let decoder = Decoder::new(set, &head, DecoderConfig::default()).unwrap();
            let (c2p, projector) = (&decoder.camera_to_projector, &decoder.projector);
            let (s0, ds) = decoder.segment_steps();
            let (mut worst_um, mut solved) = (0.0f64, 0usize);
            for i in (0..decoder.rays.len()).step_by(97) {
                let along = ray_in_projector(c2p, &decoder.rays[i]);
                let dmd: Vec<[f64; 2]> = (0..decoder.samples())
                    .map(|j| dmd_on_ray(c2p, projector, &along, s0 + j as f64 * ds).unwrap())
                    .collect();
                for pat in decoder.set.patterns() {
                    let g = pat.frequency;
                    let ph: Vec<f64> = dmd.iter().map(|p| g[0] * p[0] + g[1] * p[1]).collect();
                    for z in [0.4, 0.47, 0.5, 0.55, 0.61, 0.65] {
                        // The surface at depth z gives this absolute phase; PDM
                        // puts the pixel in its segment or the next one.
                        let p = dmd_on_ray(c2p, projector, &along, 1.0 / z).unwrap();
                        let absolute = g[0] * p[0] + g[1] * p[1];
                        let segment = ((1.0 / z - s0) / ds) as usize;
                        for near in [segment.saturating_sub(1), segment, segment + 1] {
                            let near = near.min(ph.len() - 2);
                            let Some(step) = decoder.depth_step(&ph, &dmd, absolute, near, s0, ds)
                            else {
                                continue;
                            };
                            let s = step.solve(c2p, projector, &along, g);
                            // What the decoder keeps (NaN fails it too).
                            if s.is_nan() || s <= 0.0 {
                                continue;
                            }
                            solved += 1;
                            worst_um = worst_um.max(1e6 * (1.0 / s - z).abs());
                        }
                    }
                }
            }
            println!(
                "{distortion:?}: {} samples, {solved} depths, largest error {worst_um:.4} um",
                decoder.samples()
            );
            assert!(solved > 10_000, "only {solved} depths on the DMD");
            assert!(worst_um < 1.0, "depth off by up to {worst_um} um");
        }
    }
}
