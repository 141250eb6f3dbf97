//! Cameras read from the folder the camera vendor's software writes.
//!
//! # The contract with the vendor's software
//!
//! - **One subfolder per head**, named like the head in the rig calibration:
//!   `FRAMES/A/` holds camera A's frames, `FRAMES/B/` camera B's. (Vendor
//!   tools save one camera per folder more readily than by name pattern.)
//! - **One image file per trigger**: 8- or 16-bit grey (or RGB, reduced to
//!   luma; the high-speed mode reads RGB as its three planes and refuses
//!   grey) PNG or TIFF (`.png`, `.tif`, `.tiff`, any case). Other files, and
//!   hidden ones (name starting with `.`), are ignored, so a tool that writes
//!   `frame.png.part` or `.frame.png.tmp` and renames is read only once
//!   renamed.
//! - **Trigger order = file-name order**, digit runs compared as numbers
//!   (`img_9.png` before `img_10.png`): name frames with a counter or a
//!   timestamp, as every vendor tool can.
//! - **Only frames of this scan count**: when a plan is about to start
//!   ([`FrameSource::arm`]) the files already in the folder are noted (name,
//!   size, modification time) and ignored from then on, unless rewritten. The
//!   folder need not be emptied; files are never deleted or moved.
//! - **A frame is complete** when its size is non-zero and its size and
//!   modification time did not change between two looks one poll interval
//!   apart (so a file still being written is not read half-way); a tool that
//!   writes to a temporary name and renames is complete at once. The whole
//!   set must then stay unchanged for the settle time (below), so a writer
//!   that pauses mid-file for less than that is waited for too.
//! - **Count**: after the plan ran, [`FrameSource::take_frames`] waits up to
//!   the timeout for exactly as many new complete frames as the head's camera
//!   was triggered, then for the folder to stay so for the settle time (a
//!   late extra frame, e.g. a double trigger, is caught, not read in place of
//!   a good one); fewer at the timeout, or more at any time, is
//!   [`RigError::FrameCount`]. A file that does not decode is
//!   [`RigError::FrameDecode`], one of another size [`RigError::FrameSize`].
//! - **Values**: normalised to [0, 1] by the file's bit depth (8 or 16), or
//!   by the depth the user declares (a 12-bit camera saving 16-bit files:
//!   declare 12, values are divided by 4095 and must not exceed it).

use std::collections::HashMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime};

use super::camera_source::FrameSource;
use super::RigError;
use crate::calibration::RigCalibration;
use crate::io::images::{load_colour, load_gray};
use crate::raster::Raster;

/// One head's camera: where its frames land and their size.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FolderHead {
    /// Head name (the subfolder's name), e.g. `A`.
    pub name: String,
    /// Camera image size (width, height), pixels.
    pub image_size_px: (u32, u32),
}

impl FolderHead {
    /// Each calibrated head's camera: its name and image size.
    pub fn of_rig(calibration: &RigCalibration) -> Vec<FolderHead> {
        calibration
            .heads
            .iter()
            .map(|h| FolderHead {
                name: h.name.clone(),
                image_size_px: (h.camera.width_px, h.camera.height_px),
            })
            .collect()
    }
}

/// How to read frames from folders.
#[derive(Clone, Debug, PartialEq)]
pub struct FolderCameraConfig {
    /// The folder holding one subfolder per head.
    pub root: PathBuf,
    /// The heads in plan order (head 0 = A).
    pub heads: Vec<FolderHead>,
    /// Bits per sample the camera delivers (e.g. 12 in 16-bit files);
    /// `None`: the file's own depth (8 or 16).
    pub bit_depth: Option<u8>,
    /// How long `take_frames` waits for the frames after the plan ran.
    pub timeout: Duration,
    /// How often the folder is looked at (also the completeness check's gap).
    pub poll_interval: Duration,
    /// How long the expected count must hold before the frames are read:
    /// longer than the vendor tool's gap between two saves.
    pub settle: Duration,
}

/// Size and modification time: what tells a rewritten or growing file.
type Stamp = (u64, Option<SystemTime>);

/// Frames from the vendor software's folders; see the module doc.
#[derive(Debug)]
pub struct FolderCamera {
    config: FolderCameraConfig,
    /// Per head: files present when the current plan was armed.
    stale: Vec<HashMap<OsString, Stamp>>,
    /// Per head: frames the current plan triggers.
    expected: Vec<usize>,
}

impl FolderCamera {
    /// Frames from `config.root/<head name>/`; creates the head folders
    /// when missing (the vendor tool may want them to exist).
    pub fn new(config: FolderCameraConfig) -> Result<Self, RigError> {
        for head in &config.heads {
            let dir = config.root.join(&head.name);
            std::fs::create_dir_all(&dir)
                .map_err(|source| RigError::Folder { path: dir, source })?;
        }
        let heads = config.heads.len();
        Ok(FolderCamera {
            config,
            stale: vec![HashMap::new(); heads],
            expected: vec![0; heads],
        })
    }

    /// The folder head `head`'s frames land in.
    pub fn head_dir(&self, head: usize) -> Result<PathBuf, RigError> {
        let h = self.head(head)?;
        Ok(self.config.root.join(&h.name))
    }

    fn head(&self, head: usize) -> Result<&FolderHead, RigError> {
        self.config.heads.get(head).ok_or(RigError::NoSuchHead {
            head,
            heads: self.config.heads.len(),
        })
    }

    /// Frame files of this scan in `dir` now: name -> stamp.
    fn fresh(&self, head: usize, dir: &Path) -> Result<HashMap<OsString, Stamp>, RigError> {
        let mut now = frame_files(dir)?;
        now.retain(|name, stamp| self.stale[head].get(name) != Some(stamp));
        Ok(now)
    }

    /// Waits until `expected` complete fresh frames are there; their names
    /// in trigger order.
    fn wait_for_frames(&self, head: usize, expected: usize) -> Result<Vec<OsString>, RigError> {
        let dir = self.head_dir(head)?;
        let deadline = Instant::now() + self.config.timeout;
        let mut last: HashMap<OsString, Stamp> = HashMap::new();
        let mut reached_at: Option<Instant> = None;
        loop {
            let now = self.fresh(head, &dir)?;
            let count_error = |got| RigError::FrameCount {
                head,
                expected,
                got,
                missed: Vec::new(),
            };
            if now.len() > expected {
                return Err(count_error(now.len()));
            }
            let complete = now
                .iter()
                .filter(|(name, stamp)| stamp.0 > 0 && last.get(*name) == Some(stamp))
                .count();
            if complete == expected && now.len() == expected {
                let since = *reached_at.get_or_insert_with(Instant::now);
                // Settled: a late extra frame, or a writer that paused
                // mid-file, would have shown up by now.
                if since.elapsed() >= self.config.settle {
                    let mut names: Vec<OsString> = now.into_keys().collect();
                    names.sort_by(|a, b| natural_cmp(&a.to_string_lossy(), &b.to_string_lossy()));
                    return Ok(names);
                }
            } else {
                // Something changed: the settle time starts again.
                reached_at = None;
                if Instant::now() >= deadline {
                    return Err(count_error(now.len()));
                }
            }
            last = now;
            std::thread::sleep(self.config.poll_interval);
        }
    }

    /// Reads frame `frame` of head `head`: decoded, size-checked, normalised.
    fn read_frame(&self, head: usize, frame: usize, path: &Path) -> Result<Raster<f32>, RigError> {
        let loaded = load_gray(path).map_err(|source| RigError::FrameDecode {
            head,
            frame,
            source,
        })?;
        let mut image = loaded.image;
        self.check_size(head, frame, path, image.size())?;
        self.rescale(head, frame, path, loaded.bit_depth, &mut image.data)?;
        Ok(image)
    }

    /// Reads colour frame `frame` of head `head` (RGB): its planes decoded,
    /// size-checked, normalised together.
    fn read_colour_frame(
        &self,
        head: usize,
        frame: usize,
        path: &Path,
    ) -> Result<[Raster<f32>; 3], RigError> {
        let loaded = load_colour(path).map_err(|source| RigError::FrameDecode {
            head,
            frame,
            source,
        })?;
        let mut planes = loaded.planes;
        self.check_size(head, frame, path, planes[0].size())?;
        for plane in &mut planes {
            self.rescale(head, frame, path, loaded.bit_depth, &mut plane.data)?;
        }
        Ok(planes)
    }

    /// Fails unless a frame of `got` pixels is head `head`'s image size.
    fn check_size(
        &self,
        head: usize,
        frame: usize,
        path: &Path,
        got: (usize, usize),
    ) -> Result<(), RigError> {
        let expected = self.head(head)?.image_size_px;
        if got != (expected.0 as usize, expected.1 as usize) {
            return Err(RigError::FrameSize {
                head,
                frame,
                path: path.to_owned(),
                expected,
                got,
            });
        }
        Ok(())
    }

    /// Rescales `data`, read from a `file_bits`-deep file, to the declared
    /// bit depth, if one is declared, refusing values the depth cannot hold.
    fn rescale(
        &self,
        head: usize,
        frame: usize,
        path: &Path,
        file_bits: u8,
        data: &mut [f32],
    ) -> Result<(), RigError> {
        let Some(declared) = self.config.bit_depth else {
            return Ok(());
        };
        let file_max = ((1u32 << file_bits) - 1) as f32;
        let declared_max = ((1u64 << declared.min(32)) - 1) as f32;
        let max_value = data
            .iter()
            .map(|v| (v * file_max).round() as u32)
            .max()
            .unwrap_or(0);
        if declared > file_bits || max_value as f32 > declared_max {
            return Err(RigError::FrameBitDepth {
                head,
                frame,
                path: path.to_owned(),
                file_bits,
                declared_bits: declared,
                max_value,
            });
        }
        let scale = file_max / declared_max;
        data.iter_mut().for_each(|v| *v *= scale);
        Ok(())
    }

    /// Head `head`'s frames of the armed plan, each read by `read`.
    fn take_with<T>(
        &mut self,
        head: usize,
        read: fn(&Self, usize, usize, &Path) -> Result<T, RigError>,
    ) -> Result<Vec<T>, RigError> {
        self.head(head)?;
        let expected = self.expected[head];
        let names = self.wait_for_frames(head, expected)?;
        let dir = self.head_dir(head)?;
        let frames = names
            .iter()
            .enumerate()
            .map(|(i, name)| read(self, head, i, &dir.join(name)))
            .collect::<Result<Vec<_>, _>>()?;
        // Taken: a second call for the same plan finds nothing new.
        self.stale[head].extend(frame_files(&dir)?);
        self.expected[head] = 0;
        Ok(frames)
    }
}

impl FrameSource for FolderCamera {
    fn image_size_px(&self, head: usize) -> Result<(u32, u32), RigError> {
        Ok(self.head(head)?.image_size_px)
    }

    fn arm(&mut self, frames_per_head: &[usize]) -> Result<(), RigError> {
        for head in 0..self.config.heads.len() {
            let dir = self.head_dir(head)?;
            let stale = frame_files(&dir)?;
            if !stale.is_empty() {
                tracing::info!(
                    folder = %dir.display(),
                    files = stale.len(),
                    "frames already in the folder belong to earlier scans; ignored"
                );
            }
            self.stale[head] = stale;
            self.expected[head] = frames_per_head.get(head).copied().unwrap_or(0);
        }
        Ok(())
    }

    fn take_frames(&mut self, head: usize) -> Result<Vec<Raster<f32>>, RigError> {
        self.take_with(head, Self::read_frame)
    }

    fn take_colour_frames(&mut self, head: usize) -> Result<Vec<[Raster<f32>; 3]>, RigError> {
        self.take_with(head, Self::read_colour_frame)
    }
}

/// The frame files of `dir` (PNG/TIFF, not hidden) with their stamps.
fn frame_files(dir: &Path) -> Result<HashMap<OsString, Stamp>, RigError> {
    let io = |source| RigError::Folder {
        path: dir.to_owned(),
        source,
    };
    let mut out = HashMap::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let entry = entry.map_err(io)?;
        let name = entry.file_name();
        if !is_frame_name(&name.to_string_lossy()) {
            continue;
        }
        // A file renamed or deleted between listing and stat is skipped:
        // the next look sees the folder as it is then.
        let Ok(meta) = entry.metadata() else { continue };
        if meta.is_file() {
            out.insert(name, (meta.len(), meta.modified().ok()));
        }
    }
    Ok(out)
}

/// PNG or TIFF by extension (any case), not hidden.
fn is_frame_name(name: &str) -> bool {
    if name.starts_with('.') {
        return false;
    }
    let ext = Path::new(name)
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    matches!(ext.as_deref(), Some("png" | "tif" | "tiff"))
}

/// File-name order with digit runs compared as numbers: `f9` < `f10`.
pub fn natural_cmp(a: &str, b: &str) -> std::cmp::Ordering {
    let (mut a, mut b) = (a, b);
    loop {
        match (a.is_empty(), b.is_empty()) {
            (true, true) => return std::cmp::Ordering::Equal,
            (true, false) => return std::cmp::Ordering::Less,
            (false, true) => return std::cmp::Ordering::Greater,
            _ => {}
        }
        let (ra, rest_a) = split_run(a);
        let (rb, rest_b) = split_run(b);
        let digits = |s: &str| s.starts_with(|c: char| c.is_ascii_digit());
        let order = if digits(ra) && digits(rb) {
            let (ta, tb) = (ra.trim_start_matches('0'), rb.trim_start_matches('0'));
            ta.len()
                .cmp(&tb.len())
                .then_with(|| ta.cmp(tb))
                .then_with(|| ra.len().cmp(&rb.len()))
        } else {
            ra.cmp(rb)
        };
        if order.is_ne() {
            return order;
        }
        (a, b) = (rest_a, rest_b);
    }
}

/// The leading run of digits or of non-digits, and the rest.
fn split_run(s: &str) -> (&str, &str) {
    let digit = s.starts_with(|c: char| c.is_ascii_digit());
    let end = s
        .find(|c: char| c.is_ascii_digit() != digit)
        .unwrap_or(s.len());
    s.split_at(end)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::images::{save_gray_png, ImageError};

    fn temp_root(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "slscan-folder-camera-{}-{name}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    fn camera(root: &Path, bit_depth: Option<u8>) -> FolderCamera {
        FolderCamera::new(FolderCameraConfig {
            root: root.to_owned(),
            heads: vec![FolderHead {
                name: "A".into(),
                image_size_px: (4, 3),
            }],
            bit_depth,
            timeout: Duration::from_millis(300),
            poll_interval: Duration::from_millis(10),
            settle: Duration::from_millis(30),
        })
        .unwrap()
    }

    fn frame(value: f32) -> Raster<f32> {
        Raster::filled(4, 3, value)
    }

    #[test]
    fn frames_come_in_natural_name_order_and_old_ones_are_ignored() {
        let root = temp_root("order");
        let mut cam = camera(&root, None);
        let dir = root.join("A");
        save_gray_png(&dir.join("old_1.png"), &frame(0.9), false).unwrap();
        cam.arm(&[3]).unwrap();
        // Written out of order; a non-image and a hidden file are ignored.
        for (name, v) in [("f10.png", 2.0), ("f9.png", 1.0), ("f11.tif", 3.0)] {
            let img = frame(v / 10.0);
            if name.ends_with("tif") {
                let buf = image::GrayImage::from_pixel(4, 3, image::Luma([77]));
                buf.save(dir.join(name)).unwrap();
            } else {
                save_gray_png(&dir.join(name), &img, false).unwrap();
            }
        }
        std::fs::write(dir.join("notes.txt"), b"x").unwrap();
        std::fs::write(dir.join(".f12.png.tmp"), b"x").unwrap();
        let frames = cam.take_frames(0).unwrap();
        let firsts: Vec<f32> = frames.iter().map(|f| f.data[0]).collect();
        assert_eq!(firsts, [26.0 / 255.0, 51.0 / 255.0, 77.0 / 255.0]);
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn colour_frames_come_as_planes_scaled_to_the_declared_depth_and_grey_ones_are_refused() {
        let root = temp_root("colour");
        let mut cam = camera(&root, Some(12));
        let dir = root.join("A");
        cam.arm(&[2]).unwrap();
        for (k, rgb) in [[4095u16, 2048, 0], [0, 1, 4095]].iter().enumerate() {
            let buf =
                image::ImageBuffer::<image::Rgb<u16>, _>::from_fn(4, 3, |_, _| image::Rgb(*rgb));
            buf.save(dir.join(format!("f{k}.png"))).unwrap();
        }
        let frames = cam.take_colour_frames(0).unwrap();
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[0][0].size(), (4, 3));
        for (frame, rgb) in frames
            .iter()
            .zip([[4095.0, 2048.0, 0.0], [0.0, 1.0, 4095.0]])
        {
            for (plane, want) in frame.iter().zip(rgb) {
                assert!(
                    (plane.data[0] * 4095.0 - want).abs() < 1e-3,
                    "{}",
                    plane.data[0]
                );
            }
        }

        // A grey frame has lost its colours: a typed error, not a guess.
        cam.arm(&[1]).unwrap();
        save_gray_png(&dir.join("f2.png"), &frame(0.5), false).unwrap();
        let err = cam.take_colour_frames(0).unwrap_err();
        assert!(
            matches!(
                &err,
                RigError::FrameDecode {
                    frame: 0,
                    source: ImageError::UnsupportedFormat { .. },
                    ..
                }
            ),
            "{err}"
        );
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn too_few_too_many_wrong_size_and_corrupt_frames_are_typed_errors() {
        let root = temp_root("errors");
        let mut cam = camera(&root, None);
        let dir = root.join("A");
        cam.arm(&[2]).unwrap();
        save_gray_png(&dir.join("f0.png"), &frame(0.5), false).unwrap();
        let err = cam.take_frames(0).unwrap_err();
        assert!(
            matches!(
                err,
                RigError::FrameCount {
                    head: 0,
                    expected: 2,
                    got: 1,
                    ..
                }
            ),
            "{err}"
        );

        cam.arm(&[1]).unwrap();
        save_gray_png(&dir.join("f1.png"), &frame(0.5), false).unwrap();
        save_gray_png(&dir.join("f2.png"), &frame(0.5), false).unwrap();
        let err = cam.take_frames(0).unwrap_err();
        assert!(
            matches!(
                err,
                RigError::FrameCount {
                    expected: 1,
                    got: 2,
                    ..
                }
            ),
            "{err}"
        );

        cam.arm(&[1]).unwrap();
        save_gray_png(&dir.join("f3.png"), &Raster::filled(5, 3, 0.5), false).unwrap();
        let err = cam.take_frames(0).unwrap_err();
        assert!(
            matches!(
                err,
                RigError::FrameSize {
                    got: (5, 3),
                    expected: (4, 3),
                    ..
                }
            ),
            "{err}"
        );

        cam.arm(&[1]).unwrap();
        std::fs::write(dir.join("f4.png"), b"\x89PNG\r\n\x1a\n truncated").unwrap();
        let err = cam.take_frames(0).unwrap_err();
        assert!(
            matches!(err, RigError::FrameDecode { frame: 0, .. }),
            "{err}"
        );
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn an_extra_frame_arriving_while_the_count_settles_is_caught() {
        let root = temp_root("settle");
        let mut cam = camera(&root, None);
        cam.config.settle = Duration::from_millis(250);
        let dir = root.join("A");
        cam.arm(&[1]).unwrap();
        save_gray_png(&dir.join("f0.png"), &frame(0.5), false).unwrap();
        let late = dir.join("f1.png");
        let writer = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(80));
            save_gray_png(&late, &frame(0.5), false).unwrap();
        });
        let err = cam.take_frames(0).unwrap_err();
        writer.join().unwrap();
        assert!(
            matches!(
                err,
                RigError::FrameCount {
                    expected: 1,
                    got: 2,
                    ..
                }
            ),
            "{err}"
        );
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn a_file_written_in_bursts_is_read_whole() {
        let root = temp_root("bursts");
        let mut cam = camera(&root, None);
        cam.config.settle = Duration::from_millis(250);
        cam.config.timeout = Duration::from_secs(5);
        let dir = root.join("A");
        let whole_path = root.join("whole.png");
        save_gray_png(&whole_path, &frame(0.5), false).unwrap();
        let whole = std::fs::read(&whole_path).unwrap();
        cam.arm(&[1]).unwrap();
        let third = whole.len() / 3;
        std::fs::write(dir.join("f0.png"), &whole[..third]).unwrap();
        // The writer pauses twice for many poll intervals; together the
        // pauses outlast the settle time, each alone does not.
        let rest = whole[third..].to_vec();
        let path = dir.join("f0.png");
        let writer = std::thread::spawn(move || {
            use std::io::Write;
            let mut f = std::fs::OpenOptions::new().append(true).open(path).unwrap();
            for chunk in rest.chunks(rest.len().div_ceil(2)) {
                std::thread::sleep(Duration::from_millis(150));
                f.write_all(chunk).unwrap();
                f.flush().unwrap();
            }
        });
        let frames = cam.take_frames(0).unwrap();
        writer.join().unwrap();
        assert_eq!(frames[0].data[0], 128.0 / 255.0);
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn a_declared_12_bit_depth_rescales_16_bit_files_and_rejects_overflow() {
        let root = temp_root("depth");
        let mut cam = camera(&root, Some(12));
        let dir = root.join("A");
        cam.arm(&[1]).unwrap();
        // 2048 of 4095 in a 16-bit file.
        save_gray_png(&dir.join("f0.png"), &frame(2048.0 / 65535.0), true).unwrap();
        let f = cam.take_frames(0).unwrap();
        assert!(
            (f[0].data[0] - 2048.0 / 4095.0).abs() < 1e-6,
            "{}",
            f[0].data[0]
        );
        cam.arm(&[1]).unwrap();
        save_gray_png(&dir.join("f1.png"), &frame(5000.0 / 65535.0), true).unwrap();
        let err = cam.take_frames(0).unwrap_err();
        assert!(
            matches!(
                err,
                RigError::FrameBitDepth {
                    max_value: 5000,
                    declared_bits: 12,
                    ..
                }
            ),
            "{err}"
        );
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn natural_order_compares_digit_runs_as_numbers() {
        let mut names = vec!["f10.png", "f9.png", "f010.png", "g1.png", "f1.png"];
        names.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(names, ["f1.png", "f9.png", "f10.png", "f010.png", "g1.png"]);
    }
}
