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

use super::consensus::{
    consensus_inverse_depth, drop_unconfirmed, fill_holes, settle_holes, uncertain_pixels,
};
use super::demux::{cycles_to_radians, Demultiplexed, Demultiplexer, DemuxOptions};
use super::fdd::FddNet;
use super::set::{PatternSet, SetPattern};
use super::zocr::ZocrNet;
use super::HighSpeedError;
use crate::calibration::{Head, Pose, ProjectorModel};
use crate::huge_pages::filled_vec;
use crate::phase::fast_sin_cos;
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
    /// Decodes after the first, each on carriers predicted from the pass
    /// before: every pattern demodulated again against the phase it has at
    /// the depth the pass's 24 depths agree on (per pixel, the mean of those
    /// within 2 % of their median, holes filled smoothly),
    /// then unwrapped again ([`Demultiplexer::demodulate_at`]). Where the
    /// last pass's prediction was uncertain (at and next to the consensus's
    /// holes), a pattern whose depth lands more than 2 % off it is dropped
    /// (`drop_unconfirmed`): one pass, `rotor`'s per-instant depth RMSE
    /// median 15.0 -> 11.1 mm (coverage 0.755 -> 0.737), `spheres` 6.59 ->
    /// 6.02 mm, `falling` unchanged (18.8 mm).
    pub consensus_passes: u32,
    /// In each consensus pass, settle the consensus's holes at depth edges
    /// on the surface around them that best explains the fringes there
    /// (`settle_holes`) instead of filling them smoothly. Held out
    /// (`highspeed_eval`): one pass's wrapped-phase MAE 0.0847 -> 0.0785
    /// rad; but on `spheres` it decodes more rim pixels, some on the wall's
    /// side (the all-point fits' radius errors +6.3 / +8.2 -> +9.7 / +13.1
    /// mm), and `falling`'s depth RMSE median rises (18.8 -> 22.4 mm), so it
    /// is off by default.
    pub settle_edges: bool,
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
            consensus_passes: 0,
            settle_edges: false,
            simd: Simd::best(),
        }
    }
}

/// How near (relative) a pattern's inverse depth must be to the median of a
/// pixel's to count towards its consensus: 2 % is about 10 mm at 0.5 m, well
/// above the single pass's typical error (1-2 mm) and well below one fringe
/// order's jump (tens of millimetres). Chosen with `CONSENSUS_INLIERS` on the
/// training stream (`highspeed_eval --seed 1`, one pass; with 6 inliers
/// 1 %, 1.5 %, 2 % gave 0.0728, 0.0720, 0.0716 rad).
const CONSENSUS_AGREE: f64 = 0.02;

/// How many of a pixel's patterns must agree for a consensus (a quarter of
/// the 24): more leaves more holes to fill, and a filled hole predicts worse
/// than a few agreeing patterns (training stream, 2 %: 12, 8, 6, 4 inliers
/// gave 0.0805, 0.0746, 0.0716, 0.0714 rad).
const CONSENSUS_INLIERS: usize = 6;

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
    /// demodulations, sibling cancellation or with consensus passes: the
    /// network learnt the single pass's errors (and a consensus pass would
    /// replace its phases).
    pub fn with_fdd(mut self, net: FddNet) -> Result<Self, HighSpeedError> {
        let DemuxOptions {
            refinements,
            cancellations,
            ..
        } = self.config.demux;
        if refinements > 0 {
            return Err(HighSpeedError::BadConfig {
                why: format!(
                    "FDD-Net corrects the single-pass demodulation's phases; this decoder refines them {refinements} time(s)"
                ),
            });
        }
        if cancellations > 0 {
            return Err(HighSpeedError::BadConfig {
                why: format!(
                    "FDD-Net corrects the single-pass demodulation's phases; this decoder cancels siblings {cancellations} time(s) (set demux.cancellations to 0)"
                ),
            });
        }
        if self.config.consensus_passes > 0 {
            return Err(HighSpeedError::BadConfig {
                why: format!(
                    "FDD-Net corrects the single-pass demodulation's phases; this decoder demodulates again {} time(s) on consensus carriers (set consensus_passes to 0)",
                    self.config.consensus_passes
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
        let led_fringes = (self.config.consensus_passes > 0).then(|| cleaned.fringes.clone());
        let mut fringes = self.demux.demodulate_all(cleaned);
        if let Some(net) = &self.fdd {
            fringes.wrapped =
                net.correct(&self.demux, &self.set, &fringes, self.width, self.height)?;
        }
        let p = self.set.patterns().len();
        let mut maps = self.unwrap_all(&saturated_px, &fringes);
        if let Some(led_fringes) = led_fringes {
            let mut last = None;
            for _ in 0..self.config.consensus_passes {
                let first = &fringes.modulation;
                let prediction = self.consensus_dmd(&maps[p..], &led_fringes, first);
                self.demux.demodulate_at(
                    &led_fringes,
                    &prediction.dmd,
                    &mut fringes.wrapped,
                    first,
                );
                maps = self.unwrap_all(&saturated_px, &fringes);
                last = Some(prediction);
            }
            if let Some(prediction) = last {
                let (phases, depths) = maps.split_at_mut(p);
                drop_unconfirmed(
                    phases,
                    depths,
                    &prediction.inverse_depth,
                    &prediction.uncertain,
                    CONSENSUS_AGREE,
                );
            }
        }
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
            width: self.width,
            height: self.height,
            fringes,
            instants,
            saturated,
        })
    }

    /// The carriers of a consensus pass: per pixel, the inverse depth its
    /// patterns' `depths` agree on ([`consensus_inverse_depth`]); holes
    /// (grown, [`uncertain_pixels`]) filled smoothly from around them so the
    /// carriers do not jump there, or (`settle_edges`) settled where a nearby
    /// surface explains the LEDs' `fringes` better ([`settle_holes`],
    /// [`Self::fringe_fit`]; `modulation` is the first pass's).
    fn consensus_dmd(
        &self,
        depths: &[Vec<f32>],
        fringes: &[Vec<f32>; 3],
        modulation: &[Vec<f32>],
    ) -> CarrierPrediction {
        let views: Vec<&[f32]> = depths.iter().map(|d| &d[..]).collect();
        let n = self.width * self.height;
        let s = consensus_inverse_depth(&views, n, CONSENSUS_AGREE, CONSENSUS_INLIERS);
        let filled = fill_holes(&s, self.width, self.height);
        let uncertain = uncertain_pixels(&s, self.width, self.height);
        let inverse_depth = if self.config.settle_edges {
            settle_holes(
                &s,
                &filled,
                &uncertain,
                self.width,
                CONSENSUS_AGREE,
                |i, s| self.fringe_fit(fringes, modulation, i, s),
            )
        } else {
            filled
        };
        let dmd = inverse_depth
            .par_iter()
            .zip(&self.rays)
            .map(|(&s, ray)| self.dmd_at(ray, s))
            .collect();
        CarrierPrediction {
            dmd,
            inverse_depth,
            uncertain,
        }
    }

    /// Per pixel, the DMD position it sees where its surface lies at
    /// `depth_m` (camera z, metres; NaN where not finite). With a twin's true
    /// depths, [`Demultiplexer::demodulate_at`] on these shows what a
    /// consensus pass would give with a perfect prediction
    /// (`highspeed_eval`'s oracle row).
    pub fn dmd_at_depths(&self, depth_m: &Raster<f32>) -> Result<Vec<[f64; 2]>, HighSpeedError> {
        let expected = (self.width, self.height);
        let got = (depth_m.width, depth_m.height);
        if got != expected || depth_m.data.len() != self.rays.len() {
            return Err(HighSpeedError::WrongSize {
                what: "depth map".into(),
                expected,
                got,
            });
        }
        Ok(depth_m
            .data
            .par_iter()
            .zip(&self.rays)
            .map(|(&z, ray)| self.dmd_at(ray, 1.0 / f64::from(z)))
            .collect())
    }

    /// The DMD position camera ray `ray` sees at inverse depth `s` (NaN
    /// behind the projector).
    fn dmd_at(&self, ray: &[f64; 2], s: f64) -> [f64; 2] {
        let along = ray_in_projector(&self.camera_to_projector, ray);
        dmd_on_ray_or_nan(&self.camera_to_projector, &self.projector, &along, s)
    }

    /// How much of the LEDs' `fringes` on the 3x3 pixels around pixel `i`
    /// the 24 patterns explain if that patch lies at inverse depth `s`: per
    /// LED, the fringes predicted there (`sum B_m cos phi_m(s)`, `B_m` the
    /// first pass's `modulation`) scaled to fit the measured ones by least
    /// squares, the energy that fit removes (`<f, g>^2 / <g, g>`, zero for
    /// a negative scale), summed over the LEDs. Higher is better. At a depth
    /// edge the wrong side's carriers leave the prediction out of step with
    /// the light on nearly every pattern. With the twin's true depth added
    /// to the candidates (then the nearest and farthest in a square), this
    /// choice took the training stream's MAE from 0.0620 to 0.0537 rad (a
    /// pass on the true depth alone: 0.0399), so it picks the right side
    /// often, not always.
    fn fringe_fit(
        &self,
        fringes: &[Vec<f32>; 3],
        modulation: &[Vec<f32>],
        i: usize,
        s: f64,
    ) -> f64 {
        let (w, h) = (self.width, self.height);
        let (x, y) = (i % w, i / w);
        let (mut fg, mut gg) = ([0.0f64; 3], [0.0f64; 3]);
        for yy in y.saturating_sub(1)..(y + 2).min(h) {
            for xx in x.saturating_sub(1)..(x + 2).min(w) {
                let j = yy * w + xx;
                let dmd = self.dmd_at(&self.rays[j], s);
                if !dmd[0].is_finite() {
                    continue;
                }
                let mut g = [0.0f64; 3];
                for pattern in self.set.patterns() {
                    let b = f64::from(modulation[pattern.index][j]);
                    if b.is_finite() {
                        let cycles = pattern.frequency[0] * dmd[0] + pattern.frequency[1] * dmd[1];
                        g[pattern.colour] +=
                            b * f64::from(fast_sin_cos(cycles_to_radians(cycles)).1);
                    }
                }
                for c in 0..3 {
                    let f = f64::from(fringes[c][j]);
                    if f.is_finite() {
                        fg[c] += f * g[c];
                        gg[c] += g[c] * g[c];
                    }
                }
            }
        }
        (0..3)
            .filter(|&c| fg[c] > 0.0 && gg[c] > 0.0)
            .map(|c| fg[c] * fg[c] / gg[c])
            .sum()
    }

    /// Every pixel's absolute phase and depth per pattern from the
    /// demultiplexed `fringes`: maps 0..p hold pattern m's absolute phase,
    /// p..2p its depth (NaN where not decoded).
    fn unwrap_all(&self, saturated_px: &[bool], fringes: &Demultiplexed) -> Vec<Vec<f32>> {
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
                // One scratch per band, written where read.
                let mut scratch = ChunkScratch::new(self.samples);
                let first = b * BAND_ROWS * w;
                let len = out[0].len();
                for start in (0..len).step_by(CHUNK) {
                    let chunk = start..(start + CHUNK).min(len);
                    self.decode_chunk(first, chunk, saturated_px, fringes, &mut out, &mut scratch);
                }
            })
        });
        maps
    }

    /// The pixels `first + chunk`: per pattern `m` its absolute phase into
    /// `out[m][at]` and its depth into `out[p + m][at]` (p patterns, `at` in
    /// `chunk`); untouched where not decoded. Direction by direction over the
    /// chunk, not pixel by pixel: a pixel's directions read 51 maps and write
    /// 48, more streams than the caches follow, a direction's only 15. Every
    /// step is a loop without branches over all [`CHUNK`] lanes (a short
    /// chunk's last lanes are NaN and decode nothing): PDM's per-pixel
    /// searches branched on data the CPU could not predict.
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
        let lanes = chunk.len();
        let pixels = first + chunk.start..first + chunk.end;
        let ChunkScratch {
            along,
            dmd,
            phases,
            ordered,
        } = scratch;
        // Each pixel's ray; a NaN ray marks a pixel that is not decoded
        // (saturated, no ray, or past the chunk's end), and gives NaN samples.
        along.fill(Vector3::from_element(f64::NAN));
        for (a, i) in along.iter_mut().zip(pixels.clone()) {
            let ray = self.rays[i];
            if !saturated[i] && ray[0].is_finite() {
                *a = ray_in_projector(&self.camera_to_projector, &ray);
            }
        }
        // Each pixel's samples on the DMD.
        let [dmd_u, dmd_v] = dmd;
        for (j, (u, v)) in dmd_u.iter_mut().zip(dmd_v.iter_mut()).enumerate() {
            let s = s0 + j as f64 * ds;
            for k in 0..CHUNK {
                [u[k], v[k]] =
                    dmd_on_ray_or_nan(&self.camera_to_projector, &self.projector, &along[k], s);
            }
        }
        let directions = self.set.directions();
        let p = self.set.patterns().len();
        for n in 1..=directions as u32 {
            let pats = [0, 1, 2].map(|c| self.set.pattern(n, c));
            // The measured wrapped phases (cycles), NaN where the pixel is
            // not decoded or a pattern's modulation is too weak. (`&`, not
            // `&&`, in the lane loops: a short circuit is a branch, and kept
            // them scalar.)
            let mut good = [false; CHUNK];
            for (k, g) in good[..lanes].iter_mut().enumerate() {
                *g = along[k].x.is_finite();
            }
            for (c, pat) in pats.iter().enumerate() {
                let zero = &fringes.zero_order[c][pixels.clone()];
                let modulation = &fringes.modulation[pat.index][pixels.clone()];
                for (g, (&zero, &modulation)) in good.iter_mut().zip(zero.iter().zip(modulation)) {
                    let zero = zero / directions as f32;
                    *g &= (zero > 0.0) & (modulation >= self.config.min_modulation_ratio * zero);
                }
            }
            let mut wrapped = [[f64::NAN; CHUNK]; 3];
            for (w, pat) in wrapped.iter_mut().zip(&pats) {
                let measured = &fringes.wrapped[pat.index][pixels.clone()];
                for (k, &measured) in measured.iter().enumerate() {
                    let phase = f64::from(measured) / std::f64::consts::TAU;
                    w[k] = if good[k] { phase } else { f64::NAN };
                }
            }
            // Each colour's phase at the samples.
            for (phase, pat) in phases.iter_mut().zip(&pats) {
                let [fu, fv] = pat.frequency;
                for (ph, (u, v)) in phase.iter_mut().zip(dmd_u.iter().zip(dmd_v.iter())) {
                    for k in 0..CHUNK {
                        ph[k] = fu * u[k] + fv * v[k];
                    }
                }
            }
            let wrapped_ordered = reference_first(phases, &wrapped, ordered);
            let pdm = pdm_lanes(ordered, &wrapped_ordered);
            // PDM's position, kept where the three colours agree well enough
            // (no position has an infinite score).
            let kept = pdm.score.map(|score| {
                score.is_finite() & ((score / 2.0).sqrt() <= self.config.max_rms_cycles)
            });
            // PDM's segment as an index, once for the three colours.
            let index = segment_indices(&pdm.segment, dmd_u.len());
            for ((ph, w), pat) in phases.iter().zip(&wrapped).zip(&pats) {
                let absolute = absolute_orders(ph, w, &pdm, &index, &kept);
                let steps = self.depth_steps(ph, [dmd_u, dmd_v], &absolute, &pdm.segment);
                // The Newton step of each pixel: one projection; a pixel
                // without a step gets NaN, which its maps already hold.
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

    /// Per pixel of a chunk, where the Newton step toward the inverse depth
    /// at which a pattern's phase along the ray is `absolute[k]` cycles
    /// starts: the samples' segment that brackets it nearest to segment
    /// `near[k]` (where PDM put the pixel: the bracket is there or next to it;
    /// the lower one of two as near), and the point on its chord. No step
    /// (NaN) without an absolute phase, off the segment or off the DMD
    /// (judged on the segment's DMD points, a fraction of a pixel from exact).
    /// `ph` and `dmd` per sample, as in [`ChunkScratch`].
    #[inline(always)]
    fn depth_steps(
        &self,
        ph: &[[f64; CHUNK]],
        dmd: [&[[f64; CHUNK]]; 2],
        absolute: &[f64; CHUNK],
        near: &[f64; CHUNK],
    ) -> [NewtonStep; CHUNK] {
        let (s0, ds) = self.segment_steps();
        // The bracket's rank (0 at `near`, then one below, one above, two
        // below...) and its segment; then its ends' phases and DMD points.
        let mut chosen = PingPong::new([f64::INFINITY, NO_SEGMENT]);
        for pair in ph.windows(2).enumerate() {
            let (was, now) = chosen.step();
            nearer_brackets(pair, absolute, near, was, now);
        }
        let [rank, segment] = chosen.current();
        let index = segment_indices(segment, ph.len());
        let [pa, pb] = at_segments(ph, &index);
        let [ua, ub] = at_segments(dmd[0], &index);
        let [va, vb] = at_segments(dmd[1], &index);
        let (w, h) = self.set.dmd_px();
        let mut steps = [NewtonStep::NONE; CHUNK];
        for k in 0..CHUNK {
            let slope = (pb[k] - pa[k]) / ds;
            let tau = (absolute[k] - pa[k]) / (pb[k] - pa[k]);
            let s = s0 + segment[k] * ds + tau * ds;
            let u = ua[k] + tau * (ub[k] - ua[k]);
            let v = va[k] + tau * (vb[k] - va[k]);
            let inside = (rank[k] < f64::INFINITY)
                & (u >= -0.5)
                & (v >= -0.5)
                & (u < w as f64 - 0.5)
                & (v < h as f64 - 0.5);
            steps[k] = if inside {
                NewtonStep {
                    s,
                    slope,
                    absolute: absolute[k],
                }
            } else {
                NewtonStep::NONE
            };
        }
        steps
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

/// What a consensus pass demodulates against: per pixel the inverse depth
/// predicted, the DMD position seen there, and whether the prediction is
/// uncertain (no consensus there or next to it: filled or settled).
struct CarrierPrediction {
    dmd: Vec<[f64; 2]>,
    inverse_depth: Vec<f64>,
    uncertain: Vec<bool>,
}

/// Maps `a` and `b` of `out` at once (`a < b`).
fn out_pair<'a>(out: &'a mut [&mut [f32]], a: usize, b: usize) -> (&'a mut [f32], &'a mut [f32]) {
    debug_assert!(a < b);
    let (low, high) = out.split_at_mut(b);
    (&mut *low[a], &mut *high[0])
}

/// Pixels decoded together by [`Decoder::decode_chunk`]: the lanes of its loops.
const CHUNK: usize = 64;

/// The segment of a pixel without a PDM position (segments are numbered
/// from 0, as floats like the other running values: one width of lane).
const NO_SEGMENT: f64 = -1.0;

/// One band's scratch for [`Decoder::decode_chunk`]; per-sample values are
/// one array of the chunk's pixels per sample.
struct ChunkScratch {
    /// The chunk's rays in the projector frame; NaN for a pixel not decoded.
    along: [Vector3<f64>; CHUNK],
    /// The samples' DMD columns and rows.
    dmd: [Vec<[f64; CHUNK]>; 2],
    /// One direction's phases (cycles) at the samples, colour by colour.
    phases: [Vec<[f64; CHUNK]>; 3],
    /// The same per pixel in PDM's order: its reference colour, then the others.
    ordered: [Vec<[f64; CHUNK]>; 3],
}

impl ChunkScratch {
    fn new(samples: usize) -> Self {
        let values = || vec![[f64::NAN; CHUNK]; samples];
        Self {
            along: [Vector3::zeros(); CHUNK],
            dmd: [values(), values()],
            phases: [values(), values(), values()],
            ordered: [values(), values(), values()],
        }
    }
}

/// PDM's position per pixel of a chunk: the segment ([`NO_SEGMENT`] for
/// none), the fraction along it, and the two other colours' summed squared
/// distance to their nearest orders there, cycles² (infinite for none).
struct PdmBest {
    segment: [f64; CHUNK],
    tau: [f64; CHUNK],
    score: [f64; CHUNK],
}

/// A chunk's running values (`N` arrays, one value per pixel), kept twice:
/// each step reads one copy and writes the other. Updated in place, a lane
/// that keeps its value became a masked store, which AMD's cores run slowly.
struct PingPong<const N: usize> {
    copies: [[[f64; CHUNK]; N]; 2],
    current: usize,
}

impl<const N: usize> PingPong<N> {
    /// Every pixel starting at `start`. Filled in place, one value array
    /// at a time: built with `array::map` and copied in, the arrays went
    /// through memcpy (8 % of the samples in a profile of 1280x1024 decodes).
    #[inline(always)]
    fn new(start: [f64; N]) -> Self {
        let mut running = Self {
            copies: [[[0.0; CHUNK]; N]; 2],
            current: 0,
        };
        for (values, v) in running.copies[0].iter_mut().zip(start) {
            values.fill(v);
        }
        running
    }

    /// The current values and the copy to write the next ones into, which
    /// then become current.
    #[inline(always)]
    fn step(&mut self) -> (&[[f64; CHUNK]; N], &mut [[f64; CHUNK]; N]) {
        let [even, odd] = &mut self.copies;
        let flip = self.current == 0;
        self.current ^= 1;
        if flip {
            (even, odd)
        } else {
            (odd, even)
        }
    }

    /// The current values.
    #[inline(always)]
    fn current(&self) -> &[[f64; CHUNK]; N] {
        &self.copies[self.current]
    }
}

/// One segment's step of [`Decoder::depth_steps`]: per pixel, segment `j`
/// (its ends' phases `pair`) replaces the bracket in `was` (rank, segment)
/// where it brackets `absolute` and ranks nearer to `near`; the result goes
/// to `now`. Its own function so that `was` and `now` are known apart (its
/// arguments do not alias): written in the caller, the copies' aliasing
/// kept the loop scalar.
#[inline(always)]
fn nearer_brackets(
    (j, pair): (usize, &[[f64; CHUNK]]),
    absolute: &[f64; CHUNK],
    near: &[f64; CHUNK],
    was: &[[f64; CHUNK]; 2],
    now: &mut [[f64; CHUNK]; 2],
) {
    let (a, b) = (&pair[0], &pair[1]);
    let here = j as f64;
    for k in 0..CHUNK {
        let (pa, pb, target) = (a[k], b[k], absolute[k]);
        // NaN (no absolute phase) brackets nothing.
        let brackets =
            pa.is_finite() & pb.is_finite() & ((pa - target) * (pb - target) <= 0.0) & (pa != pb);
        let d = here - near[k];
        let r = if d < 0.0 { -2.0 * d - 1.0 } else { 2.0 * d };
        let take = brackets & (r < was[0][k]);
        // Computed values only: a choice between two loaded values became a
        // choice of addresses and lane-by-lane loads.
        now[0][k] = if take { r } else { was[0][k] };
        now[1][k] = if take { here } else { was[1][k] };
    }
}

/// Per pixel, its `segment` as an index of the samples (0 where it has
/// none), for [`at_segments`] over `samples` samples.
#[inline(always)]
fn segment_indices(segment: &[f64; CHUNK], samples: usize) -> [usize; CHUNK] {
    let last = samples as i32 - 2;
    // Through i32, which converts in vector lanes; NO_SEGMENT and NaN give 0.
    segment.map(|j| (j as i32).clamp(0, last) as usize)
}

/// Per pixel, the values at both ends of its segment `index` (`values` per
/// sample, [`segment_indices`]).
#[inline(always)]
fn at_segments(values: &[[f64; CHUNK]], index: &[usize; CHUNK]) -> [[f64; CHUNK]; 2] {
    let mut ends = [[f64::NAN; CHUNK]; 2];
    for k in 0..CHUNK {
        let j = index[k];
        ends[0][k] = values[j][k];
        ends[1][k] = values[j + 1][k];
    }
    ends
}

/// Per pixel, the colours' phases and wrapped phases in PDM's order: first
/// the reference, the colour with the most cycles along the whole segment
/// (the last of equals; NaN spans count as most), then the other two in
/// colour order. The phases go into `ordered`, the wrapped phases are returned.
#[inline(always)]
fn reference_first(
    phases: &[Vec<[f64; CHUNK]>; 3],
    wrapped: &[[f64; CHUNK]; 3],
    ordered: &mut [Vec<[f64; CHUNK]>; 3],
) -> [[f64; CHUNK]; 3] {
    // Per pixel, the reference colour as a float (lanes of one width).
    let mut reference = [0.0f64; CHUNK];
    let last = phases[0].len() - 1;
    for (k, r) in reference.iter_mut().enumerate() {
        let span = |c: usize| (phases[c][last][k] - phases[c][0][k]).abs();
        let (mut most, mut pick) = (span(0), 0.0);
        for c in 1..3 {
            // A NaN span counts as most, as total ordering has it (spans are
            // absolute values: no negative NaN).
            let later = (span(c) >= most) | span(c).is_nan();
            most = if later { span(c) } else { most };
            pick = if later { c as f64 } else { pick };
        }
        *r = pick;
    }
    // Slot 0 holds the reference, slots 1 and 2 the others in colour order.
    let pick = |r: f64, slot: usize, values: [f64; 3]| match slot {
        0 => {
            let low = if r == 0.0 { values[0] } else { values[1] };
            if r == 2.0 {
                values[2]
            } else {
                low
            }
        }
        1 => {
            if r == 0.0 {
                values[1]
            } else {
                values[0]
            }
        }
        _ => {
            if r == 2.0 {
                values[1]
            } else {
                values[2]
            }
        }
    };
    for (slot, out) in ordered.iter_mut().enumerate() {
        for (j, to) in out.iter_mut().enumerate() {
            let from = [&phases[0][j], &phases[1][j], &phases[2][j]];
            for k in 0..CHUNK {
                to[k] = pick(reference[k], slot, [from[0][k], from[1][k], from[2][k]]);
            }
        }
    }
    let mut wrapped_ordered = [[f64::NAN; CHUNK]; 3];
    for (slot, to) in wrapped_ordered.iter_mut().enumerate() {
        for k in 0..CHUNK {
            to[k] = pick(
                reference[k],
                slot,
                [wrapped[0][k], wrapped[1][k], wrapped[2][k]],
            );
        }
    }
    wrapped_ordered
}

/// PDM along each pixel's epipolar samples (seed 001, eq. 4), for a chunk's
/// pixels at once: `ordered[c][j][k]` is colour `c`'s phase (cycles) at sample
/// `j` of pixel `k`, the reference colour first ([`reference_first`]),
/// `wrapped[c][k]` its measured wrapped phase (cycles, NaN for a pixel not
/// decoded). Each integer order of the reference colour gives a position
/// (segment `j`, fraction `tau`); the position where the other two agree best
/// wins, the first one of equals. Segments are half open, so a sample's
/// order counts once.
#[inline(always)]
fn pdm_lanes(ordered: &[Vec<[f64; CHUNK]>; 3], wrapped: &[[f64; CHUNK]; 3]) -> PdmBest {
    // Score, fraction and segment of the best position so far.
    let mut running = PingPong::new([f64::INFINITY, f64::NAN, NO_SEGMENT]);
    let samples = ordered[0].len();
    let w = wrapped;
    for j in 0..samples - 1 {
        let [a, b] = [j, j + 1].map(|j| [&ordered[0][j], &ordered[1][j], &ordered[2][j]]);
        // The reference colour's orders on this segment, per pixel: the first
        // one and how many (orders as floats: a float-to-int cast is a
        // scalar conversion with checks).
        let mut first = [0.0f64; CHUNK];
        let mut count = [0.0f64; CHUNK];
        let mut per_cycle = [0.0f64; CHUNK];
        for k in 0..CHUNK {
            let (pa, pb, wr) = (a[0][k], b[0][k], w[0][k]);
            let usable = pa.is_finite() & pb.is_finite() & (pa != pb);
            first[k] = (pa.min(pb) - wr).ceil();
            let orders = (pa.max(pb) - wr).floor() - first[k] + 1.0;
            // NaN (a pixel not decoded) fails this too.
            count[k] = if usable & (orders > 0.0) { orders } else { 0.0 };
            per_cycle[k] = 1.0 / (pb - pa);
        }
        let most = count.iter().fold(0.0f64, |m, &c| m.max(c));
        let open_end = j + 2 < samples;
        for q in 0..most as usize {
            let q = q as f64;
            let (was, now) = running.step();
            let orders = [&first, &count, &per_cycle];
            better_positions(j, q, open_end, [a, b], w, orders, was, now);
        }
    }
    let [score, tau, segment] = *running.current();
    PdmBest {
        segment,
        tau,
        score,
    }
}

/// One order's step of [`pdm_lanes`]: per pixel, order `first + q` of the
/// reference colour on segment `j` (of `count`, `per_cycle` its inverse
/// phase step) replaces the position in `was` (score, fraction, segment)
/// where it is valid and the other two colours agree better; the result
/// goes to `now`. Its own function so that `was` and `now` are known apart
/// (see [`nearer_brackets`]).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn better_positions(
    j: usize,
    q: f64,
    open_end: bool,
    [a, b]: [[&[f64; CHUNK]; 3]; 2],
    w: &[[f64; CHUNK]; 3],
    [first, count, per_cycle]: [&[f64; CHUNK]; 3],
    was: &[[f64; CHUNK]; 3],
    now: &mut [[f64; CHUNK]; 3],
) {
    for k in 0..CHUNK {
        let tau = (w[0][k] + (first[k] + q) - a[0][k]) * per_cycle[k];
        // Colour c's squared distance to its nearest order at tau.
        let miss = |c: usize| {
            let d = a[c][k] + tau * (b[c][k] - a[c][k]) - w[c][k];
            let e = d - d.round();
            e * e
        };
        let valid = (q < count[k]) & !((tau >= 1.0) & open_end);
        let score = miss(1) + miss(2);
        let better = valid & (score < was[0][k]);
        // Computed values only (see [`nearer_brackets`]).
        now[0][k] = if better { score } else { was[0][k] };
        now[1][k] = if better { tau } else { was[1][k] };
        now[2][k] = if better { j as f64 } else { was[2][k] };
    }
}

/// Per pixel, a colour's absolute phase (cycles): its measured wrapped phase
/// `wrapped` plus the order nearest to its phase at PDM's position; NaN
/// where no position was `kept`. `phases` per sample, as in [`ChunkScratch`];
/// `index` PDM's segments ([`segment_indices`]).
#[inline(always)]
fn absolute_orders(
    phases: &[[f64; CHUNK]],
    wrapped: &[f64; CHUNK],
    pdm: &PdmBest,
    index: &[usize; CHUNK],
    kept: &[bool; CHUNK],
) -> [f64; CHUNK] {
    let [start, end] = at_segments(phases, index);
    let mut absolute = [f64::NAN; CHUNK];
    for k in 0..CHUNK {
        let predicted = start[k] + pdm.tau[k] * (end[k] - start[k]);
        let order = (predicted - wrapped[k]).round();
        absolute[k] = if kept[k] {
            wrapped[k] + order
        } else {
            f64::NAN
        };
    }
    absolute
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
    fn pdm_finds_each_pixels_position_whichever_colour_leads() {
        // 7 samples; per lane the three colours' phases grow linearly with
        // different rates, the fastest (PDM's reference) in a different
        // colour lane by lane, and the surface at a different place.
        let samples = 7;
        let rates = [[1.3, 1.1, 0.9], [0.9, 1.3, 1.1], [1.1, 0.9, 1.3]];
        let mut phases = [0, 1, 2].map(|_| vec![[f64::NAN; CHUNK]; samples]);
        let mut wrapped = [[f64::NAN; CHUNK]; 3];
        let mut truth = [f64::NAN; CHUNK];
        for k in 0..CHUNK - 4 {
            let rate = rates[k % 3];
            // The true position along the samples, 0 to 6, off the samples.
            let at = 0.05 + 5.9 * (k as f64 + 0.37) / CHUNK as f64;
            truth[k] = at;
            for c in 0..3 {
                for (j, ph) in phases[c].iter_mut().enumerate() {
                    ph[k] = 2.0 + rate[c] * j as f64;
                }
                let phase = 2.0 + rate[c] * at;
                wrapped[c][k] = phase - phase.floor();
            }
        }
        let mut ordered = [0, 1, 2].map(|_| vec![[f64::NAN; CHUNK]; samples]);
        let wrapped_ordered = reference_first(&phases, &wrapped, &mut ordered);
        let best = pdm_lanes(&ordered, &wrapped_ordered);
        for (k, truth) in truth.iter().enumerate() {
            if k < CHUNK - 4 {
                let found = best.segment[k] + best.tau[k];
                assert!(
                    (found - truth).abs() < 1e-9,
                    "lane {k}: {found} for {truth}"
                );
                assert!(best.score[k] < 1e-18, "lane {k}: score {}", best.score[k]);
            } else {
                // The last lanes are not decoded (NaN wrapped phases).
                assert_eq!(best.segment[k], NO_SEGMENT, "lane {k}");
            }
        }
    }

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
                // Every lane of a chunk is this pixel.
                let lanes =
                    |c: usize| -> Vec<[f64; CHUNK]> { dmd.iter().map(|p| [p[c]; CHUNK]).collect() };
                let (u, v) = (lanes(0), lanes(1));
                for pat in decoder.set.patterns() {
                    let g = pat.frequency;
                    let ph: Vec<[f64; CHUNK]> = dmd
                        .iter()
                        .map(|p| [g[0] * p[0] + g[1] * p[1]; CHUNK])
                        .collect();
                    // One lane per depth and PDM segment: the surface at depth
                    // z gives this absolute phase; PDM puts the pixel in its
                    // segment or the next one.
                    let (mut absolute, mut near, mut depth) =
                        ([f64::NAN; CHUNK], [NO_SEGMENT; CHUNK], [f64::NAN; CHUNK]);
                    let mut lane = 0;
                    for z in [0.4, 0.47, 0.5, 0.55, 0.61, 0.65] {
                        let p = dmd_on_ray(c2p, projector, &along, 1.0 / z).unwrap();
                        let segment = ((1.0 / z - s0) / ds) as usize;
                        for n in [segment.saturating_sub(1), segment, segment + 1] {
                            absolute[lane] = g[0] * p[0] + g[1] * p[1];
                            near[lane] = n.min(ph.len() - 2) as f64;
                            depth[lane] = z;
                            lane += 1;
                        }
                    }
                    let steps = decoder.depth_steps(&ph, [&u, &v], &absolute, &near);
                    for (step, z) in steps.iter().zip(depth).take(lane) {
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
            println!(
                "{distortion:?}: {} samples, {solved} depths, largest error {worst_um:.4} um",
                decoder.samples()
            );
            assert!(solved > 10_000, "only {solved} depths on the DMD");
            assert!(worst_um < 1.0, "depth off by up to {worst_um} um");
        }
    }
}
