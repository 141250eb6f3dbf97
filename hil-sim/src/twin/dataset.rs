//! Training-set exporter: reproducible (seed, index) -> random scene ->
//! rendered pairs with ground truth, as PNG / NPY plus a JSON manifest.
//!
//! Kinds (one per network of the project):
//! - `aliased` (seed 000): both heads project the same 4-period x 4-step
//!   fringe sequence at once; per camera the 16 aliased frames and 3 flat
//!   fields (noisy), the 16 noise-free frames of ambient + its own projector
//!   alone (what a single-head run records) and the own projector's DMD
//!   column ([`super::aliased_stack`]).
//! - `multiplexed` (seed 001): 24 binary patterns (8 directions x R/G/B)
//!   at 5 kHz inside one 4.8 ms colour exposure; the 24 clean fringes (each
//!   pattern alone, sensor scale, no crosstalk, no noise) and their phases.
//! - `underwater` (seed 002): the same fringe under water (attenuation,
//!   forward scatter, backscatter, refraction) and in air (noise-free).

use std::f64::consts::TAU;
use std::path::Path;
use std::sync::Arc;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

use super::aliased_stack::{render_aliased_stack, scan_sensor, AliasedCapture, AliasedStack};
use super::device::Rig;
use super::error::TwinError;
use super::io::{create_dir, write_json, write_npy, write_png, PngDepth};
use super::medium::{Medium, Turbidity, Water};
use super::pattern::{BitDepth, Exposure, Fringe, Pattern, ProjectorTimeline};
use super::random_scene::{random_scene, Placement};
use super::render::Renderer;
use super::scenes::{dual_head, single_head, Detail};
use super::sensor::{Image, SensorModel};

/// Which training pairs to write.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, clap::ValueEnum)]
pub enum DatasetKind {
    /// (aliased dual-head image, clean image per projector) + phases.
    Aliased,
    /// (multiplexed long exposure, 24 clean fringes) + phases.
    Multiplexed,
    /// (underwater image, in-air image) + phases.
    Underwater,
}

/// What to write.
#[derive(Clone, Copy, Debug)]
pub struct DatasetSpec {
    /// Kind of pairs.
    pub kind: DatasetKind,
    /// Number of samples.
    pub count: usize,
    /// Seed: sample i uses ChaCha8 stream i of this seed.
    pub seed: u64,
    /// Camera image width, pixels.
    pub width: u32,
    /// Camera image height, pixels.
    pub height: u32,
    /// Projector DMD size (width, height), pixels.
    pub projector: (u32, u32),
    /// Underwater only: fixed turbidity, or None for a random level per sample.
    pub turbidity: Option<Turbidity>,
    /// Aliased only: the fringe periods.
    pub periods: AliasedPeriods,
    /// Aliased only: the sensor noise scale (1 = the scan's) is drawn
    /// log-uniformly from this range per sample.
    pub noise_scale: (f64, f64),
}

/// (width, height, fringe bits, depth, pattern).
type MadePattern = (u32, u32, [u64; 3], BitDepth, Arc<Pattern>);

/// Fringe patterns made once per dataset and shared by every sample.
#[derive(Default)]
struct Patterns {
    made: Vec<MadePattern>,
}

impl Patterns {
    fn get(&mut self, width: u32, height: u32, f: &Fringe, depth: BitDepth) -> Arc<Pattern> {
        let key = [
            f.period_px.to_bits(),
            f.angle_rad.to_bits(),
            f.shift_rad.to_bits(),
        ];
        if let Some(found) = self
            .made
            .iter()
            .find(|m| m.0 == width && m.1 == height && m.2 == key && m.3 == depth)
        {
            return found.4.clone();
        }
        let p = Arc::new(Pattern::fringe(width, height, f, depth));
        self.made.push((width, height, key, depth, p.clone()));
        p
    }
}

/// Seed 000's periods, DMD pixels.
const ALIASED_PERIODS_PX: [f64; 4] = [100.0, 110.0, 120.0, 130.0];
/// Seed 002's three fringe frequencies as periods, DMD pixels.
const UNDERWATER_PERIODS_PX: [f64; 3] = [59.0, 64.0, 70.0];
/// Seed 001: theta_0 = 18 deg; periods (x, y) for R, G, B.
const THETA0_DEG: f64 = 18.0;
const LAMBDA_X_RGB: [f64; 3] = [23.0, 18.0, 21.0];
const LAMBDA_Y_RGB: [f64; 3] = [18.0, 13.0, 15.0];

const LED_NAMES: [&str; 3] = ["R", "G", "B"];

/// Where the datasets' random scenes stand: parts 0.44-0.54 m from the
/// camera, a wall at 0.6 m (the host's learned-model data and tests place
/// theirs the same way).
pub const PLACE: Placement = Placement {
    x_m: (-0.08, 0.08),
    y_m: (-0.06, 0.06),
    z_m: (0.44, 0.54),
    wall_z_m: 0.6,
};

/// Writes `spec.count` samples and `manifest.json` into `out`; calls
/// `progress(i)` after each sample. Returns the manifest.
pub fn write_dataset(
    spec: &DatasetSpec,
    out: &Path,
    mut progress: impl FnMut(usize),
) -> Result<Value, TwinError> {
    if spec.width == 0 || spec.height == 0 {
        return Err(TwinError::BadParameter {
            name: "image size",
            value: spec.width.min(spec.height) as f64,
            why: "must be > 0",
        });
    }
    let (lo, hi) = spec.noise_scale;
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi >= lo) {
        return Err(TwinError::BadParameter {
            name: "noise scale range",
            value: lo,
            why: "must be finite, > 0 and min <= max",
        });
    }
    create_dir(out)?;
    let mut samples = Vec::with_capacity(spec.count);
    let mut patterns = Patterns::default();
    for i in 0..spec.count {
        let mut rng = sample_rng(spec, i);
        let prefix = format!("{i:06}");
        let entry = match spec.kind {
            DatasetKind::Aliased => aliased(spec, out, i, &prefix)?,
            DatasetKind::Multiplexed => multiplexed(&mut rng, spec, out, &prefix, &mut patterns)?,
            DatasetKind::Underwater => underwater(&mut rng, spec, out, &prefix, &mut patterns)?,
        };
        samples.push(entry);
        progress(i);
    }
    let manifest = json!({
        "kind": spec.kind,
        "count": spec.count,
        "seed": spec.seed,
        "width": spec.width,
        "height": spec.height,
        "generator": concat!("hil-sim ", env!("CARGO_PKG_VERSION")),
        "conventions": {
            "images": "row-major, origin top-left; PNG 16-bit = sensor value in [0,1] x 65535 (8-bit for 8-bit sensors)",
            "npy": "little-endian f32, shape (H, W) or (N, H, W); NaN = undefined",
            "phase": "absolute phase 2*pi*(u cos a / lx + v sin a / ly) at the DMD point seen by each pixel, NaN where that projector does not light it",
            "depth_m": "z of the surface point in the camera frame, metres",
        },
        "samples": samples,
    });
    write_json(&out.join("manifest.json"), &manifest)?;
    Ok(manifest)
}

fn detail(spec: &DatasetSpec) -> Detail {
    Detail {
        camera: (spec.width, spec.height),
        projector: spec.projector,
    }
}

fn png_depth(sensor: &SensorModel) -> PngDepth {
    if sensor.bits == 8 {
        PngDepth::Eight
    } else {
        PngDepth::Sixteen
    }
}

fn save_image(out: &Path, name: &str, img: &Image, depth: PngDepth) -> Result<(), TwinError> {
    write_png(
        &out.join(name),
        img.width,
        img.height,
        img.channels,
        &img.data,
        depth,
    )
}

fn shape2(spec: &DatasetSpec) -> [usize; 2] {
    [spec.height as usize, spec.width as usize]
}

fn fringe_timeline(
    rig: &Rig,
    fringe: &Fringe,
    exposure: &Exposure,
    projectors: &[usize],
    patterns: &mut Patterns,
) -> Vec<ProjectorTimeline> {
    (0..rig.projectors.len())
        .map(|p| {
            if !projectors.contains(&p) {
                return ProjectorTimeline::dark();
            }
            let k = &rig.projectors[p].model.intrinsics;
            ProjectorTimeline::single(
                patterns.get(k.width, k.height, fringe, BitDepth::Eight),
                exposure.start_s,
                exposure.end_s,
            )
        })
        .collect()
}

/// The aliased kind's fringe periods.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, clap::ValueEnum)]
pub enum AliasedPeriods {
    /// The simultaneous scan's: 73, 64, 56 and 50 fringes over the DMD width
    /// (`slscan::scan::dealias_periods_px`), what the shipped de-aliaser is
    /// trained on.
    Scan,
    /// Seed 000's 100, 110, 120 and 130 DMD pixels.
    Seed,
}

impl AliasedPeriods {
    /// The periods in DMD pixels for a DMD `dmd_width_px` wide.
    pub fn periods_px(self, dmd_width_px: u32) -> Vec<f64> {
        match self {
            AliasedPeriods::Scan => [73.0, 64.0, 56.0, 50.0]
                .iter()
                .map(|f| f64::from(dmd_width_px) / f)
                .collect(),
            AliasedPeriods::Seed => ALIASED_PERIODS_PX.to_vec(),
        }
    }
}

/// Seconds each aliased frame is exposed (the scan's pattern display time;
/// the sensor scale follows it, so only the noise model depends on it).
const ALIASED_EXPOSURE_S: f64 = 1e-3;

/// Sample `index` of an aliased dataset: each camera's capture (camera 0,
/// then 1), the sensor noise scale drawn for it and the capture. The same
/// (spec, index) gives the same sample, written or not.
pub fn aliased_sample(
    spec: &DatasetSpec,
    index: usize,
) -> Result<(Vec<AliasedStack>, f64, AliasedCapture), TwinError> {
    let mut rng = sample_rng(spec, index);
    let scene = random_scene(&mut rng, &PLACE, false)?;
    let rig = aliased_rig(spec);
    let (lo, hi) = spec.noise_scale;
    let noise_scale = if hi > lo {
        (lo.ln() + rng.random::<f64>() * (hi.ln() - lo.ln())).exp()
    } else {
        lo
    };
    let capture = AliasedCapture {
        periods_px: spec.periods.periods_px(spec.projector.0),
        steps: 4,
        sensor: scan_sensor(ALIASED_EXPOSURE_S, noise_scale),
        exposure_s: ALIASED_EXPOSURE_S,
    };
    let stacks = (0..2)
        .map(|camera| render_aliased_stack(&scene, &rig, camera, &capture, rng.random()))
        .collect::<Result<_, _>>()?;
    Ok((stacks, noise_scale, capture))
}

/// The rig every aliased sample of `spec` is rendered with (the scenes
/// move, the rig does not).
pub fn aliased_rig(spec: &DatasetSpec) -> Rig {
    dual_head(&detail(spec))
}

/// Sample `index`'s random stream: ChaCha8 stream `index` of the seed.
fn sample_rng(spec: &DatasetSpec, index: usize) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    rng.set_stream(index as u64);
    rng
}

fn aliased(spec: &DatasetSpec, out: &Path, index: usize, prefix: &str) -> Result<Value, TwinError> {
    let (stacks, noise_scale, capture) = aliased_sample(spec, index)?;
    let frames = capture.periods_px.len() * capture.steps;
    let [h, w] = shape2(spec);
    let mut cameras = Vec::with_capacity(2);
    for (camera, st) in stacks.iter().enumerate() {
        let name = |what: &str| format!("{prefix}_{}_{what}", ["a", "b"][camera]);
        let files = [
            name("aliased.npy"),
            name("clean.npy"),
            name("flats.npy"),
            name("own_u_px.npy"),
            name("overlap.png"),
        ];
        write_npy(&out.join(&files[0]), &[frames, h, w], &st.aliased.concat())?;
        write_npy(
            &out.join(&files[1]),
            &[frames, h, w],
            &st.clean_own.concat(),
        )?;
        write_npy(&out.join(&files[2]), &[3, h, w], &st.flats.concat())?;
        write_npy(&out.join(&files[3]), &[h, w], &st.own_u_px)?;
        let overlap: Vec<f32> = st.overlap.iter().map(|&o| o as u8 as f32).collect();
        write_png(
            &out.join(&files[4]),
            spec.width,
            spec.height,
            1,
            &overlap,
            PngDepth::Eight,
        )?;
        cameras.push(json!({
            "camera": camera,
            "input": files[0], "target": files[1], "flats": files[2],
            "own_u_px": files[3], "overlap_mask": files[4],
            "overlap_px": st.overlap.iter().filter(|&&o| o).count(),
        }));
    }
    Ok(json!({
        "cameras": cameras,
        "periods_px": capture.periods_px, "steps": capture.steps,
        "frame_order": "period-major: frame k*steps + n is period k, shift 2 pi n / steps",
        "flats_order": ["dark", "own projector on", "other projector on"],
        "noise_scale": noise_scale,
        "exposure_us": ALIASED_EXPOSURE_S * 1e6,
    }))
}

/// Seed 001 eq. 3: the n-th direction (n = 1..8).
fn theta_n(n: usize) -> f64 {
    let sign = if n % 2 == 1 { 1.0 } else { -1.0 };
    let odd = if n % 2 == 1 { 0.0 } else { 0.5 };
    sign * (n as f64 / 2.0 - odd) * THETA0_DEG.to_radians()
}

/// Seed 001 eq. 2 as a [`Fringe`]: phase 2 pi (u cos t / lx + v sin t / ly).
fn multiplexed_fringe(n: usize, colour: usize) -> Fringe {
    let t = theta_n(n);
    let (gu, gv) = (
        t.cos() / LAMBDA_X_RGB[colour],
        t.sin() / LAMBDA_Y_RGB[colour],
    );
    Fringe {
        period_px: 1.0 / gu.hypot(gv),
        angle_rad: gv.atan2(gu),
        shift_rad: 0.0,
    }
}

fn multiplexed(
    rng: &mut ChaCha8Rng,
    spec: &DatasetSpec,
    out: &Path,
    prefix: &str,
    patterns: &mut Patterns,
) -> Result<Value, TwinError> {
    let scene = random_scene(rng, &PLACE, true)?;
    let mut rig = single_head(&detail(spec));
    // Defocus so the dithered binary patterns arrive quasi-sinusoidal.
    rig.projectors[0].defocus_sigma_px = 2.0;
    let k = rig.projectors[0].model.intrinsics;
    let slot_s = 200e-6;
    let mut fringes = Vec::with_capacity(24);
    let mut items = Vec::with_capacity(24);
    for n in 1..=8 {
        for colour in 0..3 {
            let f = multiplexed_fringe(n, colour);
            let mut led = [0.0f32; 3];
            led[colour] = 1.0;
            items.push((patterns.get(k.width, k.height, &f, BitDepth::One), led));
            fringes.push((f, colour));
        }
    }
    let timeline = vec![ProjectorTimeline::sequence(items, 0.0, slot_s)];
    let exposure = Exposure {
        start_s: 0.0,
        end_s: 24.0 * slot_s,
    };
    let sensor = SensorModel::colour8();
    let renderer = Renderer::new(&scene, &rig, 0, 0.0)?;
    let frame = renderer.frame(&timeline, exposure, &sensor, rng.random())?;
    let scale = (sensor.electrons_per_unit * sensor.gain / sensor.full_well_e) as f32;
    let n_px = (spec.width * spec.height) as usize;
    let mut clean = Vec::with_capacity(24 * n_px);
    let mut phases = Vec::with_capacity(24 * n_px);
    for (m, (f, colour)) in fringes.iter().enumerate() {
        let slot = Exposure {
            start_s: m as f64 * slot_s,
            end_s: (m + 1) as f64 * slot_s,
        };
        let e = renderer.exposed(&timeline, slot)?;
        clean.extend(e.per_projector[0].iter().map(|b| b[*colour] * scale));
        phases.extend(frame.truth.absolute_phase(0, f));
    }
    let files = [
        format!("{prefix}_long_exposure.png"),
        format!("{prefix}_clean_fringes.npy"),
        format!("{prefix}_phases.npy"),
        format!("{prefix}_depth_m.npy"),
    ];
    save_image(out, &files[0], &frame.image, png_depth(&sensor))?;
    let [h, w] = shape2(spec);
    write_npy(&out.join(&files[1]), &[24, h, w], &clean)?;
    write_npy(&out.join(&files[2]), &[24, h, w], &phases)?;
    write_npy(&out.join(&files[3]), &[h, w], frame.truth.depth_m())?;
    let list: Vec<Value> = fringes
        .iter()
        .enumerate()
        .map(|(m, (f, c))| json!({"index": m, "led": LED_NAMES[*c], "direction": m / 3 + 1, "period_px": f.period_px, "angle_rad": f.angle_rad}))
        .collect();
    Ok(json!({
        "input": files[0], "targets": files[1], "phases": files[2], "depth_m": files[3],
        "pattern_rate_hz": 1.0 / slot_s, "exposure_us": exposure.duration_s() * 1e6,
        "clean_fringe_units": "noise-free sensor value of the pattern's own LED band, before crosstalk and clipping; sum over a colour's 8 patterns = that band of the long exposure",
        "fringes": list,
    }))
}

fn underwater(
    rng: &mut ChaCha8Rng,
    spec: &DatasetSpec,
    out: &Path,
    prefix: &str,
    patterns: &mut Patterns,
) -> Result<Value, TwinError> {
    let mut scene = random_scene(rng, &PLACE, false)?;
    let level = spec.turbidity.unwrap_or(
        [Turbidity::T1, Turbidity::T2, Turbidity::T3, Turbidity::T4][rng.random_range(0..4)],
    );
    let water = Water::preset(level, 0.03);
    let air_rig = single_head(&detail(spec));
    let mut water_rig = air_rig.clone();
    water_rig.medium = Medium::Water(water);
    let period_px = UNDERWATER_PERIODS_PX[rng.random_range(0..3)];
    let step = rng.random_range(0..4usize);
    let fringe = Fringe {
        period_px,
        angle_rad: 0.0,
        shift_rad: TAU * step as f64 / 4.0,
    };
    let sensor = SensorModel::mono12();
    let air_exposure = Exposure {
        start_s: 0.0,
        end_s: 1e-3,
    };
    // Longer exposure under water, as an operator would set it: make up the
    // green attenuation over the ~1 m round trip.
    let water_exposure = Exposure {
        start_s: 0.0,
        end_s: 1e-3 * (water.attenuation_per_m[1] * 0.9).exp(),
    };
    // Seed 002 minimised room light: keep ambient exposure as in air.
    let dim = air_exposure.duration_s() / water_exposure.duration_s();
    let dry_scene = scene.clone();
    scene.ambient_surface = scene.ambient_surface.map(|a| a * dim);
    scene.ambient_direct = scene.ambient_direct.map(|a| a * dim);
    let wet = Renderer::new(&scene, &water_rig, 0, 0.0)?.frame(
        &fringe_timeline(&water_rig, &fringe, &water_exposure, &[0], patterns),
        water_exposure,
        &sensor,
        rng.random(),
    )?;
    let dry = Renderer::new(&dry_scene, &air_rig, 0, 0.0)?.frame(
        &fringe_timeline(&air_rig, &fringe, &air_exposure, &[0], patterns),
        air_exposure,
        &sensor,
        rng.random(),
    )?;
    let files = [
        format!("{prefix}_underwater.png"),
        format!("{prefix}_in_air.png"),
        format!("{prefix}_phase_in_air.npy"),
        format!("{prefix}_phase_underwater.npy"),
        format!("{prefix}_depth_m_in_air.npy"),
    ];
    let depth = png_depth(&sensor);
    save_image(out, &files[0], &wet.image, depth)?;
    save_image(out, &files[1], &dry.clean, depth)?;
    write_npy(
        &out.join(&files[2]),
        &shape2(spec),
        &dry.truth.absolute_phase(0, &fringe),
    )?;
    write_npy(
        &out.join(&files[3]),
        &shape2(spec),
        &wet.truth.absolute_phase(0, &fringe),
    )?;
    write_npy(&out.join(&files[4]), &shape2(spec), dry.truth.depth_m())?;
    Ok(json!({
        "input": files[0], "target": files[1], "phase_in_air": files[2], "phase_underwater": files[3], "depth_m_in_air": files[4],
        "turbidity": format!("{level:?}"), "water": water, "period_px": period_px, "step": step, "steps": 4,
        "exposure_us_water": water_exposure.duration_s() * 1e6, "exposure_us_air": air_exposure.duration_s() * 1e6,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("twin-dataset-{name}-{}", std::process::id()))
    }

    #[test]
    fn seed_001_directions() {
        let deg: Vec<f64> = (1..=8).map(|n| theta_n(n).to_degrees().round()).collect();
        assert_eq!(deg, vec![9.0, -9.0, 27.0, -27.0, 45.0, -45.0, 63.0, -63.0]);
        // Vertical-ish direction 1, red: phase gradient (cos t / 23, sin t / 18).
        let f = multiplexed_fringe(1, 0);
        let t = 9f64.to_radians();
        let want = TAU * (10.0 * t.cos() / 23.0 + 4.0 * t.sin() / 18.0);
        assert!((f.phase_at(10.0, 4.0) - want).abs() < 1e-9);
    }

    #[test]
    fn datasets_are_reproducible_and_complete() {
        for kind in [
            DatasetKind::Aliased,
            DatasetKind::Multiplexed,
            DatasetKind::Underwater,
        ] {
            let spec = DatasetSpec {
                kind,
                count: 2,
                seed: 11,
                width: 48,
                height: 40,
                projector: (160, 100),
                turbidity: None,
                periods: AliasedPeriods::Scan,
                noise_scale: (0.7, 1.4),
            };
            let (a, b) = (tmp(&format!("{kind:?}-a")), tmp(&format!("{kind:?}-b")));
            let ma = write_dataset(&spec, &a, |_| {}).unwrap();
            write_dataset(&spec, &b, |_| {}).unwrap();
            for entry in std::fs::read_dir(&a).unwrap() {
                let name = entry.unwrap().file_name();
                let x = std::fs::read(a.join(&name)).unwrap();
                let y = std::fs::read(b.join(&name)).unwrap();
                assert!(
                    x == y,
                    "{kind:?}: {name:?} differs between two runs with one seed"
                );
            }
            assert_eq!(ma["samples"].as_array().unwrap().len(), 2);
            std::fs::remove_dir_all(&a).unwrap();
            std::fs::remove_dir_all(&b).unwrap();
        }
    }

    #[test]
    fn multiplexed_writes_24_clean_fringes_with_signal() {
        // (Eq. 6 of seed 001, long exposure = sum of patterns, is checked in analytic_tests.)
        let spec = DatasetSpec {
            kind: DatasetKind::Multiplexed,
            count: 1,
            seed: 5,
            width: 40,
            height: 32,
            projector: (160, 100),
            turbidity: None,
            periods: AliasedPeriods::Scan,
            noise_scale: (1.0, 1.0),
        };
        let dir = tmp("sum");
        write_dataset(&spec, &dir, |_| {}).unwrap();
        let bytes = std::fs::read(dir.join("000000_clean_fringes.npy")).unwrap();
        let hl = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        let data: Vec<f32> = bytes[10 + hl..]
            .chunks(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert_eq!(data.len(), 24 * 40 * 32);
        assert!(data.iter().any(|&v| v > 0.01), "fringes must carry signal");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
