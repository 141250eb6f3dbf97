//! Captures of other systems' pattern families, rendered by the DIGITAL TWIN (ray-cast
//! tilted `plane` scene, defocused 8-bit DMD patterns, noisy mono12 sensor), decoded through
//! `slscan::capture` and `slscan reconstruct`, against the twin's true projector column
//! and surface. Every figure is printed; run with
//! `cargo test -p slscan --test capture_families -- --nocapture`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;

use hil_sim::twin::scenes::{built_in, Detail};
use hil_sim::twin::{Exposure, Pattern, ProjectorTimeline, Renderer, SensorModel};
use slscan::calibration::{write_rig, Head, RigCalibration};
use slscan::capture::decode::decode;
use slscan::capture::manifest::{to_json, FILE_NAME};
use slscan::capture::patterns::projector_images;
use slscan::capture::presets::{Preset, PresetOptions};
use slscan::capture::triangulate::triangulate;
use slscan::capture::{CaptureSpec, Frames, ProjectorAxis};
use slscan::io::images::save_gray_png;
use slscan::raster::Raster;
use slscan::reconstruct::{ReconstructConfig, Reconstructor};
use slscan::sim::calibration::from_twin::head_from_twin;
use slscan::unwrap::PixelStatus;

const DETAIL: Detail = Detail {
    camera: (320, 240),
    projector: (640, 400),
};
const PROJECTOR: (u32, u32) = (640, 400);
/// Shutter and pattern 0.5 ms: a white patch stays below full well.
const EXPOSURE_S: f64 = 0.5e-3;

struct Twin {
    renderer: Renderer,
    projectors: usize,
    head: Head,
    /// True projector (u, v) per camera pixel.
    truth_uv: Vec<[f32; 2]>,
    /// Pixels whose surface the projector lights (not background, not shadowed).
    lit: Vec<bool>,
    /// True surface point per camera pixel.
    truth_point: Vec<[f32; 3]>,
    noise_sigma: f32,
}

fn twin() -> Twin {
    let (scene, rig) = built_in("plane", &DETAIL).unwrap();
    let renderer = Renderer::new(&scene, &rig, 0, 0.0).unwrap();
    let projectors = rig.projectors.len();
    let flat = Arc::new(Pattern::flat(PROJECTOR.0, PROJECTOR.1, 0.5));
    let frame = renderer
        .frame(
            &timelines(flat, projectors),
            exposure(),
            &SensorModel::ideal(),
            0,
        )
        .unwrap();
    let truth = &frame.truth;
    Twin {
        projectors,
        head: head_from_twin(&rig, 0, 0, "A").unwrap(),
        truth_uv: truth.projector_uv_px(0).to_vec(),
        lit: truth
            .no_surface_mask()
            .iter()
            .zip(truth.shadow_mask(0))
            .map(|(none, shadow)| !none && !shadow)
            .collect(),
        truth_point: truth.point_m().to_vec(),
        noise_sigma: SensorModel::mono12().output_sigma(3000.0) as f32,
        renderer,
    }
}

fn timelines(pattern: Arc<Pattern>, projectors: usize) -> Vec<ProjectorTimeline> {
    let mut t = vec![ProjectorTimeline::single(pattern, 0.0, EXPOSURE_S)];
    t.extend((1..projectors).map(|_| ProjectorTimeline::dark()));
    t
}

fn exposure() -> Exposure {
    Exposure {
        start_s: 0.0,
        end_s: EXPOSURE_S,
    }
}

/// The twin's camera frames of every pattern of `spec`, in order.
fn render(t: &Twin, spec: &CaptureSpec, seed: u64) -> Vec<Raster<f32>> {
    projector_images(spec, PROJECTOR.0, PROJECTOR.1)
        .iter()
        .enumerate()
        .map(|(k, image)| {
            let bytes: Vec<u8> = image
                .data
                .iter()
                .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
                .collect();
            let pattern = Arc::new(Pattern::from_u8(PROJECTOR.0, PROJECTOR.1, &bytes).unwrap());
            let (img, _) = t
                .renderer
                .image(
                    &timelines(pattern, t.projectors),
                    exposure(),
                    &SensorModel::mono12(),
                    seed * 1000 + k as u64,
                )
                .unwrap();
            Raster::from_vec(img.width as usize, img.height as usize, img.data).unwrap()
        })
        .collect()
}

/// Column error, wrong orders and 3-D error of one family, measured against the truth.
struct Figures {
    valid: usize,
    lit: usize,
    rms_column_px: f64,
    wrong: usize,
    rms_point_um: f64,
}

fn measure(t: &Twin, spec: &CaptureSpec, frames: &[Raster<f32>], wrong_px: f64) -> Figures {
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let axes = decode(spec, &refs, PROJECTOR, t.noise_sigma).unwrap();
    let columns = axes
        .iter()
        .find(|a| a.axis == ProjectorAxis::Column)
        .unwrap();
    let rec = triangulate(&t.head, &axes, false).unwrap();
    let (mut n, mut sum2, mut wrong, mut sum_p2, mut lit) = (0usize, 0.0f64, 0usize, 0.0, 0usize);
    for i in 0..t.truth_uv.len() {
        let truth = t.truth_uv[i][0];
        lit += usize::from(t.lit[i]);
        let p = rec.pixels.get(i);
        if p.status != PixelStatus::Valid || !t.lit[i] {
            continue;
        }
        let e = f64::from(columns.coord_px.data[i] - truth);
        n += 1;
        if e.abs() > wrong_px {
            wrong += 1;
            continue;
        }
        sum2 += e * e;
        let d: f64 = (0..3)
            .map(|k| f64::from(p.point_m[k] - t.truth_point[i][k]).powi(2))
            .sum();
        sum_p2 += d;
    }
    let good = (n - wrong).max(1) as f64;
    Figures {
        valid: n,
        lit,
        rms_column_px: (sum2 / good).sqrt(),
        wrong,
        rms_point_um: 1e6 * (sum_p2 / good).sqrt(),
    }
}

#[test]
fn every_family_decodes_on_the_twin_and_the_wrong_origin_is_refused() {
    let t = twin();
    let families: Vec<(&str, Preset, PresetOptions, f64)> = vec![
        (
            "slscan 4-step x 20/22/24 px heterodyne",
            Preset::Slscan,
            PresetOptions {
                periods_px: Some(vec![20.0, 22.0, 24.0]),
                ..Default::default()
            },
            5.0,
        ),
        (
            "plain 3-step x 20/22/24 px heterodyne",
            Preset::Heterodyne,
            PresetOptions {
                steps: Some(3),
                periods_px: Some(vec![20.0, 22.0, 24.0]),
                both: false,
            },
            5.0,
        ),
        (
            "SinusCompleGrayCode 12-step, 32 px, 6 Gray bits",
            Preset::SinusCompleGray,
            PresetOptions {
                periods_px: Some(vec![32.0]),
                ..Default::default()
            },
            8.0,
        ),
        (
            "OpenCV GrayCodePattern 10 + 9 bits with inverses",
            Preset::OpencvGrayCode,
            PresetOptions::default(),
            2.0,
        ),
    ];
    println!("| family | frames | valid / lit pixels | column RMS error (px) | wrong orders | 3-D RMS error (um) |");
    println!("|---|---|---|---|---|---|");
    for (k, (name, preset, options, wrong_px)) in families.into_iter().enumerate() {
        let spec = preset.spec(&options, PROJECTOR).unwrap();
        let frames = render(&t, &spec, 10 + k as u64);
        let f = measure(&t, &spec, &frames, wrong_px);
        println!(
            "| {name} | {} | {} / {} | {:.4} | {} | {:.1} |",
            frames.len(),
            f.valid,
            f.lit,
            f.rms_column_px,
            f.wrong,
            f.rms_point_um
        );
        // Most of the lit plane decodes (heterodyne refuses the dim corners whose
        // phase noise could miscount an order; Gray codes alone lose the pixels where
        // their 1 px finest stripes, half a camera pixel here, blur below the contrast
        // floor), and no valid pixel has a wrong order.
        let share = if preset == Preset::OpencvGrayCode {
            5
        } else {
            7
        };
        assert!(
            f.valid * 10 > f.lit * share,
            "{name}: {} of {}",
            f.valid,
            f.lit
        );
        assert_eq!(f.wrong, 0, "{name}");
        let limit = if preset == Preset::OpencvGrayCode {
            // Whole projector pixels: quantisation 1/sqrt(12) plus blurred edges.
            0.6
        } else {
            0.1
        };
        assert!(f.rms_column_px < limit, "{name}: {}", f.rms_column_px);
    }

    // Our family through the fused pipeline gives the same points as the described path.
    let ours = Preset::Slscan
        .spec(
            &PresetOptions {
                periods_px: Some(vec![20.0, 22.0, 24.0]),
                ..Default::default()
            },
            PROJECTOR,
        )
        .unwrap();
    let frames = render(&t, &ours, 10);
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let axes = decode(&ours, &refs, PROJECTOR, t.noise_sigma).unwrap();
    let described = triangulate(&t.head, &axes, false).unwrap();
    let mut config = ReconstructConfig::new(vec![20.0, 22.0, 24.0]);
    config.noise_sigma = t.noise_sigma;
    let fused = Reconstructor::from_head(&t.head, config)
        .unwrap()
        .reconstruct(&refs, None)
        .unwrap();
    let (mut both, mut worst) = (0usize, 0.0f32);
    for i in 0..fused.pixels.len() {
        let (a, b) = (fused.pixels.get(i), described.pixels.get(i));
        if a.status == PixelStatus::Valid && b.status == PixelStatus::Valid {
            both += 1;
            for k in 0..3 {
                worst = worst.max((a.point_m[k] - b.point_m[k]).abs());
            }
        }
    }
    println!(
        "ours, fused pipeline vs described path: {} vs {} valid, {both} in both, largest point difference {:.2} um",
        fused.count(PixelStatus::Valid),
        described.count(PixelStatus::Valid),
        1e6 * worst
    );
    assert!(both * 10 > fused.count(PixelStatus::Valid) * 9);
    assert!(worst < 2e-6, "{worst}");

    // The SLMaster capture described with our phase origin: refused, cause named.
    let comple = comple_gray_32();
    let frames = render(&t, &comple, 20);
    let mut ours = comple.clone();
    for e in &mut ours.sequence {
        if let Frames::Fringes(f) = e {
            f.phase_offset_rad = 0.0;
        }
    }
    let refs: Vec<&Raster<f32>> = frames.iter().collect();
    let err = decode(&ours, &refs, PROJECTOR, t.noise_sigma)
        .unwrap_err()
        .to_string();
    println!("wrong-origin SinusCompleGrayCode capture: refused: {err}");
    assert!(
        err.contains("half a period") && err.contains("phase origin"),
        "{err}"
    );
}

/// The SinusCompleGrayCode preset with a 32 px period on this projector.
fn comple_gray_32() -> CaptureSpec {
    Preset::SinusCompleGray
        .spec(
            &PresetOptions {
                periods_px: Some(vec![32.0]),
                ..Default::default()
            },
            PROJECTOR,
        )
        .unwrap()
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("slscan-capture-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write_capture(dir: &Path, frames: &[Raster<f32>], manifest: Option<&str>) -> PathBuf {
    let images = dir.join("images");
    std::fs::create_dir_all(&images).unwrap();
    for (i, f) in frames.iter().enumerate() {
        save_gray_png(&images.join(format!("frame_{i:02}.png")), f, true).unwrap();
    }
    if let Some(text) = manifest {
        std::fs::write(images.join(FILE_NAME), text).unwrap();
    }
    images
}

fn reconstruct(dir: &Path, images: &Path, extra: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_slscan"))
        .arg("reconstruct")
        .arg("--images")
        .arg(images)
        .arg("--rig")
        .arg(dir.join("rig.json"))
        .arg("--out")
        .arg(dir.join("cloud.ply"))
        .args(extra)
        .output()
        .unwrap()
}

#[test]
fn reconstruct_reads_a_manifest_or_a_preset_and_refuses_bad_descriptions() {
    let t = twin();
    let dir = tmp("cli");
    write_rig(
        &dir.join("rig.json"),
        &RigCalibration::single(t.head.clone()),
    )
    .unwrap();
    let spec = comple_gray_32();
    let frames = render(&t, &spec, 30);

    // The preset by flag, then the same description as capture.json beside the frames.
    let images = write_capture(&dir, &frames, None);
    let noise = format!("{}", t.noise_sigma);
    let by_flag = reconstruct(
        &dir,
        &images,
        &[
            "--preset",
            "sinus-comple-gray",
            "--periods",
            "32",
            "--noise-sigma",
            &noise,
        ],
    );
    let text = String::from_utf8_lossy(&by_flag.stderr);
    assert!(by_flag.status.success(), "{text}");
    assert!(dir.join("cloud.ply").is_file());
    std::fs::write(images.join(FILE_NAME), to_json(&spec)).unwrap();
    let by_manifest = reconstruct(&dir, &images, &["--noise-sigma", &noise]);
    assert!(
        by_manifest.status.success(),
        "{}",
        String::from_utf8_lossy(&by_manifest.stderr)
    );
    let said = String::from_utf8_lossy(&by_manifest.stdout);
    println!("reconstruct with capture.json: {said}");

    // Conflicting flags, before any work.
    let out = reconstruct(&dir, &images, &["--periods", "32"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("conflicts"), "{err}");

    // A manifest whose frame count disagrees with the folder.
    std::fs::remove_file(images.join("frame_17.png")).unwrap();
    let out = reconstruct(&dir, &images, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("needs 18 frames, 17 were given"),
        "{err}"
    );

    // Frames of another heterodyne system (phase 2 pi u / P - pi) given to our default
    // decoding: the fused pipeline's order checks fail, and the cause is named.
    let dir = tmp("cli-ours-other-origin");
    write_rig(
        &dir.join("rig.json"),
        &RigCalibration::single(t.head.clone()),
    )
    .unwrap();
    let mut other = Preset::Slscan
        .spec(
            &PresetOptions {
                periods_px: Some(vec![20.0, 22.0, 24.0]),
                ..Default::default()
            },
            PROJECTOR,
        )
        .unwrap();
    if let Frames::Fringes(f) = &mut other.sequence[0] {
        f.phase_offset_rad = -std::f64::consts::PI;
    }
    let images = write_capture(&dir, &render(&t, &other, 31), None);
    let out = reconstruct(
        &dir,
        &images,
        &["--periods", "20,22,24", "--noise-sigma", &noise],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    println!("ours with another heterodyne system's frames: {err}");
    assert!(
        !out.status.success() && err.contains("phase origin"),
        "{err}"
    );
    assert!(!dir.join("cloud.ply").exists());

    // The wrong phase origin: refused with the cause, and no cloud left behind.
    let dir = tmp("cli-wrong");
    write_rig(
        &dir.join("rig.json"),
        &RigCalibration::single(t.head.clone()),
    )
    .unwrap();
    let mut ours = spec.clone();
    for e in &mut ours.sequence {
        if let Frames::Fringes(f) = e {
            f.phase_offset_rad = 0.0;
        }
    }
    let images = write_capture(&dir, &frames, Some(&to_json(&ours)));
    let out = reconstruct(&dir, &images, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("phase origin"),
        "{err}"
    );
    assert!(!dir.join("cloud.ply").exists());
}

#[test]
fn reconstruct_stereo_decodes_both_cameras_of_a_stereo_head() {
    use slscan::sim::calibration::from_twin::stereo_head_from_twin;
    let (scene, rig) = built_in("stereo-spheres", &DETAIL).unwrap();
    let cameras: Vec<Renderer> = (0..2)
        .map(|c| Renderer::new(&scene, &rig, c, 0.0).unwrap())
        .collect();
    let head = stereo_head_from_twin(&rig, 0, 1, "S").unwrap();
    let spec = comple_gray_32();
    let dir = tmp("stereo");
    let stereo_rig = RigCalibration {
        heads: vec![],
        head_poses: vec![],
        stereo_heads: vec![head],
    };
    write_rig(&dir.join("rig.json"), &stereo_rig).unwrap();
    let images = projector_images(&spec, PROJECTOR.0, PROJECTOR.1);
    for (c, side) in cameras.iter().zip(["left", "right"]) {
        let folder = dir.join(side);
        std::fs::create_dir_all(&folder).unwrap();
        for (k, image) in images.iter().enumerate() {
            let bytes: Vec<u8> = image
                .data
                .iter()
                .map(|v| (v * 255.0).round() as u8)
                .collect();
            let pattern = Arc::new(Pattern::from_u8(PROJECTOR.0, PROJECTOR.1, &bytes).unwrap());
            let (img, _) = c
                .image(
                    &timelines(pattern, rig.projectors.len()),
                    exposure(),
                    &SensorModel::mono12(),
                    40 + k as u64,
                )
                .unwrap();
            let frame =
                Raster::from_vec(img.width as usize, img.height as usize, img.data).unwrap();
            save_gray_png(&folder.join(format!("frame_{k:02}.png")), &frame, true).unwrap();
        }
    }
    let run = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_slscan"))
            .arg("reconstruct")
            .arg("--images")
            .arg(dir.join("left"))
            .arg("--stereo")
            .arg(dir.join("right"))
            .arg("--rig")
            .arg(dir.join("rig.json"))
            .arg("--out")
            .arg(dir.join("cloud.ply"))
            .args(["--preset", "sinus-comple-gray", "--periods", "32"])
            .args(extra)
            .output()
            .unwrap()
    };
    // The projector's size is needed: it is not in a stereo head's calibration.
    let out = run(&[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("--projector-size"),
        "{err}"
    );
    let out = run(&["--projector-size", "640x400"]);
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    println!("stereo head, SinusCompleGrayCode capture: {said}");
    let cloud = slscan::io::ply_read::read_ply(&dir.join("cloud.ply"), 1.0)
        .unwrap()
        .cloud;
    // The two spheres cover about 1,500 pixels of this 320x240 camera.
    assert!(cloud.points.len() > 500, "{} points", cloud.points.len());
    // In the left camera's frame: the spheres at about 0.5 m, the wall at 0.6 m.
    let mut z: Vec<f64> = cloud.points.iter().map(|p| p.z).collect();
    z.sort_by(f64::total_cmp);
    let median = z[z.len() / 2];
    assert!((0.4..0.7).contains(&median), "median depth {median} m");
}
