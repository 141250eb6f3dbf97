//! Plays the vendor tools of a real rig against hil-sim's board on a pty:
//! the DMD GUI (it reads the pattern PNGs slscan writes) and the camera
//! software (for every exposure the simulated board's cameras took, it
//! renders the digital twin lit by the patterns the simulated DMDs
//! displayed then, and saves the frame into the frames folder with a
//! temporary name and a rename), getting one thing wrong on request.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Duration;

use hil_sim::board::{spawn_on_pty, SimBoardConfig, SimBoardHandle};
use hil_sim::devices::Displayed;
use hil_sim::faults::FaultPlan;
use hil_sim::twin::scenes::{built_in, Detail};
use hil_sim::twin::{
    Display, Exposure, Image, Pattern, ProjectorTimeline, SensorModel, Shown, TwinRig,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use slscan::calibration::RigCalibration;
use slscan::io::images::load_gray;
use slscan::rig::folder_projector::{pattern_file_name, LED_FILE};
use slscan::scan::ScanConfig;
use slscan::sim::scan::sim_sensor;
use slscan::sim::truth as twin_truth;

pub const CAMERA_PX: (u32, u32) = (200, 150);
pub const HEADS: [&str; 2] = ["A", "B"];

/// The twin every test renders (ray casts cached) and its calibration.
pub fn twin() -> &'static (Arc<TwinRig>, RigCalibration) {
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

/// What the vendor tools render: a twin, how many of its heads, and the
/// cameras' sensor (a colour sensor's frames are saved as RGB).
pub struct VendorRig {
    pub twin: Arc<TwinRig>,
    pub heads: usize,
    pub sensor: SensorModel,
}

impl VendorRig {
    /// The two-head `large-part` twin of [`twin`], mono cameras.
    pub fn large_part() -> VendorRig {
        VendorRig {
            twin: twin().0.clone(),
            heads: HEADS.len(),
            sensor: sim_sensor(),
        }
    }
}

/// What goes wrong: the sync board, or the camera software.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fault {
    None,
    /// The board stops answering at this board tick.
    BoardVanishes {
        at_tick: u64,
    },
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
pub struct Folders {
    pub root: PathBuf,
    pub frames: PathBuf,
    pub patterns: PathBuf,
    pub out: PathBuf,
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
fn play_vendor_tools(
    rig: &VendorRig,
    board: &SimBoardHandle,
    folders: &Folders,
    fault: Fault,
    stop: &AtomicBool,
) {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    // Board clock of the last exposure saved per camera: the clock runs on
    // across plans, so later exposures are new ones.
    let mut last_start_ns: Vec<Option<u64>> = vec![None; rig.heads];
    let mut saved = vec![0usize; rig.heads];
    let mut dmd = DmdGui::default();
    while !stop.load(Ordering::Relaxed) {
        for cam in 0..rig.heads {
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
                // The board pads its heads to MAX_HEADS.
                let displayed: Vec<Vec<Displayed>> = heads
                    .iter()
                    .take(rig.heads)
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
                let (image, _) = rig
                    .twin
                    .image(cam, &timelines, window, &rig.sensor, &mut rng)
                    .expect("twin renders");
                save_frame(
                    &folders.frames.join(HEADS[cam]),
                    cam,
                    &mut saved[cam],
                    &image,
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
        // The GUI loads each pattern's LEDs from the coloured set's table
        // (white when there is none).
        let leds: Vec<[f32; 3]> = std::fs::read(dir.join(LED_FILE))
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok())
            .unwrap_or_default();
        let shown = displayed
            .iter()
            .filter(|d| d.end_ns > start_ns && d.start_ns < end_ns)
            .map(|d| Shown {
                pattern: self.pattern(&dir.join(pattern_file_name(d.pattern_index as usize))),
                start_s: d.start_ns as f64 * 1e-9,
                end_s: d.end_ns as f64 * 1e-9,
                led: leds
                    .get(d.pattern_index as usize)
                    .copied()
                    .unwrap_or([1.0; 3]),
                display: Display::Steady,
            })
            .collect();
        ProjectorTimeline { shown }
    }
}

/// Saves `image` as a 16-bit grey or RGB PNG (by its channels).
fn save_png(path: &Path, image: &Image) {
    let samples: Vec<u16> = image
        .data
        .iter()
        .map(|v| (v.clamp(0.0, 1.0) * 65535.0).round() as u16)
        .collect();
    let (w, h) = (image.width, image.height);
    let saved = if image.channels == 3 {
        image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(w, h, samples)
            .expect("RGB frame")
            .save(path)
    } else {
        image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, samples)
            .expect("grey frame")
            .save(path)
    };
    saved.expect("save");
}

/// Every other pixel of `image` in both directions.
fn halved(image: &Image) -> Image {
    let (w, h, c) = (image.width / 2, image.height / 2, image.channels);
    let data = (0..h)
        .flat_map(|y| (0..w).flat_map(move |x| (0..c).map(move |k| (x, y, k))))
        .map(|(x, y, k)| image.at(2 * x, 2 * y, k))
        .collect();
    Image {
        width: w,
        height: h,
        channels: c,
        data,
    }
}

/// Saves camera `cam`'s next frame as a 16-bit PNG (temporary + rename),
/// or gets it wrong as `fault` says.
fn save_frame(dir: &Path, cam: usize, saved: &mut usize, frame: &Image, fault: Fault) {
    let index = *saved;
    *saved += 1;
    let path = dir.join(format!("frame_{index:05}.png"));
    match fault {
        Fault::Drop { head, index: i } if head == cam && i == index => {}
        Fault::WrongSize { head, index: i } if head == cam && i == index => {
            save_png(&path, &halved(frame));
        }
        Fault::Corrupt { head, index: i } if head == cam && i == index => {
            let tmp = dir.join(".corrupt.tmp");
            std::fs::write(&tmp, b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR truncated").expect("write");
            std::fs::rename(&tmp, &path).expect("rename");
        }
        Fault::Extra { head, index: i } if head == cam && i == index => {
            save_png(&path, frame);
            save_png(&dir.join(format!("frame_{index:05}_again.png")), frame);
        }
        _ => save_png(&path, frame),
    }
}

/// Runs `scan` against a fresh simulated board with the vendor tools
/// playing along (getting `fault` wrong), then stops them.
pub fn with_vendor_tools<T>(
    name: &str,
    fault: Fault,
    scan: impl FnOnce(&Path, &Folders) -> T,
) -> (T, Folders) {
    with_vendor_tools_on(&VendorRig::large_part(), name, fault, scan)
}

/// [`with_vendor_tools`] on `rig`'s twin, heads and sensor.
pub fn with_vendor_tools_on<T>(
    rig: &VendorRig,
    name: &str,
    fault: Fault,
    scan: impl FnOnce(&Path, &Folders) -> T,
) -> (T, Folders) {
    let folders = folders(name);
    std::fs::create_dir_all(&folders.root).expect("temp folder");
    let board_config = match fault {
        Fault::BoardVanishes { at_tick } => SimBoardConfig {
            seed: 1,
            faults: FaultPlan {
                vanish_at_tick: Some(at_tick),
                ..FaultPlan::none()
            },
        },
        _ => SimBoardConfig::default(),
    };
    let board = spawn_on_pty(board_config).expect("pty board");
    let port = board.path().expect("pty path").to_owned();
    let stop = AtomicBool::new(false);
    let out = std::thread::scope(|s| {
        let vendor = s.spawn(|| play_vendor_tools(rig, &board, &folders, fault, &stop));
        let out = scan(&port, &folders);
        stop.store(true, Ordering::Relaxed);
        vendor.join().expect("vendor tools ran");
        out
    });
    (out, folders)
}
