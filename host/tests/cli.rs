//! `slscan patterns` and `slscan reconstruct` end to end on small formula-based renders
//! (`slscan::synth`, not twin renders), and the errors bad inputs must give.

#[path = "support/synth_capture.rs"]
mod synth_capture;

use std::path::{Path, PathBuf};
use std::process::Command;

use slscan::calibration::PinholeModel;
use slscan::io::images::save_gray_png;
use slscan::raster::Raster;

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("slscan-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Renders 12 frames (3 periods x 4 steps) as 16-bit PNGs and writes the matching rig.
fn capture(dir: &Path) -> PathBuf {
    synth_capture::capture_with(dir, PinholeModel::ideal(64, 48, 160.0))
}

fn reconstruct(dir: &Path, images: &Path, rig: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_slscan"))
        .args([
            "reconstruct",
            "--periods",
            "9,10,11",
            "--noise-sigma",
            "0.003",
        ])
        .arg("--images")
        .arg(images)
        .arg("--rig")
        .arg(rig)
        .arg("--out")
        .arg(dir.join("out.ply"))
        .arg("--pictures")
        .arg(dir.join("pictures"))
        .output()
        .unwrap()
}

fn fails_with(out: &std::process::Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "should fail");
    assert!(stderr.contains(needle), "stderr lacks {needle:?}: {stderr}");
}

/// `slscan scan --sim --scene spheres <args> --out <out>`.
#[cfg(feature = "sim")]
fn sim_scan(args: &[&str], out: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_slscan"))
        .args(["scan", "--sim", "--scene", "spheres"])
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn reconstruct_writes_a_cloud_and_pictures() {
    let dir = tmp("ok");
    let images = capture(&dir);
    let out = reconstruct(&dir, &images, &dir.join("rig.json"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let ply = std::fs::read(dir.join("out.ply")).unwrap();
    assert!(ply.starts_with(b"ply\nformat binary_little_endian 1.0\n"));
    for f in [
        "depth.png",
        "projector_column.png",
        "fringe_modulation.png",
        "camera_mean.png",
        "depth.npy",
    ] {
        assert!(dir.join("pictures").join(f).exists(), "{f}");
    }
    let page = std::fs::read_to_string(dir.join("out.html")).unwrap();
    assert!(page.contains("data:image/png;base64,") && page.contains("valid pixels"));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("points ->"), "{stdout}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_captures_give_clear_errors_and_no_output() {
    let dir = tmp("bad");
    let images = capture(&dir);
    let rig = dir.join("rig.json");
    let frame = images.join("frame_05.png");
    let original = std::fs::read(&frame).unwrap();

    std::fs::remove_file(&frame).unwrap();
    fails_with(
        &reconstruct(&dir, &images, &rig),
        "expected 12 frames, found 11",
    );

    let grey = Raster::from_fn(64, 48, |x, _| 0.2 + x as f32 / 200.0);
    save_gray_png(&frame, &grey, false).unwrap();
    fails_with(
        &reconstruct(&dir, &images, &rig),
        "is 8-bit but the set's first frame is 16-bit",
    );

    save_gray_png(
        &frame,
        &Raster::from_fn(32, 48, |x, _| x as f32 / 64.0),
        true,
    )
    .unwrap();
    fails_with(
        &reconstruct(&dir, &images, &rig),
        "(32, 48) but the set's first frame is (64, 48)",
    );

    save_gray_png(
        &frame,
        &Raster::from_fn(64, 48, |x, _| if x < 32 { 1.0 } else { 0.3 }),
        true,
    )
    .unwrap();
    fails_with(&reconstruct(&dir, &images, &rig), "saturated");

    save_gray_png(&frame, &Raster::filled(64, 48, 0.0), true).unwrap();
    fails_with(&reconstruct(&dir, &images, &rig), "no signal");

    std::fs::write(&frame, &original).unwrap();
    let text = std::fs::read_to_string(&rig).unwrap();
    let bad_rig = dir.join("bad_rig.json");
    std::fs::write(
        &bad_rig,
        text.replacen("\"fx\": 160.0", "\"fx\": -160.0", 1),
    )
    .unwrap();
    fails_with(
        &reconstruct(&dir, &images, &bad_rig),
        "focal lengths must be positive",
    );
    std::fs::write(&bad_rig, text.replacen("\"cy\": 23.5,", "", 1)).unwrap();
    fails_with(&reconstruct(&dir, &images, &bad_rig), "missing field `cy`");

    assert!(!dir.join("out.ply").exists(), "no output after failures");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn npy_frames_give_the_same_cloud_and_write_phase_writes_the_maps() {
    let dir = tmp("npy");
    let images = capture(&dir);
    let rig = dir.join("rig.json");
    // The same frames as float .npy arrays (the PNGs' decoded values).
    let npy = dir.join("npy");
    std::fs::create_dir_all(&npy).unwrap();
    for path in slscan::io::images::list_images(&images).unwrap() {
        let frame = slscan::io::images::load_gray(&path).unwrap();
        let name = path.with_extension("npy");
        slscan::io::npy::write_npy_f32(&npy.join(name.file_name().unwrap()), &frame.image).unwrap();
    }
    let png_run = reconstruct(&dir, &images, &rig);
    assert!(
        png_run.status.success(),
        "{}",
        String::from_utf8_lossy(&png_run.stderr)
    );
    let from_png = std::fs::read(dir.join("out.ply")).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_slscan"))
        .args([
            "reconstruct",
            "--periods",
            "9,10,11",
            "--noise-sigma",
            "0.003",
            "--verbose",
        ])
        .arg("--images")
        .arg(&npy)
        .arg("--rig")
        .arg(&rig)
        .arg("--out")
        .arg(dir.join("npy.ply"))
        .arg("--write-phase")
        .arg(dir.join("maps"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        std::fs::read(dir.join("npy.ply")).unwrap(),
        from_png,
        "same cloud"
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    for stage in ["phase", "unwrap", "triangulate", "cloud", "load", "write"] {
        assert!(
            stdout.lines().any(|l| l.starts_with(stage)),
            "{stage}: {stdout}"
        );
    }
    let read = |f: &str| {
        slscan::io::npy::decode_npy_2d(&std::fs::read(dir.join("maps").join(f)).unwrap()).unwrap()
    };
    let (phase, status) = (read("phase.npy"), read("status.npy"));
    assert_eq!(phase.values.size(), (64, 48));
    assert_eq!(status.dtype, slscan::io::npy::Dtype::U8);
    assert_eq!(read("modulation.npy").values.size(), (64, 48));
    // Valid pixels (code 0) have a phase; all others are NaN.
    for (p, s) in phase.values.data.iter().zip(&status.values.data) {
        assert_eq!(p.is_finite(), *s == 0.0, "phase {p} status {s}");
    }
    assert!(status.values.data.iter().filter(|s| **s == 0.0).count() > 1000);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The files `reconstruct` writes with `--pictures`.
fn reconstruct_outputs(dir: &Path) -> Vec<PathBuf> {
    let mut files = vec![dir.join("out.ply"), dir.join("out.html")];
    for kind in slscan::pictures::KINDS {
        files.push(dir.join("pictures").join(format!("{kind}.png")));
    }
    files.push(dir.join("pictures/depth.npy"));
    files
}

#[test]
fn a_failed_reconstruct_leaves_no_output_old_or_new() {
    let dir = tmp("stale");
    let images = capture(&dir);
    let rig = dir.join("rig.json");
    std::fs::create_dir_all(dir.join("pictures")).unwrap();
    for f in reconstruct_outputs(&dir) {
        std::fs::write(f, b"an earlier run").unwrap();
    }
    std::fs::remove_file(images.join("frame_05.png")).unwrap();
    fails_with(
        &reconstruct(&dir, &images, &rig),
        "expected 12 frames, found 11",
    );
    for f in reconstruct_outputs(&dir) {
        assert!(!f.exists(), "{} left behind", f.display());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_pictures_path_that_is_a_file_is_refused_before_any_work() {
    let dir = tmp("picfile");
    let images = capture(&dir);
    std::fs::write(dir.join("pictures"), b"a file").unwrap();
    fails_with(
        &reconstruct(&dir, &images, &dir.join("rig.json")),
        "exists and is not a folder",
    );
    assert!(!dir.join("out.ply").exists(), "no cloud before the failure");
    assert_eq!(std::fs::read(dir.join("pictures")).unwrap(), b"a file");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[cfg(unix)]
#[test]
fn reconstruct_refuses_to_replace_a_link_or_a_device() {
    let dir = tmp("link");
    let images = capture(&dir);
    std::fs::write(dir.join("elsewhere.ply"), b"not ours").unwrap();
    std::os::unix::fs::symlink(dir.join("elsewhere.ply"), dir.join("out.ply")).unwrap();
    fails_with(
        &reconstruct(&dir, &images, &dir.join("rig.json")),
        "is a symlink",
    );
    assert!(std::fs::symlink_metadata(dir.join("out.ply"))
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(
        std::fs::read(dir.join("elsewhere.ply")).unwrap(),
        b"not ours"
    );
    // A device node as --out (as root, a rename would replace it).
    let out = Command::new(env!("CARGO_BIN_EXE_slscan"))
        .args(["reconstruct", "--periods", "9,10,11", "--out", "/dev/null"])
        .arg("--images")
        .arg(&images)
        .arg("--rig")
        .arg(dir.join("rig.json"))
        .output()
        .unwrap();
    fails_with(&out, "is a device");
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::symlink_metadata("/dev/null")
        .unwrap()
        .file_type()
        .is_char_device());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn patterns_writes_each_family() {
    let dir = tmp("patterns");
    let run = |args: &[&str], sub: &str| {
        let out_dir = dir.join(sub);
        let out = Command::new(env!("CARGO_BIN_EXE_slscan"))
            .arg("patterns")
            .args(args)
            .args(["--width", "64", "--height", "48", "--out"])
            .arg(&out_dir)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        std::fs::read_dir(&out_dir).unwrap().count()
    };
    assert_eq!(run(&["--periods", "8,9", "--steps", "3"], "fringes"), 6);
    // A smaller set into the same folder leaves none of the larger set's
    // tail (a DMD tool would load it as part of the set); other files stay.
    std::fs::write(dir.join("fringes/notes.txt"), b"mine").unwrap();
    assert_eq!(run(&["--periods", "8", "--steps", "3"], "fringes"), 3 + 1);
    // 16 blocks of 4 px -> 4 bits, times 4 shifts (0..3).
    assert_eq!(run(&["--kind", "gray", "--block", "4"], "gray"), 16);
    assert_eq!(run(&["--kind", "tfc"], "tfc"), 8);
    // 24 TFC channel frames, error-diffused, packed into one 24-plane image.
    assert_eq!(
        run(
            &["--kind", "tfc", "--bits", "diffusion", "--pack"],
            "packed"
        ),
        1
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Built without the simulator, every `--sim` says so, exits non-zero and
/// leaves nothing on disk.
#[cfg(not(feature = "sim"))]
#[test]
fn sim_options_say_the_build_has_no_simulator() {
    let dir = tmp("no-sim");
    let runs: [&[&str]; 3] = [
        &["scan", "--sim", "--out"],
        &["calibrate", "--sim", "--out"],
        &["board", "info", "--sim"],
    ];
    for (k, args) in runs.iter().enumerate() {
        let target = dir.join(format!("run{k}")).join("out");
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_slscan"));
        cmd.args(*args);
        if args.last() == Some(&"--out") {
            cmd.arg(&target);
        }
        let out = cmd.output().unwrap();
        fails_with(&out, "built without the simulator");
        assert!(
            !dir.join(format!("run{k}")).exists(),
            "{args:?} made a folder"
        );
    }
}

/// `scan --mode high-speed` on hardware refuses, before touching a device
/// or the output folder, a monochrome camera format, and names what is
/// missing.
#[test]
fn high_speed_on_hardware_refuses_what_cannot_work_before_any_device() {
    let dir = tmp("high-speed-hw");
    let out = dir.join("out");
    let base = [
        "scan",
        "--mode",
        "high-speed",
        "--port",
        "/dev/slscan-no-such-port",
        "--calibration",
        "no-such-rig.json",
    ];
    let run = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_slscan"))
            .args(base)
            .args(extra)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap()
    };
    fails_with(
        &run(&[
            "--camera",
            "genicam:Fake-1",
            "--camera-pixel-format",
            "Mono8",
        ]),
        "needs colour frames: --camera-pixel-format Mono8 is monochrome",
    );
    let missing = Command::new(env!("CARGO_BIN_EXE_slscan"))
        .args(["scan", "--mode", "high-speed", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    fails_with(
        &missing,
        "missing: --port, --frames-from or --camera, --calibration",
    );
    assert!(!out.exists(), "a refused scan made its output folder");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--physics-correction` corrects a diffusion restorer's sampler: with the
/// shipped one-step restorer, or in air, it is refused before any capture
/// and nothing is written.
#[cfg(feature = "sim")]
#[test]
fn physics_correction_without_a_diffusion_restorer_is_refused_before_capture() {
    let dir = tmp("physics-correction");
    let out = dir.join("out");
    let run = |extra: &[&str]| sim_scan(&[extra, &["--physics-correction", "0.01"]].concat(), &out);
    let water = ["--medium", "water", "--turbidity", "T3"];
    fails_with(
        &run(&[&water[..], &["--restorer", "learned"]].concat()),
        "is a one-step network, it has no sampler to correct",
    );
    fails_with(
        &run(&[&water[..], &["--restorer", "classical"]].concat()),
        "--physics-correction corrects a learned restorer's sampler",
    );
    fails_with(&run(&[]), "describe water: add --medium water");
    assert!(!out.exists(), "a refused scan made its output folder");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--water-edge-margin` is a water scan's: in air, or negative, it is
/// refused before any capture and nothing is written.
#[cfg(feature = "sim")]
#[test]
fn a_water_edge_margin_in_air_or_negative_is_refused_before_capture() {
    let dir = tmp("water-edge-margin");
    let out = dir.join("out");
    let run = |extra: &[&str]| sim_scan(extra, &out);
    fails_with(
        &run(&["--water-edge-margin", "2"]),
        "describe water: add --medium water",
    );
    fails_with(
        &run(&[
            "--medium",
            "water",
            "--turbidity",
            "T3",
            "--water-edge-margin=-1",
        ]),
        "edge margin (PSF sigmas) = -1: must be finite and >= 0",
    );
    assert!(!out.exists(), "a refused scan made its output folder");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--demod-refinements`, `--sibling-cancellations` and
/// `--consensus-passes` belong to `--mode high-speed` and cannot join `--fdd-model` (which learnt the single
/// pass), and `--settle-edges` needs consensus passes: each refused before anything is made.
#[cfg(feature = "sim")]
#[test]
fn demodulation_passes_outside_high_speed_or_with_fdd_net_are_refused() {
    let dir = tmp("refinements");
    let out = dir.join("out");
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/highspeed_fdd.onnx");
    for flag in [
        "--demod-refinements",
        "--sibling-cancellations",
        "--consensus-passes",
    ] {
        let scan = |extra: &[&str]| sim_scan(&[&[flag, "1"], extra].concat(), &out);
        fails_with(
            &scan(&["--mode", "sequential"]),
            &format!("{flag} is for --mode high-speed only"),
        );
        fails_with(
            &scan(&[
                "--mode",
                "high-speed",
                "--fdd-model",
                shipped.to_str().unwrap(),
            ]),
            "cannot be used with",
        );
        assert!(!out.exists(), "a refused scan made its output folder");
    }
    // `--settle-edges` settles the consensus passes' holes: alone it would do nothing.
    fails_with(
        &sim_scan(&["--mode", "high-speed", "--settle-edges"], &out),
        "--settle-edges settles the consensus passes' holes: give --consensus-passes 1 or more",
    );
    assert!(!out.exists(), "a refused scan made its output folder");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--zocr-model` and `--fdd-model` are seed 001's networks: refused
/// outside `--mode high-speed`, and a file that is not a fitting model
/// fails the scan before capture, naming the file, with the earlier run's
/// report gone.
#[cfg(feature = "sim")]
#[test]
fn a_high_speed_model_outside_high_speed_or_unreadable_is_refused_before_capture() {
    for (flag, name) in [
        ("--zocr-model", "highspeed_zocr"),
        ("--fdd-model", "highspeed_fdd"),
    ] {
        let dir = tmp(name);
        let out = dir.join("out");
        let scan = |mode: &str, model: &Path| {
            Command::new(env!("CARGO_BIN_EXE_slscan"))
                .args(["scan", "--sim", "--scene", "spheres", "--mode", mode])
                .arg(flag)
                .arg(model)
                .arg("--out")
                .arg(&out)
                .output()
                .unwrap()
        };
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../models/{name}.onnx"));
        fails_with(
            &scan("sequential", &shipped),
            &format!("{flag} is seed 001's network for --mode high-speed only"),
        );
        assert!(!out.exists(), "a refused scan made its output folder");
        std::fs::create_dir_all(&out).unwrap();
        std::fs::write(out.join("report.json"), "{}").unwrap();
        let bogus = dir.join("bogus.onnx");
        std::fs::write(&bogus, b"not a network").unwrap();
        let failed = scan("high-speed", &bogus);
        fails_with(&failed, "bogus");
        fails_with(&failed, "nothing written");
        assert!(
            !out.join("report.json").exists(),
            "the earlier run's report survived a failed scan ({flag})"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
