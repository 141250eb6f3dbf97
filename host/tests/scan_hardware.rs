//! The hardware scan path without hardware: hil-sim's board on a pty stands
//! in for the sync board (passed as `--port`), and a thread plays the two
//! vendor tools a real rig needs: the DMD GUI (it reads the pattern PNGs
//! slscan writes) and the camera software (for every exposure the simulated
//! board's cameras took, it renders the digital twin lit by the patterns the
//! simulated DMDs displayed then, and saves the frame into the frames
//! folder with a temporary name and a rename). The scan then reads frames
//! exactly as on a real rig. Small images keep each scan to seconds.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Duration;

use hil_sim::board::{spawn_on_pty, SimBoardConfig, SimBoardHandle};
use hil_sim::devices::Displayed;
use hil_sim::twin::scenes::{built_in, Detail};
use hil_sim::twin::{Display, Exposure, Pattern, ProjectorTimeline, Shown, TwinRig};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use slscan::board::ClientConfig;
use slscan::calibration::{write_rig, RigCalibration};
use slscan::io::images::{load_gray, save_gray_png};
use slscan::raster::Raster;
use slscan::rig::folder_camera::{FolderCamera, FolderCameraConfig, FolderHead};
use slscan::rig::folder_projector::{
    pattern_file_name, FolderProjector, FolderProjectorHead, PatternDelivery,
};
use slscan::rig::hardware::HardwareRig;
use slscan::rig::serial_board::SerialBoard;
use slscan::rig::RigError;
use slscan::scan::{
    run_on_rig, sim_sensor, twin_truth, GroundTruth, Mode, ScanConfig, ScanError, ScanResult,
};

const CAMERA_PX: (u32, u32) = (200, 150);
const HEADS: [&str; 2] = ["A", "B"];

/// The twin every test renders (ray casts cached) and its calibration.
fn twin() -> &'static (Arc<TwinRig>, RigCalibration) {
    static TWIN: OnceLock<(Arc<TwinRig>, RigCalibration)> = OnceLock::new();
    TWIN.get_or_init(|| {
        let config = ScanConfig::new("large-part");
        let detail = Detail {
            camera: CAMERA_PX,
            projector: config.projector_px,
        };
        let (scene, rig) = built_in("large-part", &detail).expect("scene");
        let twin = Arc::new(TwinRig::new(scene, rig).expect("twin"));
        let calibration = twin_truth::twin_calibration(twin.rig(), 2);
        (twin, calibration)
    })
}

/// What the camera software gets wrong.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Fault {
    None,
    /// Frame `index` of head `head` is never saved.
    Drop {
        head: usize,
        index: usize,
    },
    /// Head `head` saves one frame too many after frame `index`.
    Extra {
        head: usize,
        index: usize,
    },
    /// Frame `index` of head `head` is saved at half size.
    WrongSize {
        head: usize,
        index: usize,
    },
    /// Frame `index` of head `head` is a truncated PNG.
    Corrupt {
        head: usize,
        index: usize,
    },
}

/// Per-test folders.
struct Folders {
    root: PathBuf,
    frames: PathBuf,
    patterns: PathBuf,
    out: PathBuf,
}

fn folders(name: &str) -> Folders {
    let root = std::env::temp_dir().join(format!("slscan-hw-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    Folders {
        frames: root.join("frames"),
        patterns: root.join("patterns"),
        out: root.join("out"),
        root,
    }
}

/// The DMD GUI and camera software: until `stop`, saves one frame per
/// finished exposure of each simulated camera (see the module doc).
fn play_vendor_tools(board: &SimBoardHandle, folders: &Folders, fault: Fault, stop: &AtomicBool) {
    let (twin, _) = twin();
    let sensor = sim_sensor();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    // Board clock of the last exposure saved per camera: the clock runs on
    // across plans, so later exposures are new ones.
    let mut last_start_ns: [Option<u64>; 2] = [None, None];
    let mut saved = [0usize; 2];
    let mut dmd = DmdGui::default();
    while !stop.load(Ordering::Relaxed) {
        for cam in 0..2 {
            let (exposures, displayed) = {
                let b = board.board();
                let heads = b.hardware().heads();
                let exposures: Vec<(u64, u64)> = heads[cam]
                    .camera
                    .exposures()
                    .iter()
                    .filter_map(|e| e.end_ns.map(|end| (e.start_ns, end)))
                    .filter(|&(start, _)| last_start_ns[cam].is_none_or(|last| start > last))
                    .collect();
                let displayed: Vec<Vec<Displayed>> = heads
                    .iter()
                    .map(|h| h.projector.displayed().to_vec())
                    .collect();
                (exposures, displayed)
            };
            for (start_ns, end_ns) in exposures {
                let timelines: Vec<ProjectorTimeline> = displayed
                    .iter()
                    .enumerate()
                    .map(|(p, shown)| {
                        dmd.timeline(&folders.patterns.join(HEADS[p]), shown, start_ns, end_ns)
                    })
                    .collect();
                let window = Exposure {
                    start_s: start_ns as f64 * 1e-9,
                    end_s: end_ns as f64 * 1e-9,
                };
                let (image, _) = twin
                    .image(cam, &timelines, window, &sensor, &mut rng)
                    .expect("twin renders");
                let frame =
                    Raster::from_vec(image.width as usize, image.height as usize, image.data)
                        .expect("mono frame");
                save_frame(
                    &folders.frames.join(HEADS[cam]),
                    cam,
                    &mut saved[cam],
                    &frame,
                    fault,
                );
                last_start_ns[cam] = Some(start_ns);
            }
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// The DMD vendor's GUI: loads the pattern PNGs slscan handed over (each
/// file decoded once per version of it).
#[derive(Default)]
struct DmdGui {
    loaded: HashMap<PathBuf, (Stamp, Arc<Pattern>)>,
}

type Stamp = (u64, Option<std::time::SystemTime>);

impl DmdGui {
    fn pattern(&mut self, path: &Path) -> Arc<Pattern> {
        let meta = std::fs::metadata(path).expect("the pattern file exists");
        let stamp = (meta.len(), meta.modified().ok());
        if let Some((s, p)) = self.loaded.get(path) {
            if *s == stamp {
                return p.clone();
            }
        }
        let p = load_gray(path)
            .expect("the DMD GUI loads the pattern")
            .image;
        let pattern = Arc::new(Pattern {
            width: p.width as u32,
            height: p.height as u32,
            values: p.data,
        });
        self.loaded
            .insert(path.to_owned(), (stamp, pattern.clone()));
        pattern
    }

    /// What projector `dir`'s DMD showed during [start_ns, end_ns]: the
    /// displayed log's patterns, from the PNG set in `dir`.
    fn timeline(
        &mut self,
        dir: &Path,
        displayed: &[Displayed],
        start_ns: u64,
        end_ns: u64,
    ) -> ProjectorTimeline {
        let shown = displayed
            .iter()
            .filter(|d| d.end_ns > start_ns && d.start_ns < end_ns)
            .map(|d| Shown {
                pattern: self.pattern(&dir.join(pattern_file_name(d.pattern_index as usize))),
                start_s: d.start_ns as f64 * 1e-9,
                end_s: d.end_ns as f64 * 1e-9,
                led: [1.0; 3],
                display: Display::Steady,
            })
            .collect();
        ProjectorTimeline { shown }
    }
}

/// Saves camera `cam`'s next frame as a 16-bit PNG (temporary + rename),
/// or gets it wrong as `fault` says.
fn save_frame(dir: &Path, cam: usize, saved: &mut usize, frame: &Raster<f32>, fault: Fault) {
    let index = *saved;
    *saved += 1;
    let path = dir.join(format!("frame_{index:05}.png"));
    match fault {
        Fault::Drop { head, index: i } if head == cam && i == index => {}
        Fault::WrongSize { head, index: i } if head == cam && i == index => {
            let half = Raster::from_fn(frame.width / 2, frame.height / 2, |x, y| {
                *frame.at(2 * x, 2 * y)
            });
            save_gray_png(&path, &half, true).expect("save");
        }
        Fault::Corrupt { head, index: i } if head == cam && i == index => {
            let tmp = dir.join(".corrupt.tmp");
            std::fs::write(&tmp, b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR truncated").expect("write");
            std::fs::rename(&tmp, &path).expect("rename");
        }
        Fault::Extra { head, index: i } if head == cam && i == index => {
            save_gray_png(&path, frame, true).expect("save");
            save_gray_png(
                &dir.join(format!("frame_{index:05}_again.png")),
                frame,
                true,
            )
            .expect("save");
        }
        _ => save_gray_png(&path, frame, true).expect("save"),
    }
}

/// A scan config for the twin's sizes.
fn config(mode: Mode) -> ScanConfig {
    let mut config = ScanConfig::new("hardware");
    config.mode = mode;
    config.camera_px = CAMERA_PX;
    config
}

/// The hardware rig on `port` with the test's folders.
fn hardware_rig(
    port: &Path,
    folders: &Folders,
    timeout: Duration,
) -> Result<HardwareRig, RigError> {
    let (_, calibration) = twin();
    let cameras = FolderCamera::new(FolderCameraConfig {
        root: folders.frames.clone(),
        heads: calibration
            .heads
            .iter()
            .map(|h| FolderHead {
                name: h.name.clone(),
                image_size_px: (h.camera.width_px, h.camera.height_px),
            })
            .collect(),
        bit_depth: None,
        timeout,
        poll_interval: Duration::from_millis(20),
        settle: Duration::from_millis(300),
    })?;
    let projector = FolderProjector::new(
        folders.patterns.clone(),
        calibration
            .heads
            .iter()
            .map(|h| FolderProjectorHead {
                name: h.name.clone(),
                dmd_size_px: (h.projector.width_px, h.projector.height_px),
            })
            .collect(),
        PatternDelivery::Write,
    );
    let board = SerialBoard::open(port, ClientConfig::default())?;
    Ok(HardwareRig::new(board, projector, cameras, 2))
}

/// Runs `scan` against a fresh simulated board with the vendor tools
/// playing along (getting `fault` wrong), then stops them.
fn with_vendor_tools<T>(
    name: &str,
    fault: Fault,
    scan: impl FnOnce(&Path, &Folders) -> T,
) -> (T, Folders) {
    let folders = folders(name);
    std::fs::create_dir_all(&folders.root).expect("temp folder");
    let board = spawn_on_pty(SimBoardConfig::default()).expect("pty board");
    let port = board.path().expect("pty path").to_owned();
    let stop = AtomicBool::new(false);
    let out = std::thread::scope(|s| {
        let vendor = s.spawn(|| play_vendor_tools(&board, &folders, fault, &stop));
        let out = scan(&port, &folders);
        stop.store(true, Ordering::Relaxed);
        vendor.join().expect("vendor tools ran");
        out
    });
    (out, folders)
}

/// A library-level hardware scan; measured against the twin when `truth`.
fn hardware_scan(
    name: &str,
    mode: Mode,
    fault: Fault,
    truth: bool,
) -> (Result<ScanResult, ScanError>, Folders) {
    // A missing frame is only known after the whole timeout; other faults
    // end the wait at once, so theirs only needs to outlast a slow machine.
    let timeout = match fault {
        Fault::Drop { .. } => 5,
        _ => 30,
    };
    with_vendor_tools(name, fault, |port, folders| {
        let (twin, calibration) = twin();
        let mut rig = hardware_rig(port, folders, Duration::from_secs(timeout))?;
        let truth = truth.then(|| GroundTruth::new(twin.clone()));
        run_on_rig(
            &mut rig,
            calibration,
            "twin truth written as a rig file",
            truth.as_ref(),
            &config(mode),
            &mut |_| {},
        )
    })
}

/// Frames in order, each from its own trigger: per-head accuracy at the
/// noise limit (a frame out of turn gives millimetres, see dual_head's
/// off-by-one DMD table test) and the fused cloud covering more.
fn check_accurate(result: &ScanResult) {
    for head in &result.heads {
        let t = head.truth.as_ref().expect("measured");
        assert!(
            t.accuracy.rmse_m < 200e-6,
            "head {}: {:?}",
            head.name,
            t.accuracy
        );
        assert_eq!(t.accuracy.outliers, 0, "head {}", head.name);
        assert!(
            t.accuracy.own_coverage > 0.9,
            "head {}: {:?}",
            head.name,
            t.accuracy
        );
    }
    let fused = result.fused.truth.as_ref().expect("measured");
    let best = result
        .heads
        .iter()
        .map(|h| h.truth.as_ref().map_or(0.0, |t| t.coverage))
        .fold(0.0, f64::max);
    assert!(
        fused.coverage > best + 0.15,
        "fused {fused:?} vs best head {best}"
    );
    assert!(result.fused.icp.as_ref().is_some_and(|icp| icp.converged));
}

#[test]
fn sequential_hardware_scan_reads_every_frame_in_order() {
    let (result, folders) = hardware_scan("sequential", Mode::Sequential, Fault::None, true);
    let result = result.expect("scan runs");
    check_accurate(&result);
    // The pattern sets were handed over as 12 numbered PNGs per head.
    for head in HEADS {
        assert!(folders
            .patterns
            .join(head)
            .join(pattern_file_name(11))
            .is_file());
        assert!(!folders
            .patterns
            .join(head)
            .join(pattern_file_name(12))
            .exists());
    }
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn multiplexed_hardware_scan_separates_the_heads() {
    let (result, folders) = hardware_scan(
        "multiplexed",
        Mode::SimultaneousMultiplexed,
        Fault::None,
        true,
    );
    check_accurate(&result.expect("scan runs"));
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn simultaneous_mode_is_refused_without_a_twin() {
    let (result, folders) = hardware_scan("simultaneous", Mode::Simultaneous, Fault::None, false);
    let err = result.expect_err("no overlap mask on hardware");
    assert!(matches!(err, ScanError::NoAliasMask), "{err:?}");
    assert!(err.to_string().contains("PLACEHOLDER"));
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn a_missing_frame_is_a_frame_count_error() {
    let fault = Fault::Drop { head: 0, index: 5 };
    let (result, folders) = hardware_scan("missing", Mode::Sequential, fault, false);
    let err = result.expect_err("a frame is missing");
    assert!(
        matches!(
            err,
            ScanError::Rig(RigError::FrameCount {
                head: 0,
                expected: 12,
                got: 11,
                ..
            })
        ),
        "{err:?}"
    );
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn an_extra_frame_is_a_frame_count_error() {
    // Head B runs second in sequential mode: head A's frames were fine.
    // (An extra frame mid-run is caught too when the settle time outlasts
    // the gap between two saves; this slow test renderer has no fixed gap.)
    let fault = Fault::Extra { head: 1, index: 11 };
    let (result, folders) = hardware_scan("extra", Mode::Sequential, fault, false);
    let err = result.expect_err("one frame too many");
    assert!(
        matches!(
            err,
            ScanError::Rig(RigError::FrameCount {
                head: 1,
                expected: 12,
                got: 13,
                ..
            })
        ),
        "{err:?}"
    );
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn a_wrong_size_frame_is_a_size_error() {
    let fault = Fault::WrongSize { head: 0, index: 3 };
    let (result, folders) = hardware_scan("size", Mode::Sequential, fault, false);
    let err = result.expect_err("a half-size frame");
    assert!(
        matches!(
            err,
            ScanError::Rig(RigError::FrameSize {
                head: 0,
                frame: 3,
                expected: (200, 150),
                got: (100, 75),
                ..
            })
        ),
        "{err:?}"
    );
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn a_corrupt_frame_is_a_decode_error() {
    let fault = Fault::Corrupt { head: 1, index: 4 };
    let (result, folders) = hardware_scan("corrupt", Mode::SimultaneousMultiplexed, fault, false);
    let err = result.expect_err("a truncated PNG");
    assert!(
        matches!(
            err,
            ScanError::Rig(RigError::FrameDecode {
                head: 1,
                frame: 4,
                ..
            })
        ),
        "{err:?}"
    );
    let _ = std::fs::remove_dir_all(&folders.root);
}

fn slscan_scan(port: &Path, folders: &Folders, extra: &[&str]) -> std::process::Output {
    let (_, calibration) = twin();
    let rig_file = folders.root.join("rig.json");
    write_rig(&rig_file, calibration).expect("rig file");
    let path = |p: &Path| p.to_string_lossy().into_owned();
    let mut args = vec![
        "scan".to_string(),
        "--port".into(),
        path(port),
        "--frames-from".into(),
        path(&folders.frames),
        "--calibration".into(),
        path(&rig_file),
        "--patterns-dir".into(),
        path(&folders.patterns),
        "--out".into(),
        path(&folders.out),
        "--frame-poll-ms".into(),
        "20".into(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    Command::new(env!("CARGO_BIN_EXE_slscan"))
        .args(&args)
        .output()
        .expect("slscan runs")
}

#[test]
fn slscan_scan_on_a_port_writes_clouds_and_a_report_without_truth() {
    let (out, folders) = with_vendor_tools("cli", Fault::None, |port, folders| {
        slscan_scan(port, folders, &["--mode", "sequential"])
    });
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("PLACEHOLDER: no DMD driver uploads patterns"),
        "{stderr}"
    );
    for file in [
        "scan.ply",
        "head_a.ply",
        "head_b.ply",
        "report.json",
        "phase_a.png",
    ] {
        assert!(folders.out.join(file).is_file(), "{file} written");
    }
    assert!(
        !folders.out.join("error_a.png").exists(),
        "no truth, no error map"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(folders.out.join("report.json")).unwrap())
            .unwrap();
    for head in 0..2 {
        let h = &report["heads"][head];
        assert!(h["points"].as_u64().unwrap() > 5_000, "{h}");
        assert!(h["rmse_um"].is_null() && h["coverage"].is_null(), "{h}");
    }
    let fused = &report["fused"];
    assert!(
        fused["rmse_um"].is_null() && fused["coverage"].is_null(),
        "{fused}"
    );
    assert!(fused["points"].as_u64().unwrap() > report["heads"][0]["points"].as_u64().unwrap());
    assert!(fused["icp"]["converged"].as_bool().unwrap(), "{fused}");
    assert!(report["calibration"].as_str().unwrap().contains("rig.json"));
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn slscan_scan_with_a_missing_frame_fails_and_writes_no_scan() {
    let fault = Fault::Drop { head: 1, index: 0 };
    let (out, folders) = with_vendor_tools("cli-missing", fault, |port, folders| {
        slscan_scan(port, folders, &["--frame-timeout-s", "5"])
    });
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("head 1: camera took 11 frames for 12 triggers"),
        "{stderr}"
    );
    assert!(!folders.out.join("scan.ply").exists());
    let _ = std::fs::remove_dir_all(&folders.root);
}

#[test]
fn slscan_scan_names_the_missing_hardware_options() {
    let out = Command::new(env!("CARGO_BIN_EXE_slscan"))
        .args([
            "scan",
            "--port",
            "/dev/ttyACM9",
            "--out",
            "/tmp/slscan-never",
        ])
        .output()
        .expect("slscan runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("--frames-from, --calibration") && stderr.contains("--sim"),
        "{stderr}"
    );
}
